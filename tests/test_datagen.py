"""Data generation: references, the tank PID, closed-loop simulation, seeds, parts and resume."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.datagen.controllers.pid import PID
from canonid.datagen.generate import (
    FlightJob,
    GenerationConfig,
    generate_dataset,
    is_loose,
    plan_flights,
    run_flight,
)
from canonid.datagen.references import drone2d_reference, tank_reference
from canonid.datagen.scenarios import Scenario, get_scenario, scenario_names
from canonid.datagen.simulate import Excitation, noise_box, simulate_closed_loop
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError, SetError, ShapeError, UnknownSystemError
from canonid.models.registry import get_system
from canonid.models.tank import Tank

# ---------------------------------------------------------------------------- references


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_tank_reference_starts_at_zero_stays_nonnegative(seed):
    ref = tank_reference(np.random.default_rng(seed))
    assert ref.shape == (200, 1)
    assert ref[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(ref >= 0.0)


def test_tank_reference_passes_through_its_waypoints():
    """Without a redraw the knots at samples 40, 80, 120, 160 are the first uniform draws."""
    for seed in range(20):
        levels = np.random.default_rng(seed).uniform(0.0, 5.0, size=5)
        ref = tank_reference(np.random.default_rng(seed))[:, 0]
        if np.allclose(ref[[40, 80, 120, 160]], levels[:4]):
            return
    pytest.fail("no seed in 0..19 reproduced its waypoints at samples 40..160")


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_drone_reference_velocity_is_the_position_derivative(seed):
    dt = 1 / 30
    ref = drone2d_reference(np.random.default_rng(seed), T=600, dt=dt)
    assert ref.shape == (600, 6)
    assert np.all(ref[:, [2, 5]] == 0.0)
    # central differences of a cubic spline: error O(dt²·|p'''|), small at 30 Hz
    central = (ref[2:, 0:2] - ref[:-2, 0:2]) / (2 * dt)
    np.testing.assert_allclose(central, ref[1:-1, 3:5], atol=5e-3)


def test_drone_reference_waypoint_count_in_range():
    counts = set()
    for seed in range(40):
        rng = np.random.default_rng(seed)
        counts.add(int(rng.integers(5, 11)))
        drone2d_reference(np.random.default_rng(seed))
    assert counts <= set(range(5, 11)) and len(counts) >= 4


def test_reference_arguments_are_checked():
    rng = np.random.default_rng(0)
    with pytest.raises(ShapeError, match="T must"):
        tank_reference(rng, T=1)
    with pytest.raises(ShapeError, match="n_waypoints"):
        drone2d_reference(rng, n_waypoints=(5, 2))


# ---------------------------------------------------------------------------- PID


def test_pid_reproduces_hand_computed_first_steps():
    """Constant set-point 1 from x0 = 0, gains (4, 0.6, 4), no saturation:
    u0 = 4·1 + 0.6·1 + 4·(1 − 0) = 8.6; x1 = (0.4·8.6, 0) = (3.44, 0);
    u1 = 4·1 + 0.6·2 + 4·0 = 5.2; x2 = (3.44 − 0.5√3.44 + 0.4·5.2, 0.2√3.44);
    u2 = 4·e2 + 0.6·(2 + e2) + 4·(e2 − 1) with e2 = 1 − 0.2√3.44."""
    tank = Tank()
    loop = simulate_closed_loop(
        tank, PID(), np.ones((3, 1)), x0=np.zeros(2), rng=np.random.default_rng(0)
    )
    x21 = 3.44 - 0.5 * math.sqrt(3.44) + 0.4 * 5.2
    x22 = 0.2 * math.sqrt(3.44)
    e2 = 1 - x22
    expected_u = [8.6, 5.2, 4 * e2 + 0.6 * (2 + e2) + 4 * (e2 - 1)]
    np.testing.assert_allclose(loop.u[:, 0], expected_u, rtol=1e-12)
    np.testing.assert_allclose(loop.x, [[0, 0], [3.44, 0], [x21, x22]], rtol=1e-12, atol=1e-15)


def test_pid_is_not_saturated_and_refuses_bad_use():
    pid = PID()
    with pytest.raises(ShapeError, match="before reset"):
        pid(0, np.zeros(2))
    pid.reset(np.full((2, 1), -10.0), np.zeros(2))
    assert pid(0, np.zeros(2)).u[0] == pytest.approx(4 * -10 + 0.6 * -10 + 4 * -10)
    with pytest.raises(ShapeError, match="state_index"):
        PID(state_index=5).reset(np.zeros((2, 1)), np.zeros(2))


# ---------------------------------------------------------------------------- simulation


class _Constant(Controller):
    name = "constant"

    def __init__(self, u, ok=True):
        self.u, self.ok = np.asarray(u, dtype=float), ok

    def reset(self, reference, x0):
        pass

    def __call__(self, t, x):
        return ControlStep(u=self.u, ok=self.ok, info={"status": "test"})

    def settings(self):
        return {"type": self.name}


# no noise, or noise above the outputs' float resolution (a level of 5e-324 vanishes in y + w)
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31), level=st.just(0.0) | st.floats(1e-9, 0.01))
def test_measurement_noise_stays_in_its_box(seed, level):
    drone = get_system("drone2d")
    box = noise_box(drone, level)
    loop = simulate_closed_loop(
        drone,
        _Constant([drone.hover_speed] * 2),
        np.zeros((50, 6)),
        x0=np.zeros(6),
        rng=np.random.default_rng(seed),
        noise=box,
        excitation=Excitation(std=1.0),
        clip_input=True,
    )
    w = loop.y - loop.y_clean
    assert np.all(np.abs(w) <= level + 1e-15)
    if level > 0:
        assert np.abs(w).max() > level / 4  # the noise is really there


def test_closed_loop_obeys_the_time_convention(rng):
    drone = get_system("drone2d")
    loop = simulate_closed_loop(
        drone,
        _Constant([drone.hover_speed] * 2),
        np.zeros((40, 6)),
        x0=np.zeros(6),
        rng=rng,
        excitation=Excitation(std=50.0, loose_probability=0.5, loose_std=80.0),
        clip_input=True,
    )
    for t in range(39):
        np.testing.assert_allclose(loop.x[t + 1], drone.step(loop.x[t], loop.u[t]), atol=1e-12)
    np.testing.assert_allclose(loop.y_clean, drone.h_batch(loop.x, loop.u))
    assert drone.U.contains(loop.u)
    assert 0 < loop.loose_steps < 40


def test_failed_steps_are_counted_with_their_status(rng):
    tank = Tank()
    loop = simulate_closed_loop(
        tank, _Constant([1.0], ok=False), np.zeros((7, 1)), x0=np.zeros(2), rng=rng
    )
    assert loop.failures == 7 and loop.failure_reasons == {"test": 7}


def test_noise_level_outside_w_is_refused():
    tank = Tank()
    with pytest.raises(SetError, match=r"outside the system's noise set W"):
        noise_box(tank, 0.5)
    with pytest.raises(SetError, match="one half-width"):
        noise_box(get_system("drone2d"), (0.01, 0.01))
    assert noise_box(tank, None) == tank.W


# ---------------------------------------------------------------------------- generation


def test_scenario_registry():
    assert "tank" in scenario_names()
    with pytest.raises(UnknownSystemError, match="no dataset scenario for system 'nope'"):
        get_scenario("nope")


def test_config_validation():
    with pytest.raises(ShapeError, match="train flights must be an integer >= 0"):
        GenerationConfig("tank", counts={"train": -1})
    with pytest.raises(ShapeError, match="unknown split"):
        GenerationConfig("tank", counts={"training": 1})
    with pytest.raises(ShapeError, match="do not apply to tank"):
        GenerationConfig("tank", controller_options={"horizon": 3})
    with pytest.raises(SetError, match="outside"):
        GenerationConfig("tank", noise=1.0)
    with pytest.raises(ShapeError, match="nothing to generate"):
        GenerationConfig("tank", counts={"train": 0, "val": 0, "test": 0})
    assert GenerationConfig("tank").counts == {"train": 60, "val": 20, "test": 20}
    assert GenerationConfig("tank", noise=0).to_json()["noise"] == 0.0


def test_loose_flights_are_every_fifth_training_flight():
    assert [i for i in range(20) if is_loose("train", i, 0.2)] == [4, 9, 14, 19]
    assert not any(is_loose("val", i, 0.2) for i in range(20))
    assert not any(is_loose("train", i, 0.0) for i in range(20))


def test_a_flight_is_a_function_of_its_seed_and_position_only():
    config = GenerationConfig("tank", seed=3, counts={"train": 3, "val": 1, "test": 0})
    jobs = plan_flights(config)
    assert [j.name for j in jobs] == ["train-00000", "train-00001", "train-00002", "val-00000"]
    forward = [run_flight(j).trajectory for j in jobs]
    backward = [run_flight(j).trajectory for j in reversed(jobs)][::-1]
    for a, b in zip(forward, backward):
        np.testing.assert_array_equal(a.u, b.u)
        np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(forward[0].reference, forward[1].reference)
    other = run_flight(FlightJob(GenerationConfig("tank", seed=4), "train", 0)).trajectory
    assert not np.array_equal(other.reference, forward[0].reference)


def _small(tmp_path, name, **kwargs):
    config = GenerationConfig("tank", seed=7, counts={"train": 4, "val": 2, "test": 2})
    return generate_dataset(config, tmp_path / name, **kwargs)


def test_generated_drone_dataset(tmp_path, monkeypatch):
    monkeypatch.setenv("CANONID_CACHE_DIR", str(tmp_path / "cache"))
    config = GenerationConfig(
        "drone2d",
        seed=1,
        counts={"train": 5, "val": 1, "test": 0},
        T=90,
        controller_options={"horizon": 10},
        noise=0.005,
    )
    ds = Dataset.load(generate_dataset(config, tmp_path / "d").path)
    assert ds.counts() == {"train": 5, "val": 1, "test": 0}
    drone = get_system("drone2d")
    for tr in ds.split("train") + ds.split("val"):
        assert tr.x.shape == (90, 6) and tr.u.shape == (90, 2) and tr.reference.shape == (90, 6)
        np.testing.assert_array_equal(tr.x[0], tr.reference[0])  # starts on the reference
        assert drone.U.contains(tr.u)
        assert np.all(np.abs(tr.y - tr.y_clean) <= 0.005)
        assert tr.info["solver_failures"] == 0
        assert tr.info["loose"] == (tr.info["index"] == 4 and tr.info["split"] == "train")
        assert (tr.info["loose_steps"] > 0) == tr.info["loose"]
    meta = ds.metadata
    assert meta["controller"]["horizon"] == 10 and meta["scenario"]["excitation_std"] == 1.0
    assert meta["noise"]["box"]["upper"] == [0.005] * 3


def test_generated_tank_dataset(tmp_path):
    result = _small(tmp_path, "a")
    ds = Dataset.load(result.path)
    assert ds.counts() == {"train": 4, "val": 2, "test": 2} == result.counts
    assert not (tmp_path / "a" / "parts").exists()
    tr = ds.split("train")[0]
    assert tr.T == 200 and tr.x.shape == (200, 2) and tr.reference.shape == (200, 1)
    assert np.all(np.abs(tr.y - tr.y_clean) <= 0.02)
    np.testing.assert_array_equal(tr.y_clean[:, 0], tr.x[:, 1])
    assert tr.info["spawn_key"] == [0, 0, 0] and tr.info["solver_failures"] == 0
    meta = ds.metadata
    assert meta["controller"]["kp"] == 4.0 and meta["generation"]["seed"] == 7
    assert meta["noise"]["box"] == {"lower": [-0.02], "upper": [0.02]}
    assert {"numpy", "casadi", "scipy"} <= set(meta["versions"])
    # the PID tracks: RMS tracking error of the lower level well under the reference's spread
    rms = np.sqrt(np.mean((tr.reference[:, 0] - tr.x[:, 1]) ** 2))
    assert rms < 0.5 * np.std(tr.reference[:, 0])


def test_same_seed_same_bytes_and_interrupted_run_resumes(tmp_path, monkeypatch):
    import canonid.datagen.generate as gen

    first = _small(tmp_path, "a").path
    calls = {"n": 0}
    real = gen.run_flight

    def interrupted(job):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(gen, "run_flight", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _small(tmp_path, "b")
    parts = sorted(p.name for p in (tmp_path / "b" / "parts").glob("*.json"))
    assert parts == ["config.json", "train-00000.json", "train-00001.json", "train-00002.json"]
    assert not (tmp_path / "b" / "dataset.json").exists()
    # parts damaged by the interruption (or, not being fsynced, by a power failure) are
    # regenerated, not trusted
    (tmp_path / "b" / "parts" / "train-00002.npz").write_bytes(b"garbage")
    (tmp_path / "b" / "parts" / "train-00001.json").write_bytes(b"")
    monkeypatch.setattr(gen, "run_flight", real)
    resumed = _small(tmp_path, "b", resume=True)
    assert (resumed.resumed, resumed.generated) == (1, 7)
    assert resumed.path.read_bytes() == first.read_bytes()
    assert resumed.path.with_suffix(".json").read_bytes() == first.with_suffix(".json").read_bytes()


def test_resume_refuses_parts_of_another_configuration(tmp_path):
    _small(tmp_path, "a", keep_parts=True)
    other = GenerationConfig("tank", seed=8, counts={"train": 4, "val": 2, "test": 2})
    with pytest.raises(DataError, match="cannot resume"):
        generate_dataset(other, tmp_path / "a", resume=True)


def test_a_dataset_of_another_configuration_is_not_replaced_silently(tmp_path):
    first = _small(tmp_path, "a").path
    before = first.read_bytes()
    other = GenerationConfig("tank", seed=8, counts={"train": 4, "val": 2, "test": 2})
    with pytest.raises(DataError, match="already holds a dataset of another configuration"):
        generate_dataset(other, tmp_path / "a")
    assert first.read_bytes() == before


@pytest.mark.parametrize("header", ['{"x": 1}', '{"metadata": 3}', '{"metadata": {}}', "[]"])
def test_a_foreign_dataset_json_is_named_not_called_another_configuration(header, tmp_path):
    """A ``dataset.json`` that no ``canonid generate`` wrote: named as such (issue 54: the
    message said "another configuration (None)"), and left as it is."""
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "dataset.json").write_text(header, encoding="utf-8")
    config = GenerationConfig("tank", seed=8, counts={"train": 4, "val": 2, "test": 2})
    with pytest.raises(DataError, match="not the record of a dataset canonid generate wrote"):
        generate_dataset(config, tmp_path / "a")
    assert (tmp_path / "a" / "dataset.json").read_text(encoding="utf-8") == header
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["dataset.json"]


def test_truncated_generated_dataset_is_refused_naming_it(tmp_path):
    path = _small(tmp_path, "a").path
    path.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(DataError, match=r"dataset\.npz.*checksum"):
        Dataset.load(tmp_path / "a")


# ---------------------------------------------------------------------------- failures


class _FailsOnSomeReferences(Controller):
    """Fails every step when the reference's second sample is above 0.5 (seed-dependent)."""

    name = "flaky"

    def reset(self, reference, x0):
        self.fail = reference[1, 0] > 0.5

    def __call__(self, t, x):
        return ControlStep(u=np.zeros(1), ok=not self.fail, info={"status": "flaky"})

    def settings(self):
        return {"type": self.name}


