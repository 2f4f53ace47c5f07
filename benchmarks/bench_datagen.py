"""Data-engine benchmark (the "Data engine" section of its notes (``benchmarks/records/``)).

Run on an idle machine for the recorded figures::

    .venv/bin/python benchmarks/bench_datagen.py --size full

Parts, in order, with the 1-minute load average recorded after each:

1. Controllers: NMPC step time and tracking versus a plain ``Opti`` + IPOPT loop of the same
   problem. Every controller flies the same flights (same references, same excitation,
   σ = 1 rad/s) with horizon 20 and the drone2d scenario's weights, taking turns flight by
   flight, called step by step; step time is the wall time of one controller call (solver +
   Python overhead), tracking RMSE the position error ‖(px, pz) − reference‖.
2. CPU per flight job of the paper-size dataset, in one process: the step loop against the
   compiled loop (the default; :mod:`canonid.datagen.compiled_loop`), alternating flight by flight,
   and the flight's solves alone; whether both loops gave the same flights.
3. Start-up: a fresh process importing the data engine and loading the cached solver (what
   each Dask worker does), and ``canonid generate drone2d`` with 20 flights, serially.
4. The paper-size dataset (540 flights × 600 steps) on 2 local Dask workers: wall time, the
   CPU of the workers and of the main process (where the wall time goes beyond the flights),
   and its ratio to the bound set by the solver alone (540 × solver CPU per flight / 2 cores).

``--size quick``: 3 controller flights, 4 CPU flights, and 40 dataset flights whose rate is
extrapolated to 540 (said so in the results); ``--size full``: 6, 10 and the whole dataset.
"""

from __future__ import annotations

import argparse
import functools
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from unittest import mock

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import load_line, publish  # noqa: E402

import canonid.datagen.generate as generate  # noqa: E402
from canonid.datagen.controllers.base import Controller, ControlStep  # noqa: E402
from canonid.datagen.controllers.nmpc import NMPC  # noqa: E402
from canonid.datagen.generate import (  # noqa: E402
    FlightJob,
    FlightResult,
    GenerationConfig,
    generate_dataset,
    run_flight,
)
from canonid.datagen.references import drone2d_reference  # noqa: E402
from canonid.datagen.scenarios import DRONE2D_INPUT_WEIGHTS, DRONE2D_STATE_WEIGHTS  # noqa: E402
from canonid.datagen.simulate import Excitation, simulate_closed_loop  # noqa: E402
from canonid.models.drone2d import Drone2D  # noqa: E402
from canonid.runner import run_jobs  # noqa: E402

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


@dataclass(frozen=True)
class FlightCpu:
    """Process CPU seconds per drone flight job, single process (medians over the flights)."""

    step_loop: float
    compiled_loop: float
    solver_alone: float
    flights: int
    identical: bool

    def line(self, label: str, seconds: float) -> str:
        return (
            f"| {label} | {seconds * 1e3:.0f} | {seconds / T * 1e3:.3f} | "
            f"{seconds / self.solver_alone:.2f} |"
        )


def flight_cpu(flights: int) -> FlightCpu:
    """The same flight jobs of the paper-size dataset run by the step loop (the loop before the
    compiled one) and by the compiled loop, alternating flight by flight so that the load of a
    shared machine falls on both alike; and the flight's 600 solver calls alone, replayed in
    one mapped CasADi call (no Python between solves)."""
    config = GenerationConfig("drone2d", seed=0, counts={"train": flights})
    calls: list[tuple[np.ndarray, np.ndarray]] = []
    solvers: list[NMPC] = []
    real_solve_once = NMPC._solve_once

    def recorded(self: NMPC, params: np.ndarray) -> Any:
        calls.append((self._guess.copy(), params.copy()))
        solvers[:] = [self]
        return real_solve_once(self, params)

    step_by_step = functools.partial(simulate_closed_loop, step_by_step=True)

    def step_loop_job(job: FlightJob) -> FlightResult:
        with mock.patch.object(generate, "simulate_closed_loop", step_by_step):
            return run_flight(job)

    run_flight(FlightJob(config, "train", 0))  # builds (or loads) the solver once
    old, new, alone, identical = [], [], [], True
    for i in range(flights):
        job = FlightJob(config, "train", i)
        start = time.process_time()
        before = step_loop_job(job)
        old.append(time.process_time() - start)
        start = time.process_time()
        after = run_flight(job)
        new.append(time.process_time() - start)
        identical &= all(
            np.array_equal(getattr(before.trajectory, k), getattr(after.trajectory, k))
            for k in ("x", "u", "y")
        )
        calls.clear()
        with mock.patch.object(NMPC, "_solve_once", recorded):  # untimed: record the solves
            step_loop_job(job)
        replay = solvers[0]._solve.map(len(calls))
        guesses, params = (np.stack(column, axis=1) for column in zip(*calls))
        start = time.process_time()
        replay(guesses, params)
        alone.append(time.process_time() - start)
    return FlightCpu(
        step_loop=float(np.median(old)),
        compiled_loop=float(np.median(new)),
        solver_alone=float(np.median(alone)),
        flights=flights,
        identical=identical,
    )


