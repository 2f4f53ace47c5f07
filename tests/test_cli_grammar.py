"""One command-line grammar, checked on the parsers themselves (in the manner of python-control's
``kwargs_test.py`` / ``docstrings_test.py``): every option says its default, the names shared by
several commands mean one thing, lists are comma-separated, former names still work (with a
warning, hidden from ``--help``), no option is taken abbreviated, a bad choice or value is one
line (exit 2, no usage), and the docs' command-line page lists every command with a summary."""

from __future__ import annotations

import argparse
import functools
import importlib.util
import re
from pathlib import Path

import pytest

from canonid.cli import build_parser
from canonid.commands import COMMANDS, _options
from canonid.kernel.catalog import (
    COMPRESSION_RATES,
    DEFAULT_MODEL,
    DEFAULT_VAL_FRACTION,
    EVAL_HORIZON,
    help_value,
)
from canonid.kernel.io import FIGURE_FORMATS
from canonid.profiles import DEFAULT_PROFILE, PROFILES, profile_values

DOCS = Path(__file__).resolve().parents[1] / "docs"

#: option names shared by several commands → the words every one of their help texts starts with
MEANINGS = {
    "--no-progress": "no progress bar",
    "--resume": "continue the interrupted ",
    "--eval-horizon": "rollout length of the evaluation",
    "--train-horizon": "final training rollout length (default from --profile: ",
    "--mpc-horizon": "prediction horizon of the NMPC",
    "--threads": "torch CPU threads",
    "--seed": "",
    "--windows": "windows ℓ, e.g. ",
}
#: former names: still read, in no command's --help
FORMER = ("--horizon",)


#: the shortest command line each command parses (its required arguments), to which a test adds
#: one mistake
MINIMAL = {
    "systems": [],
    "generate": ["tank"],
    "train": ["d.csv"],
    "reduce": ["r", "--sweep"],
    "evaluate": ["r"],
    "export": ["r", "--casadi", "m.casadi"],
    "analyze": ["tank", "--window", "2"],
    "benchmark": [],
    "reproduce": [],
}


@functools.cache
def _program() -> argparse.ArgumentParser:
    return build_parser(every=True)


@functools.cache
def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = _program()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _shown(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [
        a
        for a in parser._actions
        if a.help is not argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)
    ]


def _cases() -> list[tuple[str, argparse.Action]]:
    return [(name, a) for name, sub in _subcommands().items() for a in _shown(sub)]


def _label(case: tuple[str, argparse.Action]) -> str:
    name, action = case
    return f"{name} {action.option_strings[0] if action.option_strings else action.dest}"


@pytest.mark.parametrize("case", _cases(), ids=_label)
def test_every_option_has_help_that_states_its_default(case):
    name, action = case
    assert action.help and action.help.strip(), f"canonid {name} {_label(case)}: no help"
    text = _help(name, action)  # as --help prints it: the parser adds a default it holds
    if isinstance(action, argparse.BooleanOptionalAction):  # --x / --no-x: which when neither
        assert _states(text), f"canonid {_label(case)}: the help does not state the default"
    flag = action.nargs == 0 or action.const is True  # on or off: off unless given
    groups = [g for g in parser_groups(name) if action in g._group_actions]
    if flag or action.required or any(g.required for g in groups) or not action.option_strings:
        return
    if any(_states(o.help) for g in groups for o in g._group_actions):  # --workers | --scheduler
        return
    assert _states(text), f"canonid {_label(case)}: the help does not state the default: {text!r}"


def _usage_error(capsys, argv: list[str], *needles: str) -> str:
    """``canonid ARGV`` stops with exit status 2 and one line on stderr, no usage, holding every
    needle; returns that line."""
    with pytest.raises(SystemExit) as stop:
        _program().parse_args(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert stop.value.code == 2 and len(lines) == 1, err
    assert "usage:" not in err and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], err
    return lines[0]


def test_every_command_has_a_minimal_command_line():
    assert list(MINIMAL) == [c.name for c in COMMANDS]
    for name, argv in MINIMAL.items():
        assert _program().parse_args([name, *argv]).command == name


def test_no_parser_takes_an_option_abbreviated():
    parsers = [_program(), *_subcommands().values()]
    assert all(parser.allow_abbrev is False for parser in parsers)


