"""Run folders that are safe to share and jobs that can always be finished (issue 29, items 5–8).

* the data a run names are found by absolute path and refused when their checksum differs;
  ``run.json`` of an older canonid (a relative path, no checksum) still works;
* one lock per run folder: a second writer is refused in one line naming the holder;
* ``--out`` into a folder of the user's own files is refused, files untouched;
* a kill -9 leaves temporary files that the next writer of the folder removes;
* ``train --window 2,5`` (a selection) with a bad ``--workers`` leaves no folder.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import evaluated, one_line_error
from learning_helpers import siso_dataset_file

from canonid.cli import main
from canonid.jobs import LOCK_FILE, run_folder_lock
from canonid.kernel.errors import OutputError

ROOT = Path(__file__).resolve().parents[1]
TRAIN = ["--model", "mlp", "--window", "3", "--epochs", "2", "--hidden", "8,8"]
TRAIN += ["--no-progress", "--device", "cpu", "--threads", "1"]
FIXTURES = ROOT / "tests" / "fixtures" / "pre-namespace"
VICTIM_TEXT = "the user's own bytes\n"


@pytest.fixture(scope="module")
def data_a(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("a") / "data")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A run trained from its own folder on ``data/dataset.npz`` given by a relative path."""
    origin = tmp_path_factory.mktemp("origin")
    data = siso_dataset_file(origin / "data")
    here = Path.cwd()
    os.chdir(origin)
    try:
        assert main(["train", "data/dataset.npz", *TRAIN, "--out", "runs/a"]) == 0
    finally:
        os.chdir(here)
    return origin / "runs" / "a", data


def _copy(run: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(run, tmp_path / "run"))


# ---------------------------------------------------------------------- item 5: data paths
def test_run_json_records_the_data_by_absolute_path_and_checksum(trained):
    from canonid.datagen.loaders import data_checksum

    run, data = trained
    recipe = json.loads((run / "run.json").read_text())
    assert recipe["data"] == str(data) and Path(recipe["data"]).is_absolute()
    assert recipe["data_sha256"] == data_checksum(data)


def test_evaluate_from_another_folder_scores_the_runs_data_not_those_at_the_same_name(
    trained, tmp_path, monkeypatch, capsys
):
    run, data = trained
    elsewhere = tmp_path / "elsewhere"
    siso_dataset_file(elsewhere / "data", T=90)  # other data at the same relative path
    run = _copy(run, tmp_path)
    monkeypatch.chdir(elsewhere)
    assert main(["evaluate", str(run)]) == 0, capsys.readouterr().err
    metrics = evaluated(run, capsys.readouterr().out)
    assert metrics["data"]["path"] == str(data)


def test_other_data_at_the_recorded_path_are_refused_in_one_line(trained, tmp_path, capsys):
    run, data = trained
    run = _copy(run, tmp_path)
    before = (run / "metrics.json").read_bytes()
    recipe = json.loads((run / "run.json").read_text())
    other = siso_dataset_file(tmp_path / "other", T=90)
    recipe["data"] = str(other)  # the recorded path now holds other data than the checksum
    (run / "run.json").write_text(json.dumps(recipe))
    for argv in (["evaluate", str(run)], ["train", "--resume", "--out", str(run), "--no-progress"]):
        err = one_line_error(capsys, main(argv), str(run / "run.json"), str(other), "--data FILE")
        assert "SHA-256" in err
    assert (run / "metrics.json").read_bytes() == before
    # the same data given by --data are scored
    assert main(["evaluate", str(run), "--data", str(data)]) == 0


def test_missing_recorded_data_name_run_json_and_what_to_do(trained, tmp_path, capsys):
    run, _ = trained
    run = _copy(run, tmp_path)
    recipe = json.loads((run / "run.json").read_text())
    recipe["data"] = str(tmp_path / "gone" / "dataset.npz")
    (run / "run.json").write_text(json.dumps(recipe))
    out = tmp_path / "m.casadi"
    code = main(["export", str(run), "--casadi", str(out)])
    one_line_error(capsys, code, str(run / "run.json"), "not found", "--data FILE")
    assert not out.exists()


def test_an_old_run_json_resolves_its_relative_data_where_it_was_trained(
    tmp_path, monkeypatch, capsys, caplog
):
    """The run of commit 2bf4f1d names ``data`` relative to the folder it was trained from
    (``--out runs/mlp``): evaluated from anywhere, those are the data scored."""
    old = shutil.copytree(FIXTURES, tmp_path / "old", ignore=shutil.ignore_patterns("*.py"))
    elsewhere = tmp_path / "elsewhere"
    siso_dataset_file(elsewhere / "data", T=90)  # a trap: other data at the same relative path
    monkeypatch.chdir(elsewhere)
    assert main(["evaluate", str(old / "runs" / "mlp")]) == 0, capsys.readouterr().err
    metrics = evaluated(old / "runs" / "mlp", capsys.readouterr().out)
    assert metrics["data"]["path"] == str(old / "data")
    assert any("records no checksum" in r.getMessage() for r in caplog.records)


