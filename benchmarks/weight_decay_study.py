"""Adam weight decay and seeds as stacked candidates on several systems, validation only.

Does weight decay help the defaults, and on which data? Each system's candidates — every
combination of :data:`WEIGHT_DECAYS` and :data:`SEEDS` — train as one stack
(:func:`canonid.learning.batched.fit_batched`) with the quick profile's options, at the window
the defaults chose on that system (:data:`SYSTEMS`), on the same sub-windows. The study reads
validation losses only: ``prepare`` drops every test part before anything trains.

1. ``python weight_decay_study.py prepare`` writes each system's training and validation parts
   to ``runs/wd-study/data/NAME/dataset.npz`` (the data must exist: the small-data cuts of
   ``small_data.py``, the generated sets under ``runs/data``, Silverbox from ``--dir``).
2. ``python weight_decay_study.py all --device cuda --out DIR --deadline S`` trains every
   system at once, one process each (one CPU thread each), and stops them after ``S`` seconds;
   ``run NAME`` trains one. Checkpoints land every 25 epochs in ``DIR/NAME``.
3. ``python weight_decay_study.py collect DIR --out FILE`` reads each system's result, or the
   histories in the checkpoint of a run the deadline stopped, into one JSON file with the
   device's facts; ``--resume`` on ``run``/``all`` goes on from the checkpoints.
4. ``python weight_decay_study.py record FILE...`` (here, where ``runs/wd-study/data`` is)
   merges collections — per system the one that reached the most epochs — into
   ``benchmarks/studies/weight_decay_study.json`` and writes the section "Weight decay on small
   records" of RESULTS.md: best validation loss by the last epoch each system reached, per
   weight decay (the lowest of its seeds and their median). ``render FILE`` prints it.

Usage: python weight_decay_study.py prepare [--dir ../shared/data/silverbox]
       python weight_decay_study.py all --out DIR [--device cuda] [--deadline S] [--resume]
       python weight_decay_study.py run NAME --out DIR [--device cuda] [--resume]
       python weight_decay_study.py collect DIR --out FILE
       python weight_decay_study.py record FILE [FILE ...]
       python weight_decay_study.py render FILE
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _data import STUDY_SYSTEMS  # noqa: E402

DATA = ROOT / "runs" / "wd-study" / "data"
STUDY_FILE = ROOT / "benchmarks" / "studies" / "weight_decay_study.json"
SECTION = "Weight decay on small records"
WEIGHT_DECAYS = (0.0, 1e-5, 1e-4, 1e-3)
SEEDS = (0, 1, 2, 3)
#: system → (source, window): the shared table in this study's order, with its one override
SYSTEMS = {
    name: STUDY_SYSTEMS[name]
    for name in (
        "silverbox-1k",
        "silverbox-3k",
        "silverbox-10k",
        "silverbox",
        "overflow-tanks",
        "tank",
        "drone2d",
        "masses",
    )
}
# ℓ = 20: the defaults' model on overflow-tanks when this study ran ("Overflow tanks" is now at 10)
SYSTEMS["overflow-tanks"] = (STUDY_SYSTEMS["overflow-tanks"][0], 20)


def prepare(directory: Path) -> None:
    from canonid.datagen.benchmarks import load_benchmark
    from canonid.datagen.loaders import split_train_val
    from canonid.kernel.dataset import Dataset

    for name, (source, _) in SYSTEMS.items():
        if source == "silverbox":
            full = split_train_val(
                load_benchmark("silverbox", directory), val_fraction=0.2, record_tails=True
            )
        else:
            full = Dataset.load(ROOT / source)
        kept = Dataset(
            splits={part: full.split(part) for part in ("train", "val")},
            dt=full.dt,
            input_names=full.input_names,
            output_names=full.output_names,
            metadata={"study": f"train and val of {source}; test parts dropped"},
        )
        kept.save(DATA / name / "dataset.npz")
        sizes = {p: sum(t.T for t in kept.split(p)) for p in ("train", "val")}
        print(f"{name}: {sizes}")


def run(name: str, out: Path, device: str, epochs: int | None = None, resume: bool = False) -> None:
    import torch

    from canonid.kernel.dataset import Dataset
    from canonid.kernel.io import atomic_write_text
    from canonid.learning.batched import candidate_grid, fit_batched
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    data = Dataset.load(DATA / name / "dataset.npz")
    folder = out / name
    if (folder / "checkpoint.pt").exists() and not resume:
        raise SystemExit(f"{folder} holds a run already: give --resume, or another --out")
    folder.mkdir(parents=True, exist_ok=True)
    stamps: list[float] = []
    start = time.perf_counter()

    def progress(epoch: int) -> None:
        stamps.append(time.perf_counter() - start)
        if epoch % 50 == 0:
            print(f"{name}: epoch {epoch}, {stamps[-1]:.0f} s", flush=True)

    result = fit_batched(
        data.split("train"),
        data.split("val"),
        candidate_grid(weight_decay=list(WEIGHT_DECAYS), seed=list(SEEDS)),
        window=SYSTEMS[name][1],
        options=train_options("quick", device=device, epochs=epochs),
        callback=progress,
        run_dir=folder,
        resume=resume,
    )
    record = {
        "system": name,
        "window": SYSTEMS[name][1],
        "device": device,
        "finished": True,
        "seconds": time.perf_counter() - start,
        "epochs": len(stamps),
        "ensemble_val_loss": result.ensemble_val_loss,
        "ensemble": result.ensemble,
        "candidates": [
            {"label": c.label, **dict(c.changes), "history": _losses(r.history)}
            for c, r in zip(result.candidates, result.runs, strict=True)
        ],
    }
    atomic_write_text(folder / "result.json", json.dumps(record))


def _losses(history: list[dict]) -> list[list[float]]:
    """``[epoch, val_loss]`` of every validated epoch."""
    return [[h["epoch"], h["val_loss"]] for h in history if h.get("val_loss") is not None]


def run_all(
    out: Path, device: str, deadline: float, epochs: int | None = None, resume: bool = False
) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    procs = {
        name: subprocess.Popen(
            [sys.executable, __file__, "run", name, "--out", str(out), "--device", device]
            + ([] if epochs is None else ["--epochs", str(epochs)])
            + (["--resume"] if resume else []),
            env=env,
        )
        for name in SYSTEMS
    }
    end = time.monotonic() + deadline
    for name, proc in procs.items():
        try:
            proc.wait(timeout=max(1.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            print(f"{name}: stopped at the deadline", flush=True)


def collect(directory: Path) -> dict:
    """The device's facts and one record per system (finished or read from its checkpoint)."""
    import platform

    import torch

    records: list[dict] = []
    for name in SYSTEMS:
        folder = directory / name
        if (folder / "result.json").is_file():
            records.append(json.loads((folder / "result.json").read_text()))
            continue
        checkpoint = folder / "checkpoint.pt"
        if not checkpoint.is_file():
            print(f"{name}: no checkpoint", file=sys.stderr)
            continue
        state = torch.load(checkpoint, map_location="cpu", weights_only=True)
        labels = state["identity"]["extra"]["candidates"]
        (stack,) = state["stacks"]
        records.append(
            {
                "system": name,
                "window": SYSTEMS[name][1],
                "finished": False,
                "epochs": int(state["epoch"]),
                "candidates": [
                    {"label": label, "history": _losses(history)}
                    for (label, _), history in zip(labels, stack["history"], strict=True)
                ],
            }
        )
    card = torch.cuda.get_device_name() if torch.cuda.is_available() else "none"
    facts = {"card": card, "torch": torch.__version__, "python": platform.python_version()}
    return {**facts, "cores": os.cpu_count(), "records": records}


