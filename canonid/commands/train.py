"""``canonid train`` — identify a model by output error; write a run folder.

The run folder holds ``run.json`` (the recipe: data, options, profile; what ``--resume`` reads),
the model (``config.json``, ``weights.pt``, ``normalisation.json``), ``checkpoint.pt``,
``history.csv`` and ``training_curve.png``, then ``metrics.json`` and ``rollouts.png`` from the
evaluation on the test split (the validation split when there is none). ``--window auto`` and
``--hidden auto`` train candidates and keep the best on validation (:mod:`canonid.selection`).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import sys
from pathlib import Path
from typing import Any

from canonid.commands import _data, _options, _paths, _progress
from canonid.commands.evaluate import table
from canonid.kernel.errors import CheckpointError, DataError
from canonid.kernel.io import read_json
from canonid.learning import NETS, EpochReport, OptionError, TrainOptions, model_names, presets
from canonid.learning.nets.base import ACTIVATIONS, LINEAR_PATHS, CanonicalModel
from canonid.learning.training import CHECKPOINT_FILE
from canonid.profiles import DEFAULT_PROFILE, profile_names, train_options
from canonid.runfolder import DEFAULT_VAL_FRACTION, METRICS_FILE, RunRecipe, train_run
from canonid.selection import (
    CANDIDATES_FILE,
    WIDTH_CANDIDATES,
    WINDOW_CANDIDATES,
    allowed_windows,
    plan_candidates,
    select,
)

__all__ = ["register", "run"]

AUTO = "auto"


def _on_off(model: str, option: str) -> str:
    """``on`` / ``off``: the default of a boolean network option, read from the presets so
    that the help cannot drift from what a run gets."""
    return "on" if presets.DEFAULT_NET_OPTIONS[model][option] else "off"


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "train",
        description=(
            "Train a model on DATA (a canonid dataset, a CSV file or folder, or an .npz of "
            "arrays) by output error: ℓ measured samples burn in, the model predicts the next "
            "H outputs in open loop. Writes a run folder and scores the model on the test split."
        ),
    )
    p.add_argument("data", nargs="?", metavar="DATA", help="training data (not with --resume)")
    p.add_argument(
        "--model",
        choices=model_names(),
        help="model (default mlp, Ours (MLP); arx: the linear baseline, least squares only)",
    )
    p.add_argument(
        "--window",
        type=_window_arg,
        metavar="L",
        help="window ℓ (required unless --resume); auto: train ℓ = "
        f"{', '.join(str(w) for w in WINDOW_CANDIDATES)} (those the data allow) and keep the "
        "best on validation",
    )
    _options.add_profile(
        p, profile_names(), what="training budget", default=DEFAULT_PROFILE, keep_none=True
    )
    p.add_argument("--epochs", type=int, metavar="N", help="override the profile's epochs")
    p.add_argument("--lr", type=float, help="override the profile's learning rate")
    p.add_argument("--batch-size", type=int, metavar="B", help="override the profile's batch")
    p.add_argument(
        "--horizon",
        type=int,
        metavar="H",
        help="override the profile's final training rollout length",
    )
    p.add_argument(
        "--windows-per-epoch",
        type=int,
        metavar="N",
        help="override the profile's random sub-windows per epoch (drawn over all trajectories; "
        "an epoch is ⌈N / batch⌉ optimiser steps however the data are cut)",
    )
    p.add_argument("--seed", type=int, help="seed of weights and sub-windows (default 0)")
    _options.add_device(
        p,
        what="training device (default auto; a resumed run keeps its recorded device)",
        default=None,
    )
    p.add_argument(
        "--out", type=_paths.folder, metavar="RUN", help="run folder (default runs/MODEL-lL)"
    )
    p.add_argument("--resume", type=Path, metavar="RUN", help="continue the run in RUN")
    p.add_argument(
        "--val",
        metavar="FILE",
        help="validation data (default: DATA's val split, else a split of DATA)",
    )
    p.add_argument(
        "--val-fraction",
        type=float,
        help="share of DATA held out for validation when it has no val split (default 0.2)",
    )
    p.add_argument(
        "--hidden",
        metavar="W,W",
        help="widths of the hidden layers, e.g. 2048,2048 (the paper's Ours (MLP) on the "
        "quadrotor; default 256,256,256): Ours (MLP)'s regressor, each MLP of Masti et al., "
        "the head of Ours (GRU); not classic-gru, whose sizes follow from ℓ; auto: train "
        f"{', '.join('×'.join(map(str, w)) for w in WIDTH_CANDIDATES)} and keep the best on "
        "validation",
    )
    p.add_argument(
        "--activation",
        choices=sorted(ACTIVATIONS),
        help=f"hidden-layer nonlinearity of Ours (MLP) (default "
        f"{presets.DEFAULT_NET_OPTIONS['mlp']['activation']}; the paper's is "
        f"{presets.PAPER_NET_OPTIONS['mlp']['activation']})",
    )
    p.add_argument(
        "--residual",
        action=argparse.BooleanOptionalAction,
        help=f"predict y_t − y_{{t−1}} (default: {_on_off('mlp', 'residual')} for Ours (MLP), "
        "off for the others)",
    )
    p.add_argument(
        "--feedthrough",
        action=argparse.BooleanOptionalAction,
        help=f"the output map sees u_t (default: {_on_off('mlp', 'feedthrough')} for Ours (MLP), "
        f"{_on_off('arx', 'feedthrough')} for ARX, on for the others)",
    )
    p.add_argument(
        "--linear",
        nargs="?",
        const="arx",
        choices=LINEAR_PATHS,
        help="canonical models' affine path L·[z; u] + c beside the network: skip, a linear "
        "skip started at zero and trained with the network; arx (also a bare --linear), started "
        "at the least-squares ARX fit with the network's output layer at zero; off (default: "
        f"{presets.DEFAULT_NET_OPTIONS['mlp']['linear']} for Ours (MLP), off for the others; "
        "ARX is the affine path alone)",
    )
    p.add_argument(
        "--no-linear",
        dest="linear",
        action="store_const",
        const="off",
        help="no affine path (--linear off)",
    )
    p.add_argument(
        "--paper-options",
        action="store_true",
        help="the paper's model (the authors' code): Ours (MLP) 3 × 256 ReLU, residual, no "
        "feedthrough, no affine path; the flags above still override it",
    )
    p.add_argument(
        "--eval-horizon",
        type=int,
        metavar="H",
        help="rollout length of the final evaluation (default 100, or the final training "
        "rollout length when that is shorter, or what the scored records hold)",
    )
    p.add_argument("--threads", type=int, metavar="N", help="torch CPU threads")
    _options.add_where(
        p,
        jobs="with --window/--hidden auto: train the candidates",
        sees="DATA and RUN",
        workers=None,
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _data.add_data_options(p)
    p.set_defaults(func=run)


def _recipe(args: argparse.Namespace) -> RunRecipe:
    if args.data is None:
        raise DataError("give the training DATA (or --resume RUN)")
    if args.window is None:
        raise DataError("--window is required for a new run (e.g. --window 10)")
    if args.model is None:
        args.model = "mlp"
    if args.val_fraction is not None and not 0 < args.val_fraction < 1:
        raise OptionError(f"--val-fraction must be in (0, 1), got {args.val_fraction}")
    profile = args.profile or DEFAULT_PROFILE
    opts = train_options(
        profile,
        epochs=args.epochs,
        lr=args.lr,
        batch_size=args.batch_size,
        horizon=args.horizon,
        windows_per_epoch=args.windows_per_epoch,
        seed=args.seed,
        device=args.device or "auto",
    )
    chosen: dict[str, Any] = {
        key: getattr(args, key)
        for key in ("feedthrough", "residual")
        if getattr(args, key) is not None
    }
    if args.hidden is not None:
        chosen[_hidden_option(args.model)] = parse_widths(args.hidden)
    if args.activation is not None:
        if args.model != "mlp":
            raise OptionError(f"--activation applies to Ours (MLP) only, not {args.model}")
        chosen["activation"] = args.activation
    if args.linear is not None:
        if not issubclass(NETS[args.model], CanonicalModel):
            raise OptionError(
                f"--linear applies to the canonical models (mlp, gru, arx), not {args.model}"
            )
        if args.model == "arx" and args.linear != "arx":
            raise OptionError(f"--linear {args.linear}: ARX is the affine path alone (arx)")
        chosen["linear"] = args.linear
    net_options = presets.net_options(args.model, chosen, paper=args.paper_options)
    return RunRecipe(
        data=str(args.data),
        data_options=_data.data_options(args),
        val=args.val,
        val_fraction=DEFAULT_VAL_FRACTION if args.val_fraction is None else args.val_fraction,
        model=args.model,
        window=args.window,
        net_options=net_options,
        profile=profile,
        train_options=opts.to_dict(),
        command=("canonid", *sys.argv[1:]),
    )


def _window_arg(text: str) -> int | str:
    """argparse type of ``--window``: an integer, or ``auto``."""
    if text == AUTO:
        return AUTO
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer or auto, got {text!r}") from None


def parse_widths(text: str) -> list[int]:
    """``"2048,2048"`` → ``[2048, 2048]`` (positive integers), or :class:`OptionError`."""
    try:
        widths = [int(part) for part in text.split(",")]
    except ValueError:
        widths = []
    if not widths or min(widths) < 1:
        raise OptionError(
            f"--hidden: expected positive integer widths separated by commas (e.g. 2048,2048), "
            f"got {text!r}"
        )
    return widths


def _hidden_option(model: str) -> str:
    """The constructor argument of ``model`` that ``--hidden`` sets."""
    option = NETS[model].hidden_option
    if option is None:
        raise OptionError(
            f"--hidden does not apply to {model}: its layer sizes follow from the window "
            "(⌈ℓ(n_u+n_y)/2⌉, as in the paper)"
        )
    return option


def _check_new_run(run_dir: Path, *, selection: bool = False) -> None:
    """Refuse an output folder that holds another kind of run (a selection is continued by
    running it again, so a selection folder is accepted for a selection)."""
    _paths.check_folder(run_dir)
    if (run_dir / CHECKPOINT_FILE).exists():
        raise CheckpointError(
            f"{run_dir} already holds a training run; use --resume {run_dir} or another --out"
        )
    if not selection and (run_dir / CANDIDATES_FILE).exists():
        raise CheckpointError(
            f"{run_dir} holds a selection of candidates ({CANDIDATES_FILE}); choose another --out"
        )


def _run_selection(args: argparse.Namespace) -> int:
    """``--window auto`` / ``--hidden auto``: train the candidates, keep the best on
    validation (:mod:`canonid.selection`)."""
    window_auto, hidden_auto = args.window == AUTO, args.hidden == AUTO
    fixed = argparse.Namespace(**vars(args))
    fixed.window = WINDOW_CANDIDATES[0] if window_auto else args.window
    fixed.hidden = None if hidden_auto else args.hidden
    base = _recipe(fixed)
    if hidden_auto:
        _hidden_option(base.model)  # refuses a model without hidden widths
    windows = allowed_windows(base, WINDOW_CANDIDATES) if window_auto else [base.window]
    run_dir = args.out or Path("runs") / (
        f"{base.model}-l{'auto' if window_auto else base.window}"
        + ("-hauto" if hidden_auto else "")
    )
    _check_new_run(run_dir, selection=True)
    local = not args.workers and args.scheduler is None
    jobs = plan_candidates(
        base,
        run_dir,
        windows=windows,
        widths=WIDTH_CANDIDATES if hidden_auto else (None,),
        eval_horizon=args.eval_horizon,
        threads=args.threads if args.threads is not None or local else 1,
    )
    run_dir.mkdir(parents=True, exist_ok=True)
    selection = select(
        jobs,
        run_dir,
        workers=args.workers or 0,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    print(selection.table())
    best = selection.best
    print(
        f"chosen: {best.name} (best validation loss {best.best_val_loss:.4g}, normalised, at "
        f"epoch {best.best_epoch}); its run is the model of {run_dir}"
    )
    print(table(read_json(run_dir / METRICS_FILE, what="metrics")))
    print(f"run written to {run_dir}")
    return 0


def _resume_recipe(args: argparse.Namespace, run_dir: Path) -> RunRecipe:
    if not (run_dir / CHECKPOINT_FILE).is_file():
        raise CheckpointError(f"{run_dir} holds no {CHECKPOINT_FILE} to resume from")
    fixed = [
        f"--{k.replace('_', '-')}"
        for k in (
            "lr",
            "batch_size",
            "horizon",
            "windows_per_epoch",
            "seed",
            "residual",
            "feedthrough",
            "linear",
        )
        if getattr(args, k) is not None
    ]
    if args.paper_options:
        fixed.append("--paper-options")
    if fixed:
        raise CheckpointError(
            f"{', '.join(fixed)} cannot change when resuming (only --epochs and --device can)"
        )
    recipe = RunRecipe.read(run_dir)
    if args.out is not None and args.out.resolve() != run_dir.resolve():
        raise CheckpointError(f"--out does not apply with --resume: the run continues in {run_dir}")
    diffs = [
        f"{key}: {getattr(recipe, key)!r} there, {value!r} here"
        for key, value in (
            ("model", args.model),
            ("window", args.window),
            ("data", args.data),
            ("profile", args.profile),
            ("val", args.val),
            ("val_fraction", args.val_fraction),
        )
        if value is not None and getattr(recipe, key) != value
    ]
    recorded = recipe.data_options
    diffs += [
        f"{key}: {recorded.get(key)!r} there, {value!r} here"
        for key, value in _data.data_options(args).items()
        if value is not None and recorded.get(key) != value
    ]
    if args.hidden is not None:
        option = _hidden_option(recipe.model)
        default = inspect.signature(NETS[recipe.model]).parameters[option].default
        there = recipe.net_options.get(option, default)
        if list(there) != parse_widths(args.hidden):
            diffs.append(f"hidden widths: {list(there)} there, {parse_widths(args.hidden)} here")
    if args.activation is not None:
        there = recipe.net_options.get("activation", "relu")
        if there != args.activation:
            diffs.append(f"activation: {there} there, {args.activation} here")
    if diffs:
        raise CheckpointError(f"run {run_dir} does not match: " + "; ".join(diffs))
    opts = dict(recipe.train_options)
    for key in ("epochs",):
        if getattr(args, key) is not None:
            opts[key] = getattr(args, key)
    if args.device is not None:
        opts["device"] = args.device
    return dataclasses.replace(recipe, train_options=TrainOptions.from_dict(opts).to_dict())


def run(args: argparse.Namespace) -> int:
    for flag, value in (("--threads", args.threads), ("--eval-horizon", args.eval_horizon)):
        if value is not None and value < 1:
            raise OptionError(f"{flag} must be an integer >= 1, got {value}")
    auto = [flag for flag in ("window", "hidden") if getattr(args, flag) == AUTO]
    if not auto and (args.workers is not None or args.scheduler is not None):
        flag = "--workers" if args.workers is not None else "--scheduler"
        raise OptionError(f"{flag} applies to --window auto or --hidden auto only")
    if auto and args.resume is not None:
        raise CheckpointError(
            f"--{auto[0]} auto does not combine with --resume: run the same selection again "
            "(same DATA, options and --out) to continue it"
        )
    if args.resume is not None and (args.resume / CANDIDATES_FILE).is_file():
        raise CheckpointError(
            f"{args.resume} holds a selection of candidates ({CANDIDATES_FILE}): run the same "
            f"selection again to continue it, or resume one candidate's folder"
        )
    if args.threads is not None:
        import torch

        torch.set_num_threads(args.threads)
    if auto:
        return _run_selection(args)
    if args.resume is not None:
        run_dir: Path = args.resume
        recipe = _resume_recipe(args, run_dir)
    else:
        recipe = _recipe(args)
        run_dir = args.out or Path("runs") / f"{recipe.model}-l{recipe.window}"
        _check_new_run(run_dir)
    bar = _progress.LazyBar(
        recipe.options().epochs,
        f"train {recipe.model}",
        enabled=not args.no_progress,
        dynamic_ncols=True,
    )

    def progress(report: EpochReport) -> None:
        val_text = "-" if report.val_loss is None else f"{report.val_loss:.3g}"
        bar.show(
            report.epoch,
            f"H={report.horizon} train={report.train_loss:.3g} val={val_text} "
            f"best={report.best_val_loss:.3g}@{report.best_epoch}",
        )

    try:
        result = train_run(
            recipe,
            run_dir,
            resume=args.resume is not None,
            eval_horizon=args.eval_horizon,
            callback=progress,
        )
    finally:
        bar.close()
    fitted = result.fit
    print(
        f"{recipe.model}: {fitted.stopped} after {fitted.epochs_run} epochs, best validation "
        f"loss {fitted.best_val_loss:.4g} (normalised) at epoch {fitted.best_epoch}"
    )
    print(table(result.evaluation.to_json()))
    print(f"run written to {run_dir}")
    return 0
