"""NMPC on a learned model against NMPC on the true model, tracking tank level references.

The learned model is a trained Ours (MLP) run on tank data (``--run``), built as a CasADi system
from its weights (:func:`canonid.learned.learned_system`). Both controllers are the same
:class:`datagen.controllers.nmpc.NMPC` with an output reference (``track="output"``), the same
horizon, weights, input bounds (the tank's U) and solver; they differ only in the prediction
model and in what they are fed:

* NMPC on the true model: the true state ``x[t]`` (state feedback, no noise);
* NMPC on the learned model: its state ``z_t``, the window of the last ℓ applied inputs and
  *measured* outputs (uniform noise in the dataset's noise box) — no observer.

Each closed loop runs on the true tank along one of the first ``--references`` references of the
dataset's test split, from the recorded state at sample ℓ (the ℓ recorded samples before it fill
the learned model's first window). Reported per controller: the tracking RMSE of the true
(noise-free) level against the reference over samples ℓ … T−1, the median and 95th percentile
of the solve times, and the failed solves. Also the learned model's γ_f bracket on its training
hull (:mod:`analysis.certify`) beside the true tank's on its X.

Writes the section "NMPC on a learned model" of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages

import numpy as np
from _results import write_section

from analysis.certify import learned_gamma
from analysis.estimate import Budget
from analysis.lipschitz import lipschitz_bracket
from canonid.learned import learned_system
from datagen.controllers.nmpc import NMPC
from models.learned import LearnedSystem
from models.tank import Tank

HORIZON = 20
OUTPUT_WEIGHT, INPUT_WEIGHT = 1.0, 1e-3
LEVEL_EQ = 2.5  # the input term pulls towards the input that holds this level


def controller(system, tank: Tank, solver: str, cache: Path | None) -> NMPC:
    return NMPC(
        system,
        u_eq=[tank.equilibrium_input(LEVEL_EQ)],
        horizon=HORIZON,
        track="output",
        output_weights=[OUTPUT_WEIGHT],
        input_weights=[INPUT_WEIGHT],
        terminal="none",
        solver=solver,
        cache_dir=cache,
    )


def closed_loop(nmpc: NMPC, tank: Tank, flight, ell: int, *, learned: bool, noise, rng):
    """Track ``flight.reference`` from sample ℓ; returns (clean outputs, solve times, failures)."""
    T = flight.T
    ref = flight.reference[ell:]
    u_hist = list(flight.u[:ell])
    y_hist = list(flight.y[:ell])
    x = flight.x[ell].copy()
    state = (
        (lambda: np.concatenate([u_hist[-ell:], y_hist[-ell:]], axis=1).ravel())
        if learned
        else None
    )
    nmpc.reset(ref, state() if learned else x)
    ys, times, failures = [], [], 0
    for k in range(T - ell):
        step = nmpc(k, state() if learned else x)
        failures += not step.ok
        times.append(step.info["solve_time"])
        y_clean = tank.output(x, step.u)
        ys.append(y_clean[0])
        u_hist.append(step.u)
        y_hist.append(y_clean + rng.uniform(noise.lo, noise.hi))
        x = tank.step(x, step.u)
    return np.array(ys), np.array(times), failures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--run", type=Path, required=True, help="an Ours (MLP) run on tank data")
    parser.add_argument("--references", type=int, default=10)
    parser.add_argument(
        "--solver", default="fatrop", help="NMPC solver for both (default fatrop, not compiled)"
    )
    parser.add_argument("--cache", type=Path, help="folder of compiled solvers (fatrop-c)")
    parser.add_argument("--gamma-seconds", type=float, default=30.0)
    args = parser.parse_args()
    started = time.perf_counter()
    run = learned_system(args.run)
    tank = Tank()
    learned = LearnedSystem(
        run.system.network,
        dt=run.system.dt,
        input_names=run.system.input_names,
        output_names=run.system.output_names,
        X=run.system.X,
        U=tank.U,  # the same input bounds for both controllers (inside the training hull)
        W=run.system.W,
    )
    ell = learned.regressor.window
    flights = list(run.dataset.split("test"))[: args.references]
    rows = {"true model": ([], [], 0), "learned model": ([], [], 0)}
    per_reference = []
    build: dict[str, tuple[str, float]] = {}
    for name, system, is_learned in (("true model", tank, False), ("learned model", learned, True)):
        t0 = time.perf_counter()
        nmpc = controller(system, tank, args.solver, args.cache)
        build[name] = (nmpc.solver_used, time.perf_counter() - t0)
        rmses, times, failures = [], [], 0
        for i, flight in enumerate(flights):
            rng = np.random.default_rng(1000 + i)
            y, t, f = closed_loop(
                nmpc, tank, flight, ell, learned=is_learned, noise=learned.W, rng=rng
            )
            rmses.append(float(np.sqrt(np.mean((y - flight.reference[ell:, 0]) ** 2))))
            times.extend(t)
            failures += f
        rows[name] = (rmses, times, failures)
        print(f"{name}: RMSE {np.mean(rmses):.4f} (mean of {len(rmses)})", flush=True)
    for i in range(len(flights)):
        per_reference.append((rows["true model"][0][i], rows["learned model"][0][i]))

    budget = Budget(seconds=args.gamma_seconds)
    gamma = learned_gamma(learned, budget=budget)
    tank_gamma = lipschitz_bracket(tank.f, tank.X, tank.U, budget=budget)

    true_rmse = float(np.mean(rows["true model"][0]))
    learned_rmse = float(np.mean(rows["learned model"][0]))
    info = run.model.info
    recipe = json.loads((args.run / "run.json").read_text())
    net = learned.regressor
    lines = [
        f"Learned model: `{args.run}` — Ours (MLP), ℓ = {ell}, hidden "
        f"{[layer.n_out for layer in net.layers[:-1]]}, activation "
        f"{learned.parameters['activation']}, residual {learned.parameters['residual']}, "
        f"profile `{info.get('profile')}`, a short training on the default tank dataset "
        f"(`canonid generate tank`): `{' '.join(recipe['command'])}` "
        f"({recipe['train_options'].get('epochs')} epochs). NMPC for both: output "
        f"reference, N = {HORIZON}, Q = {OUTPUT_WEIGHT}, "
        f"R = {INPUT_WEIGHT} on u − u_eq(level {LEVEL_EQ}), U = [0, 6], solver "
        + ", ".join(f"`{s}` ({n}, built in {b:.0f} s)" for n, (s, b) in build.items())
        + f". Test references: the first {len(flights)} of the test split, "
        f"samples {ell} … {flights[0].T - 1}. Load average at the end: "
        f"{os.getloadavg()[0]:.1f} (shared machine).",
        "",
        "| prediction model | fed with | tracking RMSE (mean of refs) | median solve [ms] "
        "| p95 solve [ms] | failed solves |",
        "|---|---|---|---|---|---|",
    ]
    for name, fed in (("true model", "true state x[t]"), ("learned model", "measured window z_t")):
        rmses, times, failures = rows[name]
        lines.append(
            f"| {name} | {fed} | {np.mean(rmses):.4f} | {1e3 * np.median(times):.1f} | "
            f"{1e3 * np.percentile(times, 95):.1f} | {failures} |"
        )
    lines += [
        "",
        f"Ratio learned / true tracking RMSE: **{learned_rmse / true_rmse:.2f}** (goal ≤ 1.5).",
        "",
        "Per reference (true, learned): "
        + ", ".join(f"({a:.3f}, {b:.3f})" for a, b in per_reference),
        "",
        f"γ_f of the learned model on its training hull (dim z = {learned.n_x}): sampled lower "
        f"bound {gamma.bracket.lower.value:.4g}; certified upper bounds "
        f"{gamma.bracket.upper.value:.4g} (interval branch-and-bound, "
        f"{gamma.bracket.upper.details.get('stop')}, {args.gamma_seconds:g} s) and "
        f"{gamma.layer_norms.value:.4g} (product of layer norms, loose). The true tank's γ_f on "
        f"its X × U: [{tank_gamma.lower.value:.4g}, {tank_gamma.upper.value:.4g}] (state x, "
        "not the window z: a different quantity, set beside it).",
        "",
        f"Wall time {time.perf_counter() - started:.0f} s.",
    ]
    write_section("NMPC on a learned model", "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
