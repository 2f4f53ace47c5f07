"""Candidates side by side: the window screen's candidates and the cubic test's arms trained in
worker processes of one torch thread each (:func:`canonid.jobs.candidate_pool`) against the same
command training them one after the other, on Silverbox with canonid's defaults.

Two runs of ``canonid benchmark silverbox --dir DIR`` with the default threads (one per core),
each in its own child process, one after the other on an otherwise idle machine:

* ``side by side``: the command as a user types it;
* ``one after the other``: the same with the pool switched off (``canonid.jobs.POOL_MIN_STEPS``
  set beyond any budget in the child before the command runs): every short training in the
  command's own process with its threads, as before the pool existed.

Per run: the wall time and the CPU time of the child (user + system, ``getrusage``), the main
training's share (the sum of its epochs' wall seconds in ``history.csv``), the screen's choice
and the CPU seconds of its candidates, the cubic test's decision, and the official scores. The
two runs train their short candidates with one and with all threads, so their numbers agree to
rounding, not to the bit.

Writes the section "Candidates side by side" of the records (benchmarks/records/); ``--record``
writes it
again from the run folders and ``runs/candidates/times.json`` without training.

Usage: python benchmarks/studies/candidates/bench_candidates.py --dir ../shared/data/silverbox
[--record]
(about 25 minutes of wall time on 2 cores)
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

from _results import write_section  # noqa: E402

from canonid.jobs import available_cores  # noqa: E402
from canonid.kernel.io import atomic_write_json, read_json  # noqa: E402

OUT = ROOT / "runs" / "candidates"
SECTION = "Candidates side by side"
#: variant → (run folder, Python run before the command in the child)
VARIANTS = {
    "side by side": ("side-by-side", ""),
    "one after the other": (
        "one-after-the-other",
        "import canonid.jobs as j; j.POOL_MIN_STEPS = 10**18; ",
    ),
}


def run(name: str, data: Path) -> dict[str, Any]:
    folder, before = VARIANTS[name]
    argv = [
        "benchmark",
        "silverbox",
        "--dir",
        str(data),
        "--out",
        str(OUT / folder),
        "--no-progress",
    ]
    code = f"{before}from canonid.cli import main; raise SystemExit(main({argv!r}))"
    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime - usage0.ru_utime + usage.ru_stime - usage0.ru_stime
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "load": os.getloadavg()[0]}


def _training_wall(folder: Path) -> float:
    with (folder / "history.csv").open() as fh:
        return sum(float(row["seconds"] or 0) for row in csv.DictReader(fh))


def row(name: str, times: dict[str, Any]) -> str:
    folder = OUT / VARIANTS[name][0]
    screen = read_json(folder / "window-screen.json")
    screened = [c for c in screen["candidates"] if c.get("cpu_seconds") is not None]
    screen_cpu = sum(c["cpu_seconds"] for c in screened)
    cubic = read_json(folder / "config.json")["info"].get("cubic_test") or {}
    scores = {s["test"]: s["rmse"] for s in read_json(folder / "benchmark.json")["scores"]}
    three = " / ".join(
        f"{scores[test]:.3f}" for test in ("multisine", "arrow-no-extrapolation", "arrow-full")
    )
    t = times[name]
    train_wall = _training_wall(folder)
    arms = len(cubic.get("plain_losses") or ()) + len(cubic.get("cubic_losses") or ())
    return (
        f"| {name} | {t['wall_s'] / 60:.1f} | {t['cpu_s'] / 60:.1f} | {train_wall / 60:.1f} | "
        f"{(t['wall_s'] - train_wall) / 60:.1f} | ℓ = {screen['chosen']} ({screen_cpu:.0f} s) | "
        f"{cubic.get('units', '?')} units, {arms} arms | {three} |"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--dir", type=Path, required=True, help="Silverbox's CSV files")
    parser.add_argument("--record", action="store_true", help="write the section from the runs")
    args = parser.parse_args()
    times_file = OUT / "times.json"
    times: dict[str, Any] = read_json(times_file) if times_file.exists() else {}
    if not args.record:
        for name in VARIANTS:
            times[name] = run(name, args.dir.resolve())
            OUT.mkdir(parents=True, exist_ok=True)
            atomic_write_json(times_file, times)
    cores = available_cores()
    lines = [
        f"`canonid benchmark silverbox --dir DIR --no-progress` with the defaults (threads: one "
        f"per core, here {cores}), once as typed and once with the pool switched off "
        "(`canonid.jobs.POOL_MIN_STEPS` beyond any budget, in the child before the command): "
        "the window screen's candidates and the cubic test's arms side by side in worker "
        "processes of one thread, or one after the other in the command's process with all "
        "threads. Each run alone on the machine, one after the other; wall and CPU time of the "
        "child process (its workers included). 'Main training': the sum of the full run's "
        "epoch times in `history.csv`; 'the rest': screen, cubic test, loading and scoring.",
        "",
        "| run | wall [min] | CPU [min] | main training, wall [min] | the rest, wall [min] | "
        "screen's choice (its candidates' CPU) | cubic test | multisine / arrow no-extrap. / "
        "arrow full [mV] |",
        "|---|---:|---:|---:|---:|---|---|---|",
        *(row(name, times) for name in VARIANTS if name in times),
        "",
        "Load average (1 min) after each run: "
        + " / ".join(f"{times[n]['load']:.2f}" for n in VARIANTS if n in times)
        + ".",
    ]
    write_section(SECTION, "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
