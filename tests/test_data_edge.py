"""The edge of the data loaders: values that used to be accepted silently (complex MATLAB
variables, text where a number belongs, underscores and non-ASCII digits in CSV cells, duplicate
column names, an irregular EMPS clock), messages that must name the file and what was expected,
files that are not regular files, and the arrays a valid CSV file loads to, fixed bit for bit."""

from __future__ import annotations

import contextlib
import os
import re
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from test_benchmarks import write_benchmark
from test_blackbird import write_imu

from canonid.datagen.benchmarks import load_benchmark
from canonid.datagen.blackbird import IMU_FILE, read_imu_csv
from canonid.datagen.loaders import data_checksum, load_csv, load_data, split_train_val
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError


def refused(match: str, call, *args, **kwargs) -> str:
    """``call`` raises a one-line DataError matching ``match`` and no warning; its text."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a raw numpy warning on the way is a failure too
        with pytest.raises(DataError, match=match) as err:
            call(*args, **kwargs)
    assert "\n" not in str(err.value)
    return str(err.value)


# ------------------------------------------------------------------------------ .mat files
def _tanks(tmp_path, **replace):
    """A Cascaded Tanks file whose variables ``replace`` overrides."""
    write_benchmark("cascaded-tanks", tmp_path, flat=True)
    path = tmp_path / "dataBenchmark.mat"
    content = {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    scipy.io.savemat(path, {**content, **replace})
    return path


def test_complex_mat_values_are_refused_unless_the_imaginary_part_is_zero(tmp_path):
    u = scipy.io.loadmat(_tanks(tmp_path))["uEst"]
    _tanks(tmp_path, uEst=u + 1e-3j)
    message = refused(
        r"variable 'uEst' holds complex values", load_benchmark, "cascaded-tanks", tmp_path
    )
    assert "dataBenchmark.mat" in message and "expected real numbers" in message
    _tanks(tmp_path, uEst=u + 0j)  # stored complex, but real: the same data as before
    loaded = load_benchmark("cascaded-tanks", tmp_path).split("train")[0].u[:, 0]
    np.testing.assert_array_equal(loaded, u[:, 0])


def test_a_sampling_time_stored_as_text_is_refused_naming_the_field(tmp_path):
    _tanks(tmp_path, Ts="4.0")
    refused(
        r"dataBenchmark\.mat: variable 'Ts' is text \('4\.0'\); expected numbers",
        load_benchmark,
        "cascaded-tanks",
        tmp_path,
    )


def test_a_sampling_frequency_whose_inverse_overflows_names_fs(tmp_path):
    write_benchmark("wiener-hammerstein", tmp_path, flat=True)
    path = tmp_path / "WienerHammerBenchMark.mat"
    content = {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    scipy.io.savemat(path, {**content, "fs": [[1e-320]]})
    message = refused(r"variable 'fs' = 1e-320", load_benchmark, "wiener-hammerstein", tmp_path)
    assert "sampling frequency in Hz" in message and "inf" not in message


def _emps(tmp_path, t_train):
    write_benchmark("emps", tmp_path, flat=True)
    path = tmp_path / "DATA_EMPS.mat"
    content = {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    scipy.io.savemat(path, {**content, "t": np.asarray(t_train)[:, None]})
    return path


def test_emps_sampling_is_checked_over_the_whole_record(tmp_path):
    t = np.arange(600) * 1e-3
    jump = t.copy()
    jump[300:] += 1e-3  # one sample missing in the middle: dt from t[1] − t[0] would hide it
    _emps(tmp_path, jump)
    message = refused(r"variable 't' is not uniformly sampled", load_benchmark, "emps", tmp_path)
    assert "DATA_EMPS.mat" in message and "t[300] − t[299]" in message
    _emps(tmp_path, t[:2])  # two samples for a record of 600
    refused(r"variable 't' has 2 samples but 'vir' has 600", load_benchmark, "emps", tmp_path)
    jitter = t + np.where(np.arange(600) % 2, 1e-9, 0.0)  # within the tolerance
    _emps(tmp_path, jitter)
    assert load_benchmark("emps", tmp_path).dt == jitter[1] - jitter[0]  # the package's dt


def test_emps_records_too_short_for_n_init_are_refused(tmp_path):
    write_benchmark("emps", tmp_path, flat=True)
    path = tmp_path / "DATA_EMPS.mat"
    short = {"qm": np.ones((5, 1)), "vir": np.ones((5, 1)), "t": np.arange(5)[:, None] * 1e-3}
    scipy.io.savemat(path, short)
    refused(
        r"DATA_EMPS\.mat: variable 'vir' has 5 samples; .* at least 21",
        load_benchmark,
        "emps",
        tmp_path,
    )


# ------------------------------------------------------------------------------ CSV files
@contextlib.contextmanager
def unread_fifo(path: Path) -> Iterator[Path]:
    """A FIFO at ``path`` that must never be opened for reading: a watcher feeds and closes any
    reader (a loader that opened it would block forever otherwise) and the check fails."""
    os.mkfifo(path)
    done, opened = threading.Event(), threading.Event()

    def watch() -> None:
        while not done.wait(0.01):
            try:  # succeeds only while someone holds the FIFO open for reading
                fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:
                continue
            opened.set()
            os.write(fd, b"u,y\n1,2\n")
            os.close(fd)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        yield path
    finally:
        done.set()
        watcher.join()
    assert not opened.is_set(), f"{path} was opened for reading"


def test_a_fifo_is_named_a_fifo_not_a_missing_file(tmp_path):
    expected = r"data\.csv is a FIFO \(named pipe\), not a regular file"
    with unread_fifo(tmp_path / "data.csv") as fifo:
        refused(expected, load_csv, fifo, inputs=["u"], outputs=["y"], dt=1.0)
        refused(expected, load_data, fifo, inputs=["u"], outputs=["y"], dt=1.0)
        refused(expected, load_data, fifo)  # not opened to read a header for the message
        refused(expected, data_checksum, fifo)
    with unread_fifo(tmp_path / "data.npz") as npz:
        refused(r"data\.npz is a FIFO \(named pipe\)", load_data, npz, dt=1.0)


@pytest.mark.parametrize(
    ("cell", "shown"),
    [("1_000", "'1_000'"), ("１２", "'１２'"), ("٣", "'٣'"), ("0x10", "'0x10'")],
)
def test_only_plain_ascii_numbers_are_read(tmp_path, cell, shown):
    path = tmp_path / "d.csv"
    path.write_text(f"u,y\n1,2\n{cell},3\n", encoding="utf-8")
    refused(
        rf"d\.csv, line 3, column 'u': {shown} is not a number \(expected",
        load_csv,
        path,
        inputs=["u"],
        outputs=["y"],
        dt=1.0,
    )


@pytest.mark.parametrize("cell", ["nan", "-NaN", "inf", "+Infinity", "1e999", " -inf "])
def test_non_finite_spellings_are_still_refused_as_not_finite(tmp_path, cell):
    path = tmp_path / "d.csv"
    path.write_text(f"u,y\n1,2\n3,{cell}\n")
    refused(
        rf"line 3, column 'y': {re.escape(repr(cell.strip()))} is not finite",
        load_csv,
        path,
        inputs=["u"],
        outputs=["y"],
        dt=1.0,
    )


def test_blackbird_files_read_plain_numbers_only(tmp_path):
    t = np.array([0.0, 0.01])
    path = write_imu(tmp_path / IMU_FILE, t, np.ones((2, 3)), np.ones((2, 3)))
    lines = path.read_text().splitlines(keepends=True)
    path.write_text(lines[0] + lines[1] + lines[2].replace(",1.0,", ",1_0,", 1))
    refused(rf"{IMU_FILE}, line 3: gyroscope x '1_0' is not a number", read_imu_csv, path)
    stamp = lines[2].split(",", 1)[0]
    wide = "".join(chr(ord(c) + 0xFEE0) for c in stamp)  # the same digits, fullwidth
    path.write_text(lines[0] + lines[1] + lines[2].replace(stamp, wide, 1))
    refused(rf"{IMU_FILE}, line 3: timestamp '{wide}' is not a number", read_imu_csv, path)


def test_a_duplicate_column_name_is_refused_naming_it(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("y,u, y\n0,1,5\n0,2,6\n")
    refused(
        r"d\.csv: the header names column 'y' 2 times \(columns 1 and 3\)",
        load_csv,
        path,
        inputs=["u"],
        outputs=["y"],
        dt=1.0,
    )
    # a duplicate the loader is not asked for is no ambiguity
    other = tmp_path / "e.csv"
    other.write_text("u,y,note,note\n1,2,a,b\n3,4,c,d\n")
    data = load_csv(other, inputs=["u"], outputs=["y"], dt=1.0)
    np.testing.assert_array_equal(data.split("train")[0].y, [[2.0], [4.0]])


def test_a_valid_csv_loads_to_the_same_arrays_as_before(tmp_path):
    """Fixed expected arrays (what the loader gave before it streamed): every notation of a
    number, whitespace, CRLF line ends, a byte-order mark, blank lines, quoted cells and
    experiments, the exact doubles nearest to each decimal."""
    path = tmp_path / "d.csv"
    text = (
        "\ufeffrun, u ,y,note\r\n"
        "a,1,-2.5,x\r\n"
        "a, +.5 ,1e-3,\r\n"
        "\r\n"
        ",,,\r\n"
        'a,"7.",0.1,"q,r"\r\n'
        "b,-0,1E+2,\r\n"
        "b,123456789012345678901234567890,2.2250738585072014e-308,\r\n"
        "b,4.9e-324,0.30000000000000004,\r\n"
    )
    path.write_bytes(text.encode("utf-8"))
    data = load_csv(path, inputs=["u"], outputs=["y"], dt=0.5, experiment_column="run")
    a, b = data.split("train")
    expected_a = np.array([[1.0, -2.5], [0.5, 1e-3], [7.0, 0.1]])
    expected_b = np.array(
        [
            [-0.0, 100.0],
            [1.2345678901234568e29, 2.2250738585072014e-308],
            [5e-324, 0.30000000000000004],
        ]
    )
    for traj, expected in ((a, expected_a), (b, expected_b)):
        assert traj.u.dtype == traj.y.dtype == np.float64
        assert traj.u.tobytes() == np.ascontiguousarray(expected[:, :1]).tobytes()
        assert traj.y.tobytes() == np.ascontiguousarray(expected[:, 1:]).tobytes()
    assert np.signbit(b.u[0, 0])  # -0 stays negative zero
    assert data.metadata["experiments"] == ["d.csv:run=a", "d.csv:run=b"]


def test_a_long_csv_is_read_across_chunks_and_errors_name_their_line(tmp_path):
    rng = np.random.default_rng(3)
    values = rng.normal(size=(150_000, 2)) * 10.0 ** rng.integers(-20, 20, size=(150_000, 2))
    path = tmp_path / "long.csv"
    with path.open("w") as f:
        f.write("u,y,run\n")
        f.writelines(
            f"{float(u)!r},{float(y)!r},{'ab'[i >= 100_000]}\n" for i, (u, y) in enumerate(values)
        )
    data = load_csv(path, inputs=["u"], outputs=["y"], dt=1.0, experiment_column="run")
    first, second = data.split("train")
    np.testing.assert_array_equal(np.vstack([first.u, second.u])[:, 0], values[:, 0])
    np.testing.assert_array_equal(np.vstack([first.y, second.y])[:, 0], values[:, 1])
    assert (first.T, second.T) == (100_000, 50_000)
    # an error deep in the file names its line, and the first problem in file order wins
    lines = path.read_text().splitlines(keepends=True)
    lines[120_001] = "1,1_0,b\n"
    lines[140_001] = "1,2\n"
    path.write_text("".join(lines))
    refused(
        r"long\.csv, line 120002, column 'y': '1_0' is not a number",
        load_csv,
        path,
        inputs=["u"],
        outputs=["y"],
        dt=1.0,
    )


# ------------------------------------------------------------------------------ splits
def test_a_record_too_short_to_split_names_the_file_the_fraction_and_the_minimum(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("u,y\n" + "".join(f"{t},{t}\n" for t in range(5)))
    data = load_csv(path, inputs=["u"], outputs=["y"], dt=1.0)
    message = refused(
        r"short\.csv: record 'short\.csv' has 5 samples, too few to cut a validation tail of "
        r"--val-fraction 0\.2 \(at least 2 samples each side\): it needs at least 6 samples",
        split_train_val,
        data,
        val_fraction=0.2,
    )
    assert "record 0" not in message
    assert [t.T for t in split_train_val(data, val_fraction=0.5).split("val")] == [3]
    assert [t.T for t in split_train_val(_record(6), val_fraction=0.2).split("val")] == [2]
    # the minimum stated is the true one: one sample fewer fails, that many succeeds
    for fraction in (0.2, 0.05, 0.5, 0.9, 0.33, 0.999, 1e-4):
        text = refused("at least", split_train_val, _record(1), val_fraction=fraction)
        need = int(text.rsplit("at least ", 1)[1].split()[0])
        split_train_val(_record(need), val_fraction=fraction)
        refused("too few", split_train_val, _record(need - 1), val_fraction=fraction)


def _record(n: int) -> Dataset:
    return Dataset.from_arrays(np.zeros((n, 1)), np.zeros((n, 1)), dt=1.0)
