"""Generated quadrotor datasets: flights cut into chunks, split by flight, named as simulated,
the same bytes for the same seed whichever runner ran the flights."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from canonid.cli import main
from canonid.datagen.chunks import chunk_bounds, cut_chunks
from canonid.datagen.generate import FlightJob, GenerationConfig, generate_dataset, run_flight
from canonid.datagen.scenarios import get_scenario
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import DataError, ShapeError
from canonid.runner import run_jobs

SMALL = {"train": 2, "val": 1, "test": 1}


def test_scenario_mirrors_blackbird():
    sc = get_scenario("quadrotor")
    assert dict(sc.split_sizes) == {"train": 146, "val": 20, "test": 10}
    assert sc.chunk_length == 200 and sc.T % 200 == 0
    assert "SIMULATED" in sc.notes and sc.clip_input and sc.excitation_std > 0
    with pytest.raises(ShapeError, match="shorter than one quadrotor chunk"):
        GenerationConfig(system="quadrotor", counts=SMALL, T=150)


def test_cut_chunks_slices_every_field_alike():
    T = 7
    tr = Trajectory(
        u=np.arange(T * 2).reshape(T, 2),
        y=np.arange(T)[:, None] * 1.0,
        x=np.arange(T * 3).reshape(T, 3),
        info={"flight": "a"},
    )
    chunks = cut_chunks(tr, 3)
    assert [c.T for c in chunks] == [3, 3]
    np.testing.assert_array_equal(chunks[1].u, tr.u[3:6])
    np.testing.assert_array_equal(chunks[1].x, tr.x[3:6])
    assert chunks[1].info == {"flight": "a", "chunk": 1, "chunk_start": 3}
    assert chunks[0].y_clean is None
    assert chunk_bounds(400, 200) == [(0, 200), (200, 400)]
    with pytest.raises(DataError, match="chunk_length"):
        cut_chunks(tr, 0)


def test_generated_dataset_holds_the_chunks_of_each_flight_in_order(tmp_path):
    config = GenerationConfig(system="quadrotor", seed=5, counts=SMALL, T=400)
    result = generate_dataset(config, tmp_path / "q")
    assert result.counts == SMALL
    assert result.chunks == {"train": 4, "val": 2, "test": 2}
    ds = Dataset.load(result.path)
    assert ds.dt == 0.02 and ds.n_u == 4 and ds.n_y == 6 and len(ds.state_names or ()) == 13
    meta = ds.metadata
    assert meta["simulated"] is True
    assert meta["simulated_stand_in_for"] == "Blackbird UAV dataset (real flights)"
    assert meta["scenario"]["chunk_length"] == 200
    assert meta["controller"]["name"] == "quadrotor-cascade"
    # train chunks 0, 1 are flight 0's samples 0-199 and 200-399, chunks 2, 3 flight 1's
    flight0 = run_flight(FlightJob(config, "train", 0)).trajectory
    chunks = ds.split("train")
    assert [(c.info["index"], c.info["chunk"]) for c in chunks] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    for c in (0, 1):
        for name, arr in flight0.arrays().items():
            np.testing.assert_array_equal(getattr(chunks[c], name), arr[200 * c : 200 * (c + 1)])
    for tr in chunks:
        assert tr.T == 200
        norms = np.linalg.norm(tr.x[:, 6:10], axis=1)
        assert np.max(np.abs(norms - 1)) < 1e-12
        assert np.all(np.abs(tr.y - tr.y_clean) <= np.array([0.05] * 3 + [0.005] * 3) + 1e-15)


def test_same_seed_same_bytes_serially_and_on_two_threaded_workers(tmp_path):
    config = GenerationConfig(system="quadrotor", seed=11, counts=SMALL, T=200)
    serial = generate_dataset(config, tmp_path / "a").path
    threaded = functools.partial(run_jobs, workers=2, processes=False, progress=False)
    parallel = generate_dataset(config, tmp_path / "b", run_jobs=threaded).path
    assert serial.read_bytes() == parallel.read_bytes()
    assert serial.with_suffix(".json").read_bytes() == parallel.with_suffix(".json").read_bytes()


def test_cli_generate_quadrotor_says_simulated(tmp_path, capsys):
    out = tmp_path / "cli"
    argv = ["generate", "quadrotor", "--out", str(out), "--steps", "200", "--no-progress"]
    assert main([*argv, "--n-train", "1", "--n-val", "1", "--n-test", "1"]) == 0
    text = capsys.readouterr().out
    assert "SIMULATED data: quadrotor is a simulated stand-in for Blackbird" in text
    assert "200-sample chunks: train 1, val 1, test 1 chunks" in text
    assert Dataset.load(out).metadata["simulated"] is True
