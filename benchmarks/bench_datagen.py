"""Data-engine benchmark: NMPC step time and tracking versus a plain ``Opti`` + IPOPT loop of the
same problem, and the wall time of the paper-size planar-drone dataset on 2 workers.

Every controller flies the same flights (same references, same excitation, σ = 1 rad/s) with
horizon 20 and the drone2d scenario's weights, taking turns flight by flight; step time is the
wall time of one controller call (solver + Python overhead), tracking RMSE the position error
‖(px, pz) − reference‖.

``--size quick``: 3 flights per controller, and 40 dataset flights whose rate is extrapolated
to 540 (said so in the results); ``--size full``: 6 flights and the whole 540 × 600 dataset.
Writes the "Data engine" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import write_section  # noqa: E402

from canonid.runner import run_jobs  # noqa: E402
from datagen.controllers.base import Controller, ControlStep  # noqa: E402
from datagen.controllers.nmpc import NMPC  # noqa: E402
from datagen.generate import FlightJob, GenerationConfig, generate_dataset, run_flight  # noqa: E402
from datagen.references import drone2d_reference  # noqa: E402
from datagen.scenarios import DRONE2D_INPUT_WEIGHTS, DRONE2D_STATE_WEIGHTS  # noqa: E402
from datagen.simulate import Excitation, simulate_closed_loop  # noqa: E402
from models.drone2d import Drone2D  # noqa: E402

HORIZON = 20
T = 600


class OptiIpopt(Controller):
    """The baseline: the same NLP written with ``casadi.Opti`` and solved by IPOPT with its
    default settings, warm-started from the shifted previous solution (``set_initial``)."""

    name = "opti-ipopt"

    def __init__(self, system: Drone2D, P: np.ndarray) -> None:
        N, h = HORIZON, system.hover_speed
        opti = ca.Opti()
        self.X, self.U = opti.variable(6, N + 1), opti.variable(2, N)
        self.x_now, self.ref = opti.parameter(6), opti.parameter(6, N + 1)
        Q, R = np.diag(DRONE2D_STATE_WEIGHTS), np.diag(DRONE2D_INPUT_WEIGHTS)
        cost = 0
        opti.subject_to(self.X[:, 0] == self.x_now)
        for k in range(N):
            e, du = self.X[:, k] - self.ref[:, k], self.U[:, k] - h
            cost += ca.bilin(Q, e, e) + ca.bilin(R, du, du)
            opti.subject_to(self.X[:, k + 1] == system.f(self.X[:, k], self.U[:, k]))
            opti.subject_to(opti.bounded(0, self.U[:, k], system.U.hi[0]))
        e = self.X[:, N] - self.ref[:, N]
        opti.minimize(cost + ca.bilin(P, e, e))
        opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes"})
        self.opti, self.hover, self.system = opti, h, system

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        self.reference = reference
        self.opti.set_initial(self.X, np.tile(x0[:, None], (1, HORIZON + 1)))
        self.opti.set_initial(self.U, self.hover)

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        rows = np.minimum(np.arange(t, t + HORIZON + 1), len(self.reference) - 1)
        self.opti.set_value(self.x_now, x)
        self.opti.set_value(self.ref, self.reference[rows].T)
        try:
            sol = self.opti.solve()
        except RuntimeError:
            return ControlStep(u=np.full(2, self.hover), ok=False)
        X, U = sol.value(self.X), sol.value(self.U)
        self.opti.set_initial(self.X, np.hstack([X[:, 1:], X[:, -1:]]))
        self.opti.set_initial(self.U, np.hstack([U[:, 1:], U[:, -1:]]))
        return ControlStep(u=U[:, 0])

    def settings(self) -> dict[str, Any]:
        return {"type": self.name}


class Timed(Controller):
    """Wraps a controller and records the wall time of every call."""

    def __init__(self, inner: Controller) -> None:
        self.inner, self.times = inner, []

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        self.inner.reset(reference, x0)

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        start = time.perf_counter()
        step = self.inner(t, x)
        self.times.append(time.perf_counter() - start)
        return step

    def settings(self) -> dict[str, Any]:
        return self.inner.settings()


def interleaved(drone: Drone2D, controllers: dict[str, Controller], flights: int) -> dict[str, Any]:
    """Fly every controller on the same flights (same reference, same excitation), the
    controllers taking turns flight by flight, so that the load of a shared machine falls on all
    of them alike while each flight runs uninterrupted (as in dataset generation)."""
    timed = {name: Timed(ctrl) for name, ctrl in controllers.items()}
    squared: dict[str, list[np.ndarray]] = {name: [] for name in controllers}
    failures = dict.fromkeys(controllers, 0)
    for i in range(flights):
        ref = drone2d_reference(np.random.default_rng(1000 + i), T=T, dt=drone.dt)
        for name, ctrl in timed.items():
            loop = simulate_closed_loop(
                drone,
                ctrl,
                ref,
                x0=ref[0],
                rng=np.random.default_rng(2000 + i),
                excitation=Excitation(std=1.0),
                clip_input=True,
            )
            squared[name].append(np.sum((loop.x[:, :2] - ref[:, :2]) ** 2, axis=1))
            failures[name] += loop.failures
    return {
        name: {
            "median_ms": float(np.median(ctrl.times) * 1e3),
            "p95_ms": float(np.percentile(ctrl.times, 95) * 1e3),
            "rmse_m": float(np.sqrt(np.mean(np.concatenate(squared[name])))),
            "steps": len(ctrl.times),
            "failures": failures[name],
        }
        for name, ctrl in timed.items()
    }


def cpu_seconds_per_flight(flights: int) -> float:
    """CPU time of one whole drone flight job (controller, simulation, bookkeeping), serially."""
    config = GenerationConfig("drone2d", seed=0, counts={"train": flights})
    run_flight(FlightJob(config, "train", 0))  # builds (or loads) the solver once
    start = time.process_time()
    for i in range(flights):
        run_flight(FlightJob(config, "train", i))
    return (time.process_time() - start) / flights


def dataset_wall_time(size: str, out: Path) -> tuple[float, int, str]:
    """Seconds for the paper-size dataset on 2 local Dask workers (measured, or extrapolated
    from the start-up time and the steady rate of a smaller run)."""
    counts = {"train": 500, "val": 20, "test": 20}
    if size == "quick":
        counts = {"train": 32, "val": 4, "test": 4}
    config = GenerationConfig("drone2d", seed=0, counts=counts)
    arrivals: list[float] = []

    def runner(fn: Any, jobs: Any, *, on_result: Any = None) -> list[Any]:
        def timed(position: int, result: Any) -> None:
            arrivals.append(time.perf_counter())
            if on_result is not None:
                on_result(position, result)

        return run_jobs(fn, jobs, workers=2, progress=False, on_result=timed)

    start = time.perf_counter()
    result = generate_dataset(config, out, run_jobs=runner)
    elapsed = time.perf_counter() - start
    n = sum(result.counts.values())
    startup = arrivals[0] - start
    per_flight = (arrivals[-1] - arrivals[0]) / (n - 1)
    detail = (
        f"start-up (cluster, solver load in each worker, first flight) {startup:.1f} s, then "
        f"{per_flight * 1e3:.0f} ms per flight"
    )
    if n == 540:
        return elapsed, n, f"measured: {elapsed:.1f} s for 540 flights × {T} steps ({detail})"
    estimate = startup + per_flight * 539 + (elapsed - (arrivals[-1] - start))
    return (
        estimate,
        n,
        f"**extrapolated** from {n} flights in {elapsed:.1f} s ({detail}) to 540 flights: "
        f"{estimate:.0f} s",
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    args = parser.parse_args()
    flights = 3 if args.size == "quick" else 6
    load_before = os.getloadavg()
    drone = Drone2D()
    h = drone.hover_speed
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["CANONID_CACHE_DIR"] = str(Path(tmp) / "cache")  # inherited by the workers

        def nmpc(solver: str) -> NMPC:
            return NMPC(
                drone,
                u_eq=(h, h),
                horizon=HORIZON,
                state_weights=DRONE2D_STATE_WEIGHTS,
                input_weights=DRONE2D_INPUT_WEIGHTS,
                solver=solver,
            )

        start = time.perf_counter()
        ours = nmpc("auto")
        build_s = time.perf_counter() - start
        ours_label = f"NMPC, {ours.solver_used} (default)"
        base_label = "baseline: Opti + IPOPT (defaults, warm start)"
        rows = interleaved(
            drone,
            {
                ours_label: ours,
                "NMPC, fatrop plugin (no compiler)": nmpc("fatrop"),
                "same NLP, IPOPT (expand, mu_init 1e-3, tol 1e-4)": nmpc("ipopt"),
                base_label: OptiIpopt(drone, ours.P),
            },
            flights,
        )
        cpu = cpu_seconds_per_flight(3 if args.size == "quick" else 10)
        wall, n, how = dataset_wall_time(args.size, Path(tmp) / "dataset")
    load_after = os.getloadavg()

    base, mine = rows[base_label], rows[ours_label]
    lines = [
        f"Planar drone, horizon {HORIZON}, {flights} flights of {T} steps with σ = 1 rad/s "
        "excitation, every controller on the same flights, taking turns flight by flight (so "
        "load falls on all alike). Load average before / after: "
        f"{load_before[0]:.2f} / {load_after[0]:.2f} on 2 cores shared with other jobs.",
        "",
        "| controller | steps | median ms/step | p95 ms/step | speed-up vs Opti (median) | "
        "RMSE position [m] | failed solves |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, r in rows.items():
        lines.append(
            f"| {label} | {r['steps']} | {r['median_ms']:.3f} | {r['p95_ms']:.3f} | "
            f"{base['median_ms'] / r['median_ms']:.1f}× | {r['rmse_m']:.4f} | {r['failures']} |"
        )
    speedup = base["median_ms"] / mine["median_ms"]
    cpu_bound = 540 * cpu / 2
    lines += [
        "",
        f"First use of the default solver (generate C, compile with gcc, load): {build_s:.1f} s; "
        "later uses load the cached library.",
        "",
        f"Paper-size dataset (540 flights × {T} steps, 2 local Dask worker processes): {how}.",
        f"CPU time of one flight job: {cpu * 1e3:.0f} ms, so 540 flights on 2 otherwise idle "
        f"cores need about {cpu_bound:.0f} s plus start-up (an estimate, not a measurement).",
        "",
        "Targets:",
        f"- median step ≤ 0.5 ms: {mine['median_ms']:.3f} ms — "
        f"{'met' if mine['median_ms'] <= 0.5 else 'NOT met'}",
        f"- ≥ 10× the Opti + IPOPT loop: {speedup:.1f}× — {'met' if speedup >= 10 else 'NOT met'}",
        f"- tracking RMSE no worse than IPOPT: {mine['rmse_m']:.4f} m vs {base['rmse_m']:.4f} m — "
        f"{'met' if mine['rmse_m'] <= base['rmse_m'] * 1.001 else 'NOT met'}",
        f"- whole dataset ≤ 2 min on this machine: {wall:.0f} s"
        + (" (extrapolated)" if n != 540 else "")
        + f" — {'met' if wall <= 120 else 'NOT met under this load'}",
    ]
    body = "\n".join(lines)
    write_section("Data engine", body)
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
