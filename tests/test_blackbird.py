"""The Blackbird loader on small synthetic files written in the dataset's CSV layout.

Hand-computed answers: the overlap of two clocks, the number of 50 Hz samples and chunks,
linear signals reproduced exactly by the resampling, a constant unchanged by the filter, a
low-frequency sine kept and a high-frequency one removed; bad files name themselves.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.datagen.blackbird import (
    IMU_FILE,
    ROTOR_FILE,
    find_flights,
    load_blackbird,
    process_flight,
    read_imu_csv,
    read_rotor_rpm_csv,
    resample_linear,
    split_flights,
)
from canonid.datagen.chunks import chunk_bounds
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError

#: an epoch-sized bag time (ns): timestamps must survive int64 → seconds without rounding loss
BASE_NS = 1_528_000_000_123_456_789

IMU_HEADER = [
    "rosbagTimestamp", "header", "seq", "stamp", "secs", "nsecs", "frame_id",
    "orientation", "x", "y", "z", "w", "orientation_covariance",
    "angular_velocity", "x", "y", "z", "angular_velocity_covariance",
    "linear_acceleration", "x", "y", "z", "linear_acceleration_covariance",
]  # fmt: skip
ROTOR_HEADER = [
    "rosbagTimestamp", "header", "seq", "stamp", "secs", "nsecs", "frame_id", "sample_stamp",
    "-", "secs", "nsecs", "-", "secs", "nsecs", "-", "secs", "nsecs", "-", "secs", "nsecs",
    "rpm",
]  # fmt: skip
_COV = "[" + ", ".join(["0.0"] * 9) + "]"


def _ns(t_s: np.ndarray) -> list[int]:
    return [BASE_NS + round(float(t) * 1e9) for t in t_s]


def write_imu(path: Path, t_s, acc, gyro) -> Path:
    """IMU rows aligned with the header; acc and gyro (N, 3)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(IMU_HEADER)
        for i, (ts, a, g) in enumerate(zip(_ns(t_s), acc, gyro)):
            secs, nsecs = divmod(ts, 10**9)
            w.writerow(
                [
                    *(ts, "", i, "", secs, nsecs, "imu", "", 0, 0, 0, 1, _COV),
                    *("", *(repr(float(v)) for v in g), _COV),
                    *("", *(repr(float(v)) for v in a), _COV),
                ]
            )
    return path


