"""Sizes and numbers a user can give that would make canonid allocate without bound, divide by
zero or fail deep inside numpy or torch (issue 54, cases 7, 8, 9, 12 and 22): each is refused in
one line that names the argument or file and what was expected, exit 1, before anything is
written."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from cli_helpers import one_line_error

from canonid.cli import main

TINY = ["--profile", "tiny", "--epochs", "1", "--device", "cpu", "--no-progress"]
CSV = ["--inputs", "u", "--outputs", "y", "--dt", "1"]


def _csv(path: Path, y=lambda t: math.cos(0.2 * t), n: int = 120) -> Path:
    rows = "".join(f"{math.sin(0.3 * t)!r},{float(y(t))!r}\n" for t in range(n))
    path.write_text("u,y\n" + rows, encoding="utf-8")
    return path


def test_a_constant_output_column_is_refused_before_the_run_folder_is_written(tmp_path, capsys):
    data = _csv(tmp_path / "flat.csv", y=lambda t: 2.5)
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--window", "2", "--cubic", "0", "--out", str(out)]
    one_line_error(capsys, main(argv), "flat.csv", "output column 'y' is constant")
    assert not out.exists()


def test_arx_on_constant_data_is_refused_not_reported_as_a_perfect_fit(tmp_path, capsys):
    """Issue 54, case 14: ARX on constant data reported a 100 % fit beside raw matplotlib
    warnings; the constant output is refused first, for the linear model too."""
    data = _csv(tmp_path / "flat.csv", y=lambda t: 2.5)
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--model", "arx", "--window", "2", "--out", str(out)]
    one_line_error(capsys, main(argv), "flat.csv", "output column 'y' is constant")
    assert not out.exists()


@pytest.mark.parametrize(
    ("sizes", "needle"),
    [
        (["--hidden", "1000000000"], "--hidden 1000000000: the network would need at least"),
        (["--hidden", "100000,100000"], "--hidden 100000,100000: the network would need at least"),
        (["--cubic", "1000000000"], "--cubic 1000000000: the network would need at least"),
    ],
)
def test_a_network_past_the_memory_ceiling_is_refused_before_any_allocation(
    sizes, needle, tmp_path, capsys, monkeypatch
):
    monkeypatch.delenv("CANONID_MAX_NETWORK_GB", raising=False)
    data = _csv(tmp_path / "ok.csv")
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--window", "2", *sizes, "--out", str(out)]
    line = one_line_error(capsys, main(argv), needle, "ceiling of 4 GB", "CANONID_MAX_NETWORK_GB")
    assert " GB to train" in line
    assert not out.exists()


def test_the_memory_ceiling_can_be_lowered_and_raised(tmp_path, capsys, monkeypatch):
    from canonid.kernel.catalog import check_network_memory, network_bytes

    # one line of rule: 12 bytes (float32 weight, Adam's two moments) per parameter
    assert network_bytes([3], 2, 4, 1) == 12 * ((4 + 1) * 3 + (3 + 1) * 1 + 2 * (4 + 1 + 1))
    monkeypatch.setenv("CANONID_MAX_NETWORK_GB", "1e-6")
    data = _csv(tmp_path / "ok.csv")
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--window", "2", "--hidden", "64,64"]
    one_line_error(capsys, main([*argv, "--out", str(out)]), "ceiling of 1e-06 GB")
    assert not out.exists()
    monkeypatch.setenv("CANONID_MAX_NETWORK_GB", "1000")
    check_network_memory([100000, 100000], 0, 2, 1, given="--hidden 100000,100000")  # 120 GB
    monkeypatch.setenv("CANONID_MAX_NETWORK_GB", "lots")
    one_line_error(capsys, main([*argv, "--out", str(out)]), "CANONID_MAX_NETWORK_GB: expected")


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        (["--windows-per-epoch", "1000000000000"], "--windows-per-epoch must be an integer from 1"),
        (["--windows-per-epoch", "10000001"], "--windows-per-epoch must be an integer from 1"),
        (["--lr", "1e308"], "--lr must be a number in (0, 10], got 1e+308"),
        (["--lr", "11"], "--lr must be a number in (0, 10]"),
    ],
)
def test_training_options_out_of_range_leave_nothing_behind(option, needle, tmp_path, capsys):
    data = _csv(tmp_path / "ok.csv")
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--window", "2", "--cubic", "0", *option]
    one_line_error(capsys, main([*argv, "--out", str(out)]), needle)
    assert not out.exists()


def test_train_options_hold_the_same_maxima_for_the_api():
    from canonid.kernel.errors import OptionError
    from canonid.learning import TrainOptions

    with pytest.raises(OptionError, match="lr must be at most 10"):
        TrainOptions(lr=1e308)
    with pytest.raises(OptionError, match="windows_per_epoch must be at most 1e"):
        TrainOptions(windows_per_epoch=10**12)
    TrainOptions(lr=10.0, windows_per_epoch=10_000_000)


def test_a_subnormal_or_absurd_sampling_time_is_refused_in_one_line(tmp_path, capsys):
    import numpy as np

    data = _csv(tmp_path / "ok.csv")
    out = tmp_path / "run"
    train = ["train", "--inputs", "u", "--outputs", "y", *TINY, "--window", "2", "--cubic", "0"]
    for dt in ("1e-320", "1e12"):
        argv = [*train[:1], str(data), *train[1:], "--dt", dt, "--out", str(out)]
        one_line_error(capsys, main(argv), "ok.csv", "sampling time dt must be from 1e-09 to")
        assert not out.exists()
    # a time column that steps by a subnormal
    timed = tmp_path / "timed.csv"
    rows = "".join(f"{k * 1e-320!r},{math.sin(k)!r},{math.cos(k)!r}\n" for k in range(60))
    timed.write_text("t,u,y\n" + rows, encoding="utf-8")
    argv = [*train[:1], str(timed), *train[1:], "--out", str(out)]
    one_line_error(capsys, main(argv), "timed.csv", "time column 't'", "sampling time dt must")
    # an .npz that stores one
    npz = tmp_path / "data.npz"
    np.savez(npz, u=np.sin(np.arange(60.0))[:, None], y=np.cos(np.arange(60.0))[:, None], dt=1e-320)
    argv = ["train", str(npz), *TINY, "--window", "2", "--cubic", "0", "--out", str(out)]
    one_line_error(capsys, main(argv), "data.npz", "sampling time dt must be from")
    assert not out.exists()


def test_a_benchmark_file_with_a_subnormal_sampling_time_is_refused(tmp_path):
    import scipy.io

    from canonid.datagen.benchmarks import benchmark, load_benchmark
    from canonid.kernel.errors import DataError

    folder = tmp_path / benchmark("cascaded-tanks").folder
    folder.mkdir(parents=True)
    col = [[0.1 * k] for k in range(1024)]
    mat = {"uEst": col, "yEst": col, "uVal": col, "yVal": col, "Ts": [[1e-320]]}
    scipy.io.savemat(folder / "dataBenchmark.mat", mat)
    with pytest.raises(DataError, match=r"dataBenchmark\.mat: sampling time dt must be from"):
        load_benchmark("cascaded-tanks", tmp_path)


@pytest.mark.parametrize("budget", ["1e308", "inf", "nan", "0", "86401"])
def test_an_analysis_budget_past_its_finite_maximum_is_refused(budget, tmp_path, capsys):
    out = tmp_path / "a"
    argv = ["analyze", "linear", "--window", "2", "--budget", budget, "--out", str(out)]
    one_line_error(capsys, main(argv), "--budget must be a number of seconds in (0, 86400]")
    assert not out.exists()
