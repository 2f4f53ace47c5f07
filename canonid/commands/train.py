"""``canonid train`` — identify a model by output error into a run folder
(:func:`canonid.training.train`; the folder's files: :mod:`canonid.runfolder`)."""

from __future__ import annotations

import argparse

from canonid.commands import _options
from canonid.data_options import DATA_FLAGS
from canonid.kernel.catalog import (
    ACTIVATION_NAMES,
    DEFAULT_MODEL,
    DEFAULT_VAL_FRACTION,
    EVAL_HORIZON,
    LINEAR_PATHS,
    MODEL_NAMES,
    PAPER_NET_OPTIONS,
    help_value,
    model_label,
    preset_word,
)
from canonid.profiles import PROFILES
from canonid.training import (
    CUBIC_HELP,
    HORIZON_HELP,
    MEMBERS_HELP,
    REQUEST_TEXT_FIELDS,
    SEARCH_CUBIC_UNITS,
    SEARCH_ETA,
    WIDTH_CANDIDATES,
    WINDOW_CANDIDATES,
    TrainRequest,
    request_fields,
    train,
)


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Train a model on DATA (a canonid dataset, a CSV file or folder, or an .npz of "
        "arrays) by output error: ℓ measured samples burn in, the model predicts the next "
        "H outputs in open loop. What is not given is chosen by a search on validation. Writes "
        "a run folder and scores it on validation; canonid evaluate RUN scores the test split."
    )
    p.add_argument("data", nargs="?", metavar="DATA", help="training data (not with --resume)")
    p.add_argument(
        "--model",
        choices=MODEL_NAMES,
        help=f"model (default {DEFAULT_MODEL}, {model_label(DEFAULT_MODEL)}; arx: the linear "
        "baseline, least squares only)",
    )
    p.add_argument(
        "--window",
        metavar="L",
        help="window ℓ: L fixes it; a list, e.g. 5,10,20 or 5-8, is the search's window axis; "
        "default auto (a resumed run keeps its own): the search's axis ℓ = "
        f"{', '.join(str(w) for w in WINDOW_CANDIDATES)} (those the data allow) beside the cubic "
        f"branch ({' or '.join(map(str, SEARCH_CUBIC_UNITS))} units): successive halving, each "
        f"rung keeping the best 1/{SEARCH_ETA} of its candidates on the validation records' "
        f"simulation and training them {SEARCH_ETA}× longer, the last to the profile's epochs",
    )
    p.add_argument(
        "--max-window",
        type=int,
        metavar="L",
        help="the search tries only windows up to L, e.g. the n_init of the scoring rule you "
        "will use (a model needs ℓ measured samples before it simulates); default: every "
        "window the data allow",
    )
    _options.add_profile(p, what="training budget", keep_none=True)
    _options.add_from_profile(p, "--epochs", "training epochs", type=int, metavar="N")
    _options.add_from_profile(p, "--lr", "Adam learning rate at the schedule's start", type=float)
    p.add_argument(
        "--weight-decay",
        metavar="W",
        help=f"Adam weight decay >= 0 (default quick {PROFILES['quick']['train']['weight_decay']})",
    )
    _options.add_from_profile(p, "--batch-size", "sub-windows per batch", type=int, metavar="B")
    p.add_argument("--train-horizon", dest="horizon", type=int, metavar="H", help=HORIZON_HELP)
    _options.add_former(p, "--horizon", "--train-horizon")
    per_epoch = "random sub-windows per epoch, over all trajectories: ⌈N / batch⌉ optimiser"
    per_epoch += " steps however the data are cut"
    _options.add_from_profile(p, "--windows-per-epoch", per_epoch, type=int, metavar="N")
    p.add_argument("--seed", type=int, help="seed of weights and sub-windows (default 0)")
    _options.add_device(
        p,
        what="training device (default auto; a resumed run keeps its recorded device)",
        default=None,
    )
    _options.add_out(p, "runs/MODEL-lL, runs/MODEL-lauto without --window", what="run folder")
    _options.add_resume(p, what="training run", path=True)
    p.add_argument(
        "--val",
        metavar="FILE",
        help="validation data (default: DATA's val split, else a split of DATA)",
    )
    p.add_argument(
        "--val-fraction",
        type=float,
        help="share of DATA held out for validation when it has no val split (default "
        f"{help_value(DEFAULT_VAL_FRACTION)})",
    )
    p.add_argument(
        "--hidden",
        metavar="W,W",
        help="widths of the hidden layers, e.g. 2048,2048 (the paper's Ours (MLP) on the "
        "quadrotor; default 256,256,256): Ours (MLP)'s regressor, each MLP of Masti et al., "
        "the head of Ours (GRU); not classic-gru, whose sizes follow from ℓ; auto: train "
        f"{', '.join('×'.join(map(str, w)) for w in WIDTH_CANDIDATES)} as an axis of the "
        "search (with --window L or a list)",
    )
    p.add_argument(
        "--activation",
        choices=ACTIVATION_NAMES,
        help=f"hidden-layer nonlinearity of Ours (MLP) (default "
        f"{preset_word('mlp', 'activation')}; the paper's is "
        f"{PAPER_NET_OPTIONS['mlp']['activation']})",
    )
    p.add_argument(
        "--residual",
        action=argparse.BooleanOptionalAction,
        help=f"predict y_t − y_{{t−1}} (default: {preset_word('mlp', 'residual')} for Ours (MLP), "
        "off for the others)",
    )
    p.add_argument(
        "--feedthrough",
        action=argparse.BooleanOptionalAction,
        help="the output map sees u_t (default: "
        f"{preset_word('mlp', 'feedthrough')} for Ours (MLP): on when u_t lowers the linear "
        "fit's one-step validation error clearly; "
        f"{preset_word('arx', 'feedthrough')} for ARX, on for the others)",
    )
    p.add_argument(
        "--linear",
        action=_options.Bare,
        bare="arx",
        choices=LINEAR_PATHS,
        help="canonical models' affine path L·[z; u] + c beside the network: skip, a linear "
        "skip started at zero and trained with the network; arx, started "
        "at the least-squares ARX fit with the network's output layer at zero; off (default: "
        f"{preset_word('mlp', 'linear')} for Ours (MLP), off for the others; "
        "ARX is the affine path alone)",
    )
    p.add_argument(
        "--no-linear", dest="linear", action="store_const", const="off", help="no affine path"
    )
    p.add_argument("--cubic", metavar="K|auto", help=CUBIC_HELP)
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
        help=f"rollout length of the evaluation after training (default {EVAL_HORIZON}, or the "
        "final training rollout length when that is shorter, or what the scored records hold)",
    )
    p.add_argument("--members", type=int, metavar="K", help=MEMBERS_HELP)
    _options.add_figure_format(p)
    _options.add_threads(p)
    _options.add_where(
        p,
        jobs="train the search's candidates",
        alone="side by side, one process of one thread per core (--threads)",
        sees="DATA and --out",
        workers=None,
    )
    _options.add_no_progress(p)
    _options.add_data_options(p)
    _options.group_options(p, GROUPS)


