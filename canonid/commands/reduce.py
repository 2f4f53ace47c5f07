"""``canonid reduce`` — compress the state of a trained canonical model with an auto-encoder.

``canonid reduce RUN --compression R`` trains one reduced model and writes its run folder (see
:mod:`canonid.reduction`); ``canonid reduce RUN [RUN ...] --sweep`` runs the compression study
over rates and seeds and writes its figures.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from canonid.commands import _options, _paths, _progress
from canonid.commands.evaluate import table
from canonid.kernel.errors import DataError
from canonid.kernel.io import read_json
from canonid.learning import EpochReport
from canonid.profiles import DEFAULT_PROFILE, profile_names, reduce_options
from canonid.reduction import (
    DEFAULT_RATES,
    ReductionJob,
    SweepPlan,
    compression_sweep,
    rate_label,
    reduce_run,
)
from canonid.runfolder import METRICS_FILE

__all__ = ["register", "run"]


def _rate(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), got {text!r}") from None


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "reduce",
        description=(
            "Reduce the state z of the canonical model (Ours MLP/GRU) trained in RUN: an "
            "auto-encoder (E, D) gives the reduced model x̄⁺ = E(Ā D(x̄) + B̄ u + S̄ Ĥ(D(x̄), u)), "
            "ȳ = Ĥ(D(x̄), u) with n̄ = ⌊dim z (1 − r)⌋ + 1 states. --compression R trains one "
            "reduced model and writes a run folder that `canonid evaluate` reads; --sweep "
            "trains one per (RUN, rate, seed) and draws the reconstruction heat-map and the "
            "reduced model's 100-step MSE against n̄."
        ),
    )
    p.add_argument(
        "runs", nargs="+", type=Path, metavar="RUN", help="run folder(s) of canonid train"
    )
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument(
        "--compression", type=_rate, metavar="R", help="compression rate in (0, 1), e.g. 0.6"
    )
    mode.add_argument("--sweep", action="store_true", help="the compression study")
    _options.add_profile(p, profile_names(), what="budget", default=DEFAULT_PROFILE)
    p.add_argument(
        "--out",
        type=_paths.folder,
        metavar="DIR",
        help="output folder (default: RUN-r<rate> beside RUN; runs/compression-sweep)",
    )
    p.add_argument("--epochs", type=int, metavar="N", help="override the profile's epochs")
    p.add_argument(
        "--linear-skip",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=(
            "E and D with an affine path started from the principal components of the training "
            "windows (default: the profile's; quick on, paper off = the paper's plain MLPs)"
        ),
    )
    p.add_argument("--seed", type=int, default=0, help="seed (--sweep: the first of --seeds)")
    _options.add_device(p, what="torch device (default auto: CUDA when present)")
    p.add_argument("--threads", type=int, metavar="N", help="torch CPU threads (per job)")
    p.add_argument(
        "--resume", action="store_true", help="continue the interrupted reduction in --out"
    )
    g = p.add_argument_group("compression study (--sweep)")
    g.add_argument(
        "--rates",
        type=_rate,
        nargs="+",
        default=list(DEFAULT_RATES),
        metavar="R",
        help="rates (default 0.15 0.30 … 0.90)",
    )
    g.add_argument("--seeds", type=int, default=3, metavar="N", help="seeds per rate (default 3)")
    _options.add_where(g, jobs="run the reductions", sees="RUN and --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def _one(args: argparse.Namespace) -> int:
    if len(args.runs) != 1:
        raise DataError(f"--compression reduces one RUN, got {len(args.runs)} (use --sweep)")
    source: Path = args.runs[0]
    out = args.out or source.parent / f"{source.name}-{rate_label(args.compression)}"
    _paths.check_folder(out)
    job = ReductionJob(
        source=str(source),
        compression=args.compression,
        out=str(out),
        profile=args.profile,
        seed=args.seed,
        epochs=args.epochs,
        linear_skip=args.linear_skip,
        device=args.device,
        threads=None,
        resume=args.resume,
        command=("canonid", *sys.argv[1:]),
    )
    train_opts, red_opts = reduce_options(
        args.profile, epochs=args.epochs, linear_skip=args.linear_skip
    )
    frozen = red_opts.frozen_epochs(train_opts.epochs)
    bar = _progress.LazyBar(train_opts.epochs, "reduce", enabled=not args.no_progress)

    def progress(report: EpochReport) -> None:
        phase = "Ĥ frozen" if report.epoch <= frozen else "Ĥ fine-tuned"
        val = "-" if report.val_loss is None else f"{report.val_loss:.3g}"
        recon = report.parts.get("reconstruction", float("nan"))
        bar.show(
            report.epoch,
            f"{phase}, H={report.horizon}, recon={recon:.3g}, val rollout={val} "
            f"(best {report.best_val_loss:.3g} at {report.best_epoch})",
        )

    try:
        result = reduce_run(job, callback=progress)
    finally:
        bar.close()
    print(
        f"{result.model} (ℓ = {result.window}) reduced at r = {result.compression:.0%}: "
        f"n̄ = {result.latent_dim} of dim z = {result.state_dim}; {result.stopped} after "
        f"{result.epochs_run} epochs (best at {result.best_epoch})"
    )
    print(
        f"{result.rollout_horizon}-step rollout MSE on the {result.split} split: reduced "
        f"{result.rollout_mse:.4g}, full "
        f"{result.full_rollout_mse:.4g} (ratio {result.ratio:.3g}); reconstruction MSE "
        f"{result.reconstruction_mse:.3g} (normalised)"
    )
    print(table(read_json(out / METRICS_FILE, what="metrics")))
    print(f"run written to {out}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    if args.resume:
        raise DataError("--resume is for one reduction; a sweep always resumes its jobs")
    if args.seeds < 1:
        raise DataError(f"--seeds must be >= 1, got {args.seeds}")
    out = _paths.check_folder(args.out or Path("runs") / "compression-sweep")
    plan = SweepPlan(
        runs=tuple(str(r) for r in args.runs),
        out=str(out),
        rates=tuple(args.rates),
        seeds=tuple(range(args.seed, args.seed + args.seeds)),
        profile=args.profile,
        epochs=args.epochs,
        linear_skip=args.linear_skip,
        device=args.device,
        threads=args.threads if args.threads is not None else 1,
        command=("canonid", *sys.argv[1:]),
    )
    sweep = compression_sweep(
        plan,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    print(sweep.table())
    print(f"figures: {sweep.heatmap}, {sweep.reduced_mse}; results: {out / 'sweep.json'}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.threads is not None and not args.sweep:
        import torch

        torch.set_num_threads(args.threads)
    return _sweep(args) if args.sweep else _one(args)
