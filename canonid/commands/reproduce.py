"""``canonid reproduce`` — the paper's Table 1, figures and report in one command
(:func:`canonid.reproduce.reproduce`; the options override the profile's ``reproduce`` stage)."""

from __future__ import annotations

import argparse
from pathlib import Path

from canonid.commands import _options
from canonid.profiles import profile_values


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Reproduce the paper: generate (or reuse) the datasets, train and score every "
        "(system, model, window, seed) of Table 1, analyse α_ℓ, γ_f and Proposition 2, check "
        "the learned canonical models, run the compression study, and write one report "
        "(DIR/report.md and DIR/report.html) that sets each number beside the paper's. "
        "Every job runs serially, on --workers local Dask processes or on a Dask cluster "
        "(--scheduler); --resume keeps every finished job."
    )
    _options.add_profile(p, what="budgets and defaults of every stage (paper: the paper's sizes)")
    for name, item, what, example in (
        ("systems", str, "S", "systems, e.g. tank,drone2d,quadrotor"),
        ("windows", int, "L", "windows ℓ, e.g. 5,10,15"),
        ("models", str, "M", "models, e.g. mlp,gru,classic-gru,masti"),
    ):
        p.add_argument(
            f"--{name}",
            type=_options.comma_list(item, what),
            metavar=f"{what},...",
            help=f"{example} ({profile_values('reproduce', name)})",
        )
    p.add_argument(
        "--seeds",
        type=int,
        metavar="N",
        help=f"training seeds per cell, 0 … N−1 ({profile_values('reproduce', 'seeds')})",
    )
    _options.add_out(p, "runs/reproduce", value=Path("runs/reproduce"))
    _options.add_where(p, jobs="run the jobs", sees="--out")
    _options.add_resume(p, what="reproduction")
    _options.add_device(p, what="torch device of the training jobs")
    _options.add_figure_format(p)
    _options.add_no_progress(p, bars="bars")


def run(args: argparse.Namespace) -> int:
    from canonid.reproduce import ReproduceRequest, reproduce  # torch, CasADi

    print(reproduce(_options.request(ReproduceRequest, args).settings()).overview())
    return 0