def best_by(history: list[list[float]], epoch: int) -> float:
    return min(loss for e, loss in history if e <= epoch)


def record(files: list[Path]) -> int:
    """Merge collections (per system the one that reached the most epochs), add each system's
    training samples from :data:`DATA`, keep it as :data:`STUDY_FILE` and write the section."""
    from canonid.kernel.io import atomic_write_text

    found = [json.loads(f.read_text()) for f in files]
    best: dict[str, dict] = {}
    for rec in (r for f in found for r in f["records"]):
        if rec["system"] not in best or _reached(rec) > _reached(best[rec["system"]]):
            best[rec["system"]] = rec
    for name, rec in best.items():
        rec["train_samples"] = _train_samples(name)
    study = {**{k: v for k, v in found[0].items() if k != "records"}}
    study["records"] = [best[name] for name in SYSTEMS if name in best]
    atomic_write_text(STUDY_FILE, json.dumps(study, indent=1) + "\n")
    _write_section(render(study))
    print(render(study))
    return 0


def _train_samples(name: str) -> int:
    from canonid.kernel.dataset import Dataset

    return sum(t.T for t in Dataset.load(DATA / name).split("train"))


def _write_section(body: str) -> None:
    from _results import write_section

    write_section(SECTION, body)


def _reached(rec: dict) -> int:
    return max(c["history"][-1][0] for c in rec["candidates"])


