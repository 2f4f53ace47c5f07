"""Files written before the single namespace still load and give the numbers they gave.

``tests/fixtures/pre-namespace`` holds a dataset, a run folder of Ours (MLP) with its checkpoint,
an Ours (GRU) model folder and a CSV, all written by commit 2bf4f1d, and ``expected.json``: what
that code computed from them (its README says how). The tests work on a copy (evaluate, resume
and export write into the run folder) with the copy as working folder, as the run's ``run.json``
names its data relative to the folder it was trained from.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import casadi
import numpy as np
import pytest
from cli_helpers import evaluated

from canonid import Dataset, Model
from canonid.cli import main

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "pre-namespace"
EXPECTED = json.loads((FIXTURES / "expected.json").read_text(encoding="utf-8"))
CSV_OPTIONS = ["--inputs", "u", "--outputs", "y", "--dt", "1", "--experiment-column", "run"]
#: same weights, same data and the same arithmetic: equal up to the order of floating-point
#: operations (the numbers agree to the last bit on the machine that wrote the fixtures)
RTOL = 1e-9
#: the networks' float32 arithmetic: the CPU's matrix kernels differ between CPUs (an AMD EPYC
#: reproduces the fixtures' predictions to 1.7e-6 and their scores to 5e-9, relative)
RTOL_NETWORK = 1e-5


@pytest.fixture
def old(tmp_path, monkeypatch):
    copy = shutil.copytree(
        FIXTURES, tmp_path / "pre-namespace", ignore=shutil.ignore_patterns("*.py", "*.sh", "*.md")
    )
    monkeypatch.chdir(copy)
    return copy


def test_the_dataset_loads_with_its_checksum_and_its_arrays(old):
    expected = EXPECTED["dataset"]
    data = Dataset.load(old / "data")  # validates the checksum of dataset.json against the file
    header = json.loads((old / "data" / "dataset.json").read_text(encoding="utf-8"))
    assert header["checksum_sha256"] == expected["checksum_sha256"]
    digest = hashlib.sha256((old / "data" / "dataset.npz").read_bytes()).hexdigest()
    assert digest == expected["file_sha256"] == expected["checksum_sha256"]
    for name, split in expected["splits"].items():
        trajectories = data.split(name)
        assert len(trajectories) == split["n"]
        assert [len(t.u) for t in trajectories] == [len(t.y) for t in trajectories] == split["T"]
        assert float(sum(t.u.sum() for t in trajectories)) == split["sum_u"]
        assert float(sum(t.y.sum() for t in trajectories)) == split["sum_y"]


@pytest.mark.parametrize("name, folder", [("mlp", "runs/mlp"), ("gru", "gru-model")])
def test_saved_models_predict_what_they_predicted(old, name, folder):
    expected = EXPECTED["predictions"][name]
    model = Model.load(old / folder)
    assert model.window == expected["window"]
    test = Dataset.load(old / "data").split("test")[0]
    y = model.simulate(test.u, test.y[: model.window])
    np.testing.assert_allclose(y[:, 0], expected["y"], rtol=RTOL_NETWORK, atol=0)


@pytest.mark.parametrize("data", ["dataset", "csv"])
def test_evaluate_scores_the_old_run_as_the_old_code_did(old, data, capsys):
    argv = ["--data", "data"] if data == "dataset" else ["--data", "tank.csv", *CSV_OPTIONS]
    trained = (old / "runs" / "mlp" / "metrics.json").read_bytes()
    assert main(["evaluate", "runs/mlp", *argv]) == 0, capsys.readouterr().err
    metrics = evaluated(Path("runs/mlp"), capsys.readouterr().out)
    assert (old / "runs" / "mlp" / "metrics.json").read_bytes() == trained
    expected = EXPECTED["evaluate"][data]
    assert metrics["data"]["n_trajectories"] == expected["n_trajectories"]
    for key in ("rollout_mse", "rmse", "nrmse", "fit_percent"):
        assert metrics[key] == pytest.approx(expected[key], rel=RTOL_NETWORK), key


def test_training_resumes_from_the_old_checkpoint(old, capsys):
    before = (old / "runs" / "mlp" / "history.csv").read_text(encoding="utf-8").splitlines()
    argv = ["train", "--resume", "runs/mlp", "--epochs", "4", "--threads", "1", "--no-progress"]
    assert main(argv) == 0, capsys.readouterr().err
    after = (old / "runs" / "mlp" / "history.csv").read_text(encoding="utf-8").splitlines()
    assert after[: len(before)] == before  # the old epochs are kept as they were
    assert [row.split(",")[0] for row in after[1:]] == ["0", "1", "2", "3", "4"]
    recipe = json.loads((old / "runs" / "mlp" / "run.json").read_text(encoding="utf-8"))
    assert recipe["train_options"]["epochs"] == 4
    assert Model.load(old / "runs" / "mlp").window == 2


def test_export_writes_the_function_the_old_code_wrote(old, capsys):
    target = old / "export" / "mlp.casadi"
    assert main(["export", "runs/mlp", "--casadi", str(target)]) == 0, capsys.readouterr().err
    expected = EXPECTED["export"]
    description = json.loads(target.with_name("mlp.casadi.json").read_text(encoding="utf-8"))
    assert description["states"] == expected["states"]
    for name, box in expected["sets"].items():
        for side in ("lower", "upper"):
            np.testing.assert_allclose(description[name][side], box[side], rtol=RTOL, atol=0)
    out = casadi.Function.load(str(target))(x=expected["x"], u=expected["u"])
    for key in ("x_next", "y"):
        np.testing.assert_allclose(out[key].full().ravel(), expected[key], rtol=RTOL, atol=0)
