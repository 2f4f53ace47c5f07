"""``canonid export RUN --casadi FILE`` — a trained canonical model as a CasADi Function
(:func:`canonid.learned.export_casadi`, which says what is written)."""

from __future__ import annotations

import argparse
from pathlib import Path

from canonid.commands import _options


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Build the trained canonical model of RUN (Ours MLP/GRU, or reduced) as CasADi SX "
        "expressions from its weights — x_next = f(x, u), y = h(x, u), the state x being "
        "the canonical window z_t (or the reduced state) — and write it as a serialised "
        "casadi.Function, with a JSON description beside it. Several RUNs of the same window "
        "and signals (e.g. seeds) export as one model, the mean of their outputs."
    )
    more = "run folder of canonid train / reduce; several: their mean (sets from the first)"
    p.add_argument("runs", type=Path, nargs="+", metavar="RUN", help=more)
    written = "the .casadi file to write (FILE.json is written beside it)"
    p.add_argument("--casadi", type=Path, metavar="FILE", required=True, help=written)
    _options.add_run_data(
        p, "data for the sets X, U, W (default: the training data named in the first RUN/run.json)"
    )
    _options.add_no_progress(p, bars="bar (there is none here; every command takes the option)")


def run(args: argparse.Namespace) -> int:
    from canonid.learned import export_casadi  # torch, CasADi

    first, *members = args.runs
    print(export_casadi(first, args.casadi, data=args.data, members=members).summary())
    return 0