# ---------------------------------------------------------------------- item 6: the lock
HOLDER = """
import sys, time
from pathlib import Path
from canonid.jobs import run_folder_lock
with run_folder_lock(Path(sys.argv[1])):
    print("held", flush=True)
    sys.stdin.readline()
"""


def _hold(folder: Path) -> subprocess.Popen:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(folder), "train", "--out", str(folder)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    return holder


def test_a_second_writer_is_refused_naming_the_holder(data_a, tmp_path, capsys):
    run = tmp_path / "run"
    holder = _hold(run)
    try:
        argv = ["train", str(data_a), *TRAIN, "--out", str(run)]
        err = one_line_error(capsys, main(argv), "being written by another canonid process")
        assert f"pid {holder.pid} on " in err and f"--out {run}" in err
        assert sorted(p.name for p in run.iterdir()) == [LOCK_FILE]  # nothing written
    finally:
        holder.communicate("\n", timeout=60)
    assert main(argv) == 0  # the lock went with its holder
    assert (run / "weights.pt").is_file()


def test_the_lock_is_dropped_when_its_holder_is_killed(tmp_path):
    run = tmp_path / "run"
    holder = _hold(run)
    with pytest.raises(OutputError, match=f"pid {holder.pid}"), run_folder_lock(run):
        pass
    holder.kill()
    holder.wait(timeout=60)
    with run_folder_lock(run):
        assert json.loads((run / LOCK_FILE).read_text())["pid"] == os.getpid()


def test_a_symlink_planted_at_the_lock_name_is_refused(tmp_path):
    run, victim = tmp_path / "run", tmp_path / "victim"
    run.mkdir()
    victim.write_text(VICTIM_TEXT)
    (run / LOCK_FILE).symlink_to(victim)
    with pytest.raises(OutputError, match="symbolic link"), run_folder_lock(run):
        pass
    assert victim.read_text() == VICTIM_TEXT


def test_the_lock_removes_the_folder_it_made_when_nothing_was_written(tmp_path):
    with pytest.raises(RuntimeError), run_folder_lock(tmp_path / "a" / "b"):
        raise RuntimeError("failed before writing")
    assert not (tmp_path / "a").exists()


# ---------------------------------------------------------------------- item 7: user folders
@pytest.mark.parametrize("command", ["train", "benchmark"])
def test_out_into_a_folder_of_the_users_files_is_refused(data_a, tmp_path, capsys, command):
    mine = tmp_path / "mine"
    mine.mkdir()
    for name in ("run.json", "config.json", "history.csv"):
        (mine / name).write_text(VICTIM_TEXT)
    if command == "train":
        argv = ["train", str(data_a), *TRAIN, "--out", str(mine)]
    else:
        argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path), "--out", str(mine)]
    one_line_error(capsys, main(argv), f"--out {mine}", "did not write", "config.json")
    assert sorted(p.name for p in mine.iterdir()) == ["config.json", "history.csv", "run.json"]
    assert all(p.read_text() == VICTIM_TEXT for p in mine.iterdir())


def test_out_into_an_empty_folder_is_a_new_run(data_a, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["train", str(data_a), *TRAIN, "--out", str(tmp_path / "empty")]) == 0
    assert (tmp_path / "empty" / "weights.pt").is_file()


def test_an_empty_out_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["benchmark", "cascaded-tanks", "--out", ""])
    assert exit_.value.code == 2 and "expected a folder" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------------- half-written output
def test_a_window_list_with_a_bad_workers_leaves_no_folder(data_a, tmp_path, capsys):
    run = tmp_path / "sel" / "run"
    argv = ["train", str(data_a), "--window", "2,5", "--workers", "-1", "--out", str(run)]
    one_line_error(capsys, main([*argv, "--epochs", "1", "--no-progress"]), "workers")
    assert not (tmp_path / "sel").exists()


def test_the_next_writer_removes_what_a_killed_checkpoint_write_left(trained, tmp_path, capsys):
    run = _copy(trained[0], tmp_path)
    stale = run / ".checkpoint.pt.k1ll3d_9.tmp"
    stale.write_bytes(b"\0" * 4096)
    os.utime(stale, (time.time() - 60, time.time() - 60))
    victim = tmp_path / "victim"
    victim.write_text(VICTIM_TEXT)
    (run / ".weights.pt.abcdefgh.tmp").symlink_to(victim)  # not a plain file: left alone
    (run / "notes.tmp").write_text(VICTIM_TEXT)  # not the kernel's naming: left alone
    argv = [
        "train",
        "--resume",
        "--out",
        str(run),
        "--epochs",
        "3",
        "--no-progress",
        "--threads",
        "1",
    ]
    assert main(argv) == 0, capsys.readouterr().err
    assert not stale.exists()
    assert (run / ".weights.pt.abcdefgh.tmp").is_symlink() and victim.read_text() == VICTIM_TEXT
    assert (run / "notes.tmp").read_text() == VICTIM_TEXT
