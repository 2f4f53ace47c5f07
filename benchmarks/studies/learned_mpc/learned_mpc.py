"""NMPC on a learned model against NMPC on the true model: tank levels and planar-drone positions.

The learned models are trained Ours (MLP) runs, or ARX runs (the affine path alone): ``--run``
on tank data, ``--drone-run`` on planar-drone data, repeated for runs on several drone datasets
(their rows are labelled by the model and the scenario that generated each run's data), or
``RUN+RUN+…`` for the mean of several runs (an ensemble); built
as CasADi systems from their weights (:func:`canonid.learned.learned_system`). Per system both
controllers are the same :class:`canonid.datagen.controllers.nmpc.NMPC` with an output reference
(``track="output"``), the same horizon, weights, input bounds (the true system's U) and solver;
they differ in the prediction model, in what they are fed and (``--hessian``) in how the learned
model's NLP is solved:

* NMPC on the true model: the true state ``x[t]`` (state feedback, no noise), exact Hessian;
* NMPC on the learned model: its state ``z_t``, the window of the last ℓ applied inputs and
  *measured* outputs (uniform noise in the dataset's noise box) — no observer; by default the
  Gauss-Newton SQP (``hessian="gauss-newton"``: no second derivatives of the network, Jacobians
  in numpy), which plans the same inputs as the exact Hessian when both converge.

Each closed loop runs on the true system along one of the first ``--references`` references of
the dataset's test split, from the recorded state at sample ℓ (the ℓ recorded samples before it
fill the learned model's first window). Reported per controller: the tracking RMSE of the true
(noise-free) tracked outputs against the reference over samples ℓ … T−1 (tank: the level; drone:
px and pz — θ has weight 0), the median solve time (wall clock and the process's CPU time: the
machine is shared), the 95th percentile of the wall time and the failed solves. With
``--exact-steps`` the learned tank NMPC also runs with the exact Hessian on the first reference
for that many steps, beside the Gauss-Newton one (the cost before the option existed). Also the
learned tank model's γ_f bracket on its training hull (:mod:`canonid.analysis.certify`) beside the
true tank's on its X.

Beside the drone loops (per ``--drone-run``; ``--theory-seconds 0`` leaves it out), the theory
(:func:`loop_theory`): γ_f of the learned model in its window state z on the box hull of the
windows ``z_t`` and inputs ``u_t`` its NMPC loops visit and on its training hull (sampled lower
bound, certified branch-and-bound upper bound within ``--gamma-seconds`` per stage, certified
layer-norm upper bound); and Proposition 2 for the true drone's state estimated from each window
of ℓ measured outputs of those loops, ``‖x̂_t − x_t‖ ≤ 2 γ_f^ℓ α_ℓ^{−1}‖w̄_{t−ℓ|t−1}‖``, with the
certified constants of ``canonid analyze drone2d`` (γ_f upper bound on the box reachable from X
in ℓ − 1 steps × U, α_ℓ lower bound on X × U^ℓ; ``--theory-seconds`` per certified stage) and the
loops' recorded noise, over the windows whose premises hold (``x_{t−ℓ}`` in X, the inputs in U);
set beside it the measured ``‖w̄‖`` and the learned model's one-step output error.

The step responses of ``Case.judged`` (drone: px and θ after a rotor difference) are also run from
rest (hover) and judged: learned / true change in [0.7, 1.3] is the true sign within 30 %.

Writes the section "NMPC on a learned model" of the records (benchmarks/records/) (``--section``
names
another, so that a run on other data keeps the earlier one).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[3]))  # this checkout's packages
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: _results

import numpy as np
from _results import write_section

from canonid.analysis.bound import bound_along
from canonid.analysis.certify import layer_norm_words, learned_gamma
from canonid.analysis.estimate import Budget
from canonid.analysis.lipschitz import lipschitz_bracket
from canonid.analysis.report import analyze
from canonid.datagen.controllers.nmpc import NMPC
from canonid.learned import learned_system
from canonid.models.base import System
from canonid.models.drone2d import Drone2D
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box
from canonid.models.tank import Tank
from canonid.profiles import PROFILES

HORIZON = 20
SECTION = "NMPC on a learned model"
MODELS = {"mlp": "Ours (MLP)", "arx": "ARX (the affine path alone, least squares)"}
LEVEL_EQ = 2.5  # tank: the input term pulls towards the input that holds this level


@dataclass(frozen=True)
class Case:
    """One system of the benchmark: its NMPC weights and which outputs are scored."""

    name: str
    system: System
    u_eq: list[float]
    output_weights: list[float]
    input_weights: list[float]
    scored: list[int]  # output columns in the RMSE
    note: str
    envelope: bool  # count the loops whose true state leaves the system's X (its flight box)
    probes: dict[str, list[float]]  # input steps of the response check, added to recorded inputs
    # probe → outputs whose learned response is judged (sign, size)
    judged: dict[str, list[int]] = field(default_factory=dict)
    rest: list[float] | None = None  # an equilibrium state under u_eq the check also starts from


def cases() -> dict[str, Case]:
    tank, drone = Tank(), Drone2D()
    return {
        "tank": Case(
            "tank",
            tank,
            [tank.equilibrium_input(LEVEL_EQ)],
            [1.0],
            [1e-3],
            [0],
            f"Q = 1 on the level, R = 1e-3 on u − u_eq(level {LEVEL_EQ}), U = [0, 6]",
            False,  # the tank's X is the analysis box, which the test flights leave
            {"pump +0.5 V": [0.5]},
            {"pump +0.5 V": [0]},
            None,
        ),
        "drone2d": Case(
            "drone2d",
            drone,
            [drone.hover_speed] * 2,
            [5.0, 5.0, 0.0],
            [1e-3, 1e-3],
            [0, 1],
            "Q = (5, 5, 0) on (px, pz, θ) (the data's NMPC weights on the pose), R = 1e-3 on "
            "each rotor's deviation from hover, U = [0, 250]² rad/s",
            True,
            {
                "rotor difference Ω2 − Ω1 = +1 rad/s": [-0.5, 0.5],
                "both rotors +1 rad/s": [1.0, 1.0],
            },
            {"rotor difference Ω2 − Ω1 = +1 rad/s": [0, 2]},
            [0.0] * drone.n_x,  # hover at the origin
        ),
    }


@dataclass
class Row:
    rmses: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    failures: int = 0
    sqp_limit: int = 0
    left_X: list[int] = field(default_factory=list)  # the step each reference's loop left X
    build: float = 0.0
    solver: str = ""
    ahead_1: list[np.ndarray] = field(default_factory=list)  # open_loop_errors, per reference
    ahead_n: list[np.ndarray] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        return {
            "rmse": float(np.mean(self.rmses)),
            "rmses": self.rmses,
            "median_wall_ms": 1e3 * float(np.median(self.wall)),
            "p95_wall_ms": 1e3 * float(np.percentile(self.wall, 95)),
            "median_cpu_ms": 1e3 * float(np.median(self.cpu)),
            "failures": self.failures,
            "sqp_limit": self.sqp_limit,
            "left_X": self.left_X,
            "solves": len(self.wall),
            "build_s": self.build,
            "solver": self.solver,
            "prediction_rms_1": _rms(self.ahead_1),
            "prediction_rms_N": _rms(self.ahead_n),
            "prediction_starts": int(sum(len(e) for e in self.ahead_1)),
        }


def _rms(errors: list[np.ndarray]) -> list[float] | None:
    """Per-output RMS of the stacked error rows (``None`` when there are none)."""
    if not errors:
        return None
    return np.sqrt(np.mean(np.concatenate(errors) ** 2, axis=0)).tolist()


def controller(system: System, case: Case, solver: str, hessian: str) -> NMPC:
    return NMPC(
        system,
        u_eq=case.u_eq,
        horizon=HORIZON,
        track="output",
        output_weights=case.output_weights,
        input_weights=case.input_weights,
        terminal="none",
        solver="auto" if hessian == "gauss-newton" else solver,  # Gauss-Newton: DAQP
        hessian=hessian,
    )


@dataclass
class Loop:
    """One closed loop, sample by sample: loop step ``k = 0 … steps−1`` applies ``u[k]`` to the
    true state ``x[k]`` (``x[0]``: the recorded state at sample ℓ) and measures
    ``y_meas[ℓ + k] = y[k] + noise[k]`` with ``y[k] = h(x[k], u[k])``; ``z[k]`` is the window of
    the ℓ inputs and measured outputs before step ``k`` (``y_meas[k … k+ℓ−1]``, the learned
    model's state; recorded samples for ``k < ℓ``)."""

    y: np.ndarray  # clean outputs (steps, n_y)
    u: np.ndarray  # applied inputs (steps, n_u)
    infos: list[dict[str, Any]]
    y_meas: np.ndarray  # measured outputs (ℓ + steps, n_y): the recorded first ℓ, then the loop's
    x: np.ndarray  # true states (steps, n_x), before each step
    z: np.ndarray  # windows (steps, ℓ (n_u + n_y)), canonical ordering
    noise: np.ndarray  # the loop's measurement noise (steps, n_y)


def closed_loop(
    nmpc: NMPC, case: Case, flight, ell: int, steps: int, *, learned, noise, rng
) -> Loop:
    """Track the reference's first ``n_y`` columns from sample ℓ for ``steps`` samples (the
    learned model's NMPC is fed the window ``z``, the true model's the state ``x``)."""
    true = case.system
    ref = flight.reference[ell : ell + steps, : true.n_y]
    u_hist = list(flight.u[:ell])
    y_hist = list(flight.y[:ell])
    x = flight.x[ell].copy()

    def state() -> np.ndarray:
        return np.concatenate([u_hist[-ell:], y_hist[-ell:]], axis=1).ravel()

    nmpc.reset(ref, state() if learned else x)
    ys, us, xs, zs, ws, infos = [], [], [], [], [], []
    left = None  # the first step at which the true state is outside the system's X
    for k in range(steps):
        z = state()
        step = nmpc(k, z if learned else x)
        infos.append({"ok": step.ok, **step.info})
        y_clean = true.output(x, step.u)
        w = rng.uniform(noise.lo, noise.hi)
        ys.append(y_clean)
        us.append(step.u)
        xs.append(x)
        zs.append(z)
        ws.append(w)
        u_hist.append(step.u)
        y_hist.append(y_clean + w)
        x = true.step(x, step.u)
        if case.envelope and left is None and not true.X.contains(x):
            left = k + 1
    infos[-1]["left_X"] = left
    return Loop(
        np.array(ys),
        np.array(us),
        infos,
        np.array(y_hist),
        np.array(xs),
        np.array(zs),
        np.array(ws),
    )


def visited_hull(loops: list[Loop]) -> tuple[Box, Box]:
    """The box hulls of the windows ``z_t`` and of the inputs ``u_t`` visited along ``loops``."""
    z = np.concatenate([loop.z for loop in loops])
    u = np.concatenate([loop.u for loop in loops])
    return Box(z.min(axis=0), z.max(axis=0)), Box(u.min(axis=0), u.max(axis=0))


def open_loop_errors(
    learned: LearnedSystem, u: np.ndarray, y_meas: np.ndarray, y_clean: np.ndarray, stop: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The learned model's prediction errors along a closed loop: from every loop sample ``t``
    whose next ``HORIZON`` samples end by loop step ``stop``, ``z_t`` from the measured window
    and the applied inputs ``u[t …]`` (``u``: ``(ℓ + steps, n_u)``, ``y_meas`` likewise), the
    errors against the clean outputs ``y_clean`` ``(steps, n_y)`` one sample ahead and
    ``HORIZON`` samples ahead (the NMPC's whole prediction), each ``(starts, n_y)``."""
    ell = learned.regressor.window
    starts = np.arange(ell, ell + stop - HORIZON + 1)
    if starts.size == 0:
        return None
    z = np.stack([np.concatenate([u[t - ell : t], y_meas[t - ell : t]], 1).ravel() for t in starts])
    f, h = learned.f.map(starts.size), learned.h.map(starts.size)
    zs, errors = z.T, []
    for i in range(HORIZON):
        ui = u[starts + i].T
        errors.append(np.asarray(h(zs, ui)).T - y_clean[starts + i - ell])
        zs = f(zs, ui)
    return errors[0], errors[-1]


def input_response(learned: LearnedSystem, case: Case, flights, step: list[float]):
    """How the learned and the true model answer an input step added to recorded inputs: from
    the recorded state of the given flights at five samples each, the change of the outputs after
    ``HORIZON`` samples (the NMPC's horizon) between the recorded inputs plus ``step`` and the
    recorded inputs alone; returns the true and the learned changes ``(starts, n_y)``."""
    true_paths, learned_paths = response_paths(learned, case, flights, step)
    return true_paths[:, -1], learned_paths[:, -1]


def response_paths(learned: LearnedSystem, case: Case, flights, step: list[float]):
    """:func:`input_response` at every sample: the changes after 1 … ``HORIZON`` samples, true
    and learned, each ``(starts, HORIZON, n_y)``."""
    ell, true = learned.regressor.window, case.system
    du = np.asarray(step)
    out: dict[str, list[np.ndarray]] = {"true": [], "learned": []}
    for flight in flights[:5]:
        for t in np.linspace(2 * ell, flight.T - HORIZON, 5).astype(int):
            u = flight.u[t : t + HORIZON]
            z = np.concatenate([flight.u[t - ell : t], flight.y[t - ell : t]], 1).ravel()
            paths = {}
            for key, system, x0 in (("true", true, flight.x[t]), ("learned", learned, z)):
                for sign, inputs in (("step", u + du), ("base", u)):
                    x, ys = np.asarray(x0, dtype=np.float64), []
                    for k, uk in enumerate(inputs):
                        ys.append(np.asarray(system.output(x, uk)).ravel())
                        if k < len(inputs) - 1:
                            x = np.asarray(system.step(x, uk)).ravel()
                    paths[key, sign] = np.array(ys)
            for key in out:
                out[key].append(paths[key, "step"] - paths[key, "base"])
    return np.array(out["true"]), np.array(out["learned"])


#: the judged steps scaled by these factors for the table of the response by size
STEP_SCALES = (0.25, 0.5, 1.0, 2.0)


def response_by_size(
    learned: LearnedSystem, case: Case, flights, step: list[float], judged: list[int]
) -> list[dict[str, Any]]:
    """The judged outputs' learned / true change (means over the starts) for the step scaled by
    each of :data:`STEP_SCALES`, after ``HORIZON // 2`` and ``HORIZON`` samples."""
    rows = []
    for scale in STEP_SCALES:
        true_paths, learned_paths = response_paths(
            learned, case, flights, list(scale * np.asarray(step))
        )
        for samples in (HORIZON // 2, HORIZON):
            t, lr = true_paths[:, samples - 1].mean(0), learned_paths[:, samples - 1].mean(0)
            rows.append(
                {
                    "scale": scale,
                    "samples": samples,
                    "true": [float(t[j]) for j in judged],
                    "ratios": [float(lr[j] / t[j]) for j in judged],
                }
            )
    return rows


def rest_response(learned: LearnedSystem, case: Case, step: list[float]) -> tuple[np.ndarray, ...]:
    """The same check from rest: the true model from ``case.rest`` under ``u_eq``, the learned
    model from the window of ℓ samples of ``u_eq`` and the rest outputs (no noise); the change of
    the outputs after ``HORIZON`` samples of ``u_eq + step`` against ``u_eq``, true and learned."""
    ell, true = learned.regressor.window, case.system
    x_rest, u_eq = np.asarray(case.rest, dtype=np.float64), np.asarray(case.u_eq)
    y_rest = np.asarray(true.output(x_rest, u_eq)).ravel()
    z_rest = np.concatenate([np.tile(u_eq, (ell, 1)), np.tile(y_rest, (ell, 1))], 1).ravel()
    changes = []
    for system, x0 in ((true, x_rest), (learned, z_rest)):
        ends = []
        for u in (u_eq + np.asarray(step), u_eq):
            x = x0
            for _ in range(HORIZON - 1):
                x = np.asarray(system.step(x, u)).ravel()
            ends.append(np.asarray(system.output(x, u)).ravel())
        changes.append(ends[0] - ends[1])
    return changes[0], changes[1]


def candidates_check(run_dir: Path, folders: list[str], split: str) -> list[str]:
    """Lines for ``--candidates``: for each model folder under ``run_dir`` (a follow-up, a
    member; ``.`` the run's own), its best validation loss, the horizon check's count of k = 10
    residual correlations with the excitation outside the band (:func:`canonid.horizon_check.
    response_count`, always on the run's validation split) and the judged step's learned / true
    change from the recorded states of ``split``'s first five flights. No loop is flown."""
    from canonid.horizon_check import response_count
    from canonid.learned import learned_system
    from canonid.learning import Model
    from canonid.runfolder import RunRecipe

    case = cases()["drone2d"]
    probe, judged = next(iter(case.judged.items()))
    count = response_count(run_dir)
    data = Path(RunRecipe.read(run_dir).data)
    lines = [
        f"Candidates of `{run_dir}` (`--candidates`): validation loss, k = 10 correlations with "
        f"the excitation outside the band (validation flights), and the learned / true change "
        f"of ({', '.join(case.system.output_names[j] for j in judged)}) after {HORIZON} "
        f"samples of {probe} from the recorded states of the first five {split} flights.",
        "",
        "| model | window | validation loss | outside the band | learned / true change |",
        "|---|---:|---:|---:|---|",
    ]
    for folder in folders:
        path = run_dir / folder
        model = Model.load(path)
        run = learned_system(path, data=data)
        learned = with_sets(run.system, run.system.X, case.system.U)
        flights = list(run.dataset.split(split))
        true_change, learned_change = input_response(learned, case, flights, case.probes[probe])
        ratios = judge(true_change.mean(axis=0), learned_change.mean(axis=0), judged)["ratios"]
        loss = model.info.get("training", {}).get("best_val_loss")
        lines.append(
            f"| {folder} | {model.window} | {_num(loss)} | {count(model)} | {_vec(ratios)} |"
        )
        print(lines[-1], flush=True)
    return lines


def judge(true_change: np.ndarray, learned_change: np.ndarray, outputs: list[int]) -> dict:
    """Learned / true change of each judged output: the sign agrees when the ratio is positive,
    the size is within 30 % when the ratio is in [0.7, 1.3]."""
    ratios = [float(learned_change[j] / true_change[j]) for j in outputs]
    return {"ratios": ratios, "ok": all(0.7 <= r <= 1.3 for r in ratios)}


def dataset_label(run) -> str:
    """The scenario that generated the run's data (the dataset's metadata), else ``?``, with the
    input design when the generation replaced the scenario's (``canonid generate --excitation``)."""
    meta = run.dataset.metadata or {}
    scenario, generation = meta.get("scenario") or {}, meta.get("generation") or {}
    label = scenario.get("name") or generation.get("system", "?")
    design = generation.get("design")
    if design and design != scenario.get("design"):
        label += f", {design.get('kind')} RMS {design.get('rms', design.get('amplitude'))}"
    return label


def model_label(recipe: dict[str, Any]) -> str:
    """The run's model, with its training rollout length where it is not its profile's."""
    horizon = recipe["train_options"].get("horizon")
    if recipe["model"] == "arx" or horizon == PROFILES[recipe["profile"]]["train"]["horizon"]:
        return recipe["model"]
    return f"{recipe['model']}, horizon {horizon}"


def rmse(case: Case, y: np.ndarray, flight, ell: int) -> float:
    ref = flight.reference[ell : ell + len(y), case.scored]
    return float(np.sqrt(np.mean((y[:, case.scored] - ref) ** 2)))


def runs_of(run_dir: Path) -> list[Path]:
    """The run folders of a ``--drone-run`` value: ``RUN`` or ``RUN+RUN+…``, an ensemble."""
    return [Path(part) for part in str(run_dir).split("+")]


def learned_of(run_dir: Path, case: Case):
    first, *members = runs_of(run_dir)
    run = learned_system(first, members=members)
    # the same input bounds for both controllers
    return run, with_sets(run.system, run.system.X, case.system.U)


def with_sets(learned: LearnedSystem, X: Box, U: Box) -> LearnedSystem:
    """The same learned model with the sets ``X`` (of its window state) and ``U``."""
    return LearnedSystem(
        learned.network,
        dt=learned.dt,
        input_names=learned.input_names,
        output_names=learned.output_names,
        input_units=learned.input_units,
        output_units=learned.output_units,
        X=X,
        U=U,
        W=learned.W,
        name=learned.name,
        members=learned.members[1:],
    )


def loop_theory(
    case: Case, trained: LearnedSystem, learned: LearnedSystem, loops: list[Loop], args
) -> dict[str, Any]:
    """The theory beside the learned-model NMPC's ``loops``: γ_f of the learned model on the box
    hull of the windows and inputs they visit and on its training hull (``trained``'s sets), and
    Proposition 2's bound on the true system's state estimate from each window of ℓ of the
    loops' measured outputs, with the certified constants of ``canonid analyze`` (γ_f upper
    bound on the hull reachable from X in ℓ − 1 steps × U, α_ℓ lower bound on X × U^ℓ)."""
    t0 = time.perf_counter()
    true, ell = case.system, learned.regressor.window
    z_box, u_box = visited_hull(loops)
    budget = Budget(seconds=args.gamma_seconds)
    gammas = {
        where: learned_gamma(with_sets(learned, X, U), budget=budget)
        for where, X, U in (("loops", z_box, u_box), ("training hull", trained.X, trained.U))
    }
    # as `canonid analyze --budget S`: each stage stops at S seconds, not at a box count
    budget = Budget(seconds=args.theory_seconds, boxes=10**9)
    report = analyze(true, [ell], trials=0, budget=budget)
    result = next(r for r in report.results if r.window == ell)
    along = bound_along(
        report.constants(ell),
        [loop.noise for loop in loops],
        states=[loop.x for loop in loops],
        inputs=[loop.u for loop in loops],
        X=true.X,
        U=true.U,
    )
    # the learned model's one-step output error ‖Ĥ(z_k, u_k) − y_k‖ at the steps with x_k ∈ X
    errors = []
    for loop in loops:
        predicted = np.asarray(learned.h.map(len(loop.u))(loop.z.T, loop.u.T)).T
        inside = true.X.contains_rows(loop.x)
        errors.append(np.linalg.norm(predicted - loop.y, axis=1)[inside])
    error = np.concatenate(errors)
    return {
        "region": {
            "z": z_box.to_dict(),
            "u": u_box.to_dict(),
            "samples": int(sum(len(loop.u) for loop in loops)),
        },
        "gamma_learned": {where: g.to_dict() for where, g in gammas.items()},
        "gamma_seconds": args.gamma_seconds,
        "true": {
            "window": ell,
            "gamma_f": {
                "lower": result.gamma_f.lower.to_dict(),
                "upper": result.gamma_f.upper.to_dict(),
            },
            "alpha": {"lower": result.alpha.lower.to_dict(), "upper": result.alpha.upper.to_dict()},
            "hull": None if result.hull is None else result.hull.to_dict(),
            "limitations": report.limitations,
            "seconds_per_stage": args.theory_seconds,
        },
        "bound": along.summary(),
        "one_step_error": {
            "median": float(np.median(error)) if error.size else None,
            "max": float(np.max(error)) if error.size else None,
            "steps": int(error.size),
        },
        "seconds": time.perf_counter() - t0,
    }


def compare(case: Case, run_dir: Path, args: argparse.Namespace) -> dict[str, Any]:
    """Both controllers on the first ``--references`` references of ``case``'s ``--split``."""
    run, learned = learned_of(run_dir, case)
    ell = learned.regressor.window
    count = args.drone_references if case.name == "drone2d" else None
    flights = list(run.dataset.split(args.split))[: count or args.references]
    limit = args.drone_steps if case.name == "drone2d" else None
    rows: dict[str, Row] = {}
    learned_loops: list[Loop] = []  # the learned-model NMPC's loops, for the theory beside them
    for name, system, hessian in (
        ("true model", case.system, "exact"),
        ("learned model", learned, args.hessian),
    ):
        row = rows[name] = Row()
        t0 = time.perf_counter()
        nmpc = controller(system, case, args.solver, hessian)
        row.build, row.solver = time.perf_counter() - t0, f"{nmpc.solver_used}, {hessian}"
        for i, flight in enumerate(flights):
            steps = min(flight.T - ell, limit or flight.T)
            rng = np.random.default_rng(1000 + i)
            loop = closed_loop(
                nmpc, case, flight, ell, steps, learned=system is learned, noise=learned.W, rng=rng
            )
            if system is learned:
                learned_loops.append(loop)
            y, u, infos, y_meas = loop.y, loop.u, loop.infos, loop.y_meas
            u_all = np.vstack([flight.u[:ell], u])
            errors = open_loop_errors(learned, u_all, y_meas, y, infos[-1]["left_X"] or steps)
            if errors is not None:
                row.ahead_1.append(errors[0])
                row.ahead_n.append(errors[1])
            row.rmses.append(rmse(case, y, flight, ell))
            row.wall += [info["solve_time"] for info in infos]
            row.cpu += [info["solve_cpu"] for info in infos]
            row.failures += sum(not info["ok"] for info in infos)
            row.sqp_limit += sum("limit" in info["status"] for info in infos)
            if infos[-1]["left_X"] is not None:
                row.left_X.append(infos[-1]["left_X"])
            print(f"{case.name} {name} ref {i}: RMSE {row.rmses[-1]:.4f}", flush=True)
    responses = {}
    for probe, step in case.probes.items():
        true_change, learned_change = input_response(learned, case, flights, step)
        judged, verdict = case.judged.get(probe), {}
        if judged is not None:
            recorded = judge(true_change.mean(axis=0), learned_change.mean(axis=0), judged)
            rest = None
            if case.rest is not None:
                rest_true, rest_learned = rest_response(learned, case, step)
                rest = {
                    **judge(rest_true, rest_learned, judged),
                    "true": rest_true.tolist(),
                    "learned": rest_learned.tolist(),
                }
            by_size = response_by_size(learned, case, flights, step, judged)
            train_y = np.vstack([f.y for f in run.dataset.split("train")])
            spread = np.percentile(np.abs(train_y - train_y.mean(0)), 99, axis=0)
            verdict = {
                "judged": judged,
                "recorded": recorded,
                "rest": rest,
                "by_size": by_size,
                "train_p99": [float(spread[j]) for j in judged],
            }
        responses[probe] = {
            **verdict,
            "true_mean": true_change.mean(axis=0).tolist(),
            "true_std": true_change.std(axis=0).tolist(),
            "learned_mean": learned_change.mean(axis=0).tolist(),
            "learned_std": learned_change.std(axis=0).tolist(),
            "starts": len(true_change),
            "flights": min(5, len(flights)),
        }
    theory = None
    if case.name == "drone2d" and args.theory_seconds > 0:
        theory = loop_theory(case, run.system, learned, learned_loops, args)
    net = learned.regressor
    recipes = [json.loads((part / "run.json").read_text()) for part in runs_of(run_dir)]
    recipe = recipes[0]
    mean = f", mean of {len(recipes)}" if len(recipes) > 1 else ""
    return {
        "run": str(run_dir),
        "system": case.name,
        "model": model_label(recipe) + mean,
        "data": dataset_label(run),
        "window": ell,
        "hidden": [layer.n_out for layer in net.layers[:-1]],
        "activation": learned.parameters["activation"],
        "residual": learned.parameters["residual"],
        "affine": learned.parameters["affine"],
        "profile": run.model.info.get("profile"),
        "command": "`; `".join(" ".join(r["command"]) for r in recipes),
        "epochs": recipe["train_options"].get("epochs"),
        "samples": f"{ell} … {ell + min(flights[0].T - ell, limit or flights[0].T) - 1}",
        "references": len(flights),
        "split": args.split,
        "rows": {name: {**row.summary(), "envelope": case.envelope} for name, row in rows.items()},
        "outputs": list(case.system.output_names),
        "responses": responses,
        "theory": theory,
    }


def exact_against_gauss_newton(case: Case, run_dir: Path, args) -> dict[str, Any]:
    """The learned tank NMPC on the first reference for ``--exact-steps`` steps, both Hessians."""
    run, learned = learned_of(run_dir, case)
    ell = learned.regressor.window
    flight = next(iter(run.dataset.split("test")))
    out: dict[str, Any] = {"steps": args.exact_steps}
    inputs = {}
    for hessian in ("exact", "gauss-newton"):
        t0 = time.perf_counter()
        nmpc = controller(learned, case, args.solver, hessian)
        build = time.perf_counter() - t0
        rng = np.random.default_rng(1000)
        loop = closed_loop(
            nmpc, case, flight, ell, args.exact_steps, learned=True, noise=learned.W, rng=rng
        )
        y, u, infos = loop.y, loop.u, loop.infos
        inputs[hessian] = u
        out[hessian] = {
            "build_s": build,
            "rmse": rmse(case, y, flight, ell),
            "median_cpu_ms": 1e3 * float(np.median([i["solve_cpu"] for i in infos])),
            "median_wall_ms": 1e3 * float(np.median([i["solve_time"] for i in infos])),
        }
        print(f"{hessian}: {out[hessian]}", flush=True)
    out["max_du"] = float(np.max(np.abs(inputs["exact"] - inputs["gauss-newton"])))
    return out


def table(results: dict[str, Any]) -> list[str]:
    lines = [
        "| system | prediction model | fed with | solver, Hessian | tracking RMSE (mean of refs) "
        "| median solve wall [ms] | median solve CPU [ms] | p95 wall [ms] | failed solves "
        "| loops that left X (drone: the flight box) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for system, res in results.items():
        for name, fed in (
            ("true model", "true state x[t]"),
            ("learned model", "measured window z_t"),
        ):
            r = res["rows"][name]
            limit = f" ({r['sqp_limit']} at the SQP limit)" if r["sqp_limit"] else ""
            left = f" (after {r['left_X']} steps)" if r["left_X"] else ""
            envelope = f"{len(r['left_X'])} of {len(r['rmses'])}{left}" if r["envelope"] else "–"
            lines.append(
                f"| {system} | {name} | {fed} | {r['solver']} | {r['rmse']:.4f} | "
                f"{r['median_wall_ms']:.1f} | {r['median_cpu_ms']:.1f} | {r['p95_wall_ms']:.1f} "
                f"| {r['failures']} of {r['solves']}{limit} | {envelope} |"
            )
    return lines


def _vec(values: list[float] | None) -> str:
    return "–" if values is None else "(" + ", ".join(f"{v:.3g}" for v in values) + ")"


def model_check(key: str, res: dict[str, Any]) -> list[str]:
    """The lines on the learned model's predictions along the loops and its input responses."""
    names = ", ".join(res["outputs"])
    rows = res["rows"]
    loops = "; ".join(
        f"along the {name.split()[0]}-model NMPC's loops ({r['prediction_starts']} starts): "
        f"{_vec(r['prediction_rms_1'])} one sample ahead, {_vec(r['prediction_rms_N'])} "
        f"{HORIZON} samples ahead"
        for name, r in rows.items()
    )
    lines = [
        f"{key}, the learned model's open-loop prediction error from the measured window z_t "
        f"under the applied inputs, against the true clean outputs (RMS per output ({names}); "
        f"starts whose {HORIZON}-sample prediction ends before the loop left X): {loops}.",
        "",
    ]
    for probe, r in res["responses"].items():
        lines += [
            f"{key}, response to an input step ({probe}) added to the recorded inputs, change "
            f"of ({names}) after {HORIZON} samples from the recorded state (mean ± std over "
            f"{r['starts']} starts: {r['flights']} {res.get('split', 'test')} flights × 5 "
            f"samples): true model {_vec(r['true_mean'])} ± {_vec(r['true_std'])}, learned model "
            f"{_vec(r['learned_mean'])} ± {_vec(r['learned_std'])}.",
            "",
        ]
        if r.get("rest") is not None:
            lines += [
                f"{key}, the same step from rest (the true model from its equilibrium state under "
                f"u_eq, the learned model from the window of ℓ samples of u_eq and the rest "
                f"outputs, no noise), change of ({names}) after {HORIZON} samples: true model "
                f"{_vec(r['rest']['true'])}, learned model {_vec(r['rest']['learned'])}.",
                "",
            ]
        if r.get("by_size"):
            judged = ", ".join(res["outputs"][j] for j in r["judged"])
            lines += [
                f"{key}, the same step scaled, from the same recorded states: learned / true "
                f"change of ({judged}) by the step's size and the samples after it (the judged "
                f"figure is × 1 after {HORIZON}); the training flights' 99th percentile of "
                f"|output − its mean|: {_vec(r['train_p99'])}.",
                "",
                f"| step × | samples | true change ({judged}) | learned / true ({judged}) |",
                "|---:|---:|---|---|",
                *(
                    f"| {row['scale']:g} | {row['samples']} | {_vec(row['true'])} | "
                    f"{_vec(row['ratios'])} |"
                    for row in r["by_size"]
                ),
                "",
            ]
    return lines


def goals(results: dict[str, Any]) -> list[str]:
    """The table of the issue's goals: learned / true tracking RMSE ≤ 1.5, no learned loop out of
    X, and each judged step response of the true sign within 30 % of the true size."""
    lines = [
        "| system | model | data | learned / true tracking RMSE | learned loops that left X | step "
        "| output | learned / true change, recorded states | learned / true change, from rest |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for res in results.values():
        rows = res["rows"]
        ratio = rows["learned model"]["rmse"] / rows["true model"]["rmse"]
        learned = rows["learned model"]
        left = (
            f"{len(learned['left_X'])} of {len(learned['rmses'])}" if learned["envelope"] else "–"
        )
        for probe, r in res["responses"].items():
            for i, j in enumerate(r.get("judged", [])):
                rest = f"{r['rest']['ratios'][i]:.3g}" if r["rest"] is not None else "–"
                lines.append(
                    f"| {res['system']} | {res['model']} | {res['data']} | {ratio:.2f} | {left} "
                    f"| {probe} "
                    f"| {res['outputs'][j]} | {r['recorded']['ratios'][i]:.3g} | {rest} |"
                )
    return lines


def _num(value: float | None) -> str:
    return "∞" if value is None or value == float("inf") else f"{value:.4g}"


def _gamma_words(g: dict[str, Any]) -> str:
    """A learned model's γ_f bracket (:meth:`LearnedGamma.to_dict`), each number labelled."""
    bb = g["branch_and_bound"]
    stop = bb["details"].get("stop", bb["method"])
    return (
        f"sampled lower bound {_num(g['lower']['value'])}; certified upper bounds "
        f"{_num(bb['value'])} (interval branch-and-bound, {stop}) "
        f"and {_num(g['layer_norms']['value'])} ({layer_norm_words(g['layer_norms'])})"
    )


def theory_lines(key: str, res: dict[str, Any]) -> list[str]:
    """The lines on the theory beside the learned-model loops (:func:`loop_theory`)."""
    th = res["theory"]
    if th is None:
        return []
    ell, true, bound = res["window"], th["true"], th["bound"]
    gl = th["gamma_learned"]
    lines = [
        f"{key}, γ_f of the learned model in its window state z (dim z = "
        f"{len(th['region']['z']['lower'])}), on the box hull of the windows z_t and inputs u_t "
        f"that the learned-model NMPC loops visit ({th['region']['samples']} samples): "
        f"{_gamma_words(gl['loops'])}; on its training hull: "
        f"{_gamma_words(gl['training hull'])} ({th['gamma_seconds']:g} s per stage).",
        "",
    ]
    gamma, alpha = true["gamma_f"], true["alpha"]
    head = (
        f"{key}, Proposition 2 for the true drone's state x̂_t estimated from the window of "
        f"ℓ = {ell} measured outputs of the learned-model loops (x̂_(t−ℓ) the output-error argmin "
        f"over the drone's X): α_{ell} certified lower bound {_num(alpha['lower']['value'])} "
        f"({alpha['lower']['method']}; sampled upper bound {_num(alpha['upper']['value'])}); "
        f"γ_f certified upper bound {_num(gamma['upper']['value'])} on H_{ell - 1} × U, the box "
        f"of the states reachable from X in {ell - 1} steps (sampled lower bound "
        f"{_num(gamma['lower']['value'])}); {true['seconds_per_stage']:g} s per certified stage. "
    )
    windows = (
        f"{bound['windows_applied']} of {bound['windows']} noise windows w̄_(t−ℓ|t−1) have "
        "x_(t−ℓ) ∈ X and the inputs in U (the others are outside the proposition)"
    )
    if bound["infinite"] is not None:
        body = f"The bound is infinite: {bound['infinite']}. {windows}."
    elif bound["bound_max"] is None:
        body = f"No window satisfies the premises: {windows}."
    else:
        body = (
            f"Factor 2 γ_f^ℓ / α_ℓ = {2 * bound['factor']:.4g}; {windows}; over them the bound "
            f"‖x̂_t − x_t‖ ≤ 2 γ_f^ℓ α_ℓ^(−1) ‖w̄‖ (2-norm over the six states, mixed units) is "
            f"{_num(bound['bound_median'])} (median), {_num(bound['bound_max'])} (max)."
        )
    err = th["one_step_error"]
    measured = (
        f" Measured beside it: ‖w̄‖ {_num(bound['noise_norm_median'])} (median), "
        f"{_num(bound['noise_norm_max'])} (max); the learned model's one-step output error "
        f"‖Ĥ(z_t, u_t) − y_t‖ against the clean outputs {_num(err['median'])} (median), "
        f"{_num(err['max'])} (max) over the {err['steps']} loop steps with x_t ∈ X."
    )
    return [*lines, head + body + measured, ""]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--run", type=Path, help="an Ours (MLP) or ARX run on tank data")
    parser.add_argument(
        "--drone-run",
        type=Path,
        action="append",
        help="an Ours (MLP) or ARX run on drone2d data (repeat it to compare several runs); "
        "RUN+RUN+…: the mean of several runs of one window (an ensemble, one CasADi model)",
    )
    parser.add_argument("--references", type=int, default=10)
    parser.add_argument(
        "--split",
        default="test",
        choices=("test", "val"),
        help="the dataset split whose first references the loops track and whose flights the "
        "step responses start from (default test; val: to choose among runs or designs "
        "without reading the test references)",
    )
    parser.add_argument(
        "--drone-steps", type=int, help="at most this many drone samples per reference"
    )
    parser.add_argument(
        "--drone-references", type=int, help="drone references (default --references)"
    )
    parser.add_argument("--solver", default="fatrop", help="NMPC solver (default fatrop)")
    parser.add_argument(
        "--hessian",
        default="gauss-newton",
        choices=("exact", "gauss-newton"),
        help="the learned model's NMPC (default gauss-newton)",
    )
    parser.add_argument("--exact-steps", type=int, default=40)
    parser.add_argument(
        "--gamma-seconds",
        type=float,
        default=30.0,
        help="each stage of a learned model's γ_f bracket (sampled lower bound, branch-and-bound)",
    )
    parser.add_argument(
        "--theory-seconds",
        type=float,
        default=10.0,
        help="drone runs: each certified stage of the true drone's constants of Proposition 2 "
        "(0: no theory beside the drone loops, nor the learned γ_f on them)",
    )
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    parser.add_argument("--no-write", action="store_true", help="do not touch the record's notes")
    parser.add_argument(
        "--section",
        default=SECTION,
        help=f"the section to write (default {SECTION!r}; another keeps that one)",
    )
    parser.add_argument(
        "--candidates",
        nargs="+",
        metavar="FOLDER",
        help="with one --drone-run RUN: check these model folders under RUN (e.g. followups/l80 "
        "members/s1; . the run's own) by validation loss, the horizon check's count and the "
        "judged step, fly no loop, print the table and write nothing but --json",
    )
    args = parser.parse_args()
    if args.candidates:
        if len(args.drone_run or []) != 1:
            parser.error("--candidates needs exactly one --drone-run RUN")
        checked = candidates_check(args.drone_run[0], args.candidates, args.split)
        if args.json:
            args.json.write_text(json.dumps({"candidates": checked}, indent=1))
        return 0
    if not 0 <= args.theory_seconds < float("inf"):  # NaN fails too
        parser.error(f"--theory-seconds must be a finite number >= 0, got {args.theory_seconds}")
    started = time.perf_counter()
    all_cases = cases()
    results: dict[str, Any] = {}
    runs = [("tank", args.run)] if args.run is not None else []
    runs += [("drone2d", run_dir) for run_dir in args.drone_run or []]
    for name, run_dir in runs:
        res = compare(all_cases[name], run_dir, args)
        key = name if len(args.drone_run or []) < 2 else f"{name}, {res['model']}, {res['data']}"
        results[key if key not in results else f"{key} ({run_dir})"] = res
        if args.json:
            args.json.write_text(json.dumps(results, indent=1))
    exact = None
    if args.run is not None and args.exact_steps > 0:
        exact = exact_against_gauss_newton(all_cases["tank"], args.run, args)
    lines: list[str] = []
    for key, res in results.items():
        lines.append(
            f"Learned {key} model: `{res['run']}`, trained on `{res['data']}` data — "
            f"{MODELS.get(res['model'].split(',')[0], res['model'])}, ℓ = {res['window']}, hidden "
            f"{res['hidden']}, activation {res['activation']}, residual {res['residual']}, "
            f"affine path {res['affine']}, profile `{res['profile']}`, {res['epochs']} epochs: "
            f"`{res['command']}`. NMPC: {all_cases[res['system']].note}. References: the "
            f"first {res['references']} of the {res['split']} split, samples {res['samples']}."
        )
        lines.append("")
    lines += [
        f"NMPC for both: output reference, N = {HORIZON}, terminal weight Q, solver "
        f"`{args.solver}` (the plugin, not compiled). Learned model's NLP: Hessian "
        f"`{args.hessian}`. Load average at the end: {os.getloadavg()[0]:.1f} (shared "
        "machine: wall times are inflated, the CPU column is the process's own time).",
        "",
        *table(results),
        "",
    ]
    for key, res in results.items():
        rows = res["rows"]
        ratio = rows["learned model"]["rmse"] / rows["true model"]["rmse"]
        goal = " (goal ≤ 1.5)"
        lines += [
            f"{key}: ratio learned / true tracking RMSE **{ratio:.2f}**{goal}. Per reference "
            "(true, learned): "
            + ", ".join(
                f"({a:.3f}, {b:.3f})"
                for a, b in zip(rows["true model"]["rmses"], rows["learned model"]["rmses"])
            ),
            "",
        ]
    lines += [
        "Goals: learned / true tracking RMSE ≤ 1.5, no learned loop leaving X, and the judged "
        "step responses of the true sign within 30 % of the true size (learned / true in "
        "[0.7, 1.3]; recorded states: the mean over the starts below).",
        "",
        *goals(results),
        "",
    ]
    for key, res in results.items():
        lines += model_check(key, res)
        lines += theory_lines(key, res)
    if exact is not None:
        e, g = exact["exact"], exact["gauss-newton"]
        lines += [
            f"Exact Hessian against Gauss-Newton SQP, learned tank NMPC, first reference, "
            f"{exact['steps']} steps: build {e['build_s']:.0f} s / {g['build_s']:.1f} s, median "
            f"solve CPU {e['median_cpu_ms']:.1f} ms / {g['median_cpu_ms']:.1f} ms (wall "
            f"{e['median_wall_ms']:.0f} / {g['median_wall_ms']:.0f} ms), tracking RMSE "
            f"{e['rmse']:.6f} / {g['rmse']:.6f}, largest difference of the applied inputs "
            f"{exact['max_du']:.2e}.",
            "",
        ]
    if args.run is not None:
        _, learned = learned_of(args.run, all_cases["tank"])
        tank = all_cases["tank"].system
        budget = Budget(seconds=args.gamma_seconds)
        gamma = learned_gamma(learned, budget=budget)
        tank_gamma = lipschitz_bracket(tank.f, tank.X, tank.U, budget=budget)
        lines += [
            f"γ_f of the learned tank model on its training hull (dim z = {learned.n_x}): "
            f"sampled lower bound {gamma.bracket.lower.value:.4g}; certified upper bounds "
            f"{gamma.bracket.upper.value:.4g} (interval branch-and-bound, "
            f"{gamma.bracket.upper.details.get('stop')}, {args.gamma_seconds:g} s) and "
            f"{gamma.layer_norms.value:.4g} ({layer_norm_words(gamma.layer_norms.to_dict())}). "
            "The true tank's "
            f"γ_f on its X × U: [{tank_gamma.lower.value:.4g}, {tank_gamma.upper.value:.4g}] "
            "(state x, not the window z: a different quantity, set beside it).",
            "",
        ]
    lines.append(f"Wall time {time.perf_counter() - started:.0f} s.")
    if not args.no_write:
        write_section(args.section, "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
