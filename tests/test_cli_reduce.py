"""`canonid reduce` end to end on tiny data: one reduction read back by `canonid evaluate`,
resume, refused inputs, and a small compression sweep (serial, and on local processes)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import evaluated
from learning_helpers import damped_siso, trajectories

from canonid.cli import main
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.learning import Model
from canonid.reduction import SweepPlan, compression_sweep

COMMON = ["--epochs", "2", "--no-progress", "--device", "cpu"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A dataset and two trained runs on it: Ours (MLP) ℓ = 3 and Masti et al. ℓ = 3."""
    root = tmp_path_factory.mktemp("reduce")
    system = damped_siso()
    make = lambda n, seed: tuple(  # noqa: E731
        Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)
        for t in trajectories(system, n, 110, noise=0.01, seed=seed)
    )
    ds = Dataset(
        splits={"train": make(3, 1), "val": make(1, 2), "test": make(2, 3)},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
    )
    data = ds.save(root / "data" / "dataset.npz")
    for model in ("mlp", "masti"):
        argv = ["train", str(data), "--model", model, "--window", "3", "--out", str(root / model)]
        assert main([*argv, *COMMON]) == 0
    return root


def test_reduce_writes_a_run_folder_that_evaluate_reads(runs, tmp_path, capsys):
    out = tmp_path / "red"
    argv = ["reduce", str(runs / "mlp"), "--compression", "0.5", "--out", str(out), *COMMON]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "n̄ = 4 of dim z = 6" in printed and "ratio" in printed
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
        "reduction.json",
        "reduced_vs_full.png",
    ):
        assert (out / name).is_file(), name
    result = json.loads((out / "reduction.json").read_text())
    assert (result["latent_dim"], result["state_dim"], result["compression"]) == (4, 6, 0.5)
    # the printed line names the split the scores come from
    assert f"rollout MSE on the {result['split']} split" in printed
    assert result["split"] == json.loads((out / "metrics.json").read_text())["data"]["split"]
    recipe = json.loads((out / "run.json").read_text())
    assert recipe["reduction_options"]["linear_skip"] is True  # the quick profile's
    assert Model.load(out).net.linear_skip
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["model"] == "reduced" and metrics["rollout_horizon"] == 100
    assert metrics["rollout_mse"] == pytest.approx(result["rollout_mse"])
    # the full model's figure is its own evaluation on the same rollouts (train scored its
    # validation split; the reduction scores the test split)
    import canonid

    test = Dataset.load(runs / "data" / "dataset.npz").split(result["split"])
    full = canonid.evaluate(Model.load(runs / "mlp"), test, horizon=100).to_json()
    assert result["full_rollout_mse"] == pytest.approx(full["rollout_mse"], rel=1e-6)

    capsys.readouterr()
    assert main(["evaluate", str(out)]) == 0
    again = evaluated(out, capsys.readouterr().out)
    assert again["rollout_mse"] == pytest.approx(metrics["rollout_mse"], rel=1e-12)

    # an existing run is not overwritten; --resume continues it to more epochs
    assert main(argv) == 1
    assert "already holds a reduction run" in capsys.readouterr().err
    resume = ["reduce", str(runs / "mlp"), "--compression", "0.5", "--out", str(out), "--resume"]
    assert main([*resume, "--epochs", "3", "--no-progress", "--device", "cpu"]) == 0
    assert len((out / "history.csv").read_text().splitlines()) == 1 + 4  # header, epochs 0 … 3
    assert main([*resume[:3], "0.6", *resume[4:], "--no-progress"]) == 1
    assert "does not match: compression: 0.5 there, 0.6 here" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--compression", "1.5"], "strictly between 0 and 1"),
        (["--compression", "60"], "strictly between 0 and 1"),
        (["--compression", "0"], "strictly between 0 and 1"),
    ],
)
def test_bad_rates_are_refused(runs, tmp_path, capsys, extra, message):
    assert main(["reduce", str(runs / "mlp"), *extra, "--out", str(tmp_path / "x"), *COMMON]) == 1
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_non_canonical_runs_and_bad_arguments_are_refused(runs, tmp_path, capsys):
    argv = ["reduce", str(runs / "masti"), "--compression", "0.5", "--out", str(tmp_path / "m")]
    assert main([*argv, *COMMON]) == 1
    err = capsys.readouterr().err
    assert "only canonical models can be reduced" in err and "Masti et al. ('masti')" in err
    assert main(["reduce", str(runs / "mlp"), str(runs / "mlp"), "--compression", "0.5"]) == 1
    assert "--compression reduces one RUN" in capsys.readouterr().err
    sweep = ["reduce", str(runs / "mlp"), str(runs / "masti"), "--sweep", "--rates", "0.5"]
    assert main([*sweep, "--out", str(tmp_path / "s"), *COMMON]) == 1
    assert "only canonical models" in capsys.readouterr().err
    assert main(["reduce", str(runs / "mlp"), "--sweep", "--rates", "0.5,1.2", *COMMON]) == 1
    assert "strictly between 0 and 1" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: one mode is required
        main(["reduce", str(runs / "mlp")])