def _cells(rec: dict, last: int) -> dict[float, list[float]]:
    """Each weight decay's best validation losses by epoch ``last``, one per seed."""
    return {
        wd: [
            best_by(c["history"], last)
            for c in rec["candidates"]
            if f"weight_decay={wd}" in c["label"].split(", ")
        ]
        for wd in WEIGHT_DECAYS
    }


def _wd(value: float) -> str:
    return "0" if value == 0 else f"{value:.0e}".replace("e-0", "e-")


def _ratios(rec: dict) -> tuple[float, float]:
    """1e-5's lowest and median best validation loss over no decay's."""
    cells = _cells(rec, _reached(rec))
    low, mid = (f(cells[1e-5]) / f(cells[0.0]) for f in (min, statistics.median))
    return low, mid


def _verdicts(records: list[dict], threshold: int) -> str:
    """What 1e-5 did to the lowest and the median loss against no decay, below and from
    ``threshold`` training samples, in words: which systems it lowered both on, raised both on,
    or moved each way; then what holds of the helped larger systems and of larger decays."""
    said, helped = [], {True: [], False: []}
    for below in (True, False):
        tally: dict[str, list[str]] = {"lowered both": [], "raised both": [], "split": []}
        for rec in records:
            if (rec.get("train_samples", 0) < threshold) != below:
                continue
            lower = [r < 1 for r in _ratios(rec)]
            key = "lowered both" if all(lower) else "split" if any(lower) else "raised both"
            tally[key].append(rec["system"])
            if all(lower):
                helped[below].append(rec)
        parts = [
            ("one lower, one higher on " if k == "split" else f"{k} on ") + ", ".join(v)
            for k, v in tally.items()
            if v
        ]
        if parts:
            where = "Below" if below else "From"
            said.append(f"{where} {threshold:,} training samples it " + "; ".join(parts) + ".")
    small = [r for r in records if r.get("train_samples", 0) < threshold]
    if (
        helped[False]
        and small
        and all(min(_ratios(big)) > max(max(_ratios(r)) for r in small) for big in helped[False])
    ):
        said.append("Where it helped a larger record, it helped less than on every small one.")
    if small and all(
        min(_cells(r, _reached(r))[1e-5])
        <= min(min(_cells(r, _reached(r))[w]) for w in (1e-4, 1e-3))
        for r in small
    ):
        said.append("No larger decay had a lower lowest loss than 1e-5 on a small record.")
    return " ".join(said)


