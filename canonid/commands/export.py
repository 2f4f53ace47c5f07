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
        "casadi.Function, with a JSON description beside it."
    )
    p.add_argument("run", type=Path, metavar="RUN", help="run folder of canonid train / reduce")
    p.add_argument(
        "--casadi",
        type=Path,
        metavar="FILE",
        required=True,
        help="the .casadi file to write (FILE.json is written beside it)",
    )
    _options.add_run_data(
        p, "data for the sets X, U, W (default: the training data named in RUN/run.json)"
    )


def run(args: argparse.Namespace) -> int:
    from canonid.learned import export_casadi  # torch, CasADi

    print(export_casadi(args.run, args.casadi, data=args.data).summary())
    return 0
