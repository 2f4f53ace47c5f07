"""``canonid generate``: the dataset lands where it says, bad input is one line, exit 1."""

from __future__ import annotations

import pytest

from canonid.cli import main
from canonid.kernel.dataset import Dataset


def test_generate_tank_prints_where_the_dataset_went(tmp_path, capsys):
    out = tmp_path / "tank"
    argv = ["generate", "tank", "--out", str(out), "--n-train", "2", "--n-val", "1"]
    assert main([*argv, "--n-test", "1", "--seed", "5", "--no-progress", "--plot"]) == 0
    printed = capsys.readouterr().out
    assert f"dataset written to {(out / 'dataset.npz').resolve()}" in printed
    assert (out / "flights.png").stat().st_size > 0
    ds = Dataset.load(out)
    assert ds.counts() == {"train": 2, "val": 1, "test": 1}
    assert ds.metadata["generation"]["seed"] == 5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["tanks"], "no dataset scenario for system 'tanks'"),
        (["tank", "--n-val", "-2"], "val flights must be an integer >= 0"),
        (["tank", "--noise", "0.5"], "outside the system's noise set W"),
        (["tank", "--noise", "abc"], "--noise must be a number"),
        (["tank", "--mpc-horizon", "10"], "do not apply to tank"),
        (["drone2d", "--mpc-horizon", "0"], "horizon must be an integer >= 1"),
        (["tank", "--noise", "0,0"], "one half-width >= 0 or 1 of them"),
        (["tank", "--scheduler", "tcp://127.0.0.1:1"], "refused the connection"),
    ],
)
def test_bad_input_is_one_line(args, message, tmp_path, capsys):
    assert main(["generate", *args, "--out", str(tmp_path / "x"), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()  # nothing half-written


def test_a_dataset_without_test_flights_trains_and_scores_on_validation(tmp_path, capsys):
    data, run = tmp_path / "tank", tmp_path / "run"
    argv = ["generate", "tank", "--out", str(data), "--n-train", "2", "--n-val", "1"]
    assert main([*argv, "--n-test", "0", "--seed", "5", "--no-progress"]) == 0
    assert Dataset.load(data).counts()["test"] == 0
    train = ["train", str(data), "--window", "3", "--epochs", "1", "--hidden", "8"]
    assert main([*train, "--cubic", "0", "--no-progress", "--out", str(run)]) == 0
    printed = capsys.readouterr().out
    assert f"on {data} [val]" in printed  # the empty test split is not the one scored
    assert main(["evaluate", str(run)]) == 0
    assert "[val]" in capsys.readouterr().out
