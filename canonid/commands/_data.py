"""The loader options of the commands that read identification data (train, evaluate)."""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_data_options", "data_options"]

#: the loader options, by their argparse names (:data:`canonid.runfolder.DATA_FLAGS`)
OPTIONS = ("inputs", "outputs", "experiment_column", "dt")


def _columns(text: str) -> list[str]:
    cols = [c.strip() for c in text.split(",") if c.strip()]
    if not cols:
        raise argparse.ArgumentTypeError("expected COL[,COL...]")
    return cols


def add_data_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("CSV data (a .csv file, or a folder of them: one experiment each)")
    g.add_argument("--inputs", type=_columns, metavar="COL,...", help="input columns")
    g.add_argument("--outputs", type=_columns, metavar="COL,...", help="output columns")
    g.add_argument(
        "--experiment-column", metavar="COL", help="column whose value names the experiment"
    )
    g.add_argument("--dt", type=float, metavar="SECONDS", help="sampling time (CSV, .npz)")


def data_options(args: argparse.Namespace) -> dict[str, Any]:
    """The loader options given on the command line (``None`` where not given)."""
    return {key: getattr(args, key) for key in OPTIONS}
