"""A/B of the data engine's overhead: this tree against a git revision, in CPU time.

Usage (from the repository root)::

    .venv/bin/python benchmarks/ab_datagen.py --base REV [--rounds 2] [--flights 48]

``REV`` is exported with ``git archive`` into a temporary folder. Each round runs, for the base
then for this tree, a fresh process that measures

* the CPU time of one NMPC call (drone2d, horizon 20, one 600-step flight called step by step;
  median over the calls), and
* a dataset of ``--flights`` drone flights on 2 local Dask workers (each tree's own runner
  settings): CPU of the main process and of the workers per flight, start-up included.

The two trees alternate round by round, so that the load of a shared machine falls on both
alike; CPU times, not wall times, are the comparable figures there.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

_MEASURE = r"""
import inspect, json, resource, sys, tempfile, time
from pathlib import Path
import numpy as np
import canonid.runner as runner
from canonid.datagen.generate import GenerationConfig, _controller_for, _system, generate_dataset
from canonid.datagen.references import drone2d_reference

def children():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime

def main():
    flights = int(sys.argv[1])
    config = GenerationConfig("drone2d", seed=0, counts={"train": flights, "val": 0, "test": 0})
    nmpc, drone = _controller_for(config), _system("drone2d")
    ref = drone2d_reference(np.random.default_rng(1000), T=600, dt=drone.dt)
    nmpc.reset(ref, ref[0])
    x, cpu = ref[0], []
    for t in range(600):
        start = time.process_time()
        step = nmpc(t, x)
        cpu.append(time.process_time() - start)
        x = np.asarray(drone.f(x, step.u), dtype=np.float64).ravel()
    batch = {}
    if "batch" in inspect.signature(runner.run_jobs).parameters:
        from canonid.datagen.generate import FLIGHTS_PER_TASK
        batch = {"batch": FLIGHTS_PER_TASK}

    def run(fn, jobs, *, on_result=None):
        return runner.run_jobs(fn, jobs, workers=2, progress=False, on_result=on_result, **batch)

    with tempfile.TemporaryDirectory() as tmp:
        main_cpu, workers_cpu = time.process_time(), children()
        generate_dataset(config, Path(tmp) / "d", run_jobs=run)
        main_cpu, workers_cpu = time.process_time() - main_cpu, children() - workers_cpu
    print(json.dumps({
        "call_ms": 1e3 * float(np.median(cpu)),
        "main_ms": 1e3 * main_cpu / flights,
        "workers_ms": 1e3 * workers_cpu / flights,
    }))

if __name__ == "__main__":
    main()
"""


def measure(tree: Path, flights: int) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, "-c", _MEASURE, str(flights)],
        cwd=tree,
        env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return dict(json.loads(out.strip().splitlines()[-1]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--base", required=True, help="git revision to compare against")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--flights", type=int, default=48)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        base.mkdir()
        archive = subprocess.run(
            ["git", "archive", args.base], cwd=ROOT, capture_output=True, check=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        rows: dict[str, list[dict[str, float]]] = {"base": [], "this tree": []}
        for _ in range(args.rounds):
            rows["base"].append(measure(base, args.flights))
            rows["this tree"].append(measure(ROOT, args.flights))
    print(f"CPU ms, medians of {args.rounds} alternating rounds ({args.flights} flights each):")
    print("| tree | NMPC call | main process per flight | workers per flight |")
    print("|---|---|---|---|")
    for name, runs in rows.items():
        med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
        print(f"| {name} | {med['call_ms']:.4f} | {med['main_ms']:.2f} | {med['workers_ms']:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