def render(study: dict) -> str:
    """The section: how the study ran, its table, what it chose."""
    from canonid.kernel.catalog import SMALL_RECORD_SAMPLES, SMALL_RECORD_WEIGHT_DECAY

    lines = [
        "Which Adam weight decay the defaults should use, chosen on validation only "
        "(`benchmarks/weight_decay_study.py`; every number below is in "
        "`benchmarks/studies/weight_decay_study.json`). On each system, "
        f"{len(WEIGHT_DECAYS) * len(SEEDS)} candidates — weight decay "
        f"{', '.join(map(_wd, WEIGHT_DECAYS))} × seeds "
        f"{', '.join(map(str, SEEDS))} — trained as one stack "
        "(`canonid.learning.batched.fit_batched`, the quick profile's options, the window the "
        "defaults chose there before this study, the same sub-windows for all), on one "
        f"{study.get('card', '?')} (torch {study.get('torch', '?')}, {study.get('cores', '?')} "
        "CPU cores), all systems at once, one process each: `python weight_decay_study.py "
        "all --out DIR --deadline 465` and `collect DIR --out FILE` there, the three smallest "
        "systems then resumed by a second call (`run NAME --out DIR --resume`); `record FILE "
        "FILE` here merged the two collections into the record above (running `record` on "
        "the record writes this section again). The test parts were dropped before anything "
        "trained. The device's time ran out before the 600 epochs: the columns compare the "
        "candidates of one system at the same epoch (the learning rate still on its cosine's "
        "way down).",
        "",
        "Cell: the lowest best validation loss of the four seeds by that epoch (their median).",
        "",
        "| system | training samples | ℓ | epoch | "
        + " | ".join(f"decay {_wd(w)}" for w in WEIGHT_DECAYS)
        + " | 1e-5 / 0: lowest, median |",
        "|---|---:|---:|---:|" + "---:|" * len(WEIGHT_DECAYS) + "---:|",
    ]
    for rec in study["records"]:
        last = _reached(rec)
        cells = _cells(rec, last)
        ratio = [f"{f(cells[1e-5]) / f(cells[0.0]):.2f}" for f in (min, statistics.median)]
        lines.append(
            f"| {rec['system']} | {rec.get('train_samples', 0):,} | {rec['window']} | {last} | "
            + " | ".join(f"{min(v):.3g} ({statistics.median(v):.3g})" for v in cells.values())
            + f" | {ratio[0]}, {ratio[1]} |"
        )
    lines += [
        "",
        f"Chosen: the quick profile's `weight_decay` is `auto`, {_wd(SMALL_RECORD_WEIGHT_DECAY)} "
        f"when the training part holds fewer than {SMALL_RECORD_SAMPLES:,} samples, else 0 "
        "(`canonid.kernel.catalog`). Against no decay, on the lowest and the median loss of "
        f"the four seeds: {_verdicts(study['records'], SMALL_RECORD_SAMPLES)} Test scores were "
        'read once, after this choice (sections "Small data" and "Overflow tanks").',
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("--dir", type=Path, default=ROOT.parent / "shared" / "data" / "silverbox")
    for step in ("all", "run"):
        p = sub.add_parser(step)
        if step == "run":
            p.add_argument("name", choices=list(SYSTEMS))
        p.add_argument("--out", type=Path, required=True)
        p.add_argument("--device", default="cuda")
        p.add_argument("--deadline", type=float, default=480.0)
        p.add_argument("--epochs", type=int, help="override the profile's (a quick check)")
        p.add_argument("--resume", action="store_true", help="go on from the checkpoints")
    p = sub.add_parser("collect")
    p.add_argument("directory", type=Path)
    p.add_argument("--out", type=Path, required=True)
    p = sub.add_parser("render")
    p.add_argument("file", type=Path)
    p = sub.add_parser("record")
    p.add_argument("files", type=Path, nargs="+")
    args = parser.parse_args(argv)
    if args.step == "prepare":
        prepare(args.dir)
    elif args.step == "run":
        run(args.name, args.out, args.device, args.epochs, args.resume)
    elif args.step == "all":
        run_all(args.out, args.device, args.deadline, args.epochs, args.resume)
    elif args.step == "collect":
        from canonid.kernel.io import atomic_write_text

        found = collect(args.directory)
        atomic_write_text(args.out, json.dumps(found, indent=1))
        print(render(found))
    elif args.step == "record":
        return record(args.files)
    else:
        print(render(json.loads(args.file.read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
