"""``canonid analyze``: the files it writes, their schema, and readable errors."""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pytest

from canonid.analysis.linear import canonical_regressor
from canonid.cli import main
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import OptionError
from canonid.models.registry import get_system
from canonid.runfolder import RunRecipe
from canonid.theory import parse_box, parse_windows

TANK_SETS = ["--X", "0.05:5,0.05:5", "--U", "1:3"]


def test_analyze_tank_writes_json_table_and_figure(tmp_path, capsys):
    """Every search is bounded in boxes, the clock out of reach, so the numbers do not depend on
    the machine's load (α_2's pair search reaches its tolerance within the box budget)."""
    out = tmp_path / "run"
    code = main(
        [
            "analyze",
            "tank",
            "--windows",
            "1-2",
            "--trials",
            "40",
            "--boxes",
            "4000",
            "--budget",
            "3600",
            *TANK_SETS,
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "γ_f lower" in printed and "analysis written to" in printed
    data = json.loads((out / "analysis.json").read_text())
    assert data["schema"]["name"] == "canonid.analysis" and data["windows"] == [1, 2]
    quantities = {(e["quantity"], e["kind"]) for e in data["estimates"]}
    assert quantities == {
        (q, k) for q in ("gamma_f", "gamma_h", "alpha") for k in ("lower", "upper")
    }
    for record in data["estimates"]:
        assert set(record) >= {"quantity", "window", "value", "kind", "method", "seconds"}
        assert record.get("details", {}).get("stop") != "time budget exhausted"
    checks = {c["window"]: c for c in data["bound_checks"]}
    assert set(checks) == {1, 2}
    for c in checks.values():
        assert set(c) >= {
            "window",
            "trials",
            "violations",
            "solver_failures",
            "max_ratio",
            "constants",
        }
        assert c["violations"] == 0 and c["trials"] == 40
    assert checks[1]["max_ratio"] is None  # α_1 = 0: the bound is infinite
    assert checks[2]["max_ratio"] <= 1.0
    assert (out / "bound_vs_window.png").stat().st_size > 1000


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--window", "0"], "--window must be an integer >= 1"),
        (["--windows", "0-2"], "windows must be integers >= 1"),
        (["--window", "2", "--X", "5:0.05,0.05:5"], "lower > upper"),
        (["--window", "2", "--X", "0.05:5"], None),  # one pair broadcasts: accepted
        (["--window", "1", "--X", "0:5,0.05:5", "--trials", "0"], "unbounded"),
        (["--window", "2", "--U", "1:3,1:3"], "needs 1"),
    ],
)
def test_bad_arguments_are_one_line_errors(argv, message, tmp_path, capsys):
    if message is None:
        assert parse_box("0.05:5", 2, "X").lo.tolist() == [0.05, 0.05]
        return
    code = main(
        ["analyze", "tank", *argv, "--budget", "1", "--out", str(tmp_path), "--no-progress"]
    )
    err = capsys.readouterr().err
    assert code == 1 and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_run_checks_a_trained_model_through_its_numpy_export(tmp_path, capsys, monkeypatch):
    """A stand-in for canonid.learning.Model with the export contract of the identification layer:
    ``Model.load(run)`` has ``info`` and ``export()``, with ``H(z, u)``, ``window``, ``n_u`` and
    ``n_y``. Its H is the exact canonical
    map of the linear system, so every residual is within the noise-induced level."""
    system = get_system("linear")
    window = 2
    rng = np.random.default_rng(0)
    splits = {}
    for split, count in (("train", 3), ("test", 2)):
        trajs = []
        for _ in range(count):
            u = rng.uniform(-0.05, 0.05, size=(60, 1))
            sim = system.simulate(rng.uniform(-0.3, 0.3, size=2), u)
            w = rng.uniform(system.W.lo, system.W.hi, size=sim.y.shape)
            trajs.append(Trajectory(u=u, y=sim.y + w, y_clean=sim.y, x=sim.x))
        splits[split] = tuple(trajs)
    data = Dataset(
        splits, dt=1.0, input_names=("u1",), output_names=("y1",), state_names=("x1", "x2")
    ).save(tmp_path / "data.npz")
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    RunRecipe(data=str(data), model="mlp", window=window, train_options={}).write(run_dir)

    class Exported:
        def __init__(self):
            self.window, self.n_u, self.n_y = window, system.n_u, system.n_y
            self.H = canonical_regressor(system, window)

    class Model:
        @staticmethod
        def load(folder):
            assert folder == run_dir
            return types.SimpleNamespace(export=Exported, info={"dt": 1.0})

    fake = types.ModuleType("canonid.learning")
    fake.Model = Model
    # canonid.learned binds Model when first imported: import the real one first, so that the
    # test's own import (under the fake) is undone with the fake and later tests see the real one
    import canonid
    import canonid.learned

    monkeypatch.setattr(canonid, "learned", canonid.learned)
    monkeypatch.delitem(sys.modules, "canonid.learned")
    monkeypatch.setitem(sys.modules, "canonid.learning", fake)
    import canonid.runfolder  # the run's model is read through its checks against run.json

    monkeypatch.setattr(canonid.runfolder, "load_run_model", Model.load)
    out = tmp_path / "out"
    code = main(
        [
            "analyze",
            "linear",
            "--window",
            "3",
            "--trials",
            "20",
            "--budget",
            "1",
            "--run",
            str(run_dir),
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "learned model" in printed
    learned = json.loads((out / "analysis.json").read_text())["learned"]
    assert learned["window"] == window and learned["data"] == str(data)
    res = learned["residual"]
    assert res["rows"] == 2 * (60 - window) and res["within"] == res["rows"]
    assert learned["probe"]["test_rows"] == 2 * (60 - window)


def test_window_parsing():
    assert parse_windows("1-4") == [1, 2, 3, 4]
    assert parse_windows("2,5,10") == [2, 5, 10]
    with pytest.raises(OptionError):
        parse_windows("a-b")


@pytest.mark.slow
def test_quadrotor_analysis_keeps_to_its_box_budget_and_says_what_is_out_of_reach(tmp_path, capsys):
    """13 states: every certified search stops at --boxes (the time budget is set out of the
    way, so the work done does not depend on the machine); the sampled bounds and the
    Monte-Carlo check are there; the output says which certified bounds are out of reach."""
    boxes, out = 64, tmp_path / "quad"
    argv = ["analyze", "quadrotor", "--windows", "1-4", "--trials", "3", "--budget", "3600"]
    assert main([*argv, "--boxes", str(boxes), "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "Certified bounds out of reach:" in printed and "why (quadrotor)" in printed
    data = json.loads((out / "analysis.json").read_text())
    # one round of children (2 × 64 for the hulls, 2 × 32 for γ) may follow the last check
    for step in data["reach"]["steps"]:
        assert boxes <= step["boxes"] <= boxes + 128 and step["stop"] == "box budget exhausted"
    certified = [e for e in data["estimates"] if "boxes" in e["details"]]
    assert certified and all(e["details"]["boxes"] <= boxes + 64 for e in certified)
    by = {(e["quantity"], e["kind"], e["window"]): e for e in data["estimates"]}
    for ell in range(1, 5):
        # sampled bounds, always: γ_f from below, α_ℓ from above
        assert by["gamma_f", "lower", ell]["value"] > 0
        assert by["alpha", "upper", ell]["value"] is not None
        # α_ℓ = 0 exactly: the IMU does not see the position
        low = by["alpha", "lower", ell]
        assert low["value"] == 0 and "does not depend on px, py, pz" in low["method"]
    # interval wrapping: at this budget the hull H_4 overflows (γ_h for ℓ = 4 lives on it) and
    # H_3 is already too large for a finite γ_f bound; both get the trivial bound ∞ (null)
    assert data["reach"]["unbounded"].startswith("H_4 ") and data["hulls"]["4"] is not None
    for quantity in ("gamma_f", "gamma_h"):
        trivial = by[quantity, "upper", 4]
        assert trivial["value"] is None and trivial["method"].startswith("trivial")
    assert {c["window"]: c["trials"] for c in data["bound_checks"]} == {1: 3, 2: 3, 3: 3, 4: 3}
    text = " ".join(data["limitations"])
    assert "α_ℓ = 0 exactly for ℓ ∈ {1, 2, 3, 4}" in text and "quaternion" in text
    assert "no finite certified upper bound" in text
