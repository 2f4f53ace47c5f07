"""Dataset storage: round trip, deterministic bytes, corrupt/truncated files refused."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

import canonid.kernel.io as io
from canonid.kernel.dataset import Dataset, Trajectory, as_trajectories
from canonid.kernel.errors import DataError, ShapeError
from canonid.kernel.io import npz_bytes


def _dataset(rng, n=3, T=20):
    trajs = []
    for i in range(n):
        x = rng.normal(size=(T, 2))
        y_clean = x[:, 1:]
        trajs.append(
            Trajectory(
                u=rng.normal(size=(T, 1)),
                y=y_clean + 0.01,
                y_clean=y_clean,
                x=x,
                reference=rng.normal(size=(T, 1)),
                info={"seed": i},
            )
        )
    return Dataset(
        splits={"train": trajs[:2], "test": trajs[2:]},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
        state_names=("x1", "x2"),
        metadata={"system": "tank"},
    )


def test_round_trip(tmp_path, rng):
    ds = _dataset(rng)
    path = ds.save(tmp_path / "d.npz")
    back = Dataset.load(path)
    assert back.counts() == {"train": 2, "test": 1}
    for a, b in zip(ds.split("train"), back.split("train")):
        for k, v in a.arrays().items():
            np.testing.assert_array_equal(v, b.arrays()[k])
        assert b.info == a.info
    assert back.metadata == {"system": "tank"}


def test_same_content_same_bytes(tmp_path, rng):
    ds = _dataset(rng)
    p1 = ds.save(tmp_path / "a" / "d.npz")
    p2 = ds.save(tmp_path / "b" / "d.npz")
    assert p1.read_bytes() == p2.read_bytes()
    assert p1.with_suffix(".json").read_bytes() == p2.with_suffix(".json").read_bytes()
    arrays = {"a": np.arange(3.0)}
    assert npz_bytes(arrays) == npz_bytes(arrays)


def test_durable_false_skips_only_the_fsync(tmp_path, rng, monkeypatch):
    """Generation parts are written without fsync: the same bytes, no fsync call."""
    ds = _dataset(rng)
    durable = ds.save(tmp_path / "a" / "d.npz")
    synced = []
    monkeypatch.setattr(io.os, "fsync", synced.append)
    quick = ds.save(tmp_path / "b" / "d.npz", durable=False)
    assert synced == []
    assert quick.read_bytes() == durable.read_bytes()
    assert quick.with_suffix(".json").read_bytes() == durable.with_suffix(".json").read_bytes()
    ds.save(tmp_path / "c" / "d.npz")
    assert len(synced) == 2  # the default: the arrays and the sidecar


def test_truncated_file_is_refused_naming_it(tmp_path, rng):
    path = _dataset(rng).save(tmp_path / "d.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match=r"d\.npz.*(checksum|corrupt)"):
        Dataset.load(path)


def test_flipped_byte_is_refused(tmp_path, rng):
    path = _dataset(rng).save(tmp_path / "d.npz")
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(DataError, match="checksum"):
        Dataset.load(path)


def test_missing_or_corrupt_metadata(tmp_path, rng):
    path = _dataset(rng).save(tmp_path / "d.npz")
    meta = path.with_suffix(".json")
    meta.write_text("{ not json")
    with pytest.raises(DataError, match="not valid JSON"):
        Dataset.load(path)
    meta.unlink()
    with pytest.raises(DataError, match="no metadata file"):
        Dataset.load(path)
    with pytest.raises(DataError, match="not found"):
        Dataset.load(tmp_path / "nothing.npz")


def test_nan_in_stored_arrays_is_refused(tmp_path, rng):
    path = _dataset(rng).save(tmp_path / "d.npz")
    meta = json.loads(path.with_suffix(".json").read_text())
    from canonid.kernel.io import read_npz, write_npz

    arrays = read_npz(path)
    arrays["train/00000/y"][3, 0] = np.nan
    meta["checksum_sha256"] = write_npz(path, arrays)
    path.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(DataError, match=r"train/00000.*'y'.*non-finite"):
        Dataset.load(path)


def test_trajectory_validation():
    with pytest.raises(ShapeError, match="u has 5 samples but y has 4"):
        Trajectory(u=np.zeros((5, 1)), y=np.zeros((4, 1)))
    with pytest.raises(ShapeError, match="'y_clean'"):
        Trajectory(u=np.zeros((5, 1)), y=np.zeros((5, 1)), y_clean=np.zeros((5, 2)))
    with pytest.raises(ShapeError, match="non-finite"):
        Trajectory(u=np.full((5, 1), np.nan), y=np.zeros((5, 1)))


def test_a_trajectory_passes_the_edge_as_it_is_other_objects_are_validated_once():
    tr = Trajectory(u=np.zeros((5, 1)), y=np.ones(5))
    assert Trajectory.of(tr) is tr
    assert as_trajectories(tr) == (tr,) and as_trajectories([tr, tr])[1] is tr
    other = SimpleNamespace(u=np.arange(6.0), y=np.ones((6, 2)), x=np.zeros((6, 3)), info=None)
    (converted,) = as_trajectories([other])
    assert isinstance(converted, Trajectory)
    assert converted.u.shape == (6, 1) and converted.x.shape == (6, 3) and converted.info == {}
    assert converted.y_clean is None and converted.reference is None
    bad = SimpleNamespace(u=np.zeros((5, 1)), y=np.array([[0.0], [np.nan], [0], [0], [0]]))
    with pytest.raises(ShapeError, match=r"^test data, trajectory 1: field 'y' contains 1 non-"):
        as_trajectories([tr, bad], what="test data")
    with pytest.raises(ShapeError, match="trajectory 1: has n_u=2, n_y=1; trajectory 0 has n_u=1"):
        as_trajectories([tr, SimpleNamespace(u=np.zeros((5, 2)), y=np.zeros(5))])
    with pytest.raises(DataError, match=r"trajectory 0: expected an object with arrays \.u and"):
        as_trajectories([np.zeros(5)])
    with pytest.raises(DataError, match="data: no trajectories"):
        as_trajectories([])
    with pytest.raises(DataError, match="expected a trajectory or a sequence of them, got int"):
        as_trajectories(3)


def test_a_part_of_a_trajectory_slices_every_field_and_adds_to_its_info():
    x = np.arange(20.0).reshape(10, 2)
    tr = Trajectory(u=np.arange(10.0), y=np.arange(10.0) + 1, x=x, info={"seed": 3})
    part = tr.part(2, 6, samples=[2, 6])
    assert part.T == 4 and part.info == {"seed": 3, "samples": [2, 6]}
    np.testing.assert_array_equal(part.x, x[2:6])
    np.testing.assert_array_equal(part.y[:, 0], [3.0, 4.0, 5.0, 6.0])
    assert part.y_clean is None and tr.info == {"seed": 3}
    for start, stop in ((3, 3), (-1, 4), (0, 11)):
        with pytest.raises(ShapeError, match="not a part of a trajectory of 10"):
            tr.part(start, stop)


def test_dataset_refuses_mixed_dimensions(rng):
    a = Trajectory(u=np.zeros((5, 1)), y=np.zeros((5, 1)))
    b = Trajectory(u=np.zeros((5, 2)), y=np.zeros((5, 1)))
    with pytest.raises(ShapeError, match="trajectory 1"):
        Dataset(splits={"train": [a, b]}, dt=1.0, input_names=("u",), output_names=("y",))


def test_from_arrays_and_unknown_split():
    ds = Dataset.from_arrays(np.zeros(10), np.ones(10), dt=0.5)
    assert ds.counts() == {"train": 1} and ds.n_u == 1
    with pytest.raises(DataError, match="no split 'val'"):
        ds.split("val")
    with pytest.raises(ShapeError, match="10 samples but y has 9"):
        Dataset.from_arrays(np.zeros(10), np.ones(9), dt=0.5)


def test_atomic_writes_get_the_usual_file_mode(tmp_path):
    import os

    from canonid.kernel.io import atomic_write_text

    mask = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644
