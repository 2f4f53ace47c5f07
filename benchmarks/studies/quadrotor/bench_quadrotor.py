"""Quadrotor stand-in: controller cost and tracking, and the wall time of its dataset.

Measures, in one run on this machine:

* the cost of one step of the cascaded controller, beside the cost of one step of the model
  (``Quadrotor.step``, the baseline every closed-loop step pays anyway);
* the data engine's NMPC applied to the 13-state model (horizon 20; compiled fatrop with
  ``--size full``, the CasADi fatrop plugin with ``--size quick``) against the cascade on the
  same references and start states: step time and position RMSE;
* closed-loop tracking of the scenario's random references (position RMSE per flight, share of
  steps where the mixer saturated), excitation included as in generation;
* the wall time of the paper-size dataset (146 + 20 + 10 flights of 1000 samples): serially and
  on 2 local Dask worker processes (``--size full``); ``--size quick`` measures 20 flights both
  ways and extrapolates only the serial time linearly to 176 flights (said so in the table).

Writes the section "Quadrotor stand-in" of its notes (``benchmarks/records/``).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

from benchmarks._results import write_section
from canonid.datagen.controllers.nmpc import NMPC
from canonid.datagen.controllers.quadrotor_cascade import QuadrotorCascade
from canonid.datagen.generate import GenerationConfig, generate_dataset
from canonid.datagen.quadrotor_reference import quadrotor_initial_state, quadrotor_reference
from canonid.datagen.scenarios import get_scenario
from canonid.models.quadrotor import Quadrotor
from canonid.models.registry import get_system
from canonid.runner import run_jobs

PAPER_FLIGHTS = 146 + 20 + 10


#: NMPC weights for the 13-state quadrotor: position, velocity, quaternion, body rates
NMPC_STATE_WEIGHTS = (10.0,) * 3 + (1.0,) * 3 + (2.0,) * 4 + (0.05,) * 3
NMPC_INPUT_WEIGHTS = (1e-6,) * 4


def full_state_reference(reference: np.ndarray) -> np.ndarray:
    """(px, py, pz, vx, vy, vz, yaw) rows → 13-state targets: level with the yaw, no rotation."""
    yaw = reference[:, 6]
    zero = np.zeros_like(yaw)
    quat = np.column_stack([np.cos(yaw / 2), zero, zero, np.sin(yaw / 2)])
    return np.column_stack([reference[:, :6], quat, np.zeros((len(reference), 3))])


def compare_nmpc(
    solver: str, flights: int, steps: int, horizon: int, seed: int
) -> dict[str, float | str]:
    """The data engine's NMPC (``canonid.datagen.controllers.nmpc.NMPC``, LQR terminal cost at
    hover) and the cascade on the same references and start states, no excitation or noise."""
    system = get_system("quadrotor")
    assert isinstance(system, Quadrotor)
    t0 = time.perf_counter()
    mpc = NMPC(
        system,
        u_eq=(system.hover_speed,) * 4,
        x_eq=system.hover_state(),
        horizon=horizon,
        state_weights=NMPC_STATE_WEIGHTS,
        input_weights=NMPC_INPUT_WEIGHTS,
        solver=solver,
    )
    build = time.perf_counter() - t0
    cascade = QuadrotorCascade(system)
    rng = np.random.default_rng(seed)
    times: dict[str, list[float]] = {"nmpc": [], "cascade": []}
    rmse: dict[str, list[float]] = {"nmpc": [], "cascade": []}
    failures = 0
    for _ in range(flights):
        reference = quadrotor_reference(rng, steps=steps + horizon + 1, waypoints=(3, 6))
        x0 = quadrotor_initial_state(reference)
        runs = (
            ("nmpc", mpc, full_state_reference(reference)),
            ("cascade", cascade, reference[:steps]),
        )
        for name, controller, target in runs:
            x = x0.copy()
            controller.reset(target, x0)
            err = []
            for t in range(steps):
                start = time.perf_counter()
                step = controller(t, x)
                times[name].append(time.perf_counter() - start)
                failures += not step.ok
                err.append(x[0:3] - reference[t, 0:3])
                x = system.step(x, system.U.clip(step.u))
            rmse[name].append(float(np.sqrt(np.mean(np.sum(np.square(err), axis=1)))))
    out: dict[str, float | str] = {"solver": mpc.solver_used, "build_s": build}
    out |= {f"{k}_median_ms": float(np.median(v) * 1e3) for k, v in times.items()}
    out |= {f"{k}_p95_ms": float(np.percentile(v, 95) * 1e3) for k, v in times.items()}
    out |= {f"{k}_rmse": float(np.mean(v)) for k, v in rmse.items()}
    out |= {"failures": failures, "flights": flights, "steps": steps, "horizon": horizon}
    return out


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
    # the compiled solver (fatrop-c) is generated and compiled with gcc on first use, then loaded
    # from the cache; the quick run uses the CasADi plugin
    cmp = compare_nmpc(
        "fatrop-c" if full else "fatrop", flights=4 if full else 2, steps=400, horizon=20, seed=2
    )
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
        (f"NMPC ({cmp['solver']}, N = {cmp['horizon']}), median / p95 per step",
         f"{cmp['nmpc_median_ms']:.2f} / {cmp['nmpc_p95_ms']:.2f} ms"),
        ("NMPC construction (incl. C generation + compile unless cached)",
         f"{cmp['build_s']:.1f} s"),
        ("cascade on the same flights, median / p95 per step",
         f"{cmp['cascade_median_ms']:.3f} / {cmp['cascade_p95_ms']:.3f} ms"),
        (f"position RMSE, NMPC / cascade ({cmp['flights']} flights × {cmp['steps']} samples, "
         "no excitation)", f"{cmp['nmpc_rmse']:.3f} / {cmp['cascade_rmse']:.3f} m"),
        ("NMPC solver failures (fell back to the shifted plan)", f"{cmp['failures']}"),
        ("NMPC / cascade time per step",
         f"{cmp['nmpc_median_ms'] / cmp['cascade_median_ms']:.0f}×"),
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
    nmpc_seconds = PAPER_FLIGHTS * 1000 * float(cmp["nmpc_median_ms"]) / 1e3
    body = (
        "Simulated quadrotor (Blackbird stand-in). Cascaded controller on scenario flights of "
        "1000 samples at 50 Hz with the generation's excitation. The data engine's NMPC "
        "(`canonid.datagen.controllers.nmpc.NMPC`: multiple shooting, fatrop, LQR terminal cost at "
        "hover; weights `NMPC_STATE_WEIGHTS`, `NMPC_INPUT_WEIGHTS` here; full-state targets: "
        "the reference's position and velocity, level attitude with its yaw, no rotation) "
        "against the cascade on the same references. Load average when started: "
        f"{load:.2f} (2 cores shared).\n\n| quantity | value |\n|---|---|\n{table}\n\n"
        "At its median step time the NMPC alone would need about "
        f"{nmpc_seconds / 60:.0f} min of solver time for the paper-size dataset "
        "(176 × 1000 steps, serial), against the data engine's targets of 0.5 ms per step and "
        "2 minutes per dataset.\n"
    )
    write_section(
        "Quadrotor stand-in",
        body,
        command=f"python benchmarks/studies/quadrotor/bench_quadrotor.py --size {args.size}",
    )
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
