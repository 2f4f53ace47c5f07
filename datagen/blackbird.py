"""Loader for the **real** Blackbird UAV flights (the paper's third benchmark, "3D Drone").

Blackbird (Antonini, Guerra, Murali, Sayre-McCord, Karaman; ISER 2018 / IJRR 2020) records
aggressive indoor quadrotor flights. Following the paper (appendix, "3D drone"), this module keeps
the **rotor speeds** as inputs and the **IMU** (specific force and angular rate in the sensor's
body frame) as outputs, synchronises the two streams, low-pass filters them with a Butterworth
filter, resamples to 50 Hz, cuts 200-step chunks and splits by flight (146 / 20 / 10).

Expected files (as the dataset distributes them)
------------------------------------------------
Each flight is a folder ``<trajectory>/<yawMode>/maxSpeed<X>p<Y>/`` of the download, whose
``csv/`` subfolder holds ROS-topic exports; two of them are read::

    <flight>/csv/blackbird_slash_imu.csv        topic /blackbird/imu       (~100 Hz)
    <flight>/csv/blackbird_slash_rotor_rpm.csv  topic /blackbird/rotor_rpm (~190 Hz)

Every folder below ``root`` that holds ``blackbird_slash_imu.csv`` is a flight (the ``csv/``
level is optional); its rotor file must sit next to it. The flight's id is its folder path
relative to ``root`` without the trailing ``csv`` (e.g. ``clover/yawForward/maxSpeed5p0``).

``blackbird_slash_imu.csv`` — a header row and one row per ``sensor_msgs/Imu`` message, aligned
with the header. Columns read:

* ``rosbagTimestamp``: integer nanoseconds of the bag's clock;
* the three columns ``x, y, z`` right after the (empty) column ``angular_velocity``: the
  gyroscope [rad/s, the ``sensor_msgs/Imu`` convention; ``gyro_units="deg/s"`` converts];
* the three columns ``x, y, z`` right after the (empty) column ``linear_acceleration``: the
  accelerometer [m/s²].

Every data row must have as many fields as the header (otherwise the layout is not the one
described here and the loader says so rather than reading shifted columns).

``blackbird_slash_rotor_rpm.csv`` — a header row and one row per rotor message. Its header is
known to be misaligned with its rows (it lists a ``-`` marker per motor time stamp that the rows
do not contain), so only two things are read from each row:

* the field under ``rosbagTimestamp`` (the first column; integer nanoseconds, same clock);
* the rotor-speed vector ``[r1, r2, r3, r4]`` in rpm (one quoted field, or four fields from ``[``
  to ``]``), wherever it lies in the row. It is converted to rad/s (× 2π/60) and the motor order
  of the file is kept.

Processing (per flight)
-----------------------
1. **Synchronisation.** Both files are stamped by the same bag clock (``rosbagTimestamp``).
   Timestamps must be strictly increasing in each file. The common time base is seconds from
   ``t0``, the later of the two first stamps; only the overlap ``[t0, t1]``, ``t1`` the earlier
   of the two last stamps, is kept. No overlap is an error.
2. **Working grid.** Each stream is linearly interpolated onto the uniform grid
   ``t0 + j / work_rate_hz`` (``work_rate_hz`` an integer multiple of ``rate_hz``; 200 Hz by
   default, above both native rates), which removes the streams' jitter.
3. **Low-pass.** Butterworth, order ``filter_order`` (4), cutoff ``cutoff_hz`` (10 Hz, below the
   25 Hz Nyquist frequency of the 50 Hz output, so it is also the anti-aliasing filter), applied
   forward and backward (``scipy.signal.sosfiltfilt``: zero phase, squared magnitude response,
   i.e. −6 dB at the cutoff) to every column on the working grid. ``cutoff_hz=None`` skips it.
   The paper names the filter family only; cutoff and order are this loader's choice.
4. **Resampling.** Every ``work_rate_hz / rate_hz``-th working sample is kept: sample ``k`` of the
   flight is the signal at ``t0 + k / rate_hz``, ``k = 0 … K−1``,
   ``K = ⌊(t1 − t0) rate_hz⌋ + 1``. (With the filter off, a signal linear in time is reproduced
   exactly.)
5. **Chunks.** Consecutive, non-overlapping chunks of ``chunk_length`` samples from ``k = 0``;
   the last ``K mod chunk_length`` samples are dropped. Chunk ``c`` holds samples
   ``c·chunk_length … (c+1)·chunk_length − 1``. A flight shorter than one chunk is skipped (and
   listed in the metadata).

Time alignment of the result (the project's convention): sample ``t`` holds the rotor speeds
``u[t]`` and the IMU reading ``y[t]`` taken at the same instant. There is no state ``x`` and no
noise-free ``y_clean``: this is measured data.

Split
-----
By flight, so no flight feeds two splits: the usable flights (sorted by id) are permuted with
``numpy.random.default_rng(seed)``; the first ``n_test`` go to ``test``, the next ``n_val`` to
``val`` and the rest (or the next ``n_train``) to ``train``. On the 176 flights the paper used,
the defaults give its 146 / 20 / 10.
"""

