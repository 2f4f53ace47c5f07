"""Command-line options that several commands share, each written once: where the jobs run,
the profile, the torch device (no import of torch: ``canonid generate`` uses it), the figures'
file format, threads, progress, ``--resume``, ``--out``, the CSV loader options
(:data:`canonid.data_options.DATA_OPTIONS`); comma-separated lists, former option names kept as
deprecated aliases; and the typed request built from the parsed options."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from canonid.data_options import DATA_FLAGS, DATA_OPTIONS
from canonid.jobs import resume_target
from canonid.kernel.catalog import DEVICE_NAMES, parse_list
from canonid.kernel.errors import OptionError
from canonid.kernel.io import FIGURE_FORMATS
from canonid.profiles import DEFAULT_PROFILE, profile_names, profile_values

__all__ = [
    "Bare",
    "Former",
    "Items",
    "add_data_options",
    "add_device",
    "add_figure_format",
    "add_former",
    "add_from_profile",
    "add_no_progress",
    "add_out",
    "add_profile",
    "add_resume",
    "add_run_data",
    "add_threads",
    "add_where",
    "argument",
    "comma_list",
    "group_options",
    "request",
    "resumed",
]

_Request = TypeVar("_Request")


def add_where(
    parser: Any,
    *,
    jobs: str,
    sees: str,
    workers: int | None = 0,
    alone: str = "one after the other in this process",
) -> None:
    """``--workers N`` or ``--scheduler ADDRESS`` on ``parser`` (a parser or an argument
    group): where ``jobs`` run; the cluster's workers must see ``sees``. ``workers`` is the
    default of ``--workers`` (``None`` tells a command that it was not given); ``alone``: where
    they run without either."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        default=workers,
        metavar="N",
        help=f"{jobs} on N local Dask worker processes (default"
        f"{'' if workers is None else f' {workers}'}: {alone})",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help=f"{jobs} on the Dask cluster at ADDRESS, e.g. tcp://host:8786 (its workers must "
        f"have canonid installed and see {sees})",
    )


def add_profile(parser: Any, *, what: str, keep_none: bool = False) -> None:
    """``--profile NAME``: one of the profiles (:func:`canonid.profiles.profile_names`), ``what``
    they set, :data:`canonid.profiles.DEFAULT_PROFILE` when not given; ``keep_none`` leaves the
    argument ``None`` then, for a command that must tell whether it was given."""
    parser.add_argument(
        "--profile",
        choices=profile_names(),
        default=None if keep_none else DEFAULT_PROFILE,
        help=f"{what} (default {DEFAULT_PROFILE})",
    )


def add_from_profile(parser: Any, flag: str, what: str, stage: str = "train", **kw: Any) -> None:
    """``flag``, which overrides the key of the same name (its ``dest``) of the profile's
    ``stage``: its help, ``what``, ends with every profile's value
    (:func:`canonid.profiles.profile_values`)."""
    key = kw.get("dest", flag[2:].replace("-", "_"))
    parser.add_argument(flag, help=f"{what} ({profile_values(stage, key)})", **kw)


def add_device(parser: Any, *, what: str, default: str | None = "auto") -> None:
    """``--device {auto,cpu,cuda}``: the torch device of ``what``."""
    if default == "auto":
        what += " (default auto: CUDA when present and the job is large enough to run faster there)"
    parser.add_argument("--device", choices=DEVICE_NAMES, default=default, help=what)


def add_figure_format(parser: Any) -> None:
    """``--figure-format {png,pdf,svg}``: the file format of the figures a command writes."""
    parser.add_argument(
        "--figure-format",
        choices=FIGURE_FORMATS,
        default=FIGURE_FORMATS[0],
        help=f"file format of the figures (default {FIGURE_FORMATS[0]}; pdf and svg are vector "
        "graphics for a paper)",
    )


def add_threads(parser: Any, *, per: str = "", default: str = "torch's, one per core") -> None:
    """``--threads N``: torch's CPU threads (``per``: e.g. `` per job``; ``default``: what the
    command uses when it is not given)."""
    parser.add_argument(
        "--threads", type=int, metavar="N", help=f"torch CPU threads{per} (default: {default})"
    )