def _prefixes() -> list[tuple[str, str, argparse.Action]]:
    """(command, an option's name less its last letter, the option) for every long option of
    every command and of the program whose shortened name is no option itself."""
    cases = []
    for name, parser in [("", _program()), *_subcommands().items()]:
        for action in parser._actions:
            for option in action.option_strings:
                if option.startswith("--") and option[:-1] not in parser._option_string_actions:
                    cases.append((name, option[:-1], action))
    return cases


@pytest.mark.parametrize("case", _prefixes(), ids=lambda c: f"{c[0] or 'canonid'} {c[1]}")
def test_an_abbreviated_option_is_refused_in_one_line(case, capsys):
    name, short, action = case
    value = [] if action.nargs == 0 else ["1"]
    if name:
        argv = [name, *MINIMAL[name], short, *value]
    else:  # a program option, before the command
        argv = [short, *value, "systems"]
    err = _usage_error(capsys, argv, "error: unrecognized argument", short)
    assert err.startswith(f"canonid {name or 'systems'}: error:"), err


def test_an_unknown_option_names_the_nearest(capsys):
    err = _usage_error(capsys, ["train", "d.csv", "--epoch", "2"], "--epoch 2")
    assert err.endswith("(did you mean --epochs?)"), err


def _choices() -> list[tuple[str, argparse.Action]]:
    return [(name, a) for name, sub in _subcommands().items() for a in sub._actions if a.choices]


@pytest.mark.parametrize("case", _choices(), ids=_label)
def test_a_bad_choice_is_one_line(case, capsys):
    name, action = case
    option = action.option_strings[0]
    _usage_error(
        capsys,
        [name, *MINIMAL[name], option, "nope"],
        f"canonid {name}: error: argument",
        option,
        "invalid choice: 'nope'",
        repr(action.choices[0]),
    )


def test_a_bad_command_is_one_line(capsys):
    _usage_error(capsys, ["frobnicate"], "invalid choice: 'frobnicate'", "'train'")


def _refuses(action: argparse.Action, text: str) -> bool:
    try:
        action.type(text)  # type: ignore[misc]
    except (ValueError, TypeError, argparse.ArgumentTypeError):
        return True
    return False


def _typed() -> list[tuple[str, argparse.Action]]:
    """Every option whose type refuses a word that is no number."""
    return [
        (name, a)
        for name, sub in _subcommands().items()
        for a in sub._actions
        if a.option_strings and a.type is not None and _refuses(a, "x@")
    ]


@pytest.mark.parametrize("case", _typed(), ids=_label)
def test_a_bad_value_is_one_line(case, capsys):
    name, action = case
    option = action.option_strings[0]
    _usage_error(capsys, [name, *MINIMAL[name], option, "x@"], f"canonid {name}: error:", option)


def _valued() -> list[tuple[str, argparse.Action]]:
    return [
        (name, a)
        for name, sub in _subcommands().items()
        for a in sub._actions
        if a.option_strings and a.nargs in (None, "+") and a.help is not argparse.SUPPRESS
    ]


@pytest.mark.parametrize("case", _valued(), ids=_label)
def test_a_missing_value_is_one_line(case, capsys):
    name, action = case
    option = action.option_strings[0]
    _usage_error(capsys, [name, *MINIMAL[name], option], f"canonid {name}: error:", option)


def _help(name: str, action: argparse.Action) -> str:
    """The option's help as ``--help`` prints it (``%(default)s`` filled in), on one line."""
    return " ".join(_subcommands()[name]._get_formatter()._expand_help(action).split())


def _defaulted() -> list[tuple[str, argparse.Action]]:
    """Every option that takes a value and has one when not given."""
    return [
        (name, a)
        for name, a in _cases()
        if a.option_strings
        and a.nargs != 0
        and a.default not in (None, "", argparse.SUPPRESS)
        and not isinstance(a.default, bool)
    ]


@pytest.mark.parametrize("case", _defaulted(), ids=_label)
def test_an_options_default_value_is_in_its_help(case):
    name, action = case
    text = _help(name, action)
    assert f"default {help_value(action.default)}" in text, f"canonid {_label(case)}: {text!r}"


#: options that another change replaces (the search of windows, widths, cubic branch and members)
SEARCH_OPTIONS = {"window", "max_window", "weight_decay", "cubic", "members"}