_STARTUP = """
import time
start = time.perf_counter(), time.process_time()
from canonid.datagen.generate import GenerationConfig, _controller_for
imported = time.perf_counter(), time.process_time()
_controller_for(GenerationConfig("drone2d"))
built = time.perf_counter(), time.process_time()
print(*(b - a for a, b in zip(start, imported)), *(b - a for a, b in zip(imported, built)))
"""


def startup_seconds() -> dict[str, float]:
    """A fresh process (what every Dask worker does): import the data engine, build the
    drone's NMPC from the cached library; wall and CPU seconds. The python-control import the
    NMPC no longer needs. A local cluster of 2 workers started, given 2 trivial jobs, closed."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", _STARTUP], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    control = (
        subprocess.run(
            [sys.executable, "-X", "importtime", "-c", "import control"],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        .stderr.strip()
        .splitlines()[-1]
    )
    start = time.perf_counter()
    run_jobs(abs, [-1, -2], workers=2, progress=False)
    cluster = time.perf_counter() - start
    return {
        "cluster": cluster,
        "import_wall": float(out[0]),
        "import_cpu": float(out[1]),
        "build_wall": float(out[2]),
        "build_cpu": float(out[3]),
        "control_import": int(control.split("|")[1]) * 1e-6,  # cumulative µs of "control"
    }


def small_generation_seconds(out: Path) -> tuple[float, float, int]:
    """Wall and CPU seconds of ``canonid generate drone2d`` for 20 flights, serially, as a user
    types it (a fresh process: imports, cached solver, flights, files)."""
    flights = 20
    command = [
        str(Path(sys.executable).with_name("canonid")),
        "generate",
        "drone2d",
        "--n-train",
        str(flights),
        "--n-val",
        "0",
        "--n-test",
        "0",
        "--out",
        str(out),
        "--no-progress",
    ]
    cpu = _children_cpu()
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start, _children_cpu() - cpu, flights


def _children_cpu() -> float:
    """CPU seconds of the finished child processes of this one (user + system)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


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

        return run_jobs(
            fn, jobs, workers=2, progress=False, on_result=timed, batch=generate.FLIGHTS_PER_TASK
        )  # as `canonid generate --workers 2` runs them

    start, main_cpu, workers_cpu = time.perf_counter(), time.process_time(), _children_cpu()
    result = generate_dataset(config, out, run_jobs=runner)
    elapsed = time.perf_counter() - start
    # the worker processes are children of this one, reaped when the cluster closes
    main_cpu, workers_cpu = time.process_time() - main_cpu, _children_cpu() - workers_cpu
    n = sum(result.counts.values())
    startup = arrivals[0] - start
    per_flight = (arrivals[-1] - arrivals[0]) / (n - 1)
    detail = (
        f"start-up (cluster, data engine and solver load in each worker, first flight) "
        f"{startup:.1f} s, then {per_flight * 1e3:.0f} ms per flight; CPU: workers "
        f"{workers_cpu:.1f} s ({workers_cpu / n * 1e3:.0f} ms per flight, start-up included), "
        f"main process (scheduler, client, parts, dataset file) {main_cpu:.1f} s "
        f"({main_cpu / n * 1e3:.1f} ms per flight)"
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
    load = [os.getloadavg()[0]]
    began = time.perf_counter()
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

        start, gcc = time.perf_counter(), _children_cpu()
        ours = nmpc("auto")
        build_s, gcc = time.perf_counter() - start, _children_cpu() - gcc
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
        load.append(os.getloadavg()[0])
        cpu = flight_cpu(4 if args.size == "quick" else 10)
        load.append(os.getloadavg()[0])
        startup = startup_seconds()
        small_wall, small_cpu, small_n = small_generation_seconds(Path(tmp) / "small")
        load.append(os.getloadavg()[0])
        wall, n, how = dataset_wall_time(args.size, Path(tmp) / "dataset")
    load.append(os.getloadavg()[0])
    took = time.perf_counter() - began

    base, mine = rows[base_label], rows[ours_label]
    sentence, loaded = load_line(
        load,
        "a loaded machine: wall times are not idle times; the CPU times per flight are the "
        "comparable figures",
        own=[0, 1, 1, 1, 2],  # start; controllers, CPU per flight, start-up: one; the dataset: 2
    )
    lines = [
        sentence,
        "",
        f"**Controllers.** Planar drone, horizon {HORIZON}, {flights} flights of {T} steps with "
        "σ = 1 rad/s excitation, every controller on the same flights, taking turns flight by "
        "flight (so load falls on all alike), called step by step (the step time is the wall "
        "time of one controller call).",
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
    solver_bound = 540 * cpu.solver_alone / 2
    lines += [
        "",
        f"First use of the default solver (generate C for the solver and the compiled loop, "
        f"compile with gcc, load): {build_s:.1f} s wall ({gcc:.1f} s CPU in gcc); later uses "
        "load the cached library.",
        "",
        f"**CPU per flight** (process CPU time, one process; median of {cpu.flights} jobs of the "
        "paper-size dataset, the two loops alternating flight by flight):",
        "",
        "| loop | ms per flight | ms per step | × solver alone |",
        "|---|---|---|---|",
        cpu.line("step loop (one Python call into CasADi per solve and per f)", cpu.step_loop),
        cpu.line(
            "compiled loop (chunks of 50 steps, one CasADi call each; default)", cpu.compiled_loop
        ),
        cpu.line(
            "solver alone (the flight's 600 solves replayed in one mapped call)", cpu.solver_alone
        ),
        "",
        f"The compiled loop's flights are byte-identical to the step loop's: "
        f"{'yes' if cpu.identical else '**NO**'} ({cpu.flights} flights). Outside the solver: "
        f"{1 - cpu.solver_alone / cpu.step_loop:.0%} of the step loop's CPU, "
        f"{1 - cpu.solver_alone / cpu.compiled_loop:.0%} of the compiled loop's.",
        "",
        f"**Start-up**: a local Dask cluster of 2 workers, started, given 2 trivial jobs and "
        f"closed, {startup['cluster']:.1f} s wall. In a fresh process (as in each worker): "
        f"importing the data engine "
        f"{startup['import_wall']:.2f} s wall ({startup['import_cpu']:.2f} s CPU), building the "
        f"drone NMPC from the cached library {startup['build_wall']:.2f} s wall "
        f"({startup['build_cpu']:.2f} s CPU); the python-control import the terminal weight no "
        f"longer needs took {startup['control_import']:.2f} s. `canonid generate drone2d` with "
        f"{small_n} flights, serially: {small_wall:.1f} s wall, {small_cpu:.1f} s CPU, of "
        f"which the flights' are about {small_n * cpu.compiled_loop:.1f} s.",
        "",
        f"**Paper-size dataset** (540 flights × {T} steps, 2 local Dask worker processes): "
        f"{how}. The solver alone bounds it at 540 × {cpu.solver_alone * 1e3:.0f} ms / 2 cores "
        f"= {solver_bound:.0f} s: the run took {wall / solver_bound:.2f}× that.",
        "",
        "Targets:",
        f"- median step ≤ 0.3 ms: {mine['median_ms']:.3f} ms — "
        + (
            "met"
            if mine["median_ms"] <= 0.3
            else "NOT met" + (" under this load" if loaded else "")
        ),
        f"- ≥ 10× the Opti + IPOPT loop: {speedup:.1f}× — {'met' if speedup >= 10 else 'NOT met'}",
        f"- tracking RMSE no worse than IPOPT: {mine['rmse_m']:.4f} m vs {base['rmse_m']:.4f} m — "
        f"{'met' if mine['rmse_m'] <= base['rmse_m'] * 1.001 else 'NOT met'}",
        f"- compiled loop = step loop, byte for byte: {'met' if cpu.identical else 'NOT met'}",
        f"- paper-size dataset ≤ 45 s on 2 idle cores: {wall:.0f} s"
        + (" (extrapolated)" if n != 540 else "")
        + " — "
        + ("met" if wall <= 45 else "NOT met" + (" under this load" if loaded else "")),
    ]
    return publish("Data engine", lines, took / 60)


if __name__ == "__main__":
    sys.exit(main())
