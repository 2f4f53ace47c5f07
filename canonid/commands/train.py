"""``canonid train`` — identify a model by output error; write a run folder.

The run folder holds ``run.json`` (the recipe: data, options, profile; what ``--resume`` reads),
the model (``config.json``, ``weights.pt``, ``normalisation.json``), ``checkpoint.pt``,
``history.csv`` and ``training_curve.png``, then ``metrics.json`` and ``rollouts.png`` from the
evaluation on the test split (the validation split when there is none).
"""

from __future__ import annotations

import argparse
import csv
import inspect
import io
import sys
from pathlib import Path
from typing import Any

from canonid.commands import _data
from canonid.commands.evaluate import RUN_FILE, evaluate_run, table
from canonid.profiles import profile_names, train_options
from datagen.loaders import split_train_val
from learning import NETS, EpochReport, OptionError, TrainOptions, fit, model_names, presets
from learning.nets.base import ACTIVATIONS, CanonicalModel
from learning.plots import plot_training_curve
from learning.training import CHECKPOINT_FILE
from models.errors import CheckpointError, DataError
from models.io import atomic_write_json, atomic_write_text, read_json

__all__ = ["register", "run"]


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "train",
        help="identify a model (Ours MLP/GRU, Classic GRU, Masti et al.) by output error",
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
    p.add_argument("--window", type=int, metavar="L", help="window ℓ (required unless --resume)")
    p.add_argument(
        "--profile",
        choices=profile_names(),
        default="quick",
        help="training budget (default quick)",
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
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto")
    p.add_argument("--out", type=Path, metavar="RUN", help="run folder (default runs/MODEL-lL)")
    p.add_argument("--resume", type=Path, metavar="RUN", help="continue the run in RUN")
    p.add_argument(
        "--val",
        metavar="FILE",
        help="validation data (default: DATA's val split, else a split of DATA)",
    )
    p.add_argument(
        "--val-fraction",
        type=float,
        default=0.2,
        help="share of DATA held out for validation when it has no val split",
    )
    p.add_argument(
        "--hidden",
        metavar="W,W",
        help="widths of the hidden layers, e.g. 2048,2048 (the paper's Ours (MLP) on the "
        "quadrotor; default 256,256,256): Ours (MLP)'s regressor, each MLP of Masti et al., "
        "the head of Ours (GRU); not classic-gru, whose sizes follow from ℓ",
    )
    p.add_argument(
        "--activation",
        choices=sorted(ACTIVATIONS),
        help="hidden-layer nonlinearity of Ours (MLP) (default silu; the paper's is relu)",
    )
    p.add_argument(
        "--residual",
        action=argparse.BooleanOptionalAction,
        help="predict y_t − y_{t−1} (default: on for Ours (MLP), off for the others)",
    )
    p.add_argument(
        "--feedthrough",
        action=argparse.BooleanOptionalAction,
        help="the output map sees u_t (default: off for Ours (MLP) and ARX, on for the others)",
    )
    p.add_argument(
        "--linear",
        action=argparse.BooleanOptionalAction,
        help="canonical models: an affine path started from the least-squares ARX fit "
        "(default: on for Ours (MLP))",
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
        default=100,
        metavar="H",
        help="rollout length of the final evaluation (default 100)",
    )
    p.add_argument("--threads", type=int, metavar="N", help="torch CPU threads")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _data.add_data_options(p)
    p.set_defaults(func=run)


def _recipe(args: argparse.Namespace) -> dict[str, Any]:
    if args.data is None:
        raise DataError("give the training DATA (or --resume RUN)")
    if args.window is None:
        raise DataError("--window is required for a new run (e.g. --window 10)")
    if args.model is None:
        args.model = "mlp"
    opts = train_options(
        args.profile,
        epochs=args.epochs,
        lr=args.lr,
        batch_size=args.batch_size,
        horizon=args.horizon,
        windows_per_epoch=args.windows_per_epoch,
        seed=args.seed,
        device=args.device,
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
        if args.model == "arx" and not args.linear:
            raise OptionError("--no-linear: ARX is the affine path alone")
        chosen["linear"] = args.linear
    net_options = presets.net_options(args.model, chosen, paper=args.paper_options)
    return {
        "format": "canonid-run",
        "data": str(args.data),
        "data_options": _data.data_options(args),
        "val": args.val,
        "val_fraction": args.val_fraction,
        "model": args.model,
        "window": args.window,
        "net_options": net_options,
        "profile": args.profile,
        "train_options": opts.to_dict(),
        "command": ["canonid", *sys.argv[1:]],
    }


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


def _resume_recipe(args: argparse.Namespace, run_dir: Path) -> dict[str, Any]:
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
    recipe = read_json(run_dir / RUN_FILE, what="run recipe")
    if not isinstance(recipe, dict) or recipe.get("format") != "canonid-run":
        raise CheckpointError(f"{run_dir / RUN_FILE} is not a canonid run recipe")
    diffs = [
        f"{key}: {recipe.get(key)!r} there, {value!r} here"
        for key, value in (("model", args.model), ("window", args.window), ("data", args.data))
        if value is not None and recipe.get(key) != value
    ]
    if args.hidden is not None:
        option = _hidden_option(recipe["model"])
        default = inspect.signature(NETS[recipe["model"]]).parameters[option].default
        there = recipe["net_options"].get(option, default)
        if list(there) != parse_widths(args.hidden):
            diffs.append(f"hidden widths: {list(there)} there, {parse_widths(args.hidden)} here")
    if args.activation is not None:
        there = recipe["net_options"].get("activation", "relu")
        if there != args.activation:
            diffs.append(f"activation: {there} there, {args.activation} here")
    if diffs:
        raise CheckpointError(f"run {run_dir} does not match: " + "; ".join(diffs))
    opts = dict(recipe["train_options"])
    for key in ("epochs",):
        if getattr(args, key) is not None:
            opts[key] = getattr(args, key)
    opts["device"] = args.device
    recipe["train_options"] = TrainOptions.from_dict(opts).to_dict()
    return recipe


def _splits(recipe: dict[str, Any]) -> tuple[Any, list[Any], list[Any], str, str]:
    data_path, options = recipe["data"], recipe["data_options"]
    dataset = _data.load(data_path, options)
    if recipe["val"] is not None:
        val_set = _data.load(recipe["val"], options)
        val = list(val_set.split("val") if "val" in val_set.splits else val_set.split("train"))
    elif "val" in dataset.splits:
        val = list(dataset.split("val"))
    else:
        dataset = split_train_val(dataset, val_fraction=recipe["val_fraction"])
        val = list(dataset.split("val"))
    train = list(dataset.split("train"))
    return dataset, train, val, "test" if "test" in dataset.splits else "val", data_path


def _write_history(run_dir: Path, history: list[dict[str, Any]]) -> None:
    keys: list[str] = []
    for row in history:
        keys += [k for k in row if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: ("" if row.get(k) is None else row[k]) for k in keys})
    atomic_write_text(run_dir / "history.csv", buf.getvalue())
    plot_training_curve(history, run_dir / "training_curve.png")


def run(args: argparse.Namespace) -> int:
    if args.threads is not None:
        import torch

        torch.set_num_threads(args.threads)
    if args.resume is not None:
        run_dir: Path = args.resume
        recipe = _resume_recipe(args, run_dir)
    else:
        recipe = _recipe(args)
        run_dir = args.out or Path("runs") / f"{recipe['model']}-l{recipe['window']}"
        if (run_dir / CHECKPOINT_FILE).exists():
            raise CheckpointError(
                f"{run_dir} already holds a training run; use --resume {run_dir} or another --out"
            )
    dataset, train, val, test_name, data_path = _splits(recipe)
    opts = TrainOptions.from_dict(recipe["train_options"])
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_json(run_dir / RUN_FILE, recipe)

    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(
            total=opts.epochs,
            desc=f"train {recipe['model']}",
            unit="epoch",
            file=sys.stderr,
            dynamic_ncols=True,
        )

    def progress(report: EpochReport) -> None:
        if bar is None:
            return
        bar.n = report.epoch
        val_text = "-" if report.val_loss is None else f"{report.val_loss:.3g}"
        bar.set_postfix_str(
            f"H={report.horizon} train={report.train_loss:.3g} val={val_text} "
            f"best={report.best_val_loss:.3g}@{report.best_epoch}"
        )

    try:
        result = fit(
            train,
            val,
            model=recipe["model"],
            window=recipe["window"],
            options=opts,
            net_options=recipe["net_options"],
            run_dir=run_dir,
            resume=args.resume is not None,
            callback=progress,
            info={
                "profile": recipe["profile"],
                "data": {"path": data_path, "splits": dataset.counts()},
                "input_names": list(dataset.input_names),
                "output_names": list(dataset.output_names),
                "dt": dataset.dt,
            },
        )
    finally:
        if bar is not None:
            bar.close()
    _write_history(run_dir, result.history)
    metrics = evaluate_run(
        run_dir,
        result.model,
        dataset,
        data_path=data_path,
        split=test_name,
        horizon=100 if opts.rollout_horizon >= 100 else opts.rollout_horizon,
        stride=1,
        n_init=None,
    )
    print(
        f"{recipe['model']}: {result.stopped} after {result.epochs_run} epochs, best validation "
        f"loss {result.best_val_loss:.4g} (normalised) at epoch {result.best_epoch}"
    )
    print(table(metrics))
    print(f"run written to {run_dir}")
    return 0
