"""``canonid train --window 2,5,10,20`` / ``--hidden auto``: candidates trained fully through the
job runner, the lowest validation loss kept, the table written, the chosen run the folder's
model."""

from __future__ import annotations

import dataclasses
import json

import pytest
from cli_helpers import evaluated, one_line_error
from learning_helpers import siso_dataset_file

from canonid.cli import main
from canonid.kernel.errors import CheckpointError
from canonid.profiles import train_options
from canonid.runfolder import RunRecipe
from canonid.selection import Selection, plan_candidates

FAST = ["--profile", "tiny", "--epochs", "2", "--no-progress", "--device", "cpu"]


@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("data"), T=60)


@pytest.fixture(scope="module")
def selection(dataset_path, tmp_path_factory):
    run = tmp_path_factory.mktemp("auto") / "run"
    argv = [
        "train",
        str(dataset_path),
        "--window",
        "2,5,10,20",
        "--hidden",
        "8,8",
        "--out",
        str(run),
    ]
    assert main([*argv, *FAST]) == 0
    return run


def test_the_terminal_shows_a_plain_table_naming_the_scored_split(dataset_path, tmp_path, capsys):
    argv = ["train", str(dataset_path), "--window", "2,5,10,20", "--hidden", "8,8"]
    assert main([*argv, "--out", str(tmp_path / "run"), *FAST]) == 0
    out = capsys.readouterr().out
    split = Selection.read(tmp_path / "run").candidates[0].split
    assert f"rollout MSE ({split})" in out and "|" not in out and "**" not in out, out
    assert f"rollout MSE ({split})" in (tmp_path / "run" / "candidates.md").read_text()


def test_a_window_list_keeps_the_lowest_validation_loss_and_writes_the_table(selection):
    table = Selection.read(selection)
    # T = 60: ℓ = 20 leaves 40 samples, enough for the tiny profile's rollouts of 10 and 20
    assert [c.window for c in table.candidates] == [2, 5, 10, 20]
    best = min(table.candidates, key=lambda c: c.best_val_loss)
    assert table.chosen == best.name and table.best == best
    assert all(c.hidden == [8, 8] for c in table.candidates)
    assert (selection / "candidates.md").read_text().count("**yes**") == 1
    config = json.loads((selection / "config.json").read_text())
    assert config["net"]["window"] == best.window
    recipe = json.loads((selection / "run.json").read_text())
    assert recipe["window"] == best.window
    for c in table.candidates:
        assert (selection / "candidates" / c.name / "result.json").is_file()
    assert not (selection / "checkpoint.pt").exists()  # a selection is not resumed as one run


def test_the_chosen_run_is_the_folders_model(selection, capsys):
    capsys.readouterr()
    assert main(["evaluate", str(selection)]) == 0
    metrics = evaluated(selection, capsys.readouterr().out)
    assert metrics["window"] == Selection.read(selection).best.window


def test_running_the_selection_again_reuses_every_candidate(selection, dataset_path, capsys):
    before = {p: p.stat().st_mtime_ns for p in selection.glob("candidates/*/weights.pt")}
    argv = ["train", str(dataset_path), "--window", "2,5,10,20", "--hidden", "8,8"]
    assert main([*argv, "--out", str(selection), *FAST]) == 0
    assert {p: p.stat().st_mtime_ns for p in selection.glob("candidates/*/weights.pt")} == before
    assert "chosen:" in capsys.readouterr().out


def test_hidden_auto_tries_the_width_grid(dataset_path, tmp_path):
    run = tmp_path / "widths"
    argv = ["train", str(dataset_path), "--window", "3", "--hidden", "auto", "--out", str(run)]
    assert main([*argv, *FAST, "--epochs", "1"]) == 0
    table = Selection.read(run)
    assert [c.hidden for c in table.candidates] == [[64] * 3, [128] * 3, [256] * 3]
    assert table.chosen == min(table.candidates, key=lambda c: c.best_val_loss).name


def test_combinations_that_make_no_sense_are_refused(selection, dataset_path, tmp_path, capsys):
    data = str(dataset_path)
    code = main(["train", "--resume", "--out", str(selection), "--window", "2,5", *FAST])
    one_line_error(capsys, code, "--window 2,5 does not combine with --resume")
    code = main(["train", "--resume", "--out", str(selection), *FAST])
    one_line_error(capsys, code, "holds a selection of candidates")
    code = main(["train", data, "--window", "3", "--out", str(selection), *FAST])
    one_line_error(capsys, code, "holds a selection of candidates", "another --out")
    code = main(["train", data, "--window", "3", "--workers", "2", "--out", str(tmp_path), *FAST])
    one_line_error(capsys, code, "--workers applies to a list of windows or --hidden auto only")
    code = main(["train", data, "--window", "2,5", "--model", "classic-gru", "--hidden", "auto"])
    one_line_error(capsys, code, "--hidden does not apply to classic-gru")
    argv = ["train", data, "--window", "2,5,10,20", "--hidden", "8,8", "--lr", "0.5"]
    code = main([*argv, "--out", str(selection), *FAST])
    one_line_error(capsys, code, "another recipe", "train_options")


def test_a_stored_candidate_is_keyed_on_the_datas_checksum_not_its_path(tmp_path):
    """Without training: a stored result is reused for the same contents at another path,
    and refused (not reused) once the file at the same path holds other data."""
    data = siso_dataset_file(tmp_path / "data", T=60)
    base = RunRecipe(
        data=str(data),
        model="mlp",
        window=2,
        profile="tiny",
        train_options=train_options("tiny", seed=0, device="cpu").to_dict(),
    )

    def job_for(path):
        recipe = dataclasses.replace(base, data=str(path))
        (job,) = plan_candidates(recipe, tmp_path / "run", windows=[2])
        return job

    job = job_for(data)
    job.save({"best_val_loss": 1.0})
    assert job.cached() is not None
    moved = tmp_path / "moved"
    moved.mkdir()
    for name in ("dataset.npz", "dataset.json"):
        (moved / name).write_bytes((data.parent / name).read_bytes())
    assert job_for(moved / "dataset.npz").cached() is not None  # same contents elsewhere
    siso_dataset_file(tmp_path / "data", T=61)  # other contents at the same path
    with pytest.raises(CheckpointError, match=r"another recipe \(differs in \['data_sha256'\]\)"):
        job_for(data).cached()