def test_sweep_writes_results_and_figures_and_reuses_finished_jobs(runs, tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["reduce", str(runs / "mlp"), "--sweep", "--rates", "0.3,0.6", "--seeds", "2"]
    argv += ["--no-linear-skip"]  # the paper's plain MLPs
    assert main([*argv, "--out", str(out), *COMMON]) == 0
    printed = capsys.readouterr().out
    assert "| mlp | 3 | 30% | 5 / 6 |" in printed and "| mlp | 3 | 60% | 3 / 6 |" in printed
    sweep = json.loads((out / "sweep.json").read_text())
    results = sweep["results"]
    assert [(r["compression"], r["seed"], r["latent_dim"]) for r in results] == [
        (0.3, 0, 5),
        (0.3, 1, 5),
        (0.6, 0, 3),
        (0.6, 1, 3),
    ]
    for r in results:  # each job is a full reduction run that evaluate can read
        net = Model.load(r["out"]).net
        assert net.latent_dim == r["latent_dim"] and not net.linear_skip
    rows = {row["compression"]: row for row in sweep["summary"]}
    recon = [r["reconstruction_mse"] for r in results]
    assert rows[0.3]["reconstruction_mse_mean"] == pytest.approx(np.mean(recon[:2]))
    assert rows[0.6]["rollout_mse_std"] == pytest.approx(
        np.std([r["rollout_mse"] for r in results[2:]])
    )
    assert (out / "heatmap.png").stat().st_size > 0 and (out / "reduced_mse.png").is_file()
    # seeds change the auto-encoder
    assert results[0]["reconstruction_mse"] != results[1]["reconstruction_mse"]

    # a second run reuses the finished jobs (nothing retrained)
    stamps = {r["out"]: (Path(r["out"]) / "weights.pt").stat().st_mtime_ns for r in results}
    assert main([*argv, "--out", str(out), *COMMON]) == 0
    assert stamps == {o: (Path(o) / "weights.pt").stat().st_mtime_ns for o in stamps}


@pytest.mark.slow
def test_sweep_on_local_processes_gives_the_serial_results(runs, tmp_path):
    plan = SweepPlan(
        runs=(str(runs / "mlp"),),
        out=str(tmp_path / "serial"),
        rates=(0.5,),
        seeds=(0, 1),
        epochs=2,
    )
    serial = compression_sweep(plan, progress=False)
    parallel = compression_sweep(
        dataclasses.replace(plan, out=str(tmp_path / "dask")), workers=2, progress=False
    )
    for a, b in zip(serial.results, parallel.results):
        assert (a.latent_dim, a.seed) == (b.latent_dim, b.seed)
        assert a.reconstruction_mse == b.reconstruction_mse
        assert a.rollout_mse == b.rollout_mse


def test_the_sweep_module_imports_on_its_own():
    """Dask workers unpickle the job function by importing canonid.reduction first."""
    import subprocess
    import sys

    code = "import canonid.reduction as r; print(r.run_reduction_job.__name__)"
    res = subprocess.run(
        [sys.executable, "-c", code],
        cwd=Path(__file__).resolve().parents[1],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr[-2000:]
