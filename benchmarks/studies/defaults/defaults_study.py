"""A change of the defaults (``quick`` profile, Ours (MLP)'s network options), measured on the
three systems that choose them.

Each call trains Ours (MLP), ℓ = 10, with canonid's default network options updated by the
``--net`` overrides (``linear=off``: no affine path) and the ``quick`` profile updated by the
``--set`` overrides (none: the profile as it is; ``grad_clip=null`` switches the clipping off),
one torch thread, and appends one JSON row to ``--rows``; ``table`` turns the rows into the
section "Defaults study" of its notes (``benchmarks/records/``), the variants side by side per
system and
seed::

    python benchmarks/studies/defaults/defaults_study.py run tank --seed 0 --label "now"
    python benchmarks/studies/defaults/defaults_study.py run silverbox --seed 0 --label "5e-3, \
        no skip" \
        --set lr=0.005 grad_clip=null --net linear=off
    python benchmarks/studies/defaults/defaults_study.py table

Systems: ``tank`` (``canonid generate tank``: 60 / 20 / 20 trajectories) and ``drone2d``
(``canonid generate drone2d --n-train 40 --n-val 10 --n-test 10``, the deepSI contest's data),
both generated into ``runs/data`` when missing and scored by :func:`canonid.learning.evaluate`
(100-step rollouts from every start of the test split, MSE against ``y_clean``); ``silverbox`` (the
real record, trained and scored by ``bench_silverbox.run``: multisine-test simulation RMSE after
n_init = 50, mV). CPU time: this process's, over training (Silverbox: and scoring, ~1 s).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

from _data import ensure_dataset  # noqa: E402
from _results import append_row, read_rows, write_section  # noqa: E402

from canonid.kernel.io import atomic_write_text  # noqa: E402

WINDOW = 10
ROWS = Path(__file__).resolve().parent / "defaults_study.jsonl"
NOTES = Path(__file__).resolve().parent / "defaults_study_notes.md"
SECTION = "Defaults study"
GENERATED = {"tank": "tank-s0", "drone2d": "drone2d-small"}


def _value(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def overrides_of(pairs: Sequence[str], flag: str = "--set") -> dict[str, Any]:
    """``["lr=0.005", "epochs=900"]`` → ``{"lr": 0.005, "epochs": 900}``."""
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep:
            raise SystemExit(f"{flag} {pair!r}: expected KEY=VALUE")
        out[key] = _value(text)
    return out


def run_generated(
    system: str, seed: int, overrides: dict[str, Any], net: dict[str, Any]
) -> dict[str, Any]:
    from canonid.kernel.dataset import Dataset
    from canonid.learning import evaluate, fit
    from canonid.profiles import stage_train_options

    data = Dataset.load(ensure_dataset(GENERATED[system]))
    train, val, test = (data.split(name) for name in ("train", "val", "test"))
    opts = stage_train_options(  # None in overrides switches an option off
        "quick", {"seed": seed, "device": "cpu", "checkpoint_every": 10**6, **overrides}
    )
    start = time.process_time()
    result = fit(train, val, model="mlp", window=WINDOW, options=opts, net_options=net)
    cpu = time.process_time() - start
    scores = evaluate(result.model, test, horizon=100)
    return {
        "score": scores.clean.rollout_mse,
        "score_name": "test 100-step MSE vs y_clean",
        "best_val": result.best_val_loss,
        "best_epoch": result.best_epoch,
        "epochs": result.epochs_run,
        "cpu_s": cpu,
    }


def run_silverbox(seed: int, overrides: dict[str, Any], net: dict[str, Any]) -> dict[str, Any]:
    import bench_silverbox

    bench_silverbox.VARIANTS["study"] = ("mlp", net, overrides)
    row = bench_silverbox.run(
        bench_silverbox.load(bench_silverbox.DEFAULT_CSV), "study", seed, WINDOW
    )
    return {
        "score": row.rmse_mv,
        "score_name": "multisine test RMSE [mV]",
        "best_val": row.val_loss,
        "best_epoch": row.best_epoch,
        "epochs": row.epochs,
        "cpu_s": row.cpu_s,
    }


def _number(x: float) -> str:
    return f"{x:.4g}" if abs(x) >= 0.01 else f"{x:.2e}"


def table(rows: list[dict[str, Any]]) -> str:
    labels = list(dict.fromkeys(r["label"] for r in rows))
    cases = sorted({(r["system"], r["seed"]) for r in rows})
    found = {(r["system"], r["seed"], r["label"]): r for r in rows}
    lines = [
        "Ours (MLP), ℓ = 10, canonid's default network options and the `quick` profile with "
        "the overrides of each column, one torch thread; tank and planar drone: test 100-step MSE "
        "against y_clean (`canonid.learning.evaluate`); Silverbox: multisine-test simulation "
        "RMSE after n_init = 50 (mV). Each cell: score (best validation loss, normalised; CPU "
        "seconds of "
        "training).",
        "",
        "| system | seed | " + " | ".join(labels) + " |",
        "|---|---:|" + "---:|" * len(labels),
    ]
    for system, seed in cases:
        cells = []
        for label in labels:
            r = found.get((system, seed, label))
            cells.append(
                "—"
                if r is None
                else f"{_number(r['score'])} ({_number(r['best_val'])}; {r['cpu_s']:.0f} s)"
            )
        lines.append(f"| {system} | {seed} | " + " | ".join(cells) + " |")
    overrides = {r["label"]: (r["overrides"], r.get("net", {})) for r in rows}
    lines += [
        "",
        "Overrides per column (profile; network options): "
        + "; ".join(
            f"{label}: `{json.dumps(overrides[label][0])}`; `{json.dumps(overrides[label][1])}`"
            for label in labels
        )
        + ".",
    ]
    loads = [r["load"] for r in rows if r.get("load") is not None]
    if loads:
        lines.append(
            f"Load average (1 min) at the end of the runs that recorded it: "
            f"{min(loads):.1f}–{max(loads):.1f} on {os.cpu_count()} cores."
        )
    if NOTES.is_file():  # how the rows were produced, for a reader who was not there
        lines += ["", NOTES.read_text(encoding="utf-8").strip()]
    return "\n".join(lines)


#: the column without feedthrough (the defaults before feedthrough="auto") and the one with it
NO_FEEDTHROUGH = "3e-3, clip 1, skip from zero, no feedthrough"
FEEDTHROUGH = "3e-3, clip 1, skip from zero, feedthrough"
#: the column of today's defaults (composed: see :func:`compose`), the reference of the choice
REFERENCE = "feedthrough auto (now)"


def decide(system: str) -> Any:
    """What ``feedthrough="auto"`` decides on ``system``'s training and validation data, ℓ = 10
    (:func:`canonid.learning.linear.feedthrough_test`)."""
    from canonid.kernel.dataset import Dataset, Trajectory
    from canonid.learning.data import Normalisation
    from canonid.learning.linear import feedthrough_test

    if system == "silverbox":
        import bench_silverbox as sb

        train, val = ([Trajectory.of(r)] for r in sb.train_val(sb.load(sb.DEFAULT_CSV)))
    else:
        ds = Dataset.load(ensure_dataset(GENERATED[system]) / "dataset.npz")
        train, val = ds.split("train"), ds.split("val")
    return feedthrough_test(train, val, Normalisation.fit(train), window=WINDOW)


def compose(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of :data:`REFERENCE`: on each system, the row of the column that
    ``feedthrough="auto"`` picks there (the decision reads the same data as those runs, and
    training is otherwise the same), named as such."""
    out = []
    for system in sorted({r["system"] for r in rows}):
        test = decide(system)
        source = FEEDTHROUGH if test.feedthrough else NO_FEEDTHROUGH
        for r in rows:
            if r["system"] == system and r["label"] == source:
                out.append(
                    {
                        **r,
                        "label": REFERENCE,
                        "net": {**r["net"], "feedthrough": "auto"},
                        "source": f"composed: feedthrough_test gave with/without u_t = "
                        f"{test.with_u / test.without_u:.3f}, so the row of '{source}'",
                    }
                )
    return out


