"""The command line: help, version, the systems table, readable errors."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from canonid import __version__
from canonid.cli import EXIT_BROKEN_PIPE, build_parser, main
from canonid.models.registry import system_names


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert __version__ in capsys.readouterr().out


@pytest.mark.parametrize(
    "command",
    ["systems", "generate", "train", "reduce", "evaluate", "export", "analyze", "reproduce"],
)
def test_every_subcommand_has_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert "usage: canonid" in capsys.readouterr().out


def test_systems_lists_the_registry(capsys):
    assert main(["systems"]) == 0
    out = capsys.readouterr().out
    for name in system_names():
        assert f"{name}:" in out
    assert "dt=" in out and "X = " in out


def test_console_entry_point_errors_are_one_line():
    """An unknown subcommand: argparse's usage error, non-zero, no traceback."""
    res = subprocess.run(
        [sys.executable, "-m", "canonid", "frobnicate"], capture_output=True, text=True, timeout=120
    )
    assert res.returncode != 0
    assert "Traceback" not in res.stderr and "invalid choice" in res.stderr


@pytest.mark.parametrize("argv", [["systems"], ["systems", "--json"], ["--help"]])
def test_a_reader_that_stops_ends_the_command_quietly(argv):
    """``canonid systems | head -1``: the pipe is closed (here before the first write, so the
    test does not depend on timing); no traceback, no error line."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        res = subprocess.run(
            [sys.executable, "-m", "canonid", *argv],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert res.stderr == ""
    assert res.returncode in (0, EXIT_BROKEN_PIPE)


def test_parser_builds():
    assert build_parser().prog == "canonid"


@pytest.mark.parametrize("option", ["residual", "feedthrough", "linear"])
def test_train_help_states_the_default_a_run_gets(option, capsys):
    """The help's default for Ours (MLP) is the preset's (it once said the affine path was on)."""
    from canonid.learning.presets import DEFAULT_NET_OPTIONS

    with pytest.raises(SystemExit):
        main(["train", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    value = DEFAULT_NET_OPTIONS["mlp"][option]
    word = value if isinstance(value, str) else "on" if value else "off"
    flag = "--linear {off,skip,arx}" if option == "linear" else f"--{option}, --no-{option}"
    start = help_text.index(flag, help_text.index("options:"))
    assert f"default: {word} for Ours (MLP)" in help_text[start : start + 400]
