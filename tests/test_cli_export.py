"""`canonid export RUN --casadi FILE` end to end on tiny data, as a user types it: the file
loads in a fresh process and gives the torch model's numbers; refused inputs say why."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from learning_helpers import damped_siso, trajectories

from canonid.cli import main
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import DataError
from canonid.learning import Model
from canonid.models.learned import load_function

COMMON = ["--epochs", "1", "--no-progress", "--device", "cpu"]
ELL = 3


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A dataset (noise box in its metadata) and runs of Ours (MLP), its reduced model and
    Classic GRU, ℓ = 3."""
    root = tmp_path_factory.mktemp("export")
    system = damped_siso()
    make = lambda n, seed: tuple(  # noqa: E731
        Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)
        for t in trajectories(system, n, 110, noise=0.01, seed=seed)
    )
    ds = Dataset(
        splits={"train": make(2, 1), "val": make(1, 2), "test": make(1, 3)},
        dt=0.5,
        input_names=("pump",),
        output_names=("level",),
        metadata={
            "noise": {"box": {"lower": [-0.01], "upper": [0.01]}},
            "units": {"inputs": {"pump": "V"}, "outputs": {"level": "m"}},
        },
    )
    data = ds.save(root / "data" / "dataset.npz")
    for model, extra in (("mlp", ["--residual", "--hidden", "8,8"]), ("classic-gru", [])):
        argv = ["train", str(data), "--model", model, "--window", str(ELL), *extra]
        assert main([*argv, "--out", str(root / model), *COMMON]) == 0
    reduce = ["reduce", str(root / "mlp"), "--compression", "0.5", "--out", str(root / "red")]
    assert main([*reduce, *COMMON]) == 0
    return root


FRESH = """
import sys, json, casadi as ca, numpy as np
f = ca.Function.load(sys.argv[1])
x, u = np.array(json.loads(sys.argv[2])), np.array(json.loads(sys.argv[3]))
x_next, y = f(x, u)
print(json.dumps([np.asarray(x_next).ravel().tolist(), np.asarray(y).ravel().tolist()]))
"""