SELECTION = "Defaults study: the choice on validation"


def choose(rows: list[dict[str, Any]], reference: str = REFERENCE) -> tuple[list[dict], str]:
    """Each column's best validation losses against ``reference``'s, and the column the rule
    keeps: the lowest mean over systems of the mean over seeds of ``ln(val / val_reference)``,
    among the columns that are options of the code and have every case the reference has.
    Test scores are not read."""
    found = {(r["system"], r["seed"], r["label"]): r["best_val"] for r in rows}
    cases = sorted({(r["system"], r["seed"]) for r in rows if r["label"] == reference})
    systems = sorted({s for s, _ in cases})
    out = []
    for label in dict.fromkeys(r["label"] for r in rows):
        option = all(r.get("code_option", True) for r in rows if r["label"] == label)
        logs: dict[str, list[float]] = {s: [] for s in systems}
        for system, seed in cases:
            v = found.get((system, seed, label))
            if v is not None:
                logs[system].append(math.log(v / found[(system, seed, reference)]))
        per_system = {s: statistics.fmean(v) for s, v in logs.items() if v}
        out.append(
            {
                "label": label,
                "cases": sum(len(v) for v in logs.values()),
                "per_system": per_system,
                "score": statistics.fmean(per_system.values()) if per_system else math.nan,
                "complete": all(
                    len(logs[s]) == sum(1 for c in cases if c[0] == s) for s in systems
                ),
                "option": option,
            }
        )
    eligible = [c for c in out if c["complete"] and c["option"]]
    return out, min(eligible, key=lambda c: c["score"])["label"]