def write_rotor(path: Path, t_s, rpm) -> Path:
    """Rotor rows as distributed: 4 (secs, nsecs) motor stamps, then the quoted rpm vector,
    i.e. fewer fields than the (misaligned) header."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(ROTOR_HEADER)
        for i, (ts, r) in enumerate(zip(_ns(t_s), rpm)):
            secs, nsecs = divmod(ts, 10**9)
            stamps = [secs, nsecs] * 4
            vector = "[" + ", ".join(repr(float(v)) for v in r) + "]"
            w.writerow([ts, "", i, "", secs, nsecs, "", "", *stamps, vector])
    return path


def _acc(t):
    t = np.asarray(t)
    return np.column_stack([1 + 0.5 * t, -2 + 0.1 * t, 9.81 - 0.2 * t])


def _gyro(t):
    t = np.asarray(t)
    return np.column_stack([0.3 * t, -0.1 * t, 1 + 0.05 * t])


def _rpm(t):
    t = np.asarray(t)
    return np.column_stack([9000 + 100 * t + 10 * i for i in range(4)])


def _on_ns(t: np.ndarray) -> np.ndarray:
    """Times rounded to the nanoseconds the file stores, so signals are exact at its stamps."""
    return np.round(np.asarray(t) * 1e9) / 1e9


def _imu_times(start: float, stop: float) -> np.ndarray:
    return _on_ns(start + 0.01 * np.arange(round((stop - start) / 0.01) + 1))


def _rotor_times(start: float, stop: float, rng) -> np.ndarray:
    n = round((stop - start) * 190)
    t = start + np.arange(n + 1) / 190 + rng.uniform(-1e-3, 1e-3, n + 1)
    t[0], t[-1] = start, stop
    return _on_ns(t)


def write_linear_flight(folder: Path, rng, imu_span=(1.003, 10.993), rotor_span=(0.5, 10.6)):
    t_imu = _imu_times(*imu_span)
    t_rot = _rotor_times(*rotor_span, rng)
    write_imu(folder / "csv" / IMU_FILE, t_imu, _acc(t_imu), _gyro(t_imu))
    write_rotor(folder / "csv" / ROTOR_FILE, t_rot, _rpm(t_rot))
    return folder / "csv"


# ---------------------------------------------------------------- reading


def test_readers_parse_the_distributed_layout(tmp_path, rng):
    csv_dir = write_linear_flight(tmp_path / "f", rng)
    imu = read_imu_csv(csv_dir / IMU_FILE)
    rotor = read_rotor_rpm_csv(csv_dir / ROTOR_FILE)
    assert imu.values.shape == (1000, 6) and rotor.values.shape[1] == 4
    assert imu.t_ns[0] == BASE_NS + 1_003_000_000 and imu.t_ns.dtype == np.int64
    t = (imu.t_ns - BASE_NS) / 1e9
    np.testing.assert_allclose(imu.values, np.hstack([_acc(t), _gyro(t)]), rtol=1e-12)
    tr = (rotor.t_ns - BASE_NS) / 1e9
    np.testing.assert_allclose(rotor.values, _rpm(tr) * 2 * math.pi / 60, rtol=1e-12)
    deg = read_imu_csv(csv_dir / IMU_FILE, gyro_units="deg/s")
    np.testing.assert_allclose(deg.values[:, 3:], imu.values[:, 3:] * math.pi / 180)


# ---------------------------------------------------------------- resampling and chunks


def test_linear_signals_are_resampled_exactly_on_the_overlap(tmp_path, rng):
    """Overlap [1.003, 10.6] s → K = ⌊9.597 · 50⌋ + 1 = 480 samples at t = 1.003 + 0.02 k."""
    csv_dir = write_linear_flight(tmp_path / "f", rng)
    sig = process_flight(
        read_imu_csv(csv_dir / IMU_FILE), read_rotor_rpm_csv(csv_dir / ROTOR_FILE), cutoff_hz=None
    )
    assert sig.t0_ns == BASE_NS + 1_003_000_000
    assert len(sig.t_s) == 480
    t_abs = 1.003 + 0.02 * np.arange(480)
    np.testing.assert_allclose(sig.y, np.hstack([_acc(t_abs), _gyro(t_abs)]), atol=1e-9)
    np.testing.assert_allclose(sig.u, _rpm(t_abs) * 2 * math.pi / 60, atol=1e-9)
    assert sig.max_gap_s["imu"] == pytest.approx(0.01, abs=1e-9)


def test_chunks_are_consecutive_and_drop_the_remainder():
    assert chunk_bounds(480, 200) == [(0, 200), (200, 400)]
    assert chunk_bounds(400, 200) == [(0, 200), (200, 400)]
    assert chunk_bounds(199, 200) == []
    assert chunk_bounds(7, 3) == [(0, 3), (3, 6)]
    with pytest.raises(DataError, match="chunk_length"):
        chunk_bounds(10, 0)


@settings(max_examples=30, deadline=None)
@given(
    st.floats(-50, 50),
    st.floats(-5, 5),
    st.lists(st.floats(1e-3, 0.1), min_size=3, max_size=40),
)
def test_resampling_reproduces_any_linear_signal(intercept, slope, steps):
    t = np.concatenate(([0.0], np.cumsum(steps)))
    grid = np.linspace(t[0], t[-1], 17)
    out = resample_linear(t, (intercept + slope * t)[:, None], grid)
    np.testing.assert_allclose(out[:, 0], intercept + slope * grid, atol=1e-9)


def test_resampling_refuses_to_extrapolate():
    with pytest.raises(DataError, match="no extrapolation"):
        resample_linear(np.array([0.0, 1.0]), np.ones((2, 1)), np.array([0.0, 1.5]))


# ---------------------------------------------------------------- the filter


def _process_with(tmp_path, acc, gyro, rpm, cutoff_hz):
    t_imu = _imu_times(0.0, 20.0)
    t_rot = np.arange(0, 20.0 * 190 + 1) / 190
    write_imu(tmp_path / IMU_FILE, t_imu, acc(t_imu), gyro(t_imu))
    write_rotor(tmp_path / ROTOR_FILE, t_rot, rpm(t_rot))
    imu, rotor = read_imu_csv(tmp_path / IMU_FILE), read_rotor_rpm_csv(tmp_path / ROTOR_FILE)
    return process_flight(imu, rotor, cutoff_hz=cutoff_hz)


def test_filter_leaves_a_constant_unchanged(tmp_path):
    def const(value):
        return lambda t: np.tile(value, (len(t), 1))

    sig = _process_with(
        tmp_path, const([0.1, -0.2, 9.81]), const([0.0, 0.5, -1.0]), const([9e3] * 4), 10.0
    )
    np.testing.assert_allclose(sig.y, np.tile([0.1, -0.2, 9.81, 0.0, 0.5, -1.0], (1001, 1)))
    np.testing.assert_allclose(sig.u, 9e3 * 2 * math.pi / 60, rtol=1e-12)


def test_filter_keeps_a_slow_sine_and_removes_a_fast_one(tmp_path):
    """acc_x = sin(2π·0.5 t) + 0.5 sin(2π·20 t). With a 10 Hz order-4 Butterworth run forward
    and backward, the 20 Hz part keeps 0.5 / (1 + 2⁸) ≈ 0.002 of amplitude, the 0.5 Hz part is
    untouched in gain and phase; linear interpolation of the 100 Hz samples adds ≤ 1.3e-4.
    Away from the ends (1 s) the output is the slow sine within 0.005."""

    def acc(t):
        slow = np.sin(2 * np.pi * 0.5 * t)
        return np.column_stack([slow + 0.5 * np.sin(2 * np.pi * 20 * t), slow, slow])

    zeros3 = lambda t: np.zeros((len(t), 3))  # noqa: E731
    rpm = lambda t: np.full((len(t), 4), 9e3)  # noqa: E731
    filtered = _process_with(tmp_path, acc, zeros3, rpm, cutoff_hz=10.0)
    inner = slice(50, -50)
    slow = np.sin(2 * np.pi * 0.5 * filtered.t_s[inner])
    assert np.max(np.abs(filtered.y[inner, 0] - slow)) < 0.005
    assert np.max(np.abs(filtered.y[inner, 1] - slow)) < 5e-4  # slow part alone: no lag
    raw = _process_with(tmp_path, acc, zeros3, rpm, cutoff_hz=None)
    assert np.max(np.abs(raw.y[inner, 0] - slow)) > 0.1  # without the filter it stays


def test_cutoff_must_lie_below_nyquist(tmp_path, rng):
    csv_dir = write_linear_flight(tmp_path / "f", rng)
    imu, rotor = read_imu_csv(csv_dir / IMU_FILE), read_rotor_rpm_csv(csv_dir / ROTOR_FILE)
    with pytest.raises(DataError, match="cutoff_hz must lie in"):
        process_flight(imu, rotor, cutoff_hz=150.0)
    with pytest.raises(DataError, match="integer multiple"):
        process_flight(imu, rotor, work_rate_hz=130.0)


# ---------------------------------------------------------------- flights, split, dataset


def _write_flights(root: Path, rng, n: int) -> dict[str, int]:
    """n flights of different lengths; returns the expected number of 200-step chunks."""
    expected = {}
    for i in range(n):
        folder = root / f"traj{i}" / "yawForward" / "maxSpeed1p0"
        stop = 9.0 + 4.0 * i  # overlap [1.003, stop] → K = ⌊(stop − 1.003)·50⌋ + 1
        write_linear_flight(folder, rng, imu_span=(1.003, stop), rotor_span=(0.5, stop))
        expected[f"traj{i}/yawForward/maxSpeed1p0"] = (math.floor((stop - 1.003) * 50) + 1) // 200
    return expected


def test_load_splits_by_flight_into_a_real_dataset(tmp_path, rng):
    expected_chunks = _write_flights(tmp_path, rng, 5)
    ds = load_blackbird(tmp_path, n_val=1, n_test=1, seed=3)
    assert ds.dt == 0.02 and ds.n_u == 4 and ds.n_y == 6 and ds.state_names is None
    meta = ds.metadata
    assert meta["real_data"] is True and meta["simulated"] is False
    assert meta["source"] == "Blackbird UAV dataset (real flights)"
    flights = meta["split"]["flights"]
    assert meta["split"]["flight_counts"] == {"train": 3, "val": 1, "test": 1}
    assert sorted(f for ids in flights.values() for f in ids) == sorted(expected_chunks)
    for name, ids in flights.items():
        chunks = ds.split(name)
        assert {tr.info["flight"] for tr in chunks} == set(ids)
        assert len(chunks) == sum(expected_chunks[f] for f in ids)
        for tr in chunks:
            assert tr.T == 200 and tr.x is None and tr.y_clean is None
            assert tr.info["chunk_start"] == 200 * tr.info["chunk"]
    assert set(meta["files"]) == set(expected_chunks)
    assert len(meta["files"]["traj0/yawForward/maxSpeed1p0"]["imu"]["sha256"]) == 64
    # same seed → same split; the dataset round-trips through storage
    assert load_blackbird(tmp_path, n_val=1, n_test=1, seed=3).metadata["split"] == meta["split"]
    path = ds.save(tmp_path / "out" / "blackbird.npz")
    back = Dataset.load(path)
    assert back.counts() == ds.counts() and back.metadata["real_data"] is True


def test_split_is_seeded_disjoint_and_counts_are_checked():
    ids = [f"f{i:03d}" for i in range(176)]
    split = split_flights(ids, seed=0)
    assert {k: len(v) for k, v in split.items()} == {"train": 146, "val": 20, "test": 10}
    assert sorted(f for ids in split.values() for f in ids) == ids
    assert split_flights(ids, seed=0) == split
    assert split_flights(ids, seed=1) != split
    assert len(split_flights(ids, n_train=50, seed=0)["train"]) == 50
    with pytest.raises(DataError, match="3 usable flight"):
        split_flights(["a", "b", "c"], n_val=2, n_test=1)


def test_a_flight_shorter_than_a_chunk_is_skipped_and_listed(tmp_path, rng):
    _write_flights(tmp_path, rng, 3)
    write_linear_flight(tmp_path / "short", rng, imu_span=(1.003, 3.0), rotor_span=(0.5, 3.0))
    ds = load_blackbird(tmp_path, n_val=1, n_test=1)
    assert ds.metadata["skipped_flights"] == [{"flight": "short", "samples": 100}]
    assert all("short" not in ids for ids in ds.metadata["split"]["flights"].values())


# ---------------------------------------------------------------- bad input names the file


def test_missing_column_names_the_file(tmp_path):
    path = tmp_path / IMU_FILE
    path.write_text("rosbagTimestamp,angular_velocity,x,y,z\n1,,0,0,0\n")
    with pytest.raises(DataError, match=rf"{IMU_FILE}: missing column 'linear_acceleration'"):
        read_imu_csv(path)
    path = tmp_path / ROTOR_FILE
    path.write_text("time,rpm\n1,[1, 2, 3, 4]\n")
    with pytest.raises(DataError, match=rf"{ROTOR_FILE}: missing column 'rosbagTimestamp'"):
        read_rotor_rpm_csv(path)


def test_non_monotonic_timestamps_name_the_file_and_line(tmp_path):
    t = np.array([0.0, 0.01, 0.03, 0.02, 0.04])
    write_imu(tmp_path / IMU_FILE, t, _acc(t), _gyro(t))
    with pytest.raises(DataError, match=rf"{IMU_FILE}: timestamps are not strictly.*line 5"):
        read_imu_csv(tmp_path / IMU_FILE)
    t = np.array([0.0, 0.01, 0.01])
    write_rotor(tmp_path / ROTOR_FILE, t, _rpm(t))
    with pytest.raises(DataError, match=rf"{ROTOR_FILE}: timestamps are not strictly.*line 4"):
        read_rotor_rpm_csv(tmp_path / ROTOR_FILE)


def test_no_overlap_between_the_clocks_names_both_files(tmp_path, rng):
    t_imu = _imu_times(0.0, 5.0)
    t_rot = _rotor_times(6.0, 9.0, rng)
    write_imu(tmp_path / "csv" / IMU_FILE, t_imu, _acc(t_imu), _gyro(t_imu))
    write_rotor(tmp_path / "csv" / ROTOR_FILE, t_rot, _rpm(t_rot))
    with pytest.raises(DataError, match=rf"no overlap.*{IMU_FILE}.*{ROTOR_FILE}"):
        load_blackbird(tmp_path, n_val=0, n_test=0)


def test_malformed_rows_and_layouts_are_refused(tmp_path):
    t = np.array([0.0, 0.01])
    write_rotor(tmp_path / ROTOR_FILE, t, _rpm(t))
    text = (tmp_path / ROTOR_FILE).read_text().replace('"[', '"').replace(']"', '"')
    (tmp_path / ROTOR_FILE).write_text(text)
    with pytest.raises(DataError, match=rf"{ROTOR_FILE}, line 2: no rotor-speed vector"):
        read_rotor_rpm_csv(tmp_path / ROTOR_FILE)
    write_imu(tmp_path / IMU_FILE, t, _acc(t), _gyro(t))
    lines = (tmp_path / IMU_FILE).read_text().splitlines()
    (tmp_path / IMU_FILE).write_text("\n".join([*lines[:2], lines[2] + ",extra"]) + "\n")
    with pytest.raises(DataError, match=rf"{IMU_FILE}, line 3: 24 fields but the header has 23"):
        read_imu_csv(tmp_path / IMU_FILE)
    gyro = _gyro(t)
    gyro[1, 2] = np.nan
    write_imu(tmp_path / IMU_FILE, t, _acc(t), gyro)
    with pytest.raises(
        DataError, match=rf"{IMU_FILE}, line 3: gyroscope z is 'nan' \(not finite\)"
    ):
        read_imu_csv(tmp_path / IMU_FILE)


def test_missing_files_and_empty_roots(tmp_path):
    with pytest.raises(DataError, match="not a folder"):
        find_flights(tmp_path / "nowhere")
    with pytest.raises(DataError, match="no Blackbird flight below"):
        find_flights(tmp_path)
    t = np.array([0.0, 0.01])
    write_imu(tmp_path / "a" / "csv" / IMU_FILE, t, _acc(t), _gyro(t))
    with pytest.raises(DataError, match=rf"{IMU_FILE}: the rotor-speed file .* is missing"):
        find_flights(tmp_path)
    with pytest.raises(DataError, match="not found"):
        read_imu_csv(tmp_path / "missing.csv")
