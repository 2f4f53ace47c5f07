"""``canonid evaluate`` — score a trained run on test data; rewrite its ``metrics.json``.

Reads the model of ``RUN`` and either the data it was trained on, split again exactly as
training split them (``RUN/run.json``), or ``--data FILE`` read with the run's data options (a
CSV or ``.npz`` file's records form the split ``all``); scores the ``test`` split (else ``val``,
or ``--split``) with :func:`canonid.learning.evaluate.evaluate`, writes ``RUN/metrics.json`` and
``RUN/rollouts.png`` and prints a short table.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from canonid.commands import _data
from canonid.kernel.errors import DataError
from canonid.learning import Model
from canonid.runfolder import METRICS_FILE, eval_defaults, evaluate_run

__all__ = ["eval_defaults", "evaluate_run", "register", "run", "table"]


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
    p.add_argument(
        "--data",
        type=Path,
        metavar="FILE",
        help="data (default: the run's data, split as training split them); CSV options "
        "default to the run's",
    )
    p.add_argument(
        "--split",
        help="split to score (default: test, else the run's validation split, or all the "
        "records of a CSV / .npz --data file)",
    )
    p.add_argument(
        "--horizon",
        type=int,
        help="rollout length H (default 100, or what the longest record holds after ℓ)",
    )
    p.add_argument("--stride", type=int, default=1, help="stride of rollout starts (default 1)")
    p.add_argument(
        "--n-init",
        type=int,
        help="samples skipped by the scores (default max(ℓ, 50), at most the longest record "
        "minus one)",
    )
    _data.add_data_options(p)
    p.set_defaults(func=run)


def table(metrics: Mapping[str, Any]) -> str:
    """A short text table of the main scores (measured and, if any, noise-free targets) of a
    ``metrics.json`` body (:meth:`canonid.runfolder.RunEvaluation.to_json`)."""
    rows = [("target", "rollout_mse", "rmse", "nrmse", "fit %")]
    for label, scores in (("y (measured)", metrics), ("y_clean", metrics.get("clean"))):
        if scores:
            rows.append(
                (
                    label,
                    _number(scores["rollout_mse"], ".4g"),
                    _number(scores["rmse"], ".4g"),
                    _number(scores["nrmse"], ".4g"),
                    _number(scores["fit_percent"], ".2f"),
                )
            )
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    head = (
        f"{metrics['model']} (ℓ = {metrics['window']}) on {metrics['data']['path']} "
        f"[{metrics['data']['split']}]: {metrics['n_rollouts']} rollouts of "
        f"{metrics['rollout_horizon']} steps; simulation scores after n_init = {metrics['n_init']}"
    )
    diverged = (
        []
        if metrics.get("finite", True)
        else [
            "warning: the model's open-loop predictions blew up (inf or NaN) on this data: the "
            "scores marked 'not finite' are written null in metrics.json; train longer or try "
            "--linear off / --linear arx"
        ]
    )
    return "\n".join([head, *lines, *diverged, *_worst_records(metrics)])


def _number(value: float | None, spec: str) -> str:
    """``value`` formatted, or ``not finite`` for a score written ``null``."""
    return "not finite" if value is None else format(value, spec)


def _worst_records(metrics: Mapping[str, Any], count: int = 3) -> list[str]:
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
    for flag, value in (("--horizon", args.horizon), ("--stride", args.stride)):
        if value is not None and value < 1:
            raise DataError(f"{flag} must be an integer >= 1, got {value}")
    if args.n_init is not None and args.n_init < 0:
        raise DataError(f"--n-init must be an integer >= 0, got {args.n_init}")
    model = Model.load(run_dir)
    dataset, data_path, split = _data.scoring_data(
        run_dir, args.data, _data.data_options(args), split=args.split, model=model.info
    )
    name, trajs = _data.pick_split(dataset, split, where=data_path)
    horizon = eval_defaults(
        trajs,
        model.window,
        args.horizon or 100,
        where=f"{data_path} [{name}]",
        fit=args.horizon is None,
    )
    evaluation = evaluate_run(
        run_dir,
        model,
        dataset,
        data_path=data_path,
        split=name,
        horizon=horizon,
        stride=args.stride,
        n_init=args.n_init,
    )
    print(table(evaluation.to_json()))
    print(f"metrics written to {run_dir / METRICS_FILE}")
    return 0
