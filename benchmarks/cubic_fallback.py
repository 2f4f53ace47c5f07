"""The cubic branch on records too short to hold out their peaks: short trainings or full runs?

Writes the section "Cubic test on validation" of benchmarks/RESULTS.md.

Ours (MLP)'s defaults decide the cubic branch on the training part's largest excursions
(``canonid.learning.extrapolation``). A record too short to hold them out (or whose pieces
between them hold under 40 % of its samples) cannot ask that question; something else must
decide there, on the validation part. Two designs, judged on validation only, on the records of
the studies that take this path (:data:`RECORDS`):

* ``short NAME``: the cubic test's short trainings (the window screen's share of the epochs,
  seeds 0, 1, 2 per network) on the whole training part, scored on the validation part, the
  branch kept at :data:`~canonid.learning.extrapolation.CUBIC_GAIN` × the plain loss or below;
* ``run NAME UNITS``: the two networks trained fully at the defaults' window (``canonid train
  DATA --window L --cubic UNITS --threads 1``), the same rule on their best validation losses.

``record`` sets the two verdicts side by side with the verdict the defaults' own run recorded
(``info.cubic_test`` of the run folders of ``small_data.py`` and ``bench_overflow_tanks.py``).
No test part is read here: the defaults' test scores are in the sections "Small data" and
"Overflow tanks", recorded after this choice.

Usage: python benchmarks/cubic_fallback.py short NAME        (about 3 CPU-minutes)
       python benchmarks/cubic_fallback.py run NAME UNITS    (one full run, 2 to 8 CPU-minutes)
       python benchmarks/cubic_fallback.py record            (the section, from the runs)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import publish  # noqa: E402
from bench_overflow_tanks import child_cpu, validation  # noqa: E402

from canonid.kernel.io import atomic_write_json  # noqa: E402

SECTION = "Cubic test on validation"
RUNS = ROOT / "runs" / "cubic-fallback"
CPU_FILE = RUNS / "cpu.json"
SHORT_FILE = RUNS / "short.json"
UNITS = (0, 16)
SEEDS = (0, 1, 2)


@dataclass(frozen=True)
class Record:
    """A record of the studies whose peaks cannot be held out."""

    label: str
    data: Path
    window: int
    #: the defaults' run folder on it (written by the script named in ``source``)
    defaults: Path
    source: str


RECORDS = {
    "silverbox-1k": Record(
        "Silverbox, first 1,000 samples (800 / 200)",
        ROOT / "runs" / "small-data" / "data" / "n1000",
        10,
        ROOT / "runs" / "small-data" / "n1000",
        "small_data.py",
    ),
    "overflow-tanks": Record(
        "overflow tanks, 1,024 samples (819 / 205)",
        ROOT / "runs" / "data" / "tanks-overflow",
        10,
        ROOT / "runs" / "overflow-tanks" / "mlp-default",
        "bench_overflow_tanks.py",
    ),
}


def run_folder(name: str, units: int) -> Path:
    return RUNS / f"{name}-c{units}"


def _merge(path: Path, key: str, value: object) -> None:
    RUNS.mkdir(parents=True, exist_ok=True)
    found = json.loads(path.read_text()) if path.exists() else {}
    found[key] = value
    atomic_write_json(path, found)


def train(name: str, units: int) -> int:
    """One full run of ``name`` with ``units`` cubic units; its CPU seconds into CPU_FILE."""
    record = RECORDS[name]
    out = run_folder(name, units)
    cmd = [sys.executable, "-m", "canonid", "train", str(record.data), "--window"]
    cmd += [str(record.window), "--cubic", str(units), "--threads", "1", "--no-progress"]
    _merge(CPU_FILE, out.name, child_cpu([*cmd, "--out", str(out)]))
    return 0


def short(name: str) -> int:
    """The short trainings of the cubic test on the whole training part, scored on the
    validation part: each seed's best loss per network, into SHORT_FILE."""
    import torch

    from canonid.kernel.dataset import Dataset
    from canonid.learning.screen import SCREEN_FRACTION, screen_options
    from canonid.learning.training import fit
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    record = RECORDS[name]
    ds = Dataset.load(record.data)
    train_part, val_part = ds.split("train"), ds.split("val")
    # the profile's options on this machine's CPU; the feedthrough decided as the run decides it
    opts = screen_options(train_options("quick", device="cpu"), SCREEN_FRACTION)
    losses: dict[str, list[float]] = {}
    for units in UNITS:
        losses[f"c{units}"] = [
            fit(
                train_part,
                val_part,
                window=record.window,
                options=dataclasses.replace(opts, seed=seed),
                net_options={"cubic": units},
            ).best_val_loss
            for seed in SEEDS
        ]
    _merge(SHORT_FILE, name, {"epochs": opts.epochs, **losses})
    return 0


