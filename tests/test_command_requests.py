"""The rules the commands leave to the application, tested without a parser: the loader options
(one table for the command line, the run folder and the loader), the text fields of a training
request, the benchmark's training options and summary, and what ``canonid export`` prints."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from canonid import benchmark
from canonid.benchmark import benchmark_summary, train_args
from canonid.data_options import DATA_FLAGS, DATA_OPTIONS, parse_column, parse_columns
from canonid.datagen.loaders import load_data
from canonid.kernel.errors import OptionError
from canonid.learned import Exported
from canonid.training import WINDOW_CANDIDATES, request_fields


def test_the_loader_options_are_the_loaders_keywords_by_their_flags():
    assert DATA_FLAGS == {
        "inputs": "--inputs",
        "outputs": "--outputs",
        "experiment_column": "--experiment-column",
        "time_column": "--time-column",
        "dt": "--dt",
    }
    keywords = inspect.signature(load_data).parameters
    assert all(keywords[name].kind is inspect.Parameter.KEYWORD_ONLY for name in DATA_FLAGS)
    assert [flag for flag, *_ in DATA_OPTIONS] == list(DATA_FLAGS.values())


def test_columns_are_a_comma_list_and_none_switches_a_column_off():
    assert parse_columns(" u1, u2 ,") == ["u1", "u2"]
    with pytest.raises(OptionError, match=r"^expected COL\[,COL\.\.\.\]$"):
        parse_columns(" , ")
    assert parse_column(" time ") == "time"
    assert parse_column("None") == parse_column("") == ""


def _fields(**given):
    text = {"window": None, "hidden": None, "weight_decay": None, "cubic": None, "max_window": None}
    return request_fields(**{**text, "resume": None, "out": None, **given})


def test_request_fields_parse_the_text_options():
    fields = _fields(
        window="5,10", hidden="64,64", weight_decay="1e-4", cubic="16", out=Path("run")
    )
    assert fields == {
        "window": (5, 10),
        "resume": None,
        "out": Path("run"),
        "hidden": (64, 64),
        "weight_decay": 1e-4,
        "cubic": 16,
        "window_candidates": WINDOW_CANDIDATES,
    }
    assert _fields(cubic="auto")["cubic"] == "auto"
    for bad in ("-1", "2.5", "many"):
        with pytest.raises(OptionError, match="--cubic: expected a number of units"):
            _fields(cubic=bad)
    assert _fields(max_window=20)["window_candidates"] == tuple(
        w for w in WINDOW_CANDIDATES if w <= 20
    )


def test_a_window_list_is_in_the_one_list_syntax():
    assert _fields(window="5-7,10")["window"] == (5, 6, 7, 10)
    assert _fields(window="5-5")["window"] == (5,)  # a range is a list, even of one
    for bad in ("7-5", "5,,6", "-3", "²"):
        with pytest.raises(OptionError, match="--window: expected an integer >= 1"):
            _fields(window=bad)


def test_request_fields_read_resume_and_refuse_a_cap_without_a_screen():
    assert _fields(resume=True, out=Path("run")) == {**_fields(), "resume": Path("run")}
    with pytest.raises(OptionError, match="--max-window caps the searched windows"):
        _fields(window="5", max_window=10)
    with pytest.raises(OptionError, match="--max-window caps the searched windows"):
        _fields(resume="run", max_window=10)
    with pytest.raises(OptionError, match="--window: expected an integer >= 1"):
        _fields(window="0", resume=True)  # the window is read first, as the command did


def test_the_benchmarks_no_progress_reaches_training():
    assert train_args("--epochs 2") == ["--epochs", "2"]
    assert train_args("--epochs 2", progress=False) == ["--epochs", "2", "--no-progress"]


def test_the_benchmark_summary_is_the_table_and_where_the_scores_are(tmp_path, monkeypatch):
    """The table, then (where validation misses levels of the training part) that line, then
    where the scores are."""
    from types import SimpleNamespace

    from canonid.coverage import OutsideRange, unvalidated_line

    monkeypatch.setattr(benchmark, "report_table", lambda report: f"the table of {report.name}")
    where = f"scores written to {tmp_path / 'benchmark.json'}"
    report = SimpleNamespace(name="RUN", unvalidated=())
    assert benchmark_summary(report, tmp_path) == f"the table of RUN\n{where}"
    missed = (OutsideRange("y", "output", 0.0, 1.0, share=0.3, distance=0.5, beyond=0.5),)
    line = unvalidated_line(missed)
    assert line is not None
    report = SimpleNamespace(name="RUN", unvalidated=missed)
    assert benchmark_summary(report, tmp_path) == f"the table of RUN\n{line}\n{where}"


def test_export_prints_the_model_then_each_file():
    exported = Exported("mlp model of run: 4 states", (Path("m.casadi"), Path("m.casadi.json")))
    assert exported.summary() == (
        "mlp model of run: 4 states\n  wrote m.casadi\n  wrote m.casadi.json"
    )
