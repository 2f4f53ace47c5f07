"""Quadrotor stand-in: controller cost and tracking, and the wall time of its dataset.

Measures, in one run on this machine:

* the cost of one step of the cascaded controller, beside the cost of one step of the model
  (``Quadrotor.step``, the baseline every closed-loop step pays anyway);
* closed-loop tracking of the scenario's random references (position RMSE per flight, share of
  steps where the mixer saturated), excitation included as in generation;
* the wall time of the paper-size dataset (146 + 20 + 10 flights of 1000 samples): serially and
  on 2 local Dask worker processes (``--size full``); ``--size quick`` measures 20 flights both
  ways and extrapolates only the serial time linearly to 176 flights (said so in the table).

Writes the section "Quadrotor stand-in" of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._results import write_section
from canonid.runner import run_jobs
from datagen.generate import GenerationConfig, generate_dataset
from datagen.scenarios import get_scenario
from models.registry import get_system

PAPER_FLIGHTS = 146 + 20 + 10


def _step_times(fn, n: int) -> np.ndarray:
    times = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        times[i] = time.perf_counter() - t0
    return times


def controller_figures(flights: int, seed: int) -> dict[str, float]:
    """Per-step costs and tracking over ``flights`` scenario flights (T = 1000)."""
    scenario = get_scenario("quadrotor")
    system = get_system("quadrotor")
    controller = scenario.controller(system, {})
    rng = np.random.default_rng(seed)
    ctrl_t, model_t, rmse, saturated, steps = [], [], [], 0, 0
    for _ in range(flights):
        reference = scenario.reference(system, rng, scenario.T)
        x = scenario.initial_state(system, reference)
        controller.reset(reference, x)
        err = []
        for t in range(scenario.T):
            t0 = time.perf_counter()
            step = controller(t, x)
            t1 = time.perf_counter()
            u = np.clip(
                step.u + rng.normal(0.0, scenario.excitation_std, system.n_u),
                system.U.lo,
                system.U.hi,
            )
            x_next = system.step(x, u)
            t2 = time.perf_counter()
            ctrl_t.append(t1 - t0)
            model_t.append(t2 - t1)
            saturated += bool(step.info.get("saturated"))
            steps += 1
            err.append(x[0:3] - reference[t, 0:3])
            x = x_next
        rmse.append(float(np.sqrt(np.mean(np.sum(np.square(err), axis=1)))))
    ctrl, model = np.asarray(ctrl_t), np.asarray(model_t)
    return {
        "ctrl_median_us": float(np.median(ctrl) * 1e6),
        "ctrl_p95_us": float(np.percentile(ctrl, 95) * 1e6),
        "model_median_us": float(np.median(model) * 1e6),
        "rmse_median": float(np.median(rmse)),
        "rmse_max": float(np.max(rmse)),
        "saturated_share": saturated / steps,
        "flights": flights,
    }


def generation_seconds(flights: int, workers: int) -> float:
    counts = {"train": flights, "val": 0, "test": 0}
    config = GenerationConfig(system="quadrotor", seed=0, counts=counts)
    runner = functools.partial(run_jobs, workers=workers, progress=False)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        generate_dataset(config, Path(tmp) / "q", run_jobs=runner)
        return time.perf_counter() - t0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    args = parser.parse_args()
    full = args.size == "full"
    load = os.getloadavg()[0]
    fig = controller_figures(flights=20 if full else 5, seed=1)
    gen_flights = PAPER_FLIGHTS if full else 20
    serial = generation_seconds(gen_flights, workers=0)
    two = generation_seconds(gen_flights, workers=2)
    scale = PAPER_FLIGHTS / gen_flights
    rows = [
        ("cascade controller, median / p95 per step",
         f"{fig['ctrl_median_us']:.0f} / {fig['ctrl_p95_us']:.0f} µs"),
        ("model step `Quadrotor.step` (baseline), median", f"{fig['model_median_us']:.0f} µs"),
        ("controller / model step ratio", f"{fig['ctrl_median_us'] / fig['model_median_us']:.1f}"),
        (f"position RMSE per flight, median / max over {fig['flights']} flights",
         f"{fig['rmse_median']:.3f} / {fig['rmse_max']:.3f} m"),
        ("steps with a saturated mixer", f"{100 * fig['saturated_share']:.2f} %"),
        (f"{gen_flights} flights × 1000 samples, serial (measured)", f"{serial:.1f} s"),
        (f"{gen_flights} flights, 2 Dask worker processes incl. cluster start (measured)",
         f"{two:.1f} s"),
    ]  # fmt: skip
    if not full:
        rows.append(
            ("paper-size dataset (176 flights), serial, extrapolated linearly",
             f"{serial * scale:.0f} s")
        )  # fmt: skip
    table = "\n".join(f"| {k} | {v} |" for k, v in rows)
    body = (
        "Simulated quadrotor (Blackbird stand-in), cascaded controller, scenario flights of 1000 "
        "samples at 50 Hz with the generation's excitation. Load average when started: "
        f"{load:.2f} (2 cores shared).\n\n| quantity | value |\n|---|---|\n{table}\n"
    )
    write_section(
        "Quadrotor stand-in",
        body,
        command=f"python benchmarks/bench_quadrotor.py --size {args.size}",
    )
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
