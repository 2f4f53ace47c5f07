"""The loader options of the commands that read identification data (train, evaluate)."""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_data_options", "data_options"]

#: the loader options, by their argparse names (:data:`canonid.runfolder.DATA_FLAGS`)
OPTIONS = ("inputs", "outputs", "experiment_column", "time_column", "dt")


def _columns(text: str) -> list[str]:
    cols = [c.strip() for c in text.split(",") if c.strip()]
    if not cols:
        raise argparse.ArgumentTypeError("expected COL[,COL...]")
    return cols


def _column(text: str) -> str:
    """A column name; ``none`` (or nothing) switches the column off: ``""``."""
    return "" if text.strip().lower() in ("", "none") else text.strip()


def add_data_options(p: argparse.ArgumentParser, *, recorded: bool = False) -> None:
    """The loader options; ``recorded``: they default to those the run recorded (evaluate)."""
    given = "the run's" if recorded else None
    g = p.add_argument_group(
        "CSV data of --data FILE" if recorded else "CSV data",
        "Each option defaults to the one the run recorded in RUN/run.json; give one to override "
        "it, 'none' to switch a column off."
        if recorded
        else "A .csv file, or a folder of them (one experiment each).",
    )
    g.add_argument(
        "--inputs", type=_columns, metavar="COL,...", help=f"input columns{_default(given) or _CSV}"
    )
    g.add_argument(
        "--outputs",
        type=_columns,
        metavar="COL,...",
        help=f"output columns{_default(given) or _CSV}",
    )
    g.add_argument(
        "--experiment-column",
        type=_column,
        metavar="COL|none",
        help="column whose value names the experiment of each row; its rows must be "
        f"contiguous{_default(given or 'none: one experiment per file')}",
    )
    g.add_argument(
        "--time-column",
        type=_column,
        metavar="COL|none",
        help="column of sample times in seconds: gives dt, its steps checked uniform, and "
        "warns where it goes back (records joined)"
        + _default(given or "a column named t or time, if any"),
    )
    g.add_argument(
        "--dt",
        type=float,
        metavar="SECONDS",
        help="sampling time (CSV, .npz)"
        + _default(given or "the time column's step; required without one"),
    )


_CSV = " (required for CSV data)"


def _default(text: str | None) -> str:
    return f" (default: {text})" if text else ""


def data_options(args: argparse.Namespace) -> dict[str, Any]:
    """The loader options given on the command line (``None`` where not given)."""
    return {key: getattr(args, key) for key in OPTIONS}
