"""Members on small records: what ``canonid train --members K`` (:mod:`canonid.members`)
chooses on the small records of the studies, on validation, and the test scores of its choice,
read once.

Per record: the defaults' run (seed 0: ``canonid train DATA --threads 1``, its window chosen by the
screen; the runs of the sections "Small data" and "Overflow tanks") and runs of the same recipe from
seeds 1 and 2 at the defaults' window (``python benchmarks/studies/members/members_study.py
train NAME SEED``:
``canonid train DATA --window L --seed S --threads 1``, with ``--cubic N`` where the defaults' run
has N cubic units; the feedthrough and cubic tests otherwise decide again on the same data — the
members' networks are checked equal before they are averaged). For K = 2 and 3 the members are seeds
0 … K − 1; every member and the means of the j members of lowest loss (j = 2 … K) are scored on the
defaults' validation windows by :func:`canonid.learning.members.validation_losses`, and
:func:`canonid.members.kept_candidate` chooses, as ``canonid train --members K`` does. Only then are
the test parts scored, for the defaults' model and each choice: the official Silverbox test parts
(``canonid.benchmark.score_parts``, RMSE in mV after n_init = 50) for the cuts of Silverbox's
training part, the test record for the overflow tanks (simulation after n_init = 50, RMSE in V).

``record`` writes the section "Members on small records" of the records (benchmarks/records/) and
``benchmarks/studies/members/members_study.json`` (every loss and score).

Usage: python benchmarks/studies/members/members_study.py train NAME SEED
       python benchmarks/studies/members/members_study.py record

"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

from _results import write_section  # noqa: E402

from canonid.kernel.io import atomic_write_json  # noqa: E402

RUNS = ROOT / "runs"
STUDY = Path(__file__).resolve().parent / "members_study.json"
SECTION = "Members on small records"
SEEDS = (0, 1, 2)


@dataclass(frozen=True)
class Record:
    """A small record: its data, the defaults' run (seed 0) and where its other seeds train."""

    data: str
    first: str
    members: str  # run folder of seed S: members.format(seed=S)
    score: str  # "silverbox" (the official test parts) or "record" (the test record)
    label: str


RECORDS = {
    "silverbox-1k": Record(
        "runs/small-data/data/n1000/dataset.npz",
        "runs/small-data/n1000",
        "runs/members/n1000-s{seed}",
        "silverbox",
        "Silverbox, first 1,000 samples (800 / 200)",
    ),
    "silverbox-3k": Record(
        "runs/small-data/data/n3000/dataset.npz",
        "runs/small-data/n3000",
        "runs/members/n3000-s{seed}",
        "silverbox",
        "Silverbox, first 3,000 samples (2,400 / 600)",
    ),
    "overflow-tanks": Record(
        "runs/data/tanks-overflow",
        "runs/overflow-bptt",
        "runs/members/overflow-s{seed}",
        "record",
        "overflow tanks, 1,024 samples (819 / 205)",
    ),
}


def run_of(record: Record, seed: int) -> Path:
    return ROOT / (record.first if seed == 0 else record.members.format(seed=seed))


def train(name: str, seed: int) -> int:
    """Train seed ``seed`` of record ``name`` at the defaults' window (and its cubic units,
    where it has a branch; the feedthrough and cubic tests otherwise decide on the same data,
    and :func:`study` refuses members whose networks differ)."""
    from canonid.learning import Model

    record = RECORDS[name]
    first = Model.load(ROOT / record.first)
    cubic = int(first.net.config().get("cubic") or 0)
    command = [
        sys.executable,
        "-m",
        "canonid",
        "train",
        str(ROOT / record.data),
        "--window",
        str(first.window),
        "--seed",
        str(seed),
        *(("--cubic", str(cubic)) if cubic else ()),
        "--threads",
        "1",
        "--no-progress",
        "--out",
        str(run_of(record, seed)),
    ]
    print(" ".join(command[2:]), flush=True)
    return subprocess.call(command, cwd=ROOT)


def _training_seconds(run: Path) -> float:
    with (run / "history.csv").open() as fh:
        return sum(float(row["seconds"] or 0) for row in csv.DictReader(fh))


def _test_scores(record: Record, model: Any) -> dict[str, float]:
    import numpy as np

    from canonid.kernel.dataset import Dataset

    if record.score == "silverbox":  # the cut datasets hold the official test parts
        from canonid.benchmark import score_parts
        from canonid.datagen.benchmarks import benchmark

        parts, _ = score_parts(model, Dataset.load(ROOT / record.data), benchmark("silverbox"))
        return {p.test: p.rmse for p in parts}
    from canonid.datagen.loaders import load_data
    from canonid.learning.evaluate import simulate_records

    test = list(load_data(str(ROOT / record.data)).split("test"))
    (sim,) = simulate_records(model, test, 50)
    return {"test record": float(np.sqrt(np.mean((sim - test[0].y[50:]) ** 2)))}


