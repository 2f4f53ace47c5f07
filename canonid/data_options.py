"""The loader options of user data (a CSV file or folder, an ``.npz`` of arrays), defined once:
the command-line flag that sets each, how its text is read, what it sets and its default for a
new run. ``canonid train`` and ``canonid evaluate`` offer them, a run records them
(``data_options`` of :class:`canonid.runfolder.RunSource`) and ``canonid evaluate`` reads a file
with those the run recorded, overridden by those given (:func:`canonid.scoring.run_options`).

The module imports nothing but the kernel's errors: ``--help`` reads it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from canonid.kernel.errors import OptionError

__all__ = ["DATA_FLAGS", "DATA_OPTIONS", "parse_column", "parse_columns"]


def parse_columns(text: str) -> list[str]:
    """``--inputs`` / ``--outputs``: ``"u1, u2"`` → ``["u1", "u2"]``; :class:`OptionError` when
    no column is named."""
    cols = [c.strip() for c in text.split(",") if c.strip()]
    if not cols:
        raise OptionError("expected COL[,COL...]")
    return cols


def parse_column(text: str) -> str:
    """A column name; ``none`` (or nothing) switches the column off: ``""``."""
    return "" if text.strip().lower() in ("", "none") else text.strip()


#: the loader options: flag, how its text is read, metavar, what it sets and its default for a
#: new run (``None``: required for CSV data)
DATA_OPTIONS: tuple[tuple[str, Callable[[str], Any], str, str, str | None], ...] = (
    ("--inputs", parse_columns, "COL,...", "input columns", None),
    ("--outputs", parse_columns, "COL,...", "output columns", None),
    (
        "--experiment-column",
        parse_column,
        "COL|none",
        "column whose value names the experiment of each row; its rows must be contiguous",
        "none: one experiment per file",
    ),
    (
        "--time-column",
        parse_column,
        "COL|none",
        "column of sample times in seconds: gives dt, its steps must be uniform (a --dt beside it "
        "must agree; none: read the rows as samples every --dt); warns where it goes back "
        "(records joined)",
        "a column named t or time, if any",
    ),
    (
        "--dt",
        float,
        "SECONDS",
        "sampling time (CSV, .npz)",
        "the time column's step; required without one",
    ),
)

#: the loader options a run records (keywords of :func:`canonid.datagen.loaders.load_data`), by
#: the command-line flag that sets each
DATA_FLAGS = {flag[2:].replace("-", "_"): flag for flag, *_ in DATA_OPTIONS}