def _register(monkeypatch, factory, **kwargs):
    import canonid.datagen.scenarios as sc

    base = get_scenario("tank")
    scenario = Scenario(
        system="tank",
        T=20,
        split_sizes={"train": 6, "val": 0, "test": 0},
        reference=lambda system, rng, T: rng.uniform(0, 1, size=(T, 1)),
        reference_names=base.reference_names,
        initial_state=base.initial_state,
        controller=factory,
        **kwargs,
    )
    monkeypatch.setitem(sc._SCENARIOS, "tank", scenario)


def test_failing_flights_are_regenerated_and_recorded(tmp_path, monkeypatch):
    _register(monkeypatch, lambda system, options: _FailsOnSomeReferences())
    result = generate_dataset(GenerationConfig("tank", seed=1), tmp_path / "f")
    ds = Dataset.load(result.path)
    replaced = [tr for tr in ds.split("train") if tr.info["replaced"]]
    assert result.replaced == len(replaced) > 0 and result.solver_failures == 0
    for tr in replaced:
        attempts = [r["spawn_key"][2] for r in tr.info["replaced"]]
        assert attempts == list(range(len(attempts)))
        assert tr.info["spawn_key"][2] == len(attempts)
        assert all(r["solver_failures"] == 20 for r in tr.info["replaced"])


def test_a_flight_that_always_fails_stops_generation(tmp_path, monkeypatch):
    _register(monkeypatch, lambda system, options: _Constant([0.0], ok=False), max_attempts=3)
    with pytest.raises(DataError, match="train-00000 of tank failed 3 times"):
        generate_dataset(GenerationConfig("tank"), tmp_path / "g")
    assert not (tmp_path / "g" / "dataset.json").exists()
