"""``canonid benchmark NAME`` — train on a standard benchmark's official training part and score
every official test part by the official rule; ``canonid benchmark --list`` shows the benchmarks.

The run folder is a normal ``canonid train`` run (``evaluate``, ``analyze --run`` and ``reduce``
take it) plus:

* ``benchmark-data.npz`` / ``.json``: the benchmark as a canonid dataset, the data the run was
  trained on: split ``train`` = the first 80 % (``--val-fraction``) of every official training
  record, ``val`` = the rest of each record, ``test`` = the official test parts in order;
* ``benchmark.json``: the scores (:class:`canonid.benchmark.BenchmarkReport`), each
  ``{"test", "rmse", "units", "n_init", "n_scored"}``, and the published baselines shown;
* ``benchmark-<part>.png``: the simulation of each test part.

Training goes through ``canonid train`` itself: its own parser reads the options given here and
those of ``--train-args``, so every default of ``canonid train`` applies and any of its options
can be set.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import Any, NoReturn

from canonid.benchmark import (
    REPORT_FILE,
    RULE,
    BenchmarkReport,
    check_window,
    plot_part,
    report_table,
    score_parts,
)
from canonid.commands import _options, train
from canonid.datagen.benchmarks import (
    BENCHMARKS,
    benchmark,
    benchmark_names,
    find_files,
    load_benchmark,
)
from canonid.datagen.loaders import split_train_val
from canonid.kernel.errors import CheckpointError
from canonid.kernel.io import atomic_write_json
from canonid.learning import Model, OptionError, model_names
from canonid.learning.training import CHECKPOINT_FILE
from canonid.profiles import DEFAULT_PROFILE, profile_names

__all__ = ["register", "run"]

DATA_FILE = "benchmark-data.npz"
#: window when --window is not given: 10, or n_init when the rule allows fewer measured outputs
DEFAULT_WINDOW = 10


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "benchmark",
        description=(
            "Load benchmark NAME from its files (offline), train on the official training part "
            "as `canonid train` does (the last 20 % of every training record validates), score "
            "every official test part by the official rule (simulation from the whole test "
            "input after the first n_init measured outputs) and show the published baselines."
        ),
    )
    p.add_argument("name", nargs="?", metavar="NAME", help=f"one of {', '.join(BENCHMARKS)}")
    p.add_argument("--list", action="store_true", help="list the benchmarks and their files")
    p.add_argument(
        "--dir",
        type=Path,
        metavar="DIR",
        help="folder of the benchmark files (default ~/.nonlinear_benchmarks, the package's cache)",
    )
    p.add_argument("--model", choices=model_names(), default="mlp", help="model (default mlp)")
    p.add_argument(
        "--window",
        metavar="L",
        help=f"window ℓ ≤ n_init (default min({DEFAULT_WINDOW}, n_init)); passed to canonid train",
    )
    _options.add_profile(p, profile_names(), what="training budget", default=DEFAULT_PROFILE)
    p.add_argument("--out", type=Path, metavar="RUN", help="run folder (default runs/NAME-MODEL)")
    p.add_argument("--seed", type=int, help="seed of weights and sub-windows (default 0)")
    p.add_argument("--threads", type=int, metavar="N", help="torch CPU threads")
    p.add_argument(
        "--val-fraction",
        type=float,
        metavar="F",
        default=0.2,
        help="share at the end of every training record held out for validation (default 0.2)",
    )
    p.add_argument(
        "--train-args",
        metavar="'OPTIONS'",
        default="",
        help="further options for canonid train, as one string (e.g. --train-args='--epochs 200 "
        "--batch-size 64')",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


class _TrainParser(argparse.ArgumentParser):
    """``canonid train``'s parser, raising a one-line error instead of exiting."""

    def error(self, message: str) -> NoReturn:
        raise OptionError(f"canonid train rejected the options: {message}")


def train_arguments(argv: list[str]) -> argparse.Namespace:
    """``argv`` parsed by ``canonid train``'s own parser (its defaults included)."""
    parser = _TrainParser(prog="canonid")
    train.register(parser.add_subparsers(dest="command"))
    return parser.parse_args(["train", *argv])


#: canonid train options that the benchmark sets itself
_OWN = ("--model", "--window", "--profile", "--out", "--seed", "--threads", "--resume", "--val")


def _extra_train_args(text: str) -> list[str]:
    """``--train-args`` split like a shell; the options the benchmark sets are refused."""
    try:
        extra = shlex.split(text)
    except ValueError as exc:
        raise OptionError(f"--train-args: cannot split {text!r} ({exc})") from None
    taken = [a for a in extra if a.split("=")[0] in _OWN or a.startswith("--val-")]
    if taken:
        raise OptionError(
            f"--train-args: {', '.join(taken)} set by canonid benchmark itself; give them as "
            "its own options"
        )
    return extra


def _list(directory: Path | None) -> int:
    for bench in BENCHMARKS.values():
        parts = ", ".join(bench.test_parts)
        print(
            f"{bench.name}: {bench.title}; n_init = {bench.n_init}; scored in "
            f"{bench.score_units}; test parts: {parts}"
        )
        for file, path in find_files(bench, directory).items():
            alt = f" (or {', '.join(bench.csv)})" if bench.csv else ""
            where = f"found: {path}" if path else f"missing; download from {bench.page}"
            print(f"  {bench.folder}/{file}{alt}: {where}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.list:
        return _list(args.dir)
    if args.name is None:
        raise OptionError(f"give a benchmark NAME ({', '.join(benchmark_names())}) or --list")
    bench = benchmark(args.name)
    window = args.window if args.window is not None else str(min(DEFAULT_WINDOW, bench.n_init))
    if window.isdigit():
        check_window(int(window), bench)
    run_dir: Path = args.out or Path("runs") / f"{bench.name}-{args.model}"
    argv = [str(run_dir / DATA_FILE), "--model", args.model, "--window", window]
    argv += ["--profile", args.profile, "--out", str(run_dir)]
    for flag, value in (("--seed", args.seed), ("--threads", args.threads)):
        if value is not None:
            argv += [flag, str(value)]
    if args.no_progress:
        argv.append("--no-progress")
    train_args = train_arguments(argv + _extra_train_args(args.train_args))
    if (run_dir / CHECKPOINT_FILE).exists():
        raise CheckpointError(f"{run_dir} already holds a training run; choose another --out")
    dataset = load_benchmark(bench.name, args.dir)
    split = split_train_val(dataset, val_fraction=args.val_fraction, record_tails=True)
    run_dir.mkdir(parents=True, exist_ok=True)
    split.save(run_dir / DATA_FILE)
    train.run(train_args)

    model = Model.load(run_dir)
    scores, sims = score_parts(model, split, bench)
    report = BenchmarkReport(
        benchmark=bench.name,
        title=bench.title,
        definition=str(split.metadata["definition"]),
        files=list(split.metadata["files"]),
        model=args.model,
        window=model.window,
        profile=args.profile,
        validation=str(split.metadata["validation_split"]),
        scores=scores,
        baselines=list(bench.baselines),
        rule=RULE,
    )
    for part, sim, score in zip(split.split("test"), sims, scores, strict=True):
        plot_part(
            run_dir / f"benchmark-{score.test}.png",
            part,
            sim,
            bench=bench,
            dt=split.dt,
            score=score,
            model_label=f"{model.name} ℓ = {model.window}",
        )
    atomic_write_json(run_dir / REPORT_FILE, report.to_json())
    print(report_table(report))
    print(f"scores written to {run_dir / REPORT_FILE}")
    return 0