from __future__ import annotations

import csv
import importlib.metadata
import logging
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy

from canonid.datagen.chunks import cut_chunks
from canonid.datagen.loaders import plain_float, regular_file
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import DataError
from canonid.kernel.io import sha256_file

__all__ = [
    "IMU_FILE",
    "ROTOR_FILE",
    "BlackbirdFlight",
    "FlightSignals",
    "Stream",
    "find_flights",
    "load_blackbird",
    "lowpass",
    "process_flight",
    "read_imu_csv",
    "read_rotor_rpm_csv",
    "resample_linear",
    "split_flights",
]

log = logging.getLogger(__name__)

IMU_FILE = "blackbird_slash_imu.csv"
ROTOR_FILE = "blackbird_slash_rotor_rpm.csv"

INPUT_NAMES = ("Omega1", "Omega2", "Omega3", "Omega4")
OUTPUT_NAMES = ("acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z")
_RPM_TO_RAD_S = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class Stream:
    """One time-stamped signal read from a file.

    Attributes:
        t_ns: integer timestamps [ns], strictly increasing, shape ``(N,)`` (int64).
        values: samples, ``(N, n)``; row ``i`` was taken at ``t_ns[i]``.
        path: the file it came from (for error messages and metadata).
    """

    t_ns: np.ndarray
    values: np.ndarray
    path: Path


@dataclass(frozen=True)
class BlackbirdFlight:
    """A flight found on disk: its id (folder relative to the root) and its two files."""

    flight_id: str
    imu_path: Path
    rotor_path: Path


@dataclass(frozen=True)
class FlightSignals:
    """A processed flight on the output grid ``t_s[k] = k / rate_hz`` (seconds from ``t0``).

    Attributes:
        t_s: sample times [s] from the start of the overlap, ``(K,)``.
        u: rotor speeds [rad/s], ``(K, 4)``.
        y: IMU (acc_x, acc_y, acc_z [m/s²], gyro_x, gyro_y, gyro_z [rad/s]), ``(K, 6)``.
        t0_ns: start of the overlap on the bag clock [ns].
        max_gap_s: the longest interval between two raw samples inside the overlap, per
            stream (``{"imu": …, "rotor": …}``): interpolation bridges such gaps.
    """

    t_s: np.ndarray
    u: np.ndarray
    y: np.ndarray
    t0_ns: int
    max_gap_s: dict[str, float]


# ---------------------------------------------------------------------------- reading


def _read_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    regular_file(path, "Blackbird file")
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"{path}: not a readable CSV file ({exc})") from exc
    rows = [r for r in rows if r and any(field.strip() for field in r)]
    if not rows:
        raise DataError(f"{path}: the file is empty (expected a header row and data rows)")
    header = [h.strip() for h in rows[0]]
    if len(rows) < 2:
        raise DataError(f"{path}: has a header but no data rows")
    return header, rows[1:]


def _column(header: list[str], name: str, path: Path) -> int:
    try:
        return header.index(name)
    except ValueError:
        raise DataError(
            f"{path}: missing column {name!r} (header has: {', '.join(header[:30])})"
        ) from None