def add_no_progress(parser: Any, *, bars: str = "bar") -> None:
    """``--no-progress``, alias ``--quiet``: no progress bar(s) on stderr (one meaning in every
    command; nothing else is silenced)."""
    parser.add_argument("--no-progress", "--quiet", action="store_true", help=f"no progress {bars}")


def add_resume(parser: Any, *, what: str, path: bool = False) -> None:
    """``--resume``: continue the interrupted ``what`` in the folder of ``--out``; ``path``: the
    former spelling ``--resume RUN`` (= ``--resume --out RUN``) is still read, with a warning."""
    text = f"continue the interrupted {what} in --out"
    if path:
        parser.add_argument(
            "--resume",
            action=_FormerResume,
            nargs="?",
            const=True,
            metavar="RUN",
            help=f"{text} (the former --resume RUN, = --resume --out RUN, is read with a warning)",
        )
    else:
        parser.add_argument("--resume", action="store_true", help=text)


class _FormerResume(argparse.Action):
    """``--resume``, and its former spelling ``--resume RUN``: read for one release, with a
    warning naming ``--resume --out RUN``."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        if values is not True:  # --resume RUN
            use = f"use {option} --out {values}"
            print(f"{parser.prog}: warning: {option} RUN is deprecated, {use}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def resumed(args: argparse.Namespace) -> dict[str, Path | None]:
    """The ``resume`` and ``out`` fields of a request from ``--resume [RUN]`` and ``--out``
    (:func:`add_resume` with ``path``; the rule: :func:`canonid.jobs.resume_target`)."""
    resume, out = resume_target(args.resume, args.out)
    return {"resume": resume, "out": out}


def folder(text: str) -> Path:
    """argparse type of ``--out``: a path, not an empty string (which would mean the current
    folder without saying so); the application checks it before any work is done
    (:func:`canonid.jobs.check_folder`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder, got an empty string")
    return Path(text)


def add_run_data(parser: Any, help: str) -> None:
    """``--data FILE``: data other than those the run of ``RUN`` recorded (``help``: for what)."""
    parser.add_argument("--data", type=Path, metavar="FILE", help=help)


def add_out(
    parser: Any,
    default: str,
    *,
    what: str = "output folder",
    value: Path | None = None,
) -> None:
    """``--out DIR``, in every command: ``what`` (a folder) with the ``default`` the help states;
    ``value`` is the default where the command has a fixed one, else ``None`` lets the
    application choose."""
    parser.add_argument(
        "--out", type=folder, metavar="DIR", default=value, help=f"{what} (default {default})"
    )


class Former(argparse.Action):
    """A former option name: read into the new option's ``dest``, hidden from ``--help``, with a
    warning on stderr naming the new one."""

    def __init__(self, *args: Any, new: str, **kwargs: Any) -> None:
        self.new = new
        super().__init__(*args, **kwargs)

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        print(f"{parser.prog}: warning: {option} is deprecated, use {self.new}", file=sys.stderr)
        setattr(namespace, self.dest, True if self.nargs == 0 else values)


class Bare(argparse.Action):
    """An option that takes a value and that a former release also took alone (meaning
    ``bare``): still read so for one release, with a warning; ``--help`` shows it with a value."""

    shows_one_value = True  # canonid.cli.HelpFormatter shows no [ ] around the value

    def __init__(self, *args: Any, bare: str, **kwargs: Any) -> None:
        self.former_bare = bare
        super().__init__(*args, **{**kwargs, "nargs": "?"})

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        if values is None:
            use = f"use {option} {self.former_bare}"
            print(f"{parser.prog}: warning: {option} alone is deprecated, {use}", file=sys.stderr)
        setattr(namespace, self.dest, self.former_bare if values is None else values)


def add_former(parser: Any, old: str, new: str) -> None:
    """Accept ``old``, a former name of option ``new`` already on ``parser``, as a deprecated
    alias (not shown by ``--help``)."""
    action = next(a for a in parser._actions if new in a.option_strings)
    parser.add_argument(
        old,
        action=Former,
        new=new,
        dest=action.dest,
        nargs=action.nargs,
        type=action.type,
        default=argparse.SUPPRESS,
        help=argparse.SUPPRESS,
    )


def argument(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """argparse type of an application parser: its :class:`OptionError` is argparse's one-line
    error on the option (exit status 2)."""

    def read(text: str) -> Any:
        try:
            return parse(text)
        except OptionError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    read.__name__ = parse.__name__  # argparse's "invalid float value" names it
    return read


def comma_list(item: Callable[[str], Any], what: str) -> Callable[[str], list[Any]]:
    """argparse type of a list in the one list syntax (:func:`canonid.kernel.catalog.parse_list`:
    comma-separated, integer ranges ``A-B``) of ``item`` (``what``: how one is written)."""

    def one(word: str) -> Any:
        try:
            return item(word)
        except argparse.ArgumentTypeError as exc:  # an item's own check, e.g. a rate in (0, 1)
            raise ValueError(str(exc)) from None

    def parse(text: str) -> list[Any]:
        try:
            return parse_list(text, int if item is int else one, what)
        except OptionError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.list_of = what  # type: ignore[attr-defined]  # the meta-tests find every list option
    parse.ranges = item is int  # type: ignore[attr-defined]  # A-B is read
    return parse


class Items(argparse.Action):
    """``nargs="+"`` of :func:`comma_list` words: ``0.3,0.6`` and the former ``0.3 0.6`` give
    one flat list; the former spelling, several words, with a warning naming the one syntax."""

    shows_one_value = True  # canonid.cli.HelpFormatter shows R,... and no [R,... ...]

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        flat = [v for word in values for v in word]
        if len(values) > 1:  # --rates 0.3 0.6
            use = f"use {option} {','.join(map(str, flat))}"
            print(f"{parser.prog}: warning: {option} A B is deprecated, {use}", file=sys.stderr)
        setattr(namespace, self.dest, flat)


def request(kind: type[_Request], args: argparse.Namespace, **given: Any) -> _Request:
    """The application's request ``kind`` (a dataclass): every field that an option of the same
    name (its argparse ``dest``) holds in ``args``, and those the shared options imply where
    ``kind`` has them (``progress``: not ``--no-progress``; ``command``: this command line;
    ``data_options``: :func:`add_data_options`), but those that ``given`` sets."""
    names = {f.name for f in dataclasses.fields(kind) if f.init} - given.keys()  # type: ignore[arg-type]
    values = {n: getattr(args, n) for n in names if hasattr(args, n)}
    if hasattr(args, "no_progress"):
        values["progress"] = not args.no_progress
    if hasattr(args, "inputs"):  # the loader options, None where not given
        values["data_options"] = {name: getattr(args, name) for name in DATA_FLAGS}
    values["command"] = ("canonid", *sys.argv[1:])
    return kind(**{n: v for n, v in values.items() if n in names}, **given)


def add_data_options(parser: argparse.ArgumentParser, *, recorded: bool = False) -> None:
    """The loader options (:data:`canonid.data_options.DATA_OPTIONS`); ``recorded``: they
    default to those the run recorded (evaluate)."""
    g = parser.add_argument_group(
        "CSV data of --data FILE" if recorded else "CSV data",
        "Each option defaults to the one the run recorded in RUN/run.json; give one to override "
        "it, 'none' to switch a column off."
        if recorded
        else "A .csv file, or a folder of them (one experiment each).",
    )
    for flag, parse, metavar, what, default in DATA_OPTIONS:
        given = "the run's" if recorded else default
        tail = f" (default: {given})" if given else " (required for CSV data)"
        g.add_argument(flag, type=argument(parse), metavar=metavar, help=what + tail)


def group_options(
    parser: argparse.ArgumentParser, groups: dict[str, tuple[str | None, tuple[str, ...]]]
) -> None:
    """Sort the registered arguments of ``parser`` into argument groups, in ``--help`` in the
    order of ``groups``: title → (description, the ``dest`` of each argument); an argument in
    none keeps its place, a group left empty (e.g. ``CSV data``) is dropped. One table after
    registration, so the options themselves are written once, where they are registered."""
    made = []
    for title, (description, dests) in groups.items():
        group = parser.add_argument_group(title, description)
        for action in parser._actions:
            if action.dest in dests:
                for old in parser._action_groups:
                    if action in old._group_actions:
                        old._group_actions.remove(action)
                group._group_actions.append(action)
        made.append(group)
    first = [parser._positionals, parser._optionals]  # argparse's own two groups, then ours
    rest = [g for g in parser._action_groups if g not in made and g not in first]
    order = [*first, *made, *rest]
    parser._action_groups[:] = [g for g in order if g._group_actions]
