"""MkDocs hook: the "Command line" page (``cli.md``), generated from canonid's argparse parsers.

The page is built from :func:`canonid.cli.build_parser` every time the site is built, so a flag
added to any subcommand appears in the docs with no manual edit. Run this file directly to print
the page (``python docs/hooks/cli_reference.py``).
"""

from __future__ import annotations

import argparse
import html
from typing import Any

from canonid.commands import COMMANDS

PAGE = "cli.md"
WIDTH = 96

INTRO = """\
# Command line

Every subcommand has `--help`; this page is generated from the same parsers when the site is
built, so it lists every flag of the installed version. Options are spelt out in full (`--epoch`
is not `--epochs`). A mistake on the command line (a bad choice or value, a missing or unknown
argument) prints one line on stderr and exits 2; other errors print one line and exit 1, and
`canonid --debug COMMAND ...` shows the traceback instead. `python -m canonid` is the
same program as `canonid`. Every command that writes figures takes `--figure-format png|pdf|svg`
(default png; pdf and svg are vector graphics for a paper).
"""


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = argparse.HelpFormatter(prog=parser.prog, width=WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip()


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell (no pipes, no raw HTML, one line)."""
    return html.escape(" ".join(text.split()), quote=False).replace("|", "\\|")


def _flag(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`"
    takes_value = action.nargs != 0
    metavar = action.metavar or action.dest.upper()
    if isinstance(metavar, tuple):
        metavar = " ".join(metavar)
    names = ", ".join(
        f"`{name} {metavar}`" if takes_value else f"`{name}`" for name in action.option_strings
    )
    return names


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    formatter = parser._get_formatter()
    text = formatter._expand_help(action) if action.help else ""
    extras = []
    if action.choices is not None and not isinstance(action.choices, dict):
        extras.append("one of " + ", ".join(f"`{c}`" for c in action.choices))
    if action.required and action.option_strings:
        extras.append("required")
    return _cell(text) + "".join(f" ({e})" for e in extras)


def _groups(parser: argparse.ArgumentParser) -> list[tuple[str, list[argparse.Action]]]:
    groups = []
    for group in parser._action_groups:
        actions = [
            a
            for a in group._group_actions
            if a.help is not argparse.SUPPRESS
            and not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction))
        ]
        if actions:
            groups.append((group.title or "options", actions))
    return groups


def _section(parser: argparse.ArgumentParser, level: str) -> list[str]:
    lines = ["```text", _usage(parser), "```", ""]
    if parser.description:
        lines += [" ".join(parser.description.split()), ""]
    for title, actions in _groups(parser):
        lines += [f"{level} {title[:1].upper()}{title[1:]}", "", "| argument | meaning |"]
        lines += ["|---|---|"]
        lines += [f"| {_flag(a)} | {_help(parser, a)} |" for a in actions]
        lines.append("")
    return lines


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def render(parser: argparse.ArgumentParser) -> str:
    """The Markdown page for ``parser`` and each of its subcommands, in registration order."""
    commands = _subparsers(parser)
    lines = [INTRO, "| command | what it does |", "|---|---|"]
    # the one-line summaries of `canonid --help`, from the command table (argparse format
    # strings: "%%" is a percent sign)
    helps = {c.name: c.help.replace("%%", "%") for c in COMMANDS}
    missing = [name for name in commands if not helps.get(name)]
    if missing:
        raise ValueError(f"canonid.commands.COMMANDS gives no summary for {missing}")
    lines += [f"| [`{name}`](#canonid-{name}) | {_cell(helps[name])} |" for name in commands]
    lines += ["", "## Global options", ""]
    lines += _section(parser, "###")
    for name, sub in commands.items():
        lines += [f"## canonid {name}", ""]
        lines += _section(sub, "###")
    return "\n".join(lines).rstrip() + "\n"


def on_files(files: Any, config: Any) -> Any:
    """Add the generated page to the site (MkDocs ``on_files`` event)."""
    from mkdocs.structure.files import File

    from canonid.cli import build_parser

    files.append(File.generated(config, PAGE, content=render(build_parser(every=True))))
    return files


if __name__ == "__main__":
    from canonid.cli import build_parser

    print(render(build_parser(every=True)), end="")
