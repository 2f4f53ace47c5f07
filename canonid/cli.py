"""The ``canonid`` command line.

Each subcommand lives in its own module under :mod:`canonid.commands` and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> int``. Errors raised on
purpose (:class:`models.errors.CanonidError`) and errors of the file system (``OSError``: a full
disk, a read-only folder) print as one line on stderr with a non-zero exit; ``--debug`` shows
the traceback instead. Any other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from canonid import __version__
from canonid.commands import COMMANDS
from models.errors import CanonidError, NotImplementedYetError

__all__ = ["build_parser", "main"]

EXIT_ERROR = 1
EXIT_NOT_YET = 2
EXIT_INTERRUPTED = 130


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="canonid",
        description=(
            "Learn reduced nonlinear state-space models from input/output data with the "
            "output-error canonical method; generate closed-loop datasets; check learned "
            "models against the theory."
        ),
    )
    parser.add_argument("--version", action="version", version=f"canonid {__version__}")
    parser.add_argument(
        "--debug", action="store_true", help="show full tracebacks and debug logging"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except NotImplementedYetError as exc:
        if args.debug:
            raise
        print(f"canonid {args.command}: {exc}", file=sys.stderr)
        return EXIT_NOT_YET
    except CanonidError as exc:
        if args.debug:
            raise
        print(f"canonid {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except OSError as exc:  # a file system that refuses a read or a write: not a bug of ours
        if args.debug:
            raise
        where = f"{exc.filename}: " if exc.filename is not None else ""
        print(f"canonid {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"canonid {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
