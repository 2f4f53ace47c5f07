"""``canonid analyze`` — the theory, numerically: γ_f, γ_h, α_ℓ brackets and Proposition 2
(:func:`canonid.theory.run_analysis`, whose module says what is written)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from canonid.commands import _options
from canonid.theory import MAX_BUDGET, AnalyzeRequest, run_analysis


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Estimate the Lipschitz constant γ_f and the observability constant α_ℓ of a "
        "registered system (certified bounds by interval branch-and-bound, sampled bounds "
        "by optimisation), evaluate Proposition 2's bound 2 γ_f^ℓ α_ℓ^-1 ‖w̄‖ and check it "
        "by Monte-Carlo trials of the output-error estimator; writes analysis.json and, where "
        "trials ran, the figure bound_vs_window (--figure-format) to --out. Without SYSTEM, "
        "--run RUN bounds γ_f of the learned model alone, into learned_analysis.json."
    )
    p.add_argument(
        "system",
        nargs="?",
        help="registered system name (see `canonid systems`); leave out with --run to analyse "
        "the learned model alone",
    )
    win = p.add_mutually_exclusive_group()
    win.add_argument(
        "--window",
        type=int,
        metavar="L",
        help="one window ℓ >= 1 (it or --windows is required with SYSTEM; default without "
        "SYSTEM: the run's ℓ)",
    )
    win.add_argument(
        "--windows",
        type=_options.comma_list(int, "L"),
        metavar="L,...",
        help="windows ℓ, e.g. 2,5,10, or a range A-B, e.g. 1-10 (see --window)",
    )
    p.add_argument("--trials", type=int, default=1000, help="Monte-Carlo trials per window")
    p.add_argument(
        "--budget",
        type=float,
        default=20.0,
        metavar="SECONDS",
        help=f"wall-clock limit of each stage, at most {MAX_BUDGET:g} (default %(default)g): "
        "each certified "
        "branch-and-bound search and each sampled bound, checked between steps; loading the run "
        "not counted",
    )
    p.add_argument(
        "--boxes",
        type=int,
        metavar="N",
        help="also stop each certified search after N boxes: with a budget in boxes (and the "
        "same --seed) the numbers do not depend on the machine's speed (default: no limit)",
    )
    for name, what, example in (
        ("X", "state", "0.05:5,0.05:5"),
        ("U", "input", "1:3"),
        ("W", "noise", "-0.02:0.02"),
    ):
        p.add_argument(
            f"--{name}",
            dest=name,
            metavar="LO:HI,...",
            help=f"{what} set of SYSTEM: an interval LO:HI per component, comma-separated, or one "
            f"for all, e.g. {example} (default: the system's {name})",
        )
    p.add_argument("--tol", type=float, default=0.05, help="relative tolerance of γ searches")
    p.add_argument("--seed", type=int, default=0, help="seed of the sampled bounds and trials")
    p.add_argument(
        "--run",
        type=Path,
        metavar="RUN",
        help="a trained model's run folder: adds its one-step residual and a state probe, "
        "checked against the bound, on the test split of its data (default: the system alone)",
    )
    p.add_argument(
        "--learned-gamma",
        action="store_true",
        help="with --run: also bound γ_f of the learned model on its training hull (sampled, "
        "interval branch-and-bound within --budget, product of layer norms; about a minute "
        "for a 3 × 256 network); always on without SYSTEM",
    )
    _options.add_run_data(
        p,
        "data for --run: a canonid dataset, or CSV / .npz read with the run's data options "
        "(default: the run's own data, split as training split them)",
    )
    _options.add_out(p, "runs/analyze-SYSTEM, or RUN/analysis without SYSTEM")
    _options.add_figure_format(p)
    _options.add_no_progress(p)


def run(args: argparse.Namespace) -> int:
    outcome = run_analysis(_options.request(AnalyzeRequest, args))
    print(outcome.text)
    warning = outcome.warning()
    if warning:
        print(warning, file=sys.stderr)
    return 1 if warning else 0