def verdict(run: Path) -> dict:
    """The cubic test a run recorded (``config.json``, ``info.cubic_test``)."""
    config = json.loads((run / "config.json").read_text())
    return config["info"]["cubic_test"]


def record() -> int:
    from canonid.learning.extrapolation import CUBIC_GAIN, keeps_cubic

    start = time.monotonic()
    cpus, shorts = json.loads(CPU_FILE.read_text()), json.loads(SHORT_FILE.read_text())
    lines = [
        "Ours (MLP)'s defaults decide the cubic branch on the training part's largest "
        'excursions (section "Extrapolation"). A record too short to hold them out, or whose '
        "pieces between them hold under 40 % of its samples, cannot ask that question; the "
        "validation part decides there. Two designs, judged on validation only: the cubic "
        "test's short trainings scored on the validation part (the window screen's share of "
        "the epochs, seeds 0, 1, 2 per network: `python benchmarks/cubic_fallback.py short "
        "NAME`), and the two networks trained fully (`canonid train DATA --window L --cubic "
        "UNITS --threads 1`: `python benchmarks/cubic_fallback.py run NAME UNITS`); both keep "
        f"the branch when its best loss is at most {CUBIC_GAIN} × the plain network's. Losses: "
        "best validation loss (normalised; 100-step rollouts). No test part is read here "
        "(`canonid train` writes its own test metrics into each run folder; this script does "
        "not read them).",
        "",
        "| record | why not the peaks | short: plain / cubic (seeds 0, 1, 2) | short: best "
        "cubic / best plain | full run: plain (epoch) | full run: 16 cubic units (epoch) | "
        "full: cubic / plain | short keeps | full keeps | CPU s of the full runs, plain / "
        "cubic |",
        "|---|---|---|---:|---:|---:|---:|---|---|---|",
    ]
    verdicts, differ = [], []
    for name, rec in RECORDS.items():
        test = verdict(rec.defaults)
        if test.get("fallback") is None:
            raise SystemExit(f"{rec.defaults}: its cubic test was decided on the peaks")
        found = shorts[name]
        plain_short, cubic_short = min(found["c0"]), min(found["c16"])
        plain, cubic = (validation(run_folder(name, u)) for u in UNITS)
        short_keeps = keeps_cubic(plain_short, cubic_short)
        full_keeps = keeps_cubic(plain.best, cubic.best)

        def said(keeps: bool) -> str:
            return "16 cubic units" if keeps else "the plain network"

        seeds = " ; ".join(
            f"{p:.3g} / {c:.3g}" for p, c in zip(found["c0"], found["c16"], strict=True)
        )
        lines.append(
            f"| {rec.label} | {test['fallback']} | {seeds} | "
            f"{cubic_short / plain_short:.2f} | {plain.best:.4g} ({plain.epoch}) | "
            f"{cubic.best:.4g} ({cubic.epoch}) | {cubic.best / plain.best:.2f} | "
            f"{said(short_keeps)} | {said(full_keeps)} | "
            f"{cpus[run_folder(name, 0).name]:.0f} / {cpus[run_folder(name, 16).name]:.0f} |"
        )
        if short_keeps != full_keeps:
            differ.append(rec.label)
        verdicts.append(
            f"{rec.label}: {said(bool(test['units']))} (plain {test['plain_loss']:.4g}, "
            f"16 cubic units {test['cubic_loss']:.4g}; `{rec.defaults.relative_to(ROOT)}`, "
            f"benchmarks/{rec.source})"
        )
    lines += [
        "",
        "Where the two designs differ: "
        + (
            "; ".join(differ)
            + ". There the short trainings put the branch ahead and the full runs — the "
            "budget the kept model actually trains for — put the plain network ahead. The choice "
            "is of the model that trains, so the defaults train both networks fully where the "
            "peaks cannot decide (`canonid.learning.training.fit`), at about twice the CPU of "
            "one training on such records."
            if differ
            else "nowhere."
        ),
        "",
        "What the defaults' own runs recorded (`info.cubic_test`; they train both networks "
        "fully): " + "; ".join(verdicts) + ".",
    ]
    return publish(SECTION, lines, (time.monotonic() - start) / 60)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    one = sub.add_parser("run", help="one full run of a record at one number of cubic units")
    one.add_argument("name", choices=list(RECORDS))
    one.add_argument("units", type=int, choices=UNITS)
    brief = sub.add_parser("short", help="the short trainings of a record, on validation")
    brief.add_argument("name", choices=list(RECORDS))
    sub.add_parser("record", help="write the section from the runs")
    args = parser.parse_args()
    if args.command == "run":
        return train(args.name, args.units)
    if args.command == "short":
        return short(args.name)
    return record()


if __name__ == "__main__":
    raise SystemExit(main())