def _xyz_after(header: list[str], marker: str, path: Path) -> list[int]:
    i = _column(header, marker, path)
    if header[i + 1 : i + 4] != ["x", "y", "z"]:
        raise DataError(
            f"{path}: expected the columns x, y, z right after {marker!r}, found "
            f"{header[i + 1 : i + 4]}"
        )
    return [i + 1, i + 2, i + 3]


def _timestamp(field: str, path: Path, line: int) -> int:
    text = field.strip()
    if re.fullmatch(r"[+-]?[0-9]+", text):  # ASCII digits: `int` alone also reads 1_000, １２
        return int(text)
    try:
        value = plain_float(text)
    except ValueError:
        raise DataError(
            f"{path}, line {line}: timestamp {text!r} is not a number of nanoseconds"
        ) from None
    if not math.isfinite(value):
        raise DataError(f"{path}, line {line}: timestamp {text!r} is not finite")
    return round(value)


def _number(field: str, path: Path, line: int, what: str) -> float:
    try:
        value = plain_float(field)
    except ValueError:
        raise DataError(f"{path}, line {line}: {what} {field.strip()!r} is not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{path}, line {line}: {what} is {field.strip()!r} (not finite)")
    return value


def _check_increasing(t_ns: np.ndarray, path: Path) -> None:
    bad = np.flatnonzero(np.diff(t_ns) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataError(
            f"{path}: timestamps are not strictly increasing: data row {i + 1} (line {i + 2}) "
            f"has {int(t_ns[i])} ns after {int(t_ns[i - 1])} ns"
        )


def read_imu_csv(
    path: str | os.PathLike[str], *, gyro_units: Literal["rad/s", "deg/s"] = "rad/s"
) -> Stream:
    """Read ``blackbird_slash_imu.csv`` (layout in the module docstring).

    Returns a :class:`Stream` whose ``values`` are ``(N, 6)``: accelerometer x, y, z [m/s²],
    then gyroscope x, y, z [rad/s].
    """
    p = Path(path)
    header, rows = _read_rows(p)
    i_t = _column(header, "rosbagTimestamp", p)
    gyro = _xyz_after(header, "angular_velocity", p)
    acc = _xyz_after(header, "linear_acceleration", p)
    scale = {"rad/s": 1.0, "deg/s": math.pi / 180.0}.get(gyro_units)
    if scale is None:
        raise DataError(f"gyro_units must be 'rad/s' or 'deg/s', got {gyro_units!r}")
    t_ns = np.empty(len(rows), dtype=np.int64)
    values = np.empty((len(rows), 6))
    for r, row in enumerate(rows):
        line = r + 2
        if len(row) != len(header):
            raise DataError(
                f"{p}, line {line}: {len(row)} fields but the header has {len(header)}; this is "
                "not the Blackbird IMU layout the loader expects (see canonid.datagen.blackbird)"
            )
        t_ns[r] = _timestamp(row[i_t], p, line)
        for j, col in enumerate(acc + gyro):
            what = f"{'accelerometer' if j < 3 else 'gyroscope'} {'xyz'[j % 3]}"
            values[r, j] = _number(row[col], p, line, what)
    values[:, 3:6] *= scale
    _check_increasing(t_ns, p)
    return Stream(t_ns=t_ns, values=values, path=p)


def _rpm_vector(row: Sequence[str], path: Path, line: int) -> np.ndarray:
    start = next((i for i, f in enumerate(row) if f.strip().startswith("[")), None)
    if start is not None:
        for stop in range(start, len(row)):
            if row[stop].strip().endswith("]"):
                inner = ",".join(row[start : stop + 1]).strip()[1:-1]
                parts = [s for s in inner.split(",") if s.strip()]
                if len(parts) == 4:
                    return np.array([_number(s, path, line, "rotor speed") for s in parts])
                raise DataError(
                    f"{path}, line {line}: the rotor-speed vector has {len(parts)} entries, "
                    "expected 4"
                )
    raise DataError(
        f"{path}, line {line}: no rotor-speed vector '[r1, r2, r3, r4]' (rpm) in the row"
    )


def read_rotor_rpm_csv(path: str | os.PathLike[str]) -> Stream:
    """Read ``blackbird_slash_rotor_rpm.csv`` (layout in the module docstring).

    Returns a :class:`Stream` whose ``values`` are the four rotor speeds in rad/s, ``(N, 4)``.
    """
    p = Path(path)
    header, rows = _read_rows(p)
    i_t = _column(header, "rosbagTimestamp", p)
    _column(header, "rpm", p)
    t_ns = np.empty(len(rows), dtype=np.int64)
    values = np.empty((len(rows), 4))
    for r, row in enumerate(rows):
        line = r + 2
        if len(row) <= i_t:
            raise DataError(f"{p}, line {line}: the row has no rosbagTimestamp field")
        t_ns[r] = _timestamp(row[i_t], p, line)
        values[r] = _rpm_vector(row, p, line) * _RPM_TO_RAD_S
    _check_increasing(t_ns, p)
    return Stream(t_ns=t_ns, values=values, path=p)


# ---------------------------------------------------------------------------- processing


def resample_linear(t: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``values`` ``(N, n)`` sampled at increasing ``t`` onto ``grid``.

    ``grid`` must lie inside ``[t[0], t[-1]]`` (no extrapolation; 1 ns of rounding is allowed).
    A signal linear in time is reproduced exactly (to rounding).
    """
    t = np.asarray(t, dtype=np.float64)
    grid = np.asarray(grid, dtype=np.float64)
    if grid.size and (grid[0] < t[0] - 1e-9 or grid[-1] > t[-1] + 1e-9):
        raise DataError(
            f"resampling grid [{grid[0]}, {grid[-1]}] s leaves the samples' span "
            f"[{t[0]}, {t[-1]}] s (no extrapolation)"
        )
    return np.column_stack([np.interp(grid, t, col) for col in np.asarray(values).T])


def lowpass(values: np.ndarray, *, fs_hz: float, cutoff_hz: float, order: int) -> np.ndarray:
    """Zero-phase Butterworth low-pass of each column of ``values`` sampled at ``fs_hz``.

    ``scipy.signal.butter`` in second-order sections, applied forward and backward by
    ``sosfiltfilt`` (so the effective magnitude response is the square of the filter's, and
    the phase is zero). A constant column is returned unchanged (to rounding).
    """
    if not 0 < cutoff_hz < fs_hz / 2:
        raise DataError(
            f"cutoff_hz must lie in (0, {fs_hz / 2:g}) Hz (the Nyquist frequency of the "
            f"{fs_hz:g} Hz working grid), got {cutoff_hz}"
        )
    if order < 1:
        raise DataError(f"filter order must be >= 1, got {order}")
    # imported here: scipy.signal loads scipy.stats (slow, and it probes for torch, which the
    # datagen layer must import without)
    from scipy import signal

    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs_hz, output="sos")
    return np.asarray(signal.sosfiltfilt(sos, values, axis=0))


def _max_gap(t_ns: np.ndarray, lo: int, hi: int) -> float:
    inside = t_ns[(t_ns >= lo) & (t_ns <= hi)]
    edges = np.concatenate(([lo], inside, [hi]))
    return float(np.max(np.diff(edges))) / 1e9


def process_flight(
    imu: Stream,
    rotor: Stream,
    *,
    rate_hz: float = 50.0,
    work_rate_hz: float = 200.0,
    cutoff_hz: float | None = 10.0,
    filter_order: int = 4,
) -> FlightSignals:
    """Synchronise, filter and resample one flight (steps 1–4 of the module docstring)."""
    ratio = work_rate_hz / rate_hz
    if not (rate_hz > 0 and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
        raise DataError(
            f"work_rate_hz ({work_rate_hz}) must be a positive integer multiple of rate_hz "
            f"({rate_hz})"
        )
    m = round(ratio)
    t0 = max(int(imu.t_ns[0]), int(rotor.t_ns[0]))
    t1 = min(int(imu.t_ns[-1]), int(rotor.t_ns[-1]))
    if t1 <= t0:
        raise DataError(
            f"no overlap between the clocks of {imu.path} "
            f"[{imu.t_ns[0] / 1e9:.3f}, {imu.t_ns[-1] / 1e9:.3f}] s and {rotor.path} "
            f"[{rotor.t_ns[0] / 1e9:.3f}, {rotor.t_ns[-1] / 1e9:.3f}] s (bag clock)"
        )
    span = (t1 - t0) / 1e9
    n_out = math.floor(span * rate_hz + 1e-9) + 1
    t_work = np.arange((n_out - 1) * m + 1) / work_rate_hz
    signals = []
    for stream in (rotor, imu):
        t_rel = (stream.t_ns - t0).astype(np.float64) / 1e9  # exact integer difference first
        signals.append(resample_linear(t_rel, stream.values, t_work))
    work = np.hstack(signals)
    if cutoff_hz is not None:
        padlen = 3 * (2 * math.ceil(filter_order / 2) + 1)
        if len(work) <= padlen:
            raise DataError(
                f"flight of {imu.path.parent}: overlap of {span:.3f} s is too short to filter "
                f"({len(work)} working samples, need more than {padlen})"
            )
        work = lowpass(work, fs_hz=work_rate_hz, cutoff_hz=cutoff_hz, order=filter_order)
    out = work[::m]
    return FlightSignals(
        t_s=np.arange(n_out) / rate_hz,
        u=out[:, :4],
        y=out[:, 4:],
        t0_ns=t0,
        max_gap_s={"imu": _max_gap(imu.t_ns, t0, t1), "rotor": _max_gap(rotor.t_ns, t0, t1)},
    )


# ---------------------------------------------------------------------------- flights, split


def find_flights(root: str | os.PathLike[str]) -> list[BlackbirdFlight]:
    """Every flight below ``root`` (a folder holding ``blackbird_slash_imu.csv``), sorted by id."""
    base = Path(root)
    if not base.is_dir():
        raise DataError(f"Blackbird root is not a folder: {base}")
    flights = []
    for imu_path in sorted(base.rglob(IMU_FILE)):
        folder = imu_path.parent
        rotor_path = folder / ROTOR_FILE
        if not rotor_path.is_file():
            raise DataError(f"{imu_path}: the rotor-speed file {ROTOR_FILE} is missing next to it")
        flight_dir = folder.parent if folder.name == "csv" else folder
        flight_id = flight_dir.relative_to(base).as_posix() if flight_dir != base else "."
        flights.append(BlackbirdFlight(flight_id, imu_path, rotor_path))
    if not flights:
        raise DataError(
            f"no Blackbird flight below {base}: expected folders holding {IMU_FILE} and "
            f"{ROTOR_FILE} (e.g. <trajectory>/<yawMode>/<maxSpeed>/csv/)"
        )
    return sorted(flights, key=lambda f: f.flight_id)


def split_flights(
    flight_ids: Sequence[str],
    *,
    n_train: int | None = None,
    n_val: int = 20,
    n_test: int = 10,
    seed: int = 0,
) -> dict[str, list[str]]:
    """Seeded split of flight ids into ``train``/``val``/``test`` (see the module docstring).

    Each split's ids are returned sorted. ``n_train=None`` puts every remaining flight in train.
    """
    ids = sorted(flight_ids)
    if len(set(ids)) != len(ids):
        raise DataError("flight ids must be unique")
    if min(n_val, n_test) < 0 or (n_train is not None and n_train < 1):
        raise DataError(
            f"split counts must be n_train >= 1 (or None), n_val >= 0, n_test >= 0; got "
            f"{n_train}, {n_val}, {n_test}"
        )
    needed = n_val + n_test + (n_train if n_train is not None else 1)
    if needed > len(ids):
        raise DataError(
            f"{len(ids)} usable flight(s), but the split asks for "
            f"{'at least one' if n_train is None else n_train} train + {n_val} val + "
            f"{n_test} test"
        )
    order = [ids[i] for i in np.random.default_rng(seed).permutation(len(ids))]
    rest = order[n_test + n_val :]
    return {
        "train": sorted(rest if n_train is None else rest[:n_train]),
        "val": sorted(order[n_test : n_test + n_val]),
        "test": sorted(order[:n_test]),
    }


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def load_blackbird(
    root: str | os.PathLike[str],
    *,
    rate_hz: float = 50.0,
    work_rate_hz: float = 200.0,
    cutoff_hz: float | None = 10.0,
    filter_order: int = 4,
    chunk_length: int = 200,
    n_train: int | None = None,
    n_val: int = 20,
    n_test: int = 10,
    seed: int = 0,
    gyro_units: Literal["rad/s", "deg/s"] = "rad/s",
) -> Dataset:
    """Load every Blackbird flight below ``root`` into a :class:`~canonid.kernel.dataset.Dataset`.

    Each chunk becomes one :class:`~canonid.kernel.dataset.Trajectory` (``info``: ``flight`` id,
    ``chunk`` index, ``chunk_start`` sample of the flight's 50 Hz record, ``t0_ns`` start of the
    record on the bag clock, ``max_gap_s``); all chunks of a flight land in the same split.
    The metadata marks the data as real (``real_data: True``, ``simulated: False``) and records
    the processing settings, the split and the SHA-256 of every file read. See the module
    docstring for the expected files, the processing steps and the split rule.
    """
    flights = find_flights(root)
    processed: dict[str, list[Trajectory]] = {}
    files: dict[str, dict[str, dict[str, str]]] = {}
    skipped: list[dict[str, Any]] = []
    base = Path(root)
    for flight in flights:
        imu = read_imu_csv(flight.imu_path, gyro_units=gyro_units)
        rotor = read_rotor_rpm_csv(flight.rotor_path)
        sig = process_flight(
            imu,
            rotor,
            rate_hz=rate_hz,
            work_rate_hz=work_rate_hz,
            cutoff_hz=cutoff_hz,
            filter_order=filter_order,
        )
        record = Trajectory(
            u=sig.u,
            y=sig.y,
            info={"flight": flight.flight_id, "t0_ns": sig.t0_ns, "max_gap_s": sig.max_gap_s},
        )
        chunks = cut_chunks(record, chunk_length)
        if not chunks:
            log.warning(
                "%s: %d samples, shorter than one chunk; skipped", flight.flight_id, record.T
            )
            skipped.append({"flight": flight.flight_id, "samples": record.T})
            continue
        processed[flight.flight_id] = list(chunks)
        files[flight.flight_id] = {
            kind: {"path": path.relative_to(base).as_posix(), "sha256": sha256_file(path)}
            for kind, path in (("imu", flight.imu_path), ("rotor_rpm", flight.rotor_path))
        }
    split = split_flights(list(processed), n_train=n_train, n_val=n_val, n_test=n_test, seed=seed)
    splits = {
        name: tuple(tr for fid in ids for tr in processed[fid]) for name, ids in split.items()
    }
    metadata = {
        "source": "Blackbird UAV dataset (real flights)",
        "system": "blackbird",
        "real_data": True,
        "simulated": False,
        "units": {
            **{n: "rad/s" for n in INPUT_NAMES},
            **{n: "m/s^2" for n in OUTPUT_NAMES[:3]},
            **{n: "rad/s" for n in OUTPUT_NAMES[3:]},
        },
        "preprocessing": {
            "clock": "rosbagTimestamp [ns], shared by both files; t = 0 at the overlap start",
            "synchronisation": "overlap of the two streams, linear interpolation",
            "work_rate_hz": work_rate_hz,
            "filter": None
            if cutoff_hz is None
            else {
                "type": "butterworth low-pass",
                "order": filter_order,
                "cutoff_hz": cutoff_hz,
                "zero_phase": "scipy.signal.sosfiltfilt",
            },
            "rate_hz": rate_hz,
            "chunk_length": chunk_length,
            "remainder": "last K mod chunk_length samples of each flight dropped",
            "rotor_units": "rpm in the file, converted to rad/s",
            "gyro_units_in_file": gyro_units,
        },
        "split": {
            "by": "flight",
            "seed": seed,
            "flights": split,
            "flight_counts": {k: len(v) for k, v in split.items()},
        },
        "skipped_flights": skipped,
        "files": files,
        "versions": {
            "canonid": _version("canonid"),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
        },
    }
    return Dataset(
        splits=splits,
        dt=1.0 / rate_hz,
        input_names=INPUT_NAMES,
        output_names=OUTPUT_NAMES,
        metadata=metadata,
    )
