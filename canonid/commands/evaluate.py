"""``canonid evaluate`` — score a trained run on test data; rewrite its ``metrics.json``.

Reads the model of ``RUN`` and the data it was trained on (``RUN/run.json``) or ``--data FILE``;
scores the ``test`` split (or ``--split``) with :func:`learning.evaluate.evaluate`, writes
``RUN/metrics.json`` and ``RUN/rollouts.png`` and prints a short table.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from canonid.commands import _data
from canonid.runfolder import METRICS_FILE, RUN_FILE, evaluate_run
from learning import Model
from models.errors import DataError
from models.io import read_json

__all__ = ["register", "run", "table"]


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "evaluate",
        description=(
            "Score the model of RUN on test data: the paper's metric (MSE of open-loop rollouts "
            "after an ℓ-sample burn-in, physical units) and RMSE / NRMSE / fit %% of a full "
            "open-loop simulation of each record after n_init samples. Rewrites RUN/metrics.json."
        ),
    )
    p.add_argument("run", type=Path, metavar="RUN", help="run folder written by canonid train")
    p.add_argument("--data", type=Path, metavar="FILE", help="data (default: the run's data)")
    p.add_argument("--split", help="split to score (default: test, or the only split)")
    p.add_argument("--horizon", type=int, default=100, help="rollout length H (default 100)")
    p.add_argument("--stride", type=int, default=1, help="stride of rollout starts (default 1)")
    p.add_argument("--n-init", type=int, help="samples skipped by the scores (default max(ℓ, 50))")
    _data.add_data_options(p)
    p.set_defaults(func=run)


def table(metrics: dict[str, Any]) -> str:
    """A short text table of the main scores (measured and, if any, noise-free targets)."""
    rows = [("target", "rollout_mse", "rmse", "nrmse", "fit %")]
    for label, scores in (("y (measured)", metrics), ("y_clean", metrics.get("clean"))):
        if scores:
            rows.append(
                (
                    label,
                    f"{scores['rollout_mse']:.4g}",
                    f"{scores['rmse']:.4g}",
                    f"{scores['nrmse']:.4g}",
                    f"{scores['fit_percent']:.2f}",
                )
            )
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    head = (
        f"{metrics['model']} (ℓ = {metrics['window']}) on {metrics['data']['path']} "
        f"[{metrics['data']['split']}]: {metrics['n_rollouts']} rollouts of "
        f"{metrics['rollout_horizon']} steps; simulation scores after n_init = {metrics['n_init']}"
    )
    return "\n".join([head, *lines, *_worst_records(metrics)])


def _worst_records(metrics: dict[str, Any], count: int = 3) -> list[str]:
    """One line naming the records with the largest rollout MSE (noise-free target if any)."""
    label, scores = ("y_clean", metrics["clean"]) if metrics.get("clean") else ("y", metrics)
    per = scores.get("rollout_mse_per_record") or []
    scored = sorted(((value, i) for i, value in enumerate(per) if value is not None), reverse=True)
    if len(scored) < 2:
        return []
    worst = ", ".join(f"#{i} {value:.3g}" for value, i in scored[:count])
    return [f"largest rollout_mse per record ({label}; of {len(scored)}): {worst}"]


def run(args: argparse.Namespace) -> int:
    run_dir: Path = args.run
    model = Model.load(run_dir)
    options = _data.data_options(args)
    if args.data is None:
        recipe = read_json(run_dir / RUN_FILE, what="run recipe")
        if not isinstance(recipe, dict) or "data" not in recipe:
            raise DataError(f"{run_dir / RUN_FILE}: no field 'data'; give --data FILE")
        data_path, options = recipe["data"], recipe.get("data_options", {})
    else:
        data_path = str(args.data)
    dataset = _data.load(data_path, options)
    metrics = evaluate_run(
        run_dir,
        model,
        dataset,
        data_path=str(data_path),
        split=args.split,
        horizon=args.horizon,
        stride=args.stride,
        n_init=args.n_init,
    )
    print(table(metrics))
    print(f"metrics written to {run_dir / METRICS_FILE}")
    return 0