@pytest.mark.parametrize("stage", ["train", "reduce", "reproduce"])
def test_an_option_the_profiles_set_shows_every_profiles_value(stage):
    """The command of the same name as a profile stage: every option named like a key of that
    stage shows the value of each profile (generated from canonid.profiles.PROFILES)."""
    keys = {key for stages in PROFILES.values() for key in stages[stage]}
    shown = set()
    for action in _subcommands()[stage]._actions:
        if action.dest in keys - SEARCH_OPTIONS and action.help is not argparse.SUPPRESS:
            text = _help(stage, action)
            assert profile_values(stage, action.dest) in text, text
            for profile, stages in PROFILES.items():
                value = help_value(stages[stage][action.dest])
                assert f"{profile} {value}" in text, f"{profile}'s {action.dest}: {text!r}"
            shown.add(action.dest)
    assert (
        shown
        >= {
            "train": {"epochs", "lr", "batch_size", "horizon", "windows_per_epoch"},
            "reduce": {"epochs", "linear_skip"},
            "reproduce": {"systems", "windows", "models", "seeds"},
        }[stage]
    )


def _applied() -> list[tuple[str, str, object]]:
    """(command, option, the default that the application applies when it is not given)."""
    cases: list[tuple[str, str, object]] = [
        ("train", "--model", DEFAULT_MODEL),
        ("benchmark", "--model", DEFAULT_MODEL),
        ("train", "--val-fraction", DEFAULT_VAL_FRACTION),
        ("benchmark", "--val-fraction", DEFAULT_VAL_FRACTION),
        ("train", "--eval-horizon", EVAL_HORIZON),
        ("evaluate", "--eval-horizon", EVAL_HORIZON),
        ("reduce", "--rates", COMPRESSION_RATES),
    ]
    for name, sub in _subcommands().items():
        for option, value in (
            ("--profile", DEFAULT_PROFILE),
            ("--figure-format", FIGURE_FORMATS[0]),
        ):
            if option in sub._option_string_actions:
                cases.append((name, option, value))
    return cases


@pytest.mark.parametrize(
    ("name", "option", "value"), [pytest.param(*c, id=f"{c[0]} {c[1]}") for c in _applied()]
)
def test_a_default_the_application_applies_is_in_the_help(name, option, value):
    text = _help(name, _subcommands()[name]._option_string_actions[option])
    assert f"default {help_value(value)}" in text, f"canonid {name} {option}: {text!r}"