def study() -> dict[str, Any]:
    from canonid.learning import Model
    from canonid.learning.members import average_members, validation_losses
    from canonid.members import kept_candidate
    from canonid.runfolder import RunRecipe, load_splits

    out: dict[str, Any] = {}
    for name, record in RECORDS.items():
        runs = [run_of(record, s) for s in SEEDS]
        if not all((r / "weights.pt").is_file() for r in runs):
            print(f"{name}: a member has not trained yet, skipped", file=sys.stderr)
            continue
        recipe = RunRecipe.read(runs[0])
        _, _, val, _, _ = load_splits(recipe)
        options = recipe.options()
        models = [Model.load(r) for r in runs]
        losses = validation_losses(models, val, options)
        entry: dict[str, Any] = {
            "label": record.label,
            "window": models[0].window,
            "runs": [str(r.relative_to(ROOT)) for r in runs],
            "training_seconds": [round(_training_seconds(r), 1) for r in runs],
            "losses": losses,
            "choices": {},
        }
        kept_models: dict[str, Any] = {"defaults": models[0]}
        for k in (2, 3):
            order = sorted(range(k), key=lambda i: (losses[i], i))
            means = [average_members([models[i] for i in order[:j]]) for j in range(2, k + 1)]
            mean_losses = list(zip(range(2, k + 1), validation_losses(means, val, options)))
            kept = kept_candidate(SEEDS[:k], losses[:k], mean_losses)
            entry["choices"][str(k)] = {"means": mean_losses, "kept": kept}
            by_name = {f"seed {s}": models[s] for s in SEEDS[:k]}
            by_name.update({f"mean of {j}": m for j, m in zip(range(2, k + 1), means)})
            kept_models[f"K = {k}"] = by_name[kept]
        # the test parts, read once, after every choice above
        entry["test"] = {key: _test_scores(record, model) for key, model in kept_models.items()}
        out[name] = entry
    return out


def render(found: dict[str, Any]) -> str:
    lines = [
        "What `canonid train --members K` (`canonid.members`) chooses on the small records of "
        "the studies, and what it gives (`benchmarks/studies/members/members_study.py`; every "
        "number is in "
        "`benchmarks/studies/members/members_study.json`). Members: the defaults' run (seed 0, the "
        'sections "Small data" and "Overflow tanks") and the same recipe from seeds 1 and 2 '
        "at the defaults' window (`python benchmarks/studies/members/members_study.py train NAME "
        "SEED`: "
        "`canonid train DATA --window L --seed S --threads 1`, `--cubic N` where the defaults' "
        "run has N cubic units; the feedthrough and cubic tests otherwise decided again on the "
        "same data, and as for the defaults: the members' networks are checked equal). "
        "Candidates for K members (seeds 0 … K − 1): each member alone and the "
        "means of the j members of lowest validation loss (their regressors averaged at every "
        "step), scored on the defaults' validation windows by one routine "
        "(`canonid.learning.members.validation_losses`, normalised rollout MSE, the loss "
        "training reports); the lowest is kept (`canonid.members.kept_candidate`). The test "
        "parts were scored once, after the choices.",
        "",
        "Validation (normalised):",
        "",
        "| record | ℓ | seed 0 (defaults) | seed 1 | seed 2 | K = 2: mean of 2 | K = 2 keeps "
        "| K = 3: mean of 2 / of 3 | K = 3 keeps | kept / seed 0, K = 2 | kept / seed 0, K = 3 |",
        "|---|---:|---:|---:|---:|---:|---|---|---|---:|---:|",
    ]
    for entry in found.values():
        losses = entry["losses"]
        two, three = entry["choices"]["2"], entry["choices"]["3"]

        def kept_loss(choice: dict[str, Any], k: int, losses: list[float] = losses) -> float:
            table = {f"seed {s}": losses[s] for s in SEEDS[:k]}
            table.update({f"mean of {j}": loss for j, loss in choice["means"]})
            return float(table[choice["kept"]])

        lines.append(
            f"| {entry['label']} | {entry['window']} | {losses[0]:.4g} | {losses[1]:.4g} | "
            f"{losses[2]:.4g} | {two['means'][0][1]:.4g} | {two['kept']} | "
            f"{three['means'][0][1]:.4g} / {three['means'][1][1]:.4g} | {three['kept']} | "
            f"{kept_loss(two, 2) / losses[0]:.3f} | {kept_loss(three, 3) / losses[0]:.3f} |"
        )
    lines += ["", "Test, read once after the choices (RMSE):", ""]
    lines += [
        "| record | part | defaults (seed 0) | K = 2 | K = 3 | training time of the members "
        "(s, wall, summed epochs) |",
        "|---|---|---:|---:|---:|---|",
    ]
    for entry in found.values():
        test = entry["test"]
        units = "V" if "test record" in test["defaults"] else "mV"
        seconds = " / ".join(f"{s:.0f}" for s in entry["training_seconds"])
        for part in test["defaults"]:
            lines.append(
                f"| {entry['label']} | {part} [{units}] | {test['defaults'][part]:.4g} | "
                f"{test['K = 2'][part]:.4g} | {test['K = 3'][part]:.4g} | {seconds} |"
            )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="what", required=True)
    one = sub.add_parser("train", help="train one member run")
    one.add_argument("name", choices=sorted(RECORDS))
    one.add_argument("seed", type=int, choices=SEEDS[1:])
    sub.add_parser("record", help="choose on validation, score the test once, write")
    args = parser.parse_args()
    if args.what == "train":
        return train(args.name, args.seed)
    found = study()
    atomic_write_json(STUDY, found)
    write_section(SECTION, render(found))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
