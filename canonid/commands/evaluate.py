"""``canonid evaluate``: score a run (:mod:`canonid.scoring`) or check its residuals."""

from __future__ import annotations

import argparse
from pathlib import Path

from canonid.commands import _options
from canonid.kernel.catalog import EVAL_HORIZON
from canonid.residual_check import JSON_HELP, RESIDUALS_HELP, ResidualRequest, check_residuals
from canonid.scoring import EvaluateRequest, score_run


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Score the model of RUN on test data: the paper's metric (MSE of open-loop rollouts "
        "after an ℓ-sample burn-in, physical units) and RMSE / NRMSE / fit % of a full "
        "open-loop simulation of each record after n_init samples. Writes metrics.json and "
        "rollouts.png to RUN/evaluations/DATA-SHA256[:8]-SPLIT[-OPTIONS]/, named by the data "
        "and the options; training's RUN/metrics.json stays. The same evaluation again is "
        "read back, not redone."
    )
    p.add_argument("run", type=Path, metavar="RUN", help="run folder written by canonid train")
    _options.add_run_data(
        p,
        "data (default: the run's data, split as training split them); the CSV options below "
        "default to those the run recorded",
    )
    p.add_argument(
        "--split",
        help="split to score (default: test, else the run's validation split, or all the "
        "records of a CSV / .npz --data file)",
    )
    p.add_argument(
        "--eval-horizon",
        dest="horizon",
        type=int,
        metavar="H",
        help=f"rollout length of the evaluation (default {EVAL_HORIZON}, or what the longest "
        "record holds after ℓ)",
    )
    _options.add_former(p, "--horizon", "--eval-horizon")
    p.add_argument("--stride", type=int, default=1, metavar="N", help="stride of rollout starts")
    p.add_argument(
        "--n-init",
        type=int,
        help="samples skipped by the scores (default max(ℓ, 50), at most the longest record "
        "minus one, or what the data name; the rule of canonid.evaluate too)",
    )
    _options.add_figure_format(p)
    p.add_argument("--residuals", nargs="?", const=10, type=int, metavar="K", help=RESIDUALS_HELP)
    p.add_argument("--json", type=Path, metavar="FILE", help=JSON_HELP)
    _options.add_no_progress(p, bars="bar (there is none here; every command takes the option)")
    _options.add_data_options(p, recorded=True)


def run(args: argparse.Namespace) -> int:
    if args.residuals is None and args.json is None:
        print(score_run(_options.request(EvaluateRequest, args)).summary())
    else:  # the check refuses --json without --residuals, and the scoring options
        print(check_residuals(_options.request(ResidualRequest, args)).summary())
    return 0
