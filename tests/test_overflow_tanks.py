"""Cascaded tanks with overflow: the closed-form equilibria below and at the rim, the rim and the
sensor as hard caps, water conserved, the discretisation's convergence, and the benchmark-shaped
scenario (one training and one test record, validation the training record's tail, same seed →
same bytes); benchmarks/bench_overflow_tanks.py's refusal to train without its records."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.cli import main
from canonid.datagen.generate import GenerationConfig, generate_dataset
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import SetError, ShapeError
from canonid.models import OverflowTanks, get_system

TANKS = OverflowTanks()
levels = st.tuples(st.floats(0.0, TANKS.top), st.floats(0.0, 20.0))
voltages = st.floats(0.0, 10.0)


def _settle(system: OverflowTanks, u: float, steps: int = 600) -> np.ndarray:
    """The state after ``steps`` samples of constant ``u`` from (1, 1)."""
    return system.simulate([1.0, 1.0], np.full((steps, 1), u)).x_final


@given(u=st.floats(0.5, 6.0))
@settings(max_examples=15, deadline=None)
def test_below_the_rim_the_levels_settle_at_the_closed_form(u):
    k1, k2, k3, k4 = TANKS.k
    x1 = (k4 * u / k1) ** 2
    assert TANKS.equilibrium(u) == pytest.approx((x1, (k2 / k3) ** 2 * x1), rel=1e-12)
    np.testing.assert_allclose(TANKS.step(TANKS.equilibrium(u), [u]), TANKS.equilibrium(u))
    np.testing.assert_allclose(_settle(TANKS, u), TANKS.equilibrium(u), rtol=1e-6, atol=1e-6)
    assert float(TANKS.spill(TANKS.equilibrium(u), [u])) == 0.0


@given(u=st.floats(6.5, 10.0))
@settings(max_examples=15, deadline=None)
def test_at_the_rim_the_spill_feeds_the_lower_tank_as_the_closed_form_says(u):
    k1, k2, k3, k4 = TANKS.k
    spill = k4 * u - k1 * math.sqrt(TANKS.top)
    x2 = ((k2 * math.sqrt(TANKS.top) + TANKS.spill_fraction * spill) / k3) ** 2
    assert TANKS.equilibrium(u) == pytest.approx((TANKS.top, x2), rel=1e-12)
    settled = _settle(TANKS, u)
    assert settled[0] == TANKS.top  # exactly: a full tank sits on its rim
    assert settled[1] == pytest.approx(x2, rel=1e-6)
    # the level spilled in one sample at rest on the rim: the spill rate times dt
    assert float(TANKS.spill(settled, [u])) == pytest.approx(spill * TANKS.dt, rel=1e-9)
    assert TANKS.output(settled, [u])[0] == min(x2, TANKS.y_max)


@given(x=levels, u=voltages)
@settings(max_examples=60, deadline=None)
def test_the_rim_caps_the_upper_level_and_the_sensor_caps_the_output(x, u):
    nxt = TANKS.step(x, [u])
    assert 0.0 <= nxt[0] <= TANKS.top and nxt[1] >= 0.0
    assert TANKS.output(x, [u])[0] == min(x[1], TANKS.y_max)
    assert float(TANKS.spill(x, [u])) >= 0.0


@pytest.mark.parametrize("p", [0.0, 0.5, 1.0])
@given(x=levels, u=voltages)
@settings(max_examples=25, deadline=None)
def test_water_is_conserved_what_spills_past_the_lower_tank_is_lost(p, x, u):
    """Equal sections (k2 = k1) and a closed lower tank (k3 = 0): each sample the pump adds
    k4 u dt to x1 + x2 and the share 1 − p of the spill leaves."""
    closed = OverflowTanks(k=(0.1, 0.1, 0.0, 0.05), spill_fraction=p)
    x = (max(x[0], 1.0), x[1])  # the upper tank does not run dry within the sample
    before, after = sum(x), closed.step(x, [u]).sum()
    spilled = float(closed.spill(x, [u]))
    expected = before + 0.05 * u * closed.dt - (1.0 - p) * spilled
    assert after == pytest.approx(expected, abs=1e-12 * max(1.0, before))
    if u * 0.05 > 0.1 * math.sqrt(closed.top) and x[0] == closed.top:
        assert spilled > 0.0


def test_sixteen_substeps_agree_with_a_fine_integration_through_overflow_episodes(tmp_path):
    """On a record of the scenario (it reaches the rim and the sensor's limit), 16 RK4 substeps
    per sample stay within 1e-4 V of 512."""
    ds = Dataset.load(generate_dataset(GenerationConfig("tanks-overflow"), tmp_path).path)
    test = ds.split("test")[0]
    fine = OverflowTanks(substeps=512).simulate(test.x[0], test.u)
    coarse = OverflowTanks().simulate(test.x[0], test.u)
    assert (fine.x[:, 0] == TANKS.top).any()
    assert np.abs(coarse.x - fine.x).max() < 1e-4
    np.testing.assert_allclose(coarse.y, test.y_clean, atol=1e-12)  # the dataset's own sim


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"spill_fraction": 1.5}, "spill_fraction must be in [0, 1]"),
        ({"k": (0.1, 0.1, 0.1)}, "k must be four finite coefficients"),
        ({"k": (0.0, 0.1, 0.1, 0.05)}, "k1 > 0"),
        ({"substeps": 0}, "substeps must be an integer >= 1"),
        ({"top": -1.0}, "top must be a finite number > 0"),
        ({"eps": 0.0}, "eps must be a finite number > 0"),
    ],
)
def test_bad_parameters_name_the_field(kwargs, message):
    with pytest.raises(SetError, match=message.replace("[", r"\[").replace("]", r"\]")):
        OverflowTanks(**kwargs)


def test_a_closed_lower_tank_has_no_equilibrium():
    with pytest.raises(SetError, match="k3 = 0"):
        OverflowTanks(k=(0.1, 0.1, 0.0, 0.05)).equilibrium(3.0)


# ---------------------------------------------------------------------------- the scenario
def test_the_dataset_has_the_benchmarks_shape_and_validation_is_the_training_tail(tmp_path):
    result = generate_dataset(GenerationConfig("tanks-overflow"), tmp_path)
    assert result.counts == {"train": 1, "val": 0, "test": 1}
    ds = Dataset.load(result.path)
    (train,), (val,), (test,) = ds.split("train"), ds.split("val"), ds.split("test")
    assert (train.T, val.T, test.T) == (819, 205, 1024)
    assert ds.dt == 4.0
    assert train.info["samples"] == [0, 819] and val.info["samples"] == [819, 1024]
    # one flight cut in two: the state runs on from the training part into the validation part
    system = get_system("tanks-overflow")
    np.testing.assert_allclose(system.step(train.x[-1], train.u[-1]), val.x[0], atol=1e-12)
    assert "samples 819…1023 of 1024" in ds.metadata["validation_split"]
    # different input realisations of the same family: same offset and RMS, other phases
    assert not np.allclose(train.u[:100], test.u[:100])
    whole = np.concatenate([train.u, val.u])
    for u in (whole, test.u):
        assert np.all((u >= 0.0) & (u <= 10.0))
        assert u.mean() == pytest.approx(5.3, abs=0.1)
    # both records reach the rim and the sensor's limit
    for x, y in (
        (np.concatenate([train.x, val.x]), np.concatenate([train.y_clean, val.y_clean])),
        (test.x, test.y_clean),
    ):
        assert (x[:, 0] == system.top).sum() >= 5
        assert (y[:, 0] == system.y_max).sum() >= 5


def test_same_seed_same_bytes_another_seed_other_records(tmp_path):
    paths = [
        generate_dataset(GenerationConfig("tanks-overflow", seed=s), tmp_path / name).path
        for s, name in ((3, "a"), (3, "b"), (4, "c"))
    ]
    a, b, c = (p.read_bytes() for p in paths)
    assert a == b and a != c
    assert paths[0].with_suffix(".json").read_bytes() == paths[1].with_suffix(".json").read_bytes()


def test_validation_flights_are_refused_naming_the_cut():
    with pytest.raises(ShapeError, match="last 20% of each training flight"):
        GenerationConfig("tanks-overflow", counts={"val": 1})


def test_canonid_generate_writes_it_and_says_how_validation_was_cut(tmp_path, capsys):
    out = tmp_path / "tanks"
    assert main(["generate", "tanks-overflow", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "validation: the last 20% of every training flight" in printed
    assert Dataset.load(out).counts() == {"train": 1, "val": 1, "test": 1}


def test_overflow_benchmarks_only_stops_before_training_without_the_full_runs_records(
    tmp_path, monkeypatch, capsys
):
    """``bench_overflow_tanks.py --only FOLDER`` merges one contestant into a full run's
    records: without them it names the missing file and trains nothing."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_overflow_tanks as bench

    monkeypatch.setattr(bench, "ROOT", tmp_path)
    monkeypatch.setattr(bench, "RUNS", tmp_path / "runs" / "overflow-tanks")
    trained = []
    monkeypatch.setattr(bench, "canonid_train", lambda *a, **k: trained.append(a))
    for argv in (["--only", "mlp-default"], ["--record"]):
        monkeypatch.setattr(sys, "argv", ["bench_overflow_tanks.py", *argv])
        try:
            bench.main()
        except SystemExit as exc:
            assert exc.code == 2
        else:
            raise AssertionError("no error")
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert "cpu.json not found" in err and str(tmp_path) in err
    assert trained == []
