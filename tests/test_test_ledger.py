"""The run folder's ledger of test reads (``test-ledger.jsonl``): ``canonid evaluate`` and
``canonid benchmark`` append one JSON line per read of a split named ``test`` (time in UTC, the
command, the split, the data file and its checksum), a read of another split appends nothing,
and a ledger that is a symbolic link (or not a regular file) is refused in one line naming it."""

from __future__ import annotations

import json
import os
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from cli_helpers import one_line_error
from learning_helpers import siso_dataset_file
from test_benchmarks import write_benchmark

from canonid.cli import main
from canonid.datagen.loaders import data_checksum
from canonid.kernel.errors import OutputError
from canonid.kernel.io import append_line
from canonid.runfolder import (
    TEST_LEDGER_FILE,
    check_test_ledger,
    record_test_read,
)

FIELDS = ["time", "command", "split", "data", "sha256"]


def _ledger(run: Path) -> list[dict]:
    path = run / TEST_LEDGER_FILE
    if not path.exists():
        return []
    lines = path.read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines]


def _recent(entry: dict) -> None:
    """``entry["time"]`` is UTC ISO 8601 (``…Z``) and of the last few minutes."""
    assert entry["time"].endswith("Z")
    when = datetime.fromisoformat(entry["time"].replace("Z", "+00:00"))
    assert when.tzinfo is not None and when.utcoffset() == timedelta(0)
    assert timedelta(0) <= datetime.now(timezone.utc) - when < timedelta(minutes=10)


# ------------------------------------------------------------------------------ the function
def test_each_read_is_one_json_line_with_its_fields(tmp_path):
    for command in ("evaluate", "benchmark"):
        record_test_read(
            tmp_path, command=command, split="test", data=tmp_path / "d.npz", sha256="ab" * 32
        )
    entries = _ledger(tmp_path)
    assert [list(e) for e in entries] == [FIELDS, FIELDS]
    assert [e["command"] for e in entries] == ["evaluate", "benchmark"]
    assert all(e["split"] == "test" and e["sha256"] == "ab" * 32 for e in entries)
    assert entries[0]["data"] == str(tmp_path / "d.npz")
    for entry in entries:
        _recent(entry)


def test_a_symlinked_ledger_is_refused_in_one_line_and_its_target_untouched(tmp_path):
    target = tmp_path / "elsewhere.txt"
    target.write_text("theirs\n")
    (tmp_path / TEST_LEDGER_FILE).symlink_to(target)
    for call in (
        lambda: record_test_read(tmp_path, command="evaluate", split="test", data="d", sha256="0"),
        lambda: check_test_ledger(tmp_path),
    ):
        with pytest.raises(OutputError) as err:
            call()
        text = str(err.value)
        assert str(tmp_path / TEST_LEDGER_FILE) in text and "symbolic link" in text
        assert "\n" not in text
    assert target.read_text() == "theirs\n"


def test_a_dangling_symlink_is_refused_and_nothing_is_created(tmp_path):
    (tmp_path / TEST_LEDGER_FILE).symlink_to(tmp_path / "missing")
    with pytest.raises(OutputError, match="symbolic link"):
        record_test_read(tmp_path, command="evaluate", split="test", data="d", sha256="0")
    assert not (tmp_path / "missing").exists()


def test_a_ledger_that_is_not_a_regular_file_is_refused(tmp_path):
    os.mkfifo(tmp_path / TEST_LEDGER_FILE)  # a FIFO without a reader would block a plain open
    with pytest.raises(OutputError, match="not a regular file"):
        record_test_read(tmp_path, command="evaluate", split="test", data="d", sha256="0")
    with pytest.raises(OutputError, match="not a regular file"):
        check_test_ledger(tmp_path)
    (tmp_path / TEST_LEDGER_FILE).unlink()
    (tmp_path / TEST_LEDGER_FILE).mkdir()
    with pytest.raises(OutputError, match="not a regular file"):
        record_test_read(tmp_path, command="evaluate", split="test", data="d", sha256="0")


def test_append_line_adds_to_what_is_there(tmp_path):
    path = tmp_path / "log.jsonl"
    path.write_text('{"a": 1}\n')
    append_line(path, '{"b": 2}')
    append_line(path, '{"c": 3}\n')  # one newline, whether given or not
    assert path.read_text() == '{"a": 1}\n{"b": 2}\n{"c": 3}\n'