#: ``canonid train --help``'s sections: title → (description, the options' dest)
GROUPS = {
    "data": (
        "DATA and --val: a canonid dataset, an .npz of arrays, or a .csv file or a folder of "
        "them (one experiment each), read with the CSV options.",
        ("data", "val", "val_fraction", *DATA_FLAGS),
    ),
    "model": (
        None,
        (
            *("model", "hidden", "activation", "residual", "feedthrough", "linear", "cubic"),
            *("paper_options", "members"),
        ),
    ),
    "training": (
        None,
        (
            *("profile", "epochs", "lr", "weight_decay", "batch_size", "horizon"),
            *("windows_per_epoch", "seed", "device", "threads"),
        ),
    ),
    "search": (
        "What is not given is chosen on validation; --window L and --cubic K fix those axes.",
        ("window", "max_window", "workers", "scheduler"),
    ),
    "output": (None, ("out", "resume", "eval_horizon", "figure_format", "no_progress")),
}


def request(args: argparse.Namespace) -> TrainRequest:
    """The training run that the parsed arguments ask for."""
    given = request_fields(**{key: getattr(args, key) for key in REQUEST_TEXT_FIELDS})
    return _options.request(TrainRequest, args, **given)


def run(args: argparse.Namespace) -> int:
    print(train(request(args)).summary())
    return 0