def test_train_help_shows_the_quick_profiles_budget(capsys):
    with pytest.raises(SystemExit):
        build_parser("train").parse_args(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option, value in (("--epochs N", "600"), ("--lr LR", "3e-3"), ("--batch-size B", "32")):
        start = text.index(option, text.index("options:"))
        assert f"quick {value}" in text[start : start + 200], text[start : start + 200]


def test_every_output_folder_is_out_dir():
    outs = {name: sub._option_string_actions.get("--out") for name, sub in _subcommands().items()}
    assert {name for name, out in outs.items() if out} >= {"generate", "train", "reduce"}
    assert {out.metavar for out in outs.values() if out} == {"DIR"}


def test_every_command_that_works_takes_no_progress():
    for name, sub in _subcommands().items():
        assert name == "systems" or "--no-progress" in sub._option_string_actions, name


#: the options whose value may be left out, and what that means
OPTIONAL_VALUES = {
    ("train", "--resume"): "the former spelling --resume RUN",
    ("benchmark", "--resume"): "the former spelling --resume RUN",
    ("evaluate", "--residuals"): "K = 10 lags",
}


def test_an_option_with_an_optional_value_is_one_of_few():
    optional = {
        (name, a.option_strings[0])
        for name, a in _cases()
        if a.nargs == "?" and a.option_strings and not isinstance(a, _options.Bare)
    }
    assert optional == set(OPTIONAL_VALUES)


def test_linear_takes_a_value_and_alone_is_deprecated(capsys):
    assert _parse("train", "d.csv", "--linear", "skip").linear == "skip"
    assert capsys.readouterr().err == ""
    assert _parse("train", "d.csv", "--linear", "--model", "gru").linear == "arx"
    warning = "canonid train: warning: --linear alone is deprecated, use --linear arx"
    assert capsys.readouterr().err.strip() == warning
    _usage_error(capsys, ["train", "d.csv", "--linear", "on"], "--linear", "invalid choice")
    with pytest.raises(SystemExit):
        build_parser("train").parse_args(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "[--linear {off,skip,arx}]" in text and "[{off" not in text


def test_shared_option_names_mean_one_thing():
    seen: dict[str, list[tuple[str, str, str]]] = {}
    for name, action in _cases():
        for option in action.option_strings:
            seen.setdefault(option, []).append((name, action.dest, action.help or ""))
    for option in FORMER:
        assert option not in seen, f"{option} is still shown by {[c for c, *_ in seen[option]]}"
    for option, start in MEANINGS.items():
        uses = seen.get(option, [])
        assert uses, f"no command has {option}"
        for command, _, text in uses:
            assert text.startswith(start), f"canonid {command} {option}: {text!r}"
    assert len(seen["--no-progress"]) >= 6 and len(seen["--resume"]) == 5


def _states(text: str | None) -> bool:
    """The help says the default, or when the option is required."""
    return bool(text and re.search(r"\bdefaults?\b|\brequired\b", text))


def parser_groups(name: str) -> list[argparse._MutuallyExclusiveGroup]:
    return _subcommands()[name]._mutually_exclusive_groups


def _parse(*argv: str) -> argparse.Namespace:
    return build_parser(argv[0]).parse_args(list(argv))


@pytest.mark.parametrize(
    ("argv", "dest", "value"),
    [
        (["reduce", "r", "--sweep", "--rates", "0.3,0.6"], "rates", [0.3, 0.6]),
        (["reproduce", "--windows", "5,10,15"], "windows", [5, 10, 15]),
        (["reproduce", "--windows", "5-7,10"], "windows", [5, 6, 7, 10]),
        (["reproduce", "--systems", "tank, drone2d"], "systems", ["tank", "drone2d"]),
        (["analyze", "tank", "--windows", "2,5,10"], "windows", [2, 5, 10]),
        (["analyze", "tank", "--windows", "1-4"], "windows", [1, 2, 3, 4]),
    ],
)
def test_lists_are_comma_separated(argv, dest, value, capsys):
    assert getattr(_parse(*argv), dest) == value
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    ("argv", "value"),
    [
        (["reduce", "r", "--sweep", "--rates", "0.3", "0.6"], [0.3, 0.6]),
        (["reduce", "r", "--sweep", "--rates", "0.3,0.45", "0.6"], [0.3, 0.45, 0.6]),
    ],
)
def test_a_list_of_words_is_the_former_spelling(argv, value, capsys):
    assert _parse(*argv).rates == value
    use = ",".join(map(str, value))
    warning = f"canonid reduce: warning: --rates A B is deprecated, use --rates {use}"
    assert capsys.readouterr().err.strip() == warning


#: list options of a fixed length: their metavar names each item
PAIRS = {"--band", "--hidden"}


def _lists() -> list[tuple[str, argparse.Action]]:
    """Every option that takes a list: its metavar holds a comma, or its type is a list's."""
    return [
        (name, a)
        for name, a in _cases()
        if a.option_strings and ("," in str(a.metavar) or hasattr(a.type, "list_of"))
    ]


@pytest.mark.parametrize("case", _lists(), ids=_label)
def test_every_list_option_uses_the_one_syntax(case):
    """Comma-separated (``X,...`` in --help, one word on the command line: no nargs), integer
    ranges A-B where the items are integers (canonid.kernel.catalog.parse_list)."""
    _, action = case
    option = action.option_strings[0]
    assert action.nargs is None or isinstance(action, _options.Items), _label(case)
    assert str(action.metavar).endswith(",...") or option in PAIRS, _label(case)
    if getattr(action.type, "ranges", False):  # integers
        assert action.type("1-3,5") == [1, 2, 3, 5], _label(case)


def test_no_option_takes_several_words():
    several = [_label(c) for c in _cases() if c[1].option_strings and c[1].nargs in ("+", "*")]
    assert several == ["reduce --rates"], several  # the former spelling, with a warning


@pytest.mark.parametrize(
    "argv",
    [["reduce", "r", "--sweep", "--rates", "0.3,,x"], ["reproduce", "--windows", "5,ten"]],
)
def test_a_bad_list_is_one_line_naming_the_option(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        _parse(*argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and argv[-2] in err and "expected" in err, err


@pytest.mark.parametrize(
    ("argv", "old", "new", "dest", "value"),
    [
        (["evaluate", "RUN", "--horizon", "20"], "--horizon", "--eval-horizon", "horizon", 20),
        (["train", "d.csv", "--horizon", "20"], "--horizon", "--train-horizon", "horizon", 20),
        (["generate", "drone2d", "--horizon", "10"], "--horizon", "--mpc-horizon", "horizon", 10),
    ],
)
def test_former_names_still_work_with_a_warning(argv, old, new, dest, value, capsys):
    assert getattr(_parse(*argv), dest) == value
    assert f"{old} is deprecated, use {new}" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "resume", "out"),
    [
        (["train", "--resume", "--out", "runs/a"], Path("runs/a"), None),
        (["train", "--out", "runs/a", "--resume"], Path("runs/a"), None),
        (["train", "--resume", "runs/a"], Path("runs/a"), None),  # the former spelling
        (["benchmark", "--resume", "--out", "runs/b"], Path("runs/b"), None),
        (["benchmark", "--resume", "runs/b"], Path("runs/b"), None),
        (["train", "d.csv", "--out", "runs/a"], None, Path("runs/a")),
    ],
)
def test_resume_continues_the_run_in_out(argv, resume, out, capsys):
    assert _options.resumed(_parse(*argv)) == {"resume": resume, "out": out}
    former = len(argv) == 3 and argv[1] == "--resume"
    warning = f"canonid {argv[0]}: warning: --resume RUN is deprecated, use --resume --out {resume}"
    assert capsys.readouterr().err.strip() == (warning if former else "")


def test_resume_without_a_folder_is_one_line(capsys):
    from canonid.cli import main

    assert main(["train", "--resume", "--epochs", "3"]) == 1
    err = capsys.readouterr().err
    assert (
        err.strip() == "canonid train: error: --resume continues the run in --out: give --out RUN"
    )


def test_the_docs_command_line_page_lists_every_command_with_a_summary():
    spec = importlib.util.spec_from_file_location(
        "cli_reference", DOCS / "hooks" / "cli_reference.py"
    )
    assert spec and spec.loader
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    page = hook.render(build_parser(every=True))
    rows = dict(re.findall(r"^\| \[`([a-z]+)`\]\(#canonid-[a-z]+\) \| (.*) \|$", page, re.M))
    assert list(rows) == [c.name for c in COMMANDS]
    for name, summary in rows.items():
        assert summary.strip() and "%%" not in summary, f"{name}: {summary!r}"


def test_train_help_is_grouped_data_model_training_search_output(capsys):
    parser = _subcommands()["train"]
    titles = [g.title for g in parser._action_groups]
    assert titles == ["options", "data", "model", "training", "search", "output"], titles
    grouped = {a for g in parser._action_groups[1:] for a in g._group_actions}
    loose = [a.dest for a in _shown(parser) if a not in grouped]
    assert not loose, f"canonid train options in no section: {loose}"
    with pytest.raises(SystemExit):
        build_parser("train").parse_args(["train", "--help"])
    out = capsys.readouterr().out
    heads = [line[:-1] for line in out.splitlines() if line.endswith(":") and line[:1].isalpha()]
    assert heads[-5:] == ["data", "model", "training", "search", "output"], heads


#: the commands that write nothing and show no progress
SILENT = {"systems"}


def test_quiet_is_no_progress_in_every_command(capsys):
    for name, sub in _subcommands().items():
        if name in SILENT:
            continue
        action = sub._option_string_actions.get("--quiet")
        assert action is not None, f"canonid {name} has no --quiet"
        assert action.option_strings == ["--no-progress", "--quiet"], name
        assert _parse(name, *MINIMAL[name], "--quiet").no_progress is True
        assert _parse(name, *MINIMAL[name]).no_progress is False
    assert capsys.readouterr().err == ""  # an alias, not a former name: no warning


#: commands without --out, and why
NO_OUT = {
    "systems": "writes nothing",
    "evaluate": "writes into RUN/evaluations/, a folder named by the data and the options",
    "export": "writes one file, --casadi FILE",
}
#: commands without --resume: they write nothing, or nothing they could continue
NO_RESUME = {"systems", "evaluate", "export", "analyze"}


def test_out_resume_and_quiet_are_present_with_one_meaning():
    """--out DIR in every command that writes a folder; --resume where a command can continue
    an interrupted run, always a flag continuing the run in --out (train's and benchmark's former
    --resume RUN aside); --quiet, alias of --no-progress, in every command but systems."""
    for name, sub in _subcommands().items():
        options = sub._option_string_actions
        out, resume = options.get("--out"), options.get("--resume")
        assert (out is None) == (name in NO_OUT), name
        if out is not None:
            assert out.metavar == "DIR" and out.nargs is None, name
        assert (resume is None) == (name in NO_RESUME), name
        if resume is not None:
            assert resume.help and resume.help.startswith("continue the interrupted "), name
            assert " in --out" in resume.help, name
            assert resume.nargs == 0 or (name, "--resume") in OPTIONAL_VALUES, name
        assert ("--quiet" in options) == (name not in SILENT), name
