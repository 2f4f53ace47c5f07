"""Cost of the analysis layer on the tank (X = [0.05, 5]², U = [1, 3]).

Measures, in one run:

1. the certified γ_f bracket to 5 %, 1 % and 0.1 %, against the cost of the sampled lower
   bound alone (baseline: what a guarantee costs on top of an estimate);
2. the certified lower bounds of α_2 and α_3 (pairs branch-and-bound) and their cost, against
   the sampled upper bounds;
3. 10⁴ Monte-Carlo trials of Proposition 2 (ℓ = 3, 8 argmin starts) — trials per second, with
   1 start as the baseline;
4. growth with ℓ = 1…10: seconds for the reachable hull, γ_f, α_ℓ (sampled) and 1000 trials.

Writes the section "Analysis cost" of the records (benchmarks/records/). ``--size full`` gives the
searches longer budgets.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages

from _results import write_section

from canonid.analysis.bound import BoundConstants, check_bound
from canonid.analysis.estimate import Budget
from canonid.analysis.lipschitz import lipschitz_lower, lipschitz_upper
from canonid.analysis.observability import alpha_lower, alpha_upper
from canonid.analysis.reach import reachable_hulls
from canonid.models.registry import get_system
from canonid.models.sets import Box

T = TypeVar("T")
X = Box([0.05, 0.05], [5.0, 5.0])
U = Box([1.0], [3.0])


def timed(fn: Callable[..., T], *args: Any, **kwargs: Any) -> tuple[T, float]:
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    args = parser.parse_args()
    full = args.size == "full"
    started, cpu_started = time.perf_counter(), time.process_time()
    tank = get_system("tank")
    lines = [
        f"Tank, X = [0.05, 5]², U = [1, 3], W = [−0.02, 0.02]; single process, size `{args.size}`.",
        "",
    ]

    # 1. γ_f to a tolerance ------------------------------------------------------------------
    low, t_low = timed(lipschitz_lower, tank.f, X, U, budget=Budget(samples=4096, starts=8))
    lines += [
        "**γ_f, certified bracket** (baseline: the sampled lower bound alone, "
        f"{t_low:.3f} s, value {low.value:.6f})",
        "",
        "| tolerance | lower | certified upper | boxes | seconds | × baseline |",
        "|---|---|---|---|---|---|",
    ]
    for tol in (0.05, 0.01, 0.001):
        up, t_up = timed(
            lipschitz_upper, tank.f, X, U, lower=low, tol=tol, budget=Budget(boxes=200_000)
        )
        lines.append(
            f"| {tol:g} | {low.value:.6f} | {up.value:.6f} | {up.details['boxes']} | "
            f"{t_up:.3f} | {t_up / t_low:.1f} |"
        )

    # 2. α_2, α_3 lower bounds -------------------------------------------------------------
    budgets = {2: [200_000], 3: [50_000, 200_000, 800_000] if full else [50_000, 200_000]}
    lines += [
        "",
        "**α_ℓ, certified lower bound** (pairs branch-and-bound, tolerance 10 %, budgets in pairs "
        "of boxes; baseline: the sampled upper bounds)",
        "",
        "| ℓ | box budget | certified lower | sampled upper | boxes | stop | seconds | "
        "upper seconds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    previous = []
    for ell, box_budgets in budgets.items():
        uppers, t_upper = timed(alpha_upper, tank, ell, X=X, U=U, budget=Budget())
        upper = min(e.value for e in uppers)
        for boxes in box_budgets:
            lower, t_lower = timed(
                alpha_lower, tank, ell, X=X, U=U, upper=upper, tol=0.1, budget=Budget(boxes=boxes)
            )
            previous.append(lower)
            lines.append(
                f"| {ell} | {boxes} | {lower.value:.5f} | {upper:.5f} | {lower.details['boxes']} "
                f"| {lower.details['stop']} | {t_lower:.2f} | {t_upper:.3f} |"
            )

    # 3. 10⁴ Monte-Carlo trials -------------------------------------------------------------
    ell = 3
    hulls = reachable_hulls(tank, ell - 1, X=X, U=U)
    gamma = lipschitz_upper(tank.f, hulls[ell - 1], U, window=ell, tol=0.05)
    # α_3 ≥ α_2 (monotonicity): the largest certified bound holds for ℓ = 3 and up
    alpha2 = previous[0]
    alpha3 = max(previous, key=lambda e: e.value)
    constants = BoundConstants(ell, gamma, alpha3)
    lines += [
        "",
        f"**Monte-Carlo check of Proposition 2**, ℓ = {ell}, 10⁴ trials, uniform noise in W "
        f"(γ_f = {gamma.value:.4f} on H_2×U, α_3 ≥ {alpha3.value:.5f})",
        "",
        "| argmin starts | seconds | trials/s | violations | solver failures | max error/bound |",
        "|---|---|---|---|---|---|",
    ]
    for starts in (1, 8):
        check, t_mc = timed(
            check_bound, tank, constants, trials=10_000, X=X, U=U, starts=starts, seed=1
        )
        lines.append(
            f"| {starts} | {t_mc:.1f} | {10_000 / t_mc:.0f} | {check.violations} | "
            f"{check.solver_failures} | {check.max_ratio:.4f} |"
        )

    # 4. growth with ℓ ------------------------------------------------------------------------
    lines += [
        "",
        "**Growth with ℓ** (seconds; γ_f to 5 % on H_{ℓ−1}×U, α_ℓ sampled upper bounds, "
        "1000 trials with 8 starts)",
        "",
        "| ℓ | hull H_{ℓ−1} | γ_f | α_ℓ upper | 1000 trials |",
        "|---|---|---|---|---|",
    ]
    for ell in range(1, 11):
        hulls, t_hull = timed(reachable_hulls, tank, ell - 1, X=X, U=U)
        gamma, t_gamma = timed(
            lipschitz_upper, tank.f, hulls[-1], U, lower=low, tol=0.05, budget=Budget()
        )
        _, t_alpha = timed(alpha_upper, tank, ell, X=X, U=U, budget=Budget())
        alpha = alpha_lower(tank, 1, X=X, U=U) if ell == 1 else alpha2 if ell == 2 else alpha3
        constants = BoundConstants(ell, gamma, alpha)
        _, t_mc = timed(check_bound, tank, constants, trials=1000, X=X, U=U, starts=8, seed=ell)
        lines.append(f"| {ell} | {t_hull:.3f} | {t_gamma:.3f} | {t_alpha:.3f} | {t_mc:.2f} |")
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu_started
    lines += [
        "",
        f"Whole run: {wall:.0f} s wall, {cpu:.0f} s of CPU for this process (on a shared machine "
        "the difference is time spent waiting for a core: the seconds above are wall times).",
    ]
    write_section("Analysis cost", "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