# ------------------------------------------------------------------------------ canonid evaluate
@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A run of ``canonid train`` on a small dataset with a ``test`` split (two epochs)."""
    folder = tmp_path_factory.mktemp("ledger")
    data = siso_dataset_file(folder / "data")
    run = folder / "run"
    argv = ["train", str(data), "--model", "mlp", "--window", "3", "--epochs", "2"]
    argv += ["--out", str(run), "--no-progress", "--device", "cpu", "--threads", "1"]
    assert main(argv) == 0
    return run


def _copy(run: Path, tmp_path: Path) -> Path:
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    return copy


def test_evaluate_appends_one_line_per_test_read_and_none_for_another_split(
    trained, tmp_path, capsys
):
    run = _copy(trained, tmp_path)
    assert _ledger(run) == []  # canonid train itself keeps no ledger
    recipe = json.loads((run / "run.json").read_text())
    assert main(["evaluate", str(run), "--split", "val", "--stride", "5"]) == 0
    assert _ledger(run) == []  # validation is not the test split
    assert main(["evaluate", str(run), "--stride", "5"]) == 0  # the default: test
    (entry,) = _ledger(run)
    assert list(entry) == FIELDS and entry["command"] == "evaluate" and entry["split"] == "test"
    assert entry["data"] == recipe["data"]
    assert entry["sha256"] == recipe["data_sha256"] == data_checksum(recipe["data"])
    _recent(entry)
    # the same evaluation asked again is read back from its folder: nothing is scored
    assert main(["evaluate", str(run), "--stride", "5"]) == 0
    assert "already evaluated" in capsys.readouterr().out
    assert len(_ledger(run)) == 1
    # another evaluation of the test split is another read
    assert main(["evaluate", str(run), "--split", "test", "--stride", "7"]) == 0
    assert [e["command"] for e in _ledger(run)] == ["evaluate", "evaluate"]


def test_evaluate_of_a_data_file_records_that_file_only_when_its_split_is_test(trained, tmp_path):
    run = _copy(trained, tmp_path)
    recipe = json.loads((run / "run.json").read_text())
    other = siso_dataset_file(tmp_path / "other", T=120)
    assert main(["evaluate", str(run), "--data", str(other), "--stride", "5"]) == 0
    (entry,) = _ledger(run)
    assert (entry["data"], entry["sha256"]) == (str(other), data_checksum(other))
    assert entry["sha256"] != recipe["data_sha256"]
    assert main(["evaluate", str(run), "--data", str(other), "--split", "train"]) == 0
    assert len(_ledger(run)) == 1


def test_evaluate_refuses_a_symlinked_ledger_before_scoring(trained, tmp_path, capsys):
    run = _copy(trained, tmp_path)
    target = tmp_path / "target.jsonl"
    target.write_text("")
    (run / TEST_LEDGER_FILE).symlink_to(target)
    code = main(["evaluate", str(run), "--stride", "5"])
    one_line_error(capsys, code, str(run / TEST_LEDGER_FILE), "symbolic link")
    assert target.read_text() == "" and not (run / "evaluations").exists()


# ------------------------------------------------------------------------------ canonid benchmark
BENCH_ARGS = ["--window", "5", "--profile", "tiny", "--threads", "1", "--no-progress"]


def test_benchmark_appends_one_line_per_scoring_and_refuses_a_symlinked_ledger(tmp_path, capsys):
    write_benchmark("cascaded-tanks", tmp_path / "files")
    run = tmp_path / "run"
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path / "files"), "--out", str(run)]
    argv += [*BENCH_ARGS, "--epochs", "1"]
    assert main(argv) == 0
    recipe = json.loads((run / "run.json").read_text())
    (entry,) = _ledger(run)
    assert list(entry) == FIELDS
    assert (entry["command"], entry["split"]) == ("benchmark", "test")
    assert entry["data"] == recipe["data"] == str(run / "benchmark-data.npz")
    assert entry["sha256"] == recipe["data_sha256"] == data_checksum(run / "benchmark-data.npz")
    _recent(entry)
    # the same command again scores the test parts again: a second read, a second line
    assert main(argv) == 0
    assert [e["command"] for e in _ledger(run)] == ["benchmark", "benchmark"]
    capsys.readouterr()
    # a ledger replaced by a symbolic link: refused in one line before any training
    kept = (run / TEST_LEDGER_FILE).read_bytes()
    (run / TEST_LEDGER_FILE).unlink()
    (run / TEST_LEDGER_FILE).symlink_to(tmp_path / "elsewhere")
    weights = (run / "weights.pt").read_bytes()
    more = ["benchmark", "--resume", "--out", str(run), "--no-progress", "--threads", "1"]
    code = main([*more, "--epochs", "2"])
    one_line_error(capsys, code, str(run / TEST_LEDGER_FILE), "symbolic link")
    assert (run / "weights.pt").read_bytes() == weights
    assert json.loads((run / "run.json").read_text())["train_options"]["epochs"] == 1
    assert not (tmp_path / "elsewhere").exists() and kept.count(b"\n") == 2
