"""``canonid benchmark NAME`` — train on a standard benchmark's official training part as
``canonid train`` does and score every official test part by the official rule
(:func:`canonid.benchmark.run_benchmark`, which says what is written); ``--train-args`` is read by
``canonid train``'s own parser, so all its defaults apply."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, NoReturn

from canonid.benchmark import (
    BENCHMARKS,
    BenchmarkRequest,
    benchmark_list,
    benchmark_summary,
    parse_window,
    run_benchmark,
    train_args,
)
from canonid.commands import _options, train
from canonid.kernel.catalog import DEFAULT_MODEL, DEFAULT_VAL_FRACTION, MODEL_NAMES, help_value
from canonid.kernel.errors import OptionError
from canonid.training import TrainRequest


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Load benchmark NAME from its files (offline), train on the official training part "
        "as `canonid train` does (the last 20 % of every training record validates), score "
        "every official test part by the official rule (simulation from the whole test "
        "input after the first n_init measured outputs) and show the published baselines. The "
        "same command run again continues an interrupted run, as --resume does."
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
        metavar="'OPTIONS'",
        default="",
        help="further options for canonid train, as one string (e.g. --train-args='--epochs 200 "
        "--batch-size 64'; default: none)",
    )
    _options.add_no_progress(p)


class _TrainParser(argparse.ArgumentParser):
    """``canonid train``'s parser, raising a one-line error instead of exiting, and taking
    options only as spelt out in full (``--mod`` is not ``--model``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **{**kwargs, "allow_abbrev": False})

    def error(self, message: str) -> NoReturn:
        raise OptionError(f"canonid train rejected the options: {message}")


def train_request(argv: list[str]) -> TrainRequest:
    """``argv`` read by ``canonid train``'s own parser (its defaults included)."""
    parser = _TrainParser(prog="canonid train")
    train.register(parser)
    return train.request(parser.parse_args(argv))


def run(args: argparse.Namespace) -> int:
    if args.list:
        print(benchmark_list(args.files))
        return 0
    extra = train_args(args.train_args, progress=not args.no_progress)
    request = _options.request(
        BenchmarkRequest,
        args,
        window=parse_window(args.window),
        train=train_request(extra),
        **_options.resumed(args),
    )
    print(benchmark_summary(*run_benchmark(request)))
    return 0
