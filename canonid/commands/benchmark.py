"""``canonid benchmark NAME`` — train on a standard benchmark's official training part as
``canonid train`` does and score every official test part by the official rule
(:func:`canonid.benchmark.run_benchmark`, which says what is written); ``canonid train``'s
options that the benchmark does not set itself are its options too, read into ``canonid train``'s
own parser's namespace, so all its defaults apply (as the former ``--train-args`` was)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, NoReturn

from canonid.benchmark import (
    BENCHMARKS,
    RESERVED_TRAIN_OPTIONS,
    BenchmarkRequest,
    benchmark_list,
    benchmark_summary,
    parse_window,
    run_benchmark,
    train_args,
)
from canonid.commands import _options, train
from canonid.data_options import DATA_FLAGS
from canonid.kernel.catalog import DEFAULT_MODEL, DEFAULT_VAL_FRACTION, MODEL_NAMES, help_value
from canonid.kernel.errors import OptionError
from canonid.training import TrainRequest


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Load benchmark NAME from its files (offline), train on the official training part "
        "as `canonid train` does (the last 20 % of every training record validates), score "
        "every official test part by the official rule (simulation from the whole test "
        "input after the first n_init measured outputs) and show the published baselines. "
        "--resume --out RUN continues an interrupted run (the same command again still does, "
        "with a deprecation warning)."
    )
    p.add_argument("name", nargs="?", metavar="NAME", help=f"one of {', '.join(BENCHMARKS)}")
    _options.add_resume(p, what="benchmark run (as canonid train --resume)", path=True)
    p.add_argument("--list", action="store_true", help="list the benchmarks and their files")
    p.add_argument(
        "--dir",
        dest="files",
        type=Path,
        metavar="DIR",
        help="folder of the benchmark files (default ~/.nonlinear_benchmarks, the package's cache)",
    )
    p.add_argument("--model", choices=MODEL_NAMES, help=f"model (default {DEFAULT_MODEL})")
    p.add_argument(
        "--window",
        metavar="L",
        help="window ℓ ≤ n_init, a list of them (e.g. 5,10,20) or auto (default: the windows "
        "of canonid train's screen that are ≤ n_init, screened on validation); passed to "
        "canonid train",
    )
    _options.add_profile(p, what="training budget", keep_none=True)
    _options.add_out(p, "runs/NAME-MODEL", what="run folder")
    p.add_argument("--seed", type=int, help="seed of weights and sub-windows (default 0)")
    _options.add_threads(p)
    _options.add_figure_format(p)
    p.add_argument(
        "--val-fraction",
        type=float,
        metavar="F",
        help="share at the end of every training record held out for validation (default "
        f"{help_value(DEFAULT_VAL_FRACTION)})",
    )
    p.add_argument(
        "--train-args",
        action=_options.Former,
        new="canonid train's options directly, e.g. --epochs 200",
        metavar="'OPTIONS'",
        default="",
        help=argparse.SUPPRESS,
    )
    _options.add_no_progress(p)
    passed = p.add_argument_group(
        "canonid train's options",
        "Given as to canonid train (all but those above, DATA, --val and the CSV options), e.g. "
        "--epochs 200 --batch-size 64.",
    )
    actions = _passed_on(p)
    for action in actions:
        passed._add_action(action)
    for group in _train_parser()._mutually_exclusive_groups:  # --workers | --scheduler
        one = p.add_mutually_exclusive_group()
        one._group_actions += [
            a for a in actions if a.dest in {b.dest for b in group._group_actions}
        ]
    p.set_defaults(train_options=tuple(a.dest for a in actions))  # what train_request reads


def _passed_on(p: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options of ``canonid train``'s parser that the benchmark passes on: every one that
    it neither sets itself (:data:`RESERVED_TRAIN_OPTIONS`, the data) nor has (``p``'s)."""
    own = {*RESERVED_TRAIN_OPTIONS, *p._option_string_actions}
    return [
        action
        for action in _train_parser()._actions
        if action.option_strings
        and action.dest not in DATA_FLAGS
        and not own & set(action.option_strings)
    ]


class _TrainParser(argparse.ArgumentParser):
    """``canonid train``'s parser, raising a one-line error instead of exiting, and taking
    options only as spelt out in full (``--mod`` is not ``--model``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **{**kwargs, "allow_abbrev": False})

    def error(self, message: str) -> NoReturn:
        raise OptionError(f"canonid train rejected the options: {message}")


def _train_parser() -> _TrainParser:
    parser = _TrainParser(prog="canonid train")
    train.register(parser)
    return parser


def train_request(argv: list[str], given: argparse.Namespace | None = None) -> TrainRequest:
    """``argv`` read by ``canonid train``'s own parser (its defaults included), and the options
    of it that the benchmark's parsed ``given`` holds other than their defaults."""
    parser = _train_parser()
    args = parser.parse_args(argv)
    passed = getattr(given, "train_options", ())
    for action in parser._actions:
        if action.dest in passed and getattr(given, action.dest) != action.default:
            setattr(args, action.dest, getattr(given, action.dest))  # given to the benchmark
    return train.request(args)


def run(args: argparse.Namespace) -> int:
    if args.list:
        print(benchmark_list(args.files))
        return 0
    extra = train_args(args.train_args, progress=not args.no_progress)
    request = _options.request(
        BenchmarkRequest,
        args,
        window=parse_window(args.window),
        train=train_request(extra, args),
        **_options.resumed(args),
    )
    print(benchmark_summary(*run_benchmark(request)))
    return 0
