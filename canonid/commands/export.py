"""``canonid export RUN --casadi FILE`` — a trained canonical model as a CasADi Function.

Writes ``FILE``, the serialised ``casadi.Function`` ``learned_model(x, u) -> (x_next, y)`` of
:class:`canonid.models.learned.LearnedSystem` (load it with ``casadi.Function.load(FILE)``), and
``FILE.json`` beside it: dimensions, names, units, ``dt``, the sets X, U, W and how the state is
filled from measured data. For a reduced model it also writes ``FILE`` with the suffix
``.encoder.casadi``: ``encode(z) -> x``, the reduced state of a measured window (physical units).
Only canonical models export (Ours (MLP), Ours (GRU) and their reduced models); the others
are refused.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from canonid.kernel.errors import DataError
from canonid.kernel.io import atomic_write_json
from canonid.learned import learned_system
from canonid.models.learned import model_function, save_function

__all__ = ["register", "run"]


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "export",
        help="write a trained canonical model as a CasADi Function (.casadi)",
        description=(
            "Build the trained canonical model of RUN (Ours MLP/GRU, or reduced) as CasADi SX "
            "expressions from its weights — x_next = f(x, u), y = h(x, u), the state x being "
            "the canonical window z_t (or the reduced state) — and write it as a serialised "
            "casadi.Function, with a JSON description beside it."
        ),
    )
    p.add_argument("run", type=Path, metavar="RUN", help="run folder of canonid train / reduce")
    p.add_argument(
        "--casadi",
        type=Path,
        metavar="FILE",
        required=True,
        help="the .casadi file to write (FILE.json is written beside it)",
    )
    p.add_argument(
        "--data",
        type=Path,
        metavar="FILE",
        help="data for the sets X, U, W (default: the training data named in RUN/run.json)",
    )
    p.set_defaults(func=run)


def encoder_path(path: Path) -> Path:
    """Where the encoder of a reduced model is written beside ``path``."""
    return path.with_name(f"{path.stem}.encoder.casadi")


def run(args: argparse.Namespace) -> int:
    target: Path = args.casadi
    if target.suffix != ".casadi":
        raise DataError(f"--casadi: expected a file name ending in .casadi, got {target}")
    if target.is_dir():
        raise DataError(f"--casadi: {target} is a folder, expected a file name")
    learned = learned_system(args.run, data=args.data)
    system = learned.system
    fun = model_function(system)
    reg = system.regressor
    files = [save_function(fun, target)]
    reduced = system.reduced
    if reduced:
        files.append(save_function(system.encoder, encoder_path(target)))
    description = {
        "format": "canonid-casadi-model",
        "run": str(args.run),
        "model": learned.model.name,
        "function": {
            "name": fun.name(),
            "inputs": {"x": system.n_x, "u": system.n_u},
            "outputs": {"x_next": system.n_x, "y": system.n_y},
        },
        "state": (
            "reduced state x̄ = E(z_t): run the encoder file on the measured window z_t"
            if reduced
            else "canonical window z_t = (u[t-ℓ], y[t-ℓ], …, u[t-1], y[t-1]), oldest first"
        ),
        "window": reg.window,
        **system.describe(),
    }
    json_path = atomic_write_json(target.with_name(target.name + ".json"), description)
    print(
        f"{learned.model.name} model of {args.run}: {system.n_x} states, {system.n_u} "
        f"input(s), {system.n_y} output(s), dt = {system.dt:g} s"
    )
    for path in [*files, json_path]:
        print(f"  wrote {path}")
    return 0