def _fresh_process(path, x, u):
    res = subprocess.run(
        [sys.executable, "-c", FRESH, str(path), json.dumps(x.tolist()), json.dumps(u.tolist())],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    x_next, y = json.loads(res.stdout)
    return np.array(x_next), np.array(y)


def test_exported_mlp_loads_in_a_fresh_process_with_the_same_numbers(runs, tmp_path, capsys):
    target = tmp_path / "out" / "tank.casadi"
    assert main(["export", str(runs / "mlp"), "--casadi", str(target)]) == 0
    printed = capsys.readouterr().out
    assert "9 states" not in printed and f"{ELL * 2} states" in printed
    meta = json.loads((target.parent / "tank.casadi.json").read_text())
    assert meta["dt"] == 0.5 and meta["window"] == ELL and meta["n_x"] == ELL * 2
    assert meta["inputs"] == ["pump [V]"] and meta["W"] == {"lower": [-0.01], "upper": [0.01]}
    assert meta["states"][-1] == "level[t-1] [m]"

    model = Model.load(runs / "mlp").export()
    rng = np.random.default_rng(0)
    z = rng.uniform(-1, 1, size=ELL * 2)
    u = rng.uniform(-1, 1, size=1)
    x_next, y = _fresh_process(target, z, u)
    np.testing.assert_allclose(y, model.H(z, u), rtol=0, atol=1e-9)
    np.testing.assert_allclose(x_next, np.concatenate([z[2:], u, y]), rtol=0, atol=1e-12)
    # the loader used by the docs gives the same function
    f = load_function(target)
    np.testing.assert_array_equal(np.asarray(f(z, u)[1]).ravel(), y)


def test_exported_reduced_model_comes_with_its_encoder(runs, tmp_path, capsys):
    target = tmp_path / "red.casadi"
    assert main(["export", str(runs / "red"), "--casadi", str(target)]) == 0
    assert "red.encoder.casadi" in capsys.readouterr().out
    model = Model.load(runs / "red").export()
    z = np.random.default_rng(1).uniform(-1, 1, size=ELL * 2)
    u = np.array([0.3])
    x = np.asarray(load_function(tmp_path / "red.encoder.casadi")(z)).ravel()
    np.testing.assert_allclose(x, model.encode(z), rtol=0, atol=1e-9)
    x_next, y = _fresh_process(target, x, u)
    np.testing.assert_allclose(y, model.H(z, u), rtol=0, atol=1e-9)
    np.testing.assert_allclose(x_next, model.step(x, u), rtol=0, atol=1e-9)


def test_a_non_canonical_model_is_refused_in_one_line(runs, tmp_path, capsys):
    target = tmp_path / "gru.casadi"
    assert main(["export", str(runs / "classic-gru"), "--casadi", str(target)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "only canonical models export" in err and "Classic GRU ('classic-gru')" in err
    assert not target.exists() and not list(tmp_path.iterdir())


def test_a_file_name_without_the_suffix_is_refused(runs, tmp_path, capsys):
    assert main(["export", str(runs / "mlp"), "--casadi", str(tmp_path / "model.txt")]) == 1
    assert "ending in .casadi" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("run", "in_the_way"),
    [("mlp", "m.casadi.json"), ("red", "m.casadi.json"), ("red", "m.encoder.casadi")],
)
def test_an_output_that_is_a_folder_is_refused_before_any_file_is_written(
    runs, tmp_path, capsys, run, in_the_way
):
    (tmp_path / in_the_way).mkdir()
    code = main(["export", str(runs / run), "--casadi", str(tmp_path / "m.casadi")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{tmp_path / in_the_way} is a folder" in err
    assert [p.name for p in tmp_path.iterdir()] == [in_the_way]  # no .casadi without its JSON


def test_a_failed_later_write_removes_the_files_written_before(runs, tmp_path, monkeypatch):
    import canonid.learned as learned
    from canonid.kernel.errors import OutputError

    def full_disk(path, body):
        raise OutputError(f"cannot write {path}: No space left on device")

    monkeypatch.setattr(learned, "atomic_write_json", full_disk)
    with pytest.raises(OutputError, match="No space left"):
        learned.export_casadi(runs / "red", tmp_path / "m.casadi")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("content", [b"hello", b"", bytes(range(256)) * 4])
def test_a_file_that_is_not_a_casadi_function_is_refused(tmp_path, content):
    path = tmp_path / "bad.casadi"
    path.write_bytes(content)
    with pytest.raises(DataError, match=r"bad.casadi is not a serialised CasADi Function"):
        load_function(path)
    with pytest.raises(DataError, match="no such file"):
        load_function(tmp_path / "missing.casadi")


def test_analyze_run_reports_the_learned_models_gamma_beside_the_true_systems(
    runs, tmp_path, capsys
):
    # the run must be of data of `linear` (its names u1/y1 and dt = 1 s): trained here on those
    ds = Dataset.load(runs / "data" / "dataset.npz")
    ds = Dataset(splits=ds.splits, dt=1.0, input_names=("u1",), output_names=("y1",))
    data = ds.save(tmp_path / "linear" / "dataset.npz")
    run = tmp_path / "linear-mlp"
    train = ["train", str(data), "--model", "mlp", "--window", str(ELL), "--residual"]
    # the plain network: a cubic branch has no layer-norm bound on the whole space
    train += ["--cubic", "0"]
    assert main([*train, "--hidden", "8,8", "--out", str(run), *COMMON]) == 0
    capsys.readouterr()
    out = tmp_path / "analysis"
    argv = ["analyze", "linear", "--window", "3", "--trials", "5", "--budget", "30"]
    argv += ["--boxes", "40", "--run", str(run), "--learned-gamma"]
    argv += ["--out", str(out), "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "γ_f at ℓ = 3: true system [" in printed
    assert "γ_f of the learned model (its state z, dim 6" in printed
    gamma = json.loads((out / "analysis.json").read_text())["learned"]["gamma_f"]
    lower = gamma["lower"]["value"]
    assert gamma["lower"]["kind"] == "lower" and gamma["branch_and_bound"]["kind"] == "upper"
    assert lower <= gamma["branch_and_bound"]["value"] and lower <= gamma["layer_norms"]["value"]
    assert gamma["best_upper"] == min(
        gamma["branch_and_bound"]["value"], gamma["layer_norms"]["value"]
    )
    assert "product of layer norms" in gamma["layer_norms"]["method"]
    # a finite layer-norm bound: the printed line as before, without a reason
    bound = gamma["layer_norms"]["value"]
    assert f"{bound:.4g} (product of layer norms, loose); so γ_f ≤ " in printed
    assert "unbounded" not in gamma["layer_norms"]["details"]
    # a non-canonical model: the residual check as before, γ_f says why it is missing
    gru = tmp_path / "linear-gru"
    train = ["train", str(data), "--model", "classic-gru", "--window", str(ELL), "--out", str(gru)]
    assert main([*train, *COMMON]) == 0
    capsys.readouterr()
    argv[argv.index(str(run))] = str(gru)
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "not computed (only canonical models export" in printed, printed


def _python_blocks(markdown: str) -> list[str]:
    parts = markdown.split("```python\n")[1:]
    return [part.split("```", 1)[0] for part in parts]


@pytest.mark.slow
def test_the_docs_examples_run(runs, tmp_path):
    """docs/casadi-export.md: the MPC step on the exported file (CasADi only, in a fresh
    process) and the recipe inside canonid, exactly as written (the run path replaced)."""
    from pathlib import Path

    docs = (Path(__file__).resolve().parents[1] / "docs" / "casadi-export.md").read_text()
    standalone, inside = _python_blocks(docs)
    assert main(["export", str(runs / "mlp"), "--casadi", str(tmp_path / "tank.casadi")]) == 0
    (tmp_path / "step.py").write_text(standalone)
    res = subprocess.run(
        [sys.executable, "step.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.startswith("apply u = [")
    code = inside.replace('"runs/mlp-l5"', repr(str(runs / "mlp")))
    res = subprocess.run(
        [sys.executable, "-c", code],
        cwd=Path(__file__).resolve().parents[1],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert "apply u = [" in res.stdout


def test_several_runs_export_as_their_mean(runs, tmp_path, capsys):
    """`canonid export RUN RUN`: one function whose output is the mean of the runs' (another
    seed of the same recipe), the runs named in the description; a run of another window or a
    non-canonical model is refused in one line, before anything is written."""
    data = runs / "data" / "dataset.npz"
    second = tmp_path / "mlp-seed1"
    argv = ["train", str(data), "--model", "mlp", "--window", str(ELL), "--residual"]
    assert main([*argv, "--hidden", "8,8", "--seed", "1", "--out", str(second), *COMMON]) == 0
    capsys.readouterr()
    target = tmp_path / "mean.casadi"
    assert main(["export", str(runs / "mlp"), str(second), "--casadi", str(target)]) == 0
    assert "the mean of 2 mlp models" in capsys.readouterr().out
    meta = json.loads((tmp_path / "mean.casadi.json").read_text())
    assert (
        meta["members"] == [str(runs / "mlp"), str(second)] and meta["parameters"]["members"] == 2
    )
    rng = np.random.default_rng(2)
    z, u = rng.uniform(-1, 1, size=ELL * 2), rng.uniform(-1, 1, size=1)
    mean = (Model.load(runs / "mlp").export().H(z, u) + Model.load(second).export().H(z, u)) / 2
    x_next, y = _fresh_process(target, z, u)
    np.testing.assert_allclose(y, mean, rtol=0, atol=1e-9)
    np.testing.assert_allclose(x_next, np.concatenate([z[2:], u, y]), rtol=0, atol=1e-12)

    other = tmp_path / "mlp-l2"
    argv[argv.index(str(ELL))] = "2"
    assert main([*argv, "--hidden", "8,8", "--out", str(other), *COMMON]) == 0
    capsys.readouterr()
    for run, says in (
        (other, "window ℓ = 2, the first run's is 3"),
        (runs / "classic-gru", "only canonical models export"),
    ):
        bad = tmp_path / "bad" / "m.casadi"
        assert main(["export", str(runs / "mlp"), str(run), "--casadi", str(bad)]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and says in err and "Traceback" not in err
        assert not bad.parent.exists()
