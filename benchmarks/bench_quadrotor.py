"""Quadrotor stand-in: controller cost and tracking, and the wall time of its dataset.

Measures, in one run on this machine:

* the cost of one step of the cascaded controller, beside the cost of one step of the model
  (``Quadrotor.step``, the baseline every closed-loop step pays anyway);
* a tracking NMPC on the 13-state model (multiple shooting, CasADi's fatrop plugin, horizon 20)
  against the cascade on the same references and start states: step time and position RMSE;
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

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._results import write_section
from canonid.runner import run_jobs
from datagen.controllers.quadrotor_cascade import QuadrotorCascade
from datagen.generate import GenerationConfig, generate_dataset
from datagen.quadrotor_reference import quadrotor_initial_state, quadrotor_reference
from datagen.scenarios import get_scenario
from models.quadrotor import Quadrotor
from models.registry import get_system

PAPER_FLIGHTS = 146 + 20 + 10


def nmpc_function(system: Quadrotor, horizon: int) -> ca.Function:
    """A tracking NMPC for the 13-state quadrotor, written here for the measurement only.

    Direct multiple shooting over ``horizon`` steps of the model's own ``f`` (RK4 + quaternion
    renormalisation), constraints in fatrop's stage order (``x[k+1] − f(x[k], u[k]) = 0``, the
    initial state, the input box), cost ``Σ 10‖p − p_ref‖² + ‖v − v_ref‖² + 2 (1 − (q·q_ψ)²)
    + 0.05‖ω‖² + 1e-6‖u − Ω_h‖²`` (``q_ψ`` the level attitude with the reference yaw), solved
    by CasADi's fatrop plugin (the structure-exploiting solver the data engine uses), warm
    started from the shifted previous plan. Returns ``(x0, ref (7, N+1), X guess, U guess) ->
    (X, U)``.
    """
    opti = ca.Opti()
    xs, us = [], []
    for k in range(horizon + 1):
        xs.append(opti.variable(system.n_x))
        if k < horizon:
            us.append(opti.variable(system.n_u))
    x0 = opti.parameter(system.n_x)
    ref = opti.parameter(7, horizon + 1)
    cost = 0
    for k in range(horizon + 1):
        p, v, q, w = xs[k][0:3], xs[k][3:6], xs[k][6:10], xs[k][10:13]
        r = ref[:, k]
        q_yaw = ca.vertcat(ca.cos(r[6] / 2), 0, 0, ca.sin(r[6] / 2))
        cost += 10 * ca.sumsqr(p - r[0:3]) + ca.sumsqr(v - r[3:6])
        cost += 2 * (1 - ca.dot(q, q_yaw) ** 2) + 0.05 * ca.sumsqr(w)
        if k < horizon:
            cost += 1e-6 * ca.sumsqr(us[k] - system.hover_speed)
    opti.minimize(cost)
    for k in range(horizon):
        opti.subject_to(xs[k + 1] - system.f(xs[k], us[k]) == 0)
        if k == 0:
            opti.subject_to(xs[0] == x0)
        opti.subject_to(opti.bounded(system.U.lo, us[k], system.U.hi))
    opti.solver(
        "fatrop",
        {"expand": True, "structure_detection": "auto", "print_time": False},
        {"print_level": 0, "tol": 1e-6, "mu_init": 1e-2},
    )
    X, U = ca.horzcat(*xs), ca.horzcat(*us)
    return opti.to_function("nmpc", [x0, ref, X, U], [X, U])


def compare_nmpc(flights: int, steps: int, horizon: int, seed: int) -> dict[str, float]:
    """NMPC and cascade on the same references and start states, no excitation or noise."""
    system = get_system("quadrotor")
    assert isinstance(system, Quadrotor)
    mpc = nmpc_function(system, horizon)
    cascade = QuadrotorCascade(system)
    rng = np.random.default_rng(seed)
    times: dict[str, list[float]] = {"nmpc": [], "cascade": []}
    rmse: dict[str, list[float]] = {"nmpc": [], "cascade": []}
    failures = 0
    for _ in range(flights):
        reference = quadrotor_reference(rng, steps=steps + horizon + 1, waypoints=(3, 6))
        x0 = quadrotor_initial_state(reference)
        for name in ("nmpc", "cascade"):
            x = x0.copy()
            cascade.reset(reference[:steps], x0)
            X_guess = np.tile(x0, (horizon + 1, 1))
            U_guess = np.full((horizon, system.n_u), system.hover_speed)
            err = []
            for t in range(steps):
                t0 = time.perf_counter()
                if name == "cascade":
                    u = cascade(t, x).u
                else:
                    try:
                        X, U = mpc(x, reference[t : t + horizon + 1].T, X_guess.T, U_guess.T)
                        X, U = np.asarray(X).T, np.asarray(U).T
                    except RuntimeError:
                        failures += 1
                        X, U = X_guess, U_guess  # the shifted previous plan
                    u = U[0]
                    X_guess = np.vstack([X[1:], X[-1:]])
                    U_guess = np.vstack([U[1:], U[-1:]])
                times[name].append(time.perf_counter() - t0)
                err.append(x[0:3] - reference[t, 0:3])
                x = system.step(x, system.U.clip(u))
            rmse[name].append(float(np.sqrt(np.mean(np.sum(np.square(err), axis=1)))))
    out = {f"{k}_median_ms": float(np.median(v) * 1e3) for k, v in times.items()}
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
    cmp = compare_nmpc(flights=4 if full else 2, steps=400, horizon=20, seed=2)
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
        (f"NMPC (fatrop, N = {cmp['horizon']}), median / p95 per step",
         f"{cmp['nmpc_median_ms']:.2f} / {cmp['nmpc_p95_ms']:.2f} ms"),
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
    nmpc_steps = PAPER_FLIGHTS * 1000 * cmp["nmpc_median_ms"] / 1e3
    body = (
        "Simulated quadrotor (Blackbird stand-in). Cascaded controller on scenario flights of "
        "1000 samples at 50 Hz with the generation's excitation; NMPC (written in the benchmark, "
        "fatrop, see `nmpc_function`) against the cascade on the same references. Load average "
        f"when started: {load:.2f} (2 cores shared).\n\n| quantity | value |\n|---|---|\n"
        f"{table}\n\nAt its median step time the NMPC alone would need about "
        f"{nmpc_steps / 60:.0f} min of solver time for the paper-size dataset "
        "(176 × 1000 steps, serial).\n"
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
