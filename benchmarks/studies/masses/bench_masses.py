"""The chain of masses (1 input, 3 acceleration outputs, light damping) with canonid's defaults.

Generates ``canonid generate masses-id --n-train 10 --n-val 3 --n-test 3 --seed 1`` into
``runs/data/masses-id`` when missing, trains ``canonid train DATA --window L --threads 1`` for
each ``--windows`` L (the defaults otherwise: feedthrough decided on validation), and writes the
section "Chain of masses" of the records (benchmarks/records/): per window the best validation
loss (what
chooses the window), the feedthrough decision, and the test fit % per output (read after the
choice), with the training's CPU time. ``--record DATA RUN [RUN ...]`` writes the section from
runs already made (their CPU times given by ``--cpu-seconds``, one per run).

Usage: python benchmarks/studies/masses/bench_masses.py [--windows 10,30]
       python benchmarks/studies/masses/bench_masses.py --record DATA RUN ... --cpu-seconds S \
           ... --load TEXT
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import load_line, write_section  # noqa: E402

GENERATE = ["masses-id", "--n-train", "10", "--n-val", "3", "--n-test", "3", "--seed", "1"]


def canonid(*args: str) -> float:
    """Run ``canonid ARGS``; the CPU seconds it took."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "canonid", *args], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def row(run: Path, cpu: float) -> tuple[int, float, str]:
    """(window, best validation loss, the table row) of one run folder."""
    config = json.loads((run / "config.json").read_text())
    metrics = json.loads((run / "metrics.json").read_text())
    training, test = config["info"]["training"], config["info"].get("feedthrough_test")
    decided = "—" if test is None else ("on" if test["feedthrough"] else "off")
    ratio = "—" if test is None else f"{test['with_u'] / test['without_u']:.4f}"
    fits = " / ".join(f"{v:.1f}" for v in metrics["fit_percent_per_output"])
    clean = metrics.get("clean") or {}
    clean_fits = " / ".join(f"{v:.1f}" for v in clean.get("fit_percent_per_output", []))
    window = int(metrics["window"])
    cubic = config["info"].get("cubic_test")
    branch = (
        "—"
        if cubic is None
        else (f"{cubic['units']} units" if cubic["units"] else "none")
        + (
            ""
            if cubic is None or cubic["plain_loss"] is None
            else (f" ({cubic['cubic_loss'] / cubic['plain_loss']:.2f})")
        )
    )
    return (
        window,
        float(training["best_val_loss"]),
        f"| {window} | {training['best_val_loss']:.3g} | {decided} ({ratio}) | {branch} | "
        f"{fits} | {clean_fits or '—'} | {min(metrics['fit_percent_per_output']):.1f} | "
        f"{cpu:.0f} |",
    )


def section(runs: list[Path], cpus: list[float], load: str) -> str:
    rows = sorted(row(r, c) for r, c in zip(runs, cpus, strict=True))
    chosen = min(rows, key=lambda r: r[1])[0]
    names = json.loads((runs[0] / "metrics.json").read_text())["output_names"]
    return "\n".join(
        [
            f"Data: `canonid generate {' '.join(GENERATE)}` (10 / 3 / 3 open-loop experiments of "
            "2,000 samples at 50 Hz, a full-band multisine force; outputs "
            f"{', '.join(names)} in m/s²). Each run: `canonid train DATA --window L --threads 1` "
            "(canonid's defaults: Ours (MLP), the quick profile, feedthrough decided on the "
            "validation split, the cubic branch by the test on the training part's largest "
            "excursions). The window is chosen by the best validation loss; the test fit % "
            "(simulation after n_init = 50, per output) is read after that choice.",
            "",
            "| ℓ | best validation loss (normalised) | feedthrough (with / without u_t) "
            "| cubic branch (held-out loss with / without) | test fit % per output (measured) "
            "| test fit % per output (noise-free) | lowest | CPU s |",
            "|---:|---:|---|---|---|---|---:|---:|",
            *(r[2] for r in rows),
            "",
            f"Chosen on validation: **ℓ = {chosen}**.",
            "",
            load,
        ]
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--windows", default="10,30", help="windows to train (default 10,30)")
    parser.add_argument("--record", nargs="+", type=Path, metavar="PATH")
    parser.add_argument("--cpu-seconds", nargs="+", type=float, default=[])
    parser.add_argument("--load", default="", help="for --record: the load while the runs ran")
    args = parser.parse_args()
    load = [os.getloadavg()[0]]
    if args.record:
        runs = args.record[1:]  # the first path is the data the runs trained on
        if len(args.cpu_seconds) != len(runs):
            parser.error("--record DATA RUN ...: give one --cpu-seconds per run")
        body = section(runs, args.cpu_seconds, args.load)
        write_section("Chain of masses", body, command="python bench_masses.py --record ...")
        print(body)
        return 0
    start = time.perf_counter()
    data = ROOT / "runs" / "data" / "masses-id"
    if not (data / "dataset.npz").is_file():
        canonid("generate", *GENERATE, "--out", str(data))
    runs, cpus = [], []
    for window in (int(w) for w in args.windows.split(",")):
        out = ROOT / "runs" / f"masses-l{window}"
        cpus.append(
            canonid(
                "train",
                str(data),
                "--window",
                str(window),
                "--threads",
                "1",
                "--no-progress",
                "--out",
                str(out),
            )
        )
        runs.append(out)
        load.append(os.getloadavg()[0])
    sentence, _ = load_line(load, "CPU times of one thread are less affected than wall times")
    body = section(runs, cpus, sentence)
    body += f"\n\nThis benchmark took {(time.perf_counter() - start) / 60:.1f} min."
    write_section("Chain of masses", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
