"""What a local Dask cluster costs besides the jobs (the "Dask overhead" section of
its notes (``benchmarks/records/``)): Dask's default settings against the ones canonid's runner
gives its
local clusters (:data:`canonid.runner.LOCAL_CLUSTER_CONFIG`).

Run::

    .venv/bin/python benchmarks/bench_dask_overhead.py --size quick

Parts, each measured in CPU seconds (comparable on a loaded machine) with the load average:

1. An idle cluster of 2 worker processes: CPU per second of the workers and of this process
   (scheduler, nannies, client), over 10 s.
2. ``generate_dataset`` of drone flights on 2 workers through :func:`canonid.runner.run_jobs`,
   each setting in a fresh process, the two taking turns: wall time, CPU of the main process
   (scheduler, client, writing the parts) and of the workers (start-up included), per flight.

``--size quick``: 20 flights, 2 runs each; ``--size full``: 100 flights, 3 runs each.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import load_line, publish  # noqa: E402

import canonid.runner as runner  # noqa: E402

SETTINGS = {"Dask defaults": {}, "canonid (LOCAL_CLUSTER_CONFIG)": runner.LOCAL_CLUSTER_CONFIG}


def _own_cpu(_: Any = None) -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def idle_cpu(config: dict[str, Any], seconds: float = 10.0) -> tuple[float, float]:
    """CPU milliseconds per second of (the workers, this process) with an idle cluster."""
    import dask
    from dask.distributed import Client, LocalCluster

    with dask.config.set(config):
        cluster = LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster, set_as_default=False)
    try:
        time.sleep(2.0)  # start-up over
        workers0, own0, start = sum(client.run(_own_cpu).values()), _own_cpu(), time.perf_counter()
        time.sleep(seconds)
        workers1, own1 = sum(client.run(_own_cpu).values()), _own_cpu()
        elapsed = time.perf_counter() - start
    finally:
        client.close()
        cluster.close()
    return (workers1 - workers0) / elapsed * 1e3, (own1 - own0) / elapsed * 1e3


def _generate(label: str, flights: int) -> None:
    """Child process: generate ``flights`` drone flights on 2 workers with setting ``label``;
    prints wall, main-process CPU and workers' CPU seconds."""
    from canonid.datagen.generate import GenerationConfig, _controller_for, generate_dataset

    runner.LOCAL_CLUSTER_CONFIG = SETTINGS[label]
    config = GenerationConfig("drone2d", seed=0, counts={"train": flights, "val": 0, "test": 0})
    _controller_for(config)  # builds or loads the solver before the clock starts

    def on_two_workers(fn: Any, jobs: Any, *, on_result: Any = None) -> list[Any]:
        return runner.run_jobs(fn, jobs, workers=2, progress=False, on_result=on_result)

    with tempfile.TemporaryDirectory() as tmp:
        cpu, start = time.process_time(), time.perf_counter()
        generate_dataset(config, tmp, run_jobs=on_two_workers)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(wall, cpu, children.ru_utime + children.ru_stime)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--child", nargs=2, metavar=("SETTING", "FLIGHTS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _generate(args.child[0], int(args.child[1]))
        return 0
    flights, rounds = (20, 2) if args.size == "quick" else (100, 3)
    load = [os.getloadavg()[0]]
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "CANONID_CACHE_DIR": str(Path(tmp) / "cache"), "PYTHONPATH": str(ROOT)}
        os.environ["CANONID_CACHE_DIR"] = env["CANONID_CACHE_DIR"]
        idle = {label: idle_cpu(config) for label, config in SETTINGS.items()}
        load.append(os.getloadavg()[0])
        runs: dict[str, list[list[float]]] = {label: [] for label in SETTINGS}
        for _ in range(rounds):
            for label in SETTINGS:
                out = subprocess.run(
                    [sys.executable, __file__, "--child", label, str(flights)],
                    env=env,
                    capture_output=True,
                    text=True,
                    check=True,
                ).stdout.split()
                runs[label].append([float(v) for v in out[-3:]])
        load.append(os.getloadavg()[0])
    took = time.perf_counter() - began
    sentence, _ = load_line(
        load,
        "a loaded machine: CPU times are inflated too, and only their ratios carry over to an "
        "idle machine",
    )
    lines = [
        sentence,
        "",
        "Canonid's local clusters switch off Dask's statistical profiler of running tasks and "
        "slow its event-loop ticks and system and memory monitors (all for a dashboard that "
        f"canonid does not open): `{runner.LOCAL_CLUSTER_CONFIG}`.",
        "",
        "**Idle cluster** of 2 worker processes, 10 s: CPU milliseconds per second.",
        "",
        "| settings | workers | main process (scheduler, nannies, client) | total |",
        "|---|---|---|---|",
    ]
    for label, (workers, own) in idle.items():
        lines.append(f"| {label} | {workers:.0f} | {own:.0f} | {workers + own:.0f} |")
    lines += [
        "",
        f"**Drone flights on 2 workers**: `generate_dataset` of {flights} drone2d flights "
        f"through `run_jobs(workers=2)`, each a fresh process, the settings taking turns; "
        f"medians of {rounds} runs (CPU includes the cluster's start-up).",
        "",
        "| settings | wall s | main process CPU s | workers CPU s | CPU ms per flight |",
        "|---|---|---|---|---|",
    ]
    for label, values in runs.items():
        wall, main_cpu, workers_cpu = np.median(np.array(values), axis=0)
        lines.append(
            f"| {label} | {wall:.1f} | {main_cpu:.2f} | {workers_cpu:.2f} | "
            f"{(main_cpu + workers_cpu) / flights * 1e3:.0f} |"
        )
    return publish("Dask overhead", lines, took / 60)


if __name__ == "__main__":
    sys.exit(main())