def selection_section(rows: list[dict[str, Any]]) -> str:
    columns, kept = choose(rows)
    systems = sorted({s for c in columns for s in c["per_system"]})
    n_cases = max(c["cases"] for c in columns)
    lines = [
        'The columns of the section "Defaults study" compared by their **best validation '
        "losses** only (normalised rollout MSE on each system's validation split; the test "
        f"scores are not read): for every case (system and seed) that the column of today's "
        f"defaults ({REFERENCE}) has, the ratio of the column's best validation loss to that "
        "column's, as a geometric mean over seeds per system, then over systems. The rule keeps "
        f"the lowest among the columns that are options of the code and cover all {n_cases} "
        "cases.",
        "",
        "| column | cases | "
        + " | ".join(f"{s}: validation ratio" for s in systems)
        + " | mean over systems | eligible |",
        "|---|---:|" + "---:|" * (len(systems) + 1) + "---|",
    ]
    for c in sorted(columns, key=lambda c: (not (c["complete"] and c["option"]), c["score"])):
        ratios = [
            f"{math.exp(c['per_system'][s]):.3f}" if s in c["per_system"] else "—" for s in systems
        ]
        why = (
            "yes"
            if c["complete"] and c["option"]
            else ("no: not an option of the code" if not c["option"] else "no: cases missing")
        )
        if c["label"] == kept:
            why = "**kept**"
        lines.append(
            f"| {c['label']} | {c['cases']} | "
            + " | ".join(ratios)
            + f" | {math.exp(c['score']):.3f} | {why} |"
        )
    from canonid.learning.linear import FEEDTHROUGH_GAIN

    lines += ["", f"Kept on validation: **{kept}**.", ""]
    lines += [
        'What `feedthrough="auto"` decides on each system (ℓ = 10, the runs\' training and '
        "validation splits): the one-step validation MSE of the least-squares fit with u_t "
        "over that without it, against the threshold "
        f"{FEEDTHROUGH_GAIN}; its column above takes each system's row from the column of that "
        "decision.",
        "",
        "| system | with / without u_t | feedthrough |",
        "|---|---:|---|",
    ]
    for system in systems:
        test = decide(system)
        lines.append(
            f"| {system} | {test.with_u / test.without_u:.3f} | "
            f"{'on' if test.feedthrough else 'off'} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    one = sub.add_parser("run", help="train and score one case; append its row")
    one.add_argument("system", choices=("tank", "drone2d", "silverbox"))
    one.add_argument("--seed", type=int, default=0)
    one.add_argument("--label", required=True, help="the variant's column in the table")
    one.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="profile")
    one.add_argument("--net", nargs="*", default=[], metavar="KEY=VALUE", help="network options")
    one.add_argument("--rows", type=Path, default=ROWS)
    tab = sub.add_parser("table", help="write the section from the rows")
    tab.add_argument("--rows", type=Path, default=ROWS)
    pick = sub.add_parser("select", help="choose a column on validation; write its section")
    pick.add_argument("--rows", type=Path, default=ROWS)
    both = sub.add_parser("compose", help="add the rows of the auto-feedthrough column")
    both.add_argument("--rows", type=Path, default=ROWS)
    args = parser.parse_args()
    if args.command == "compose":
        rows = read_rows(args.rows)
        rows = [r for r in rows if r["label"] != REFERENCE] + compose(rows)
        atomic_write_text(args.rows, "".join(json.dumps(r) + "\n" for r in rows))
        print(f"{sum(r['label'] == REFERENCE for r in rows)} rows of {REFERENCE!r}")
        return 0
    if args.command == "select":
        rows = read_rows(args.rows)
        body = selection_section(rows)
        write_section(SELECTION, body)
        print(body)
        return 0
    if args.command == "table":
        rows = read_rows(args.rows)
        body = table(rows)
        write_section(SECTION, body)
        print(body)
        return 0
    torch.set_num_threads(1)
    overrides, net = overrides_of(args.set), overrides_of(args.net, "--net")
    if args.system == "silverbox":
        measured = run_silverbox(args.seed, overrides, net)
    else:
        measured = run_generated(args.system, args.seed, overrides, net)
    row = {
        "system": args.system,
        "seed": args.seed,
        "label": args.label,
        "overrides": overrides,
        "net": net,
        **measured,
        "load": os.getloadavg()[0],
    }
    append_row(args.rows, row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
