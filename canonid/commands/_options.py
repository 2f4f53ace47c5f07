"""Command-line options that several commands share, each written once: where the jobs run,
the profile, the torch device (no import of torch: ``canonid generate`` uses it), the figures'
file format; and the typed request built from the parsed options."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from typing import Any, TypeVar

from canonid.kernel.io import FIGURE_FORMATS

__all__ = ["add_device", "add_figure_format", "add_profile", "add_where", "request"]

_Request = TypeVar("_Request")

DEVICES = ("auto", "cpu", "cuda")


def add_where(parser: Any, *, jobs: str, sees: str, workers: int | None = 0) -> None:
    """``--workers N`` or ``--scheduler ADDRESS`` on ``parser`` (a parser or an argument
    group): where ``jobs`` run; the cluster's workers must see ``sees``. ``workers`` is the
    default of ``--workers`` (``None`` tells a command that it was not given)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        default=workers,
        metavar="N",
        help=f"{jobs} on N local Dask worker processes (default: one after the other in this "
        "process)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help=f"{jobs} on the Dask cluster at ADDRESS, e.g. tcp://host:8786 (its workers must "
        f"have canonid installed and see {sees})",
    )


def add_profile(
    parser: Any, names: Sequence[str], *, what: str, default: str, keep_none: bool = False
) -> None:
    """``--profile NAME``: one of the profiles ``names``, ``what`` they set, ``default``
    (:data:`canonid.profiles.DEFAULT_PROFILE`) when not given; ``keep_none`` leaves the
    argument ``None`` then, for a command that must tell whether it was given."""
    parser.add_argument(
        "--profile",
        choices=names,
        default=None if keep_none else default,
        help=f"{what} (default {default})",
    )


def add_device(parser: Any, *, what: str, default: str | None = "auto") -> None:
    """``--device {auto,cpu,cuda}``: the torch device of ``what``."""
    if default == "auto":
        what += " (default auto: CUDA when present and the job is large enough to run faster there)"
    parser.add_argument("--device", choices=DEVICES, default=default, help=what)


def add_figure_format(parser: Any) -> None:
    """``--figure-format {png,pdf,svg}``: the file format of the figures a command writes."""
    parser.add_argument(
        "--figure-format",
        choices=FIGURE_FORMATS,
        default=FIGURE_FORMATS[0],
        help=f"file format of the figures (default {FIGURE_FORMATS[0]}; pdf and svg are vector "
        "graphics for a paper)",
    )


def request(kind: type[_Request], args: argparse.Namespace, **given: Any) -> _Request:
    """The application's request ``kind`` (a dataclass): every field that an option of the same
    name (its argparse ``dest``) holds in ``args``, but those that ``given`` sets."""
    names = {f.name for f in dataclasses.fields(kind) if f.init} - given.keys()  # type: ignore[arg-type]
    return kind(**{n: getattr(args, n) for n in names if hasattr(args, n)}, **given)
