"""The ``canonid`` command line.

Each subcommand lives in its own module under :mod:`canonid.commands` and exposes
``register(parser)``, which gives the command's parser its description and arguments, and
``run(args) -> int``. Only the module of the command being run is imported: ``canonid --help``
and ``canonid systems`` load neither torch nor CasADi. Errors raised on purpose
(:class:`canonid.kernel.errors.CanonidError`) and errors of the file system (``OSError``: a full
disk, a read-only folder) print as one line on stderr with a non-zero exit; ``--debug`` shows the
traceback instead. A reader that closes the pipe (``canonid systems | head -1``) ends the command
quietly. Any other exception is a bug and keeps its traceback.

Every parser, the program's and each command's, is a :class:`Parser`: an option is taken only as
spelt out in full, a mistake on the command line is one line on stderr with exit status 2, and
an option's help that does not say its default gets it from the parser (:class:`HelpFormatter`).
"""

from __future__ import annotations

import argparse
import difflib
import logging
import os
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from canonid import __version__
from canonid.commands import COMMANDS
from canonid.kernel.catalog import help_value
from canonid.kernel.errors import CanonidError

__all__ = ["HelpFormatter", "Parser", "build_parser", "main"]

EXIT_ERROR = 1
#: a mistake on the command line (argparse's status)
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
#: the shell's status of a program ended by SIGPIPE
EXIT_BROKEN_PIPE = 141


class HelpFormatter(argparse.HelpFormatter):
    """argparse's help, with `` (default X)`` after the help of an option that has a value when
    not given and does not say it (X as :func:`canonid.kernel.catalog.help_value` writes it): the
    default shown is the one the parser holds, never a copy typed beside it."""

    def _format_args(self, action: argparse.Action, default_metavar: str) -> str:
        if getattr(action, "shows_one_value", False):  # the spelling of this release alone
            return str(self._metavar_formatter(action, default_metavar)(1)[0])
        return super()._format_args(action, default_metavar)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        value = action.default
        if action.option_strings and action.nargs != 0 and "default" not in text:
            if value not in (None, "", argparse.SUPPRESS) and not isinstance(value, bool):
                text += f" (default {help_value(value)})".replace("%", "%%")
        return text


class Parser(argparse.ArgumentParser):
    """canonid's argument parser, of the program and of each command (``add_subparsers`` makes
    its parsers of the same class): an option is taken only as spelt out in full (``--epoch`` is
    not ``--epochs``), and a bad choice, a bad value, a missing or an unknown argument is one
    line on stderr, ``PROG: error: MESSAGE``, with exit status 2 and no usage (``--help`` shows
    it); an unknown option names the nearest one. Its help is a :class:`HelpFormatter`'s."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **{**kwargs, "allow_abbrev": False})

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:  # named by the command's parser, which argparse leaves to the program's
            where = self._command_parser(parsed)
            plural = "s" if len(extras) > 1 else ""
            near = _nearest(extras, [*where._actions, *self._actions])
            where.error(f"unrecognized argument{plural}: {' '.join(extras)}{near}")
        return parsed

    def _command_parser(self, parsed: argparse.Namespace) -> Parser:
        """The parser of the command that ``parsed`` ran, else this one."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = action.choices.get(getattr(parsed, action.dest, None) or "")
                if isinstance(chosen, Parser):
                    return chosen
        return self


def _nearest(extras: list[str], actions: list[argparse.Action]) -> str:
    """`` (did you mean --epochs?)`` for the first unknown option of ``extras`` close to one
    that ``actions`` show in ``--help``, else nothing."""
    shown = [
        option
        for action in actions
        if action.help is not argparse.SUPPRESS
        for option in action.option_strings
        if option.startswith("--")
    ]
    for word in extras:
        if word.startswith("--"):
            near = difflib.get_close_matches(word.split("=", 1)[0], shown, n=1, cutoff=0.75)
            if near:
                return f" (did you mean {near[0]}?)"
    return ""


def build_parser(command: str | None = None, *, every: bool = False) -> argparse.ArgumentParser:
    """The parser listing every subcommand; only ``command``'s module is imported and its
    arguments registered (the others parse nothing but are listed by ``--help``), or every
    command's with ``every`` (the documentation's command-line page). Every parser is a
    :class:`canonid.commands.Parser`: no abbreviated option, a mistake in one line (exit 2)."""
    parser = Parser(
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
    for cmd in COMMANDS:
        command_parser = sub.add_parser(cmd.name, help=cmd.help)
        if every or cmd.name == command:
            module = cmd.load()
            module.register(command_parser)
            command_parser.set_defaults(func=module.run)
    return parser


def _command(argv: Sequence[str]) -> str | None:
    """The subcommand named on the command line: its first word that is not an option (no
    top-level option takes a value)."""
    return next((word for word in argv if not word.startswith("-")), None)


def _silence_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's last flush at exit does not
    fail on the closed pipe again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # a stdout with no file descriptor
        pass


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(_command(argv)).parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        status = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return status
    except BrokenPipeError:  # the reader stopped (canonid systems | head -1): nothing to say
        _silence_stdout()
        return EXIT_BROKEN_PIPE
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
