"""`canonid train` and `canonid evaluate` end to end on tiny data (real training, few epochs)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_helpers import evaluated
from learning_helpers import damped_siso, siso_dataset_file, trajectories

from canonid.cli import main

KEYS = ("rollout_mse", "rmse", "nrmse", "fit_percent")


@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("data"))


def test_train_writes_a_run_folder_and_evaluate_rewrites_its_metrics(
    dataset_path, tmp_path, capsys
):
    run = tmp_path / "run"
    argv = [
        "train",
        str(dataset_path),
        "--model",
        "mlp",
        "--window",
        "3",
        "--epochs",
        "2",
        "--out",
        str(run),
        "--no-progress",
        "--device",
        "cpu",
        "--residual",
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "rollout_mse" in out and "y_clean" in out
    for name in (
        "run.json",
        "config.json",
        "weights.pt",
        "normalisation.json",
        "checkpoint.pt",
        "history.csv",
        "training_curve.png",
        "metrics.json",
        "rollouts.png",
    ):
        assert (run / name).is_file(), name
    metrics = json.loads((run / "metrics.json").read_text())
    for key in KEYS:
        assert np.isfinite(metrics[key]) and len(metrics[f"{key}_per_output"]) == 1
        assert np.isfinite(metrics["clean"][key])
    # train scores validation; the test split is evaluate's to read
    assert metrics["rollout_horizon"] == 100 and metrics["data"]["split"] == "val"
    assert metrics["n_rollouts"] == 1 * (110 - 3 - 100 + 1)  # the one validation record
    assert metrics["n_init"] == 50 and metrics["n_scored_samples"] == 1 * 60
    assert len(metrics["kstep_nrmse"]) == 100
    history = (run / "history.csv").read_text().splitlines()
    assert history[0].startswith("epoch,horizon,lr,train_loss,val_loss") and len(history) == 4
    config = json.loads((run / "config.json").read_text())
    assert config["model"] == "mlp" and config["net"]["residual"] is True

    trained = (run / "metrics.json").read_bytes()
    assert (
        main(["evaluate", str(run), "--eval-horizon", "20", "--stride", "5", "--n-init", "10"]) == 0
    )
    out = capsys.readouterr().out
    again = evaluated(run, out)
    assert (run / "metrics.json").read_bytes() == trained  # training's scores stay
    per = again["clean"]["rollout_mse_per_record"]
    worst = max(range(2), key=lambda i: per[i])
    assert "rollout_mse" in out and "largest rollout_mse per record (y_clean; of 2)" in out
    assert f"#{worst} {per[worst]:.3g}, #{1 - worst} " in out
    assert again["rollout_horizon"] == 20 and again["n_init"] == 10
    assert again["n_rollouts"] == 2 * len(range(0, 110 - 3 - 20 + 1, 5))

    # resume with more epochs continues the same run
    assert (
        main(
            [
                "train",
                "--resume",
                "--out",
                str(run),
                "--epochs",
                "3",
                "--no-progress",
                "--device",
                "cpu",
            ]
        )
        == 0
    )
    assert len((run / "history.csv").read_text().splitlines()) == 5
    capsys.readouterr()
    # a new run into a used folder, or a resume under another model, is refused in one line
    assert main(argv) == 1
    assert "already holds a training run" in capsys.readouterr().err
    assert main(["train", "--resume", "--out", str(run), "--model", "gru", "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "model: 'mlp' there, 'gru' here" in err and "Traceback" not in err
    assert main(["train", "--resume", "--out", str(run), "--lr", "0.1", "--no-progress"]) == 1
    assert "--lr cannot change when resuming" in capsys.readouterr().err


def test_train_on_csv_splits_off_validation_and_evaluates_on_it(tmp_path, capsys):
    data = trajectories(damped_siso(), 4, 110, noise=0.01, seed=9)
    folder = tmp_path / "csv"
    folder.mkdir()
    for k, tr in enumerate(data):
        rows = ["time,pump,level"] + [
            f"{t * 0.5},{float(tr.u[t, 0])!r},{float(tr.y[t, 0])!r}" for t in range(110)
        ]
        (folder / f"exp{k}.csv").write_text("\n".join(rows) + "\n")
    run = tmp_path / "run"
    csv_args = [str(folder), "--inputs", "pump", "--outputs", "level", "--no-progress"]
    common = "--window 3 --epochs 1 --device cpu".split()
    argv = ["train", *csv_args, "--dt", "0.5", "--model", "classic-gru", *common]
    assert main([*argv, "--out", str(run)]) == 0
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["data"]["split"] == "val" and metrics["data"]["n_trajectories"] == 1
    assert metrics["clean"] is None and metrics["output_names"] == ["level"]
    capsys.readouterr()
    # without --dt, the time column gives it (named 'time', so found); switched off, none does
    timed = tmp_path / "timed"
    assert main(["train", *csv_args, "--model", "mlp", *common, "--out", str(timed)]) == 0
    assert json.loads((timed / "config.json").read_text())["info"]["dt"] == 0.5
    capsys.readouterr()
    off = ["--time-column", "none", "--out", str(tmp_path / "x")]
    assert main(["train", *csv_args, "--model", "mlp", *common, *off]) == 1
    assert "need the sampling time" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--window", "200"], "no candidate window of [200] fits the records"),
        (["--window", "3", "--device", "cuda"], "CUDA is not available"),
    ],
)
def test_bad_training_requests_fail_in_one_line(dataset_path, tmp_path, capsys, extra, message):
    import torch

    if "cuda" in extra and torch.cuda.is_available():
        pytest.skip("a GPU is present")
    code = main(
        [
            "train",
            str(dataset_path),
            "--model",
            "mlp",
            "--epochs",
            "1",
            "--out",
            str(tmp_path / "r"),
            "--no-progress",
            *extra,
        ]
    )
    err = capsys.readouterr().err
    assert code == 1 and message in err and len(err.strip().splitlines()) == 1


def test_hidden_widths_are_kept_by_the_run_and_another_width_is_refused(
    dataset_path, tmp_path, capsys
):
    import shutil

    import torch

    common = ["--window", "3", "--epochs", "1", "--no-progress", "--device", "cpu"]
    base = ["train", str(dataset_path), "--model", "mlp", *common]
    run, narrow = tmp_path / "wide", tmp_path / "narrow"
    assert main([*base, "--hidden", "12,7", "--out", str(run)]) == 0
    assert json.loads((run / "run.json").read_text())["net_options"]["hidden"] == [12, 7]
    assert json.loads((run / "config.json").read_text())["net"]["hidden"] == [12, 7]
    weights = torch.load(run / "weights.pt", weights_only=True)
    layers = [tuple(v.shape) for k, v in weights.items() if k.startswith("net.") and "weight" in k]
    assert [shape[0] for shape in layers] == [12, 7, 1]  # two hidden layers, then y
    # evaluate and resume rebuild the same network from the run
    assert main(["evaluate", str(run), "--eval-horizon", "20"]) == 0
    resume = ["train", "--resume", "--out", str(run), "--no-progress", "--device", "cpu"]
    assert main([*resume, "--epochs", "2", "--hidden", "12,7"]) == 0
    capsys.readouterr()
    assert main([*resume, "--epochs", "3", "--hidden", "16,16"]) == 1
    err = capsys.readouterr().err
    assert "hidden widths: [12, 7] there, [16, 16] here" in err and "Traceback" not in err
    # weights of another width in the run folder are refused, naming the mismatch
    assert main([*base, "--hidden", "5", "--out", str(narrow)]) == 0
    shutil.copyfile(narrow / "weights.pt", run / "weights.pt")
    capsys.readouterr()
    assert main(["evaluate", str(run)]) == 1
    err = capsys.readouterr().err
    assert "weights do not fit" in err and "shape differs" in err
    assert len(err.strip().splitlines()) == 1


def test_activation_is_kept_by_the_run_and_another_is_refused(dataset_path, tmp_path, capsys):
    common = ["--window", "3", "--epochs", "1", "--no-progress", "--device", "cpu"]
    run = tmp_path / "silu"
    argv = ["train", str(dataset_path), "--model", "mlp", *common, "--out", str(run)]
    assert main([*argv, "--activation", "silu"]) == 0
    assert json.loads((run / "config.json").read_text())["net"]["activation"] == "silu"
    resume = ["train", "--resume", "--out", str(run), "--no-progress", "--device", "cpu"]
    assert main([*resume, "--epochs", "2", "--activation", "silu"]) == 0
    capsys.readouterr()
    assert main([*resume, "--epochs", "3", "--activation", "tanh"]) == 1
    err = capsys.readouterr().err
    assert "activation: silu there, tanh here" in err and "Traceback" not in err
    masti = ["train", str(dataset_path), "--model", "masti", *common, "--activation", "silu"]
    assert main([*masti, "--out", str(tmp_path / "m")]) == 1
    err = capsys.readouterr().err
    assert "--activation applies to Ours (MLP) only, not masti" in err


@pytest.mark.parametrize(
    ("model", "hidden", "message"),
    [
        ("mlp", "0,3", "--hidden: expected positive integer widths"),
        ("mlp", "2048x2", "--hidden: expected positive integer widths"),
        ("classic-gru", "8", "--hidden does not apply to classic-gru"),
    ],
)
def test_bad_hidden_widths_fail_in_one_line(dataset_path, tmp_path, capsys, model, hidden, message):
    argv = ["train", str(dataset_path), "--model", model, "--window", "3", "--hidden", hidden]
    code = main([*argv, "--out", str(tmp_path / "r"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1 and message in err and len(err.strip().splitlines()) == 1


def test_windows_per_epoch_is_kept_by_the_run_and_fixed_on_resume(dataset_path, tmp_path, capsys):
    run = tmp_path / "run"
    common = ["--window", "3", "--epochs", "1", "--no-progress", "--device", "cpu"]
    argv = ["train", str(dataset_path), "--model", "mlp", *common, "--out", str(run)]
    assert main([*argv, "--windows-per-epoch", "5"]) == 0
    recipe = json.loads((run / "run.json").read_text())
    assert recipe["train_options"]["windows_per_epoch"] == 5
    capsys.readouterr()
    resume = ["train", "--resume", "--out", str(run), "--epochs", "2", "--no-progress"]
    assert main([*resume, "--windows-per-epoch", "8"]) == 1
    assert "--windows-per-epoch cannot change when resuming" in capsys.readouterr().err
    assert main([*argv[:-1], str(tmp_path / "bad"), "--windows-per-epoch", "0"]) == 1
    err = capsys.readouterr().err
    assert "--windows-per-epoch must be an integer from 1 to" in err
    assert len(err.strip().splitlines()) == 1
    before = len((run / "history.csv").read_text().splitlines())
    assert main(resume) == 0  # no --device: the run keeps the device it recorded
    recipe = json.loads((run / "run.json").read_text())
    assert recipe["train_options"]["device"] == "cpu"
    assert len((run / "history.csv").read_text().splitlines()) == before + 1


def test_evaluate_on_the_command_line_and_in_python_score_alike(dataset_path, tmp_path, capsys):
    """One n_init rule (canonid.learning.evaluate.default_n_init): on records of 40 samples
    `canonid evaluate` and `canonid.evaluate` both start the simulation scores at sample 39
    (max(ℓ, min(50, T − 1))) and give the same numbers."""
    import canonid
    from canonid.kernel.dataset import Dataset

    run = tmp_path / "run"
    common = ["--window", "3", "--epochs", "1", "--device", "cpu", "--no-progress"]
    assert main(["train", str(dataset_path), *common, "--out", str(run)]) == 0
    short = Dataset.load(siso_dataset_file(tmp_path / "short", T=40))
    assert main(["evaluate", str(run), "--data", str(tmp_path / "short" / "dataset.npz")]) == 0
    cli = evaluated(run, capsys.readouterr().out)
    library = canonid.evaluate(
        canonid.Model.load(run), short.split("test"), horizon=cli["rollout_horizon"]
    ).to_json()
    assert cli["n_init"] == library["n_init"] == 39
    for key in KEYS:
        assert cli[key] == library[key] and cli["clean"][key] == library["clean"][key]
