"""A corpus of bad inputs, written by the tests themselves, fed to every subcommand that reads
them: each must end in one line that names the file, field or argument and what was expected,
exit 1, no traceback, and nothing half-written. The loaders are also fed random bytes and
random CSV text: a clean :class:`CanonidError` or valid data, never anything else."""

from __future__ import annotations

import errno
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from cli_helpers import one_line_error
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from learning_helpers import damped_siso, trajectories
from test_data_edge import unread_fifo

from canonid.cli import main
from canonid.datagen.loaders import load_data
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import CanonidError

TRAIN = ["--model", "mlp", "--window", "2", "--epochs", "1", "--device", "cpu", "--no-progress"]
CSV = ["--inputs", "u", "--outputs", "y", "--dt", "1"]


def files_under(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# ------------------------------------------------------------------------------- good inputs
@pytest.fixture(scope="module")
def good(tmp_path_factory) -> dict[str, Path]:
    """A small canonid dataset and a run trained on it (one epoch)."""
    root = tmp_path_factory.mktemp("good")
    make = lambda n, seed: tuple(  # noqa: E731
        Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)
        for t in trajectories(damped_siso(), n, 110, noise=0.01, seed=seed)
    )
    data = Dataset(
        splits={"train": make(2, 1), "val": make(1, 2), "test": make(1, 3)},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
    ).save(root / "data" / "dataset.npz")
    run = root / "run"
    assert main(["train", str(data.parent), *TRAIN, "--out", str(run)]) == 0
    return {"data": data.parent, "run": run}


# ---------------------------------------------------------------------------------- the corpus
def _csv(text: str | bytes) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / "bad.csv"
        path.write_bytes(text if isinstance(text, bytes) else text.encode())
        return path

    return write


def _rows(n: int, first: str = "u,y") -> str:
    return first + "\n" + "".join(f"{float(np.sin(t))!r},{float(np.cos(t))!r}\n" for t in range(n))


CSV_CORPUS = {
    "non-utf8 cell": (_csv(b"u,y\n1,2\n\xff\xfe,3\n"), "bad.csv, line 3: not UTF-8 text"),
    "non-utf8 header": (_csv(b"u,\xe9y\n1,2\n"), "bad.csv, line 1: not UTF-8 text"),
    "binary": (_csv(bytes(range(256)) * 4), "not UTF-8 text"),
    "nul bytes": (_csv("u,y\n1,\x002\n"), "bad.csv, line 2, column 'y'"),
    "empty": (_csv(""), "empty file"),
    "header only": (_csv("u,y\n"), "no data rows"),
    "missing column": (_csv("u,z\n1,2\n"), "no column(s) ['y']"),
    "not a number": (_csv("u,y\n1,2\n1,abc\n"), "line 3, column 'y': 'abc' is not a number"),
    "not finite": (_csv("u,y\n1,2\n1,inf\n"), "line 3, column 'y': 'inf' is not finite"),
    "ragged row": (_csv("u,y\n1,2\n1,2,3\n"), "line 3: 3 fields, the header has 2"),
    "underscore digits": (_csv("u,y\n1,2\n1_000,3\n"), "column 'u': '1_000' is not a number"),
    "fullwidth digits": (_csv("u,y\n1,2\n１２,3\n"), "column 'u': '１２' is not a number"),
    "duplicate column": (
        _csv("y,u,y\n0,1,2\n0,1,3\n"),
        "bad.csv: the header names column 'y' 2 times (columns 1 and 3)",
    ),
}

SCATTERED = "run,u,y\n" + "".join(f"{'ab'[t // 30 % 2]},{t},{t}\n" for t in range(120))


def _npz(**arrays) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / "bad.npz"
        np.savez(path, **arrays)
        return path

    return write


def _raw(name: str, data: bytes) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / name
        path.write_bytes(data)
        return path

    return write


def _npy_renamed(folder: Path) -> Path:
    np.save(folder / "arr.npy", np.zeros((5, 2)))
    return (folder / "arr.npy").rename(folder / "bad.npz")


U, Y = np.zeros((120, 1)), np.ones((120, 1))
NPZ_CORPUS = {
    "dt empty": (_npz(u=U, y=Y, dt=np.array([])), "array 'dt' must hold one number"),
    "dt two values": (_npz(u=U, y=Y, dt=np.array([1.0, 2.0])), "array 'dt' must hold one"),
    "dt zero": (_npz(u=U, y=Y, dt=0.0), "dt must be from 1e-09 to 1e+09 s"),
    "complex": (_npz(u=U + 1j, y=Y, dt=1.0), "array 'u' has dtype complex128"),
    "text": (_npz(u=np.array(["1"] * 120), y=Y, dt=1.0), "array 'u' has dtype <U1"),
    "npy renamed": (_npy_renamed, "bad.npz is not an .npz archive"),
    "random bytes": (_raw("bad.npz", os.urandom(512)), "bad.npz is not an .npz archive"),
    "truncated zip": (
        lambda f: _raw("bad.npz", (_npz(u=U, y=Y, dt=1.0)(f)).read_bytes()[:300])(f),
        "bad.npz",
    ),
    "no y": (_npz(u=U, dt=1.0), "needs both arrays 'u' and 'y'"),
    "length mismatch": (_npz(u=U, y=Y[:50], dt=1.0), "u has 120 samples but y has 50"),
}


def _dataset_with(**fields) -> Callable[[Path, Path], Path]:
    """A copy of the good dataset whose dataset.json fields are replaced."""

    def write(folder: Path, source: Path) -> Path:
        target = folder / "ds"
        shutil.copytree(source, target)
        meta = target / "dataset.json"
        header = json.loads(meta.read_text())
        header.update(fields)
        meta.write_text(json.dumps(header))
        return target

    return write


DATASET_CORPUS = {
    "counts a string": (_dataset_with(counts="3"), "field 'counts' must be an object"),
    "count not a number": (_dataset_with(counts={"train": "x"}), "field 'counts' must be"),
    "counts too few": (
        _dataset_with(counts={"train": 1, "val": 1, "test": 1}, trajectory_info=None),
        "that dataset.json's field 'counts' does not count",
    ),
    "counts too many": (
        _dataset_with(counts={"train": 5, "val": 1, "test": 1}, trajectory_info=None),
        "lacks trajectories ['train/00002'",
    ),
    "dt a string": (_dataset_with(dt="fast"), "field 'dt' must be a number of seconds"),
    "dt negative": (_dataset_with(dt=-1.0), "dt must be from 1e-09 to 1e+09 s"),
    "input names a string": (_dataset_with(input_names="u"), "field 'input_names' must be a list"),
    "trajectory info a list": (_dataset_with(trajectory_info=[]), "field 'trajectory_info'"),
    "metadata a list": (_dataset_with(metadata=[]), "field 'metadata' must be an object"),
    "checksum a number": (_dataset_with(checksum_sha256=5), "field 'checksum_sha256' must be"),
    "format version": (_dataset_with(format_version=999), "field 'format_version' is 999"),
}


def _bad_weights(kind: str) -> Callable[[Path], None]:
    def damage(run: Path) -> None:
        path = run / "weights.pt"
        if kind == "nan":
            state = torch.load(path, weights_only=True)
            first = next(k for k, v in state.items() if v.is_floating_point())
            state[first] = torch.full_like(state[first], float("nan"))
            torch.save(state, path)
        elif kind == "pickle":
            torch.save({"evil": Path("x")}, path)  # an object besides tensors
        else:
            path.write_bytes(os.urandom(256))

    return damage


RUN_CORPUS = {
    "nan weights": (_bad_weights("nan"), "hold NaN or infinite values"),
    "pickled object": (_bad_weights("pickle"), "never unpickles"),
    "random weights": (_bad_weights("random"), "weights.pt: not a torch file"),
    "config not json": (
        lambda run: (run / "config.json").write_text("{"),
        "config.json is not valid JSON",
    ),
    "run recipe a list": (
        lambda run: (run / "run.json").write_text("[]"),
        "run.json is not",
    ),
}


# ------------------------------------------------------------------------------------ the tests
@pytest.mark.parametrize("case", sorted(CSV_CORPUS))
def test_bad_csv_is_refused_by_train_and_evaluate(case, good, tmp_path, capsys):
    write, needle = CSV_CORPUS[case]
    path = write(tmp_path)
    out = tmp_path / "run"
    one_line_error(capsys, main(["train", str(path), *CSV, *TRAIN, "--out", str(out)]), needle)
    assert not out.exists()
    before = files_under(good["run"])
    code = main(["evaluate", str(good["run"]), "--data", str(path), *CSV])
    one_line_error(capsys, code, needle)
    assert files_under(good["run"]) == before


def test_scattered_experiment_rows_and_overflowing_values_are_refused(tmp_path, capsys):
    scattered = tmp_path / "scattered.csv"
    scattered.write_text(SCATTERED)
    argv = ["train", str(scattered), *CSV, "--experiment-column", "run", *TRAIN]
    code = main([*argv, "--out", str(tmp_path / "a")])
    one_line_error(capsys, code, "scattered.csv, line 62: experiment 'a'", "contiguous")
    huge = tmp_path / "huge.csv"
    huge.write_text(_rows(600).replace("\n0.0,", "\n1e308,", 1))
    run = tmp_path / "b"
    code = main(["train", str(huge), *CSV, *TRAIN, "--out", str(run)])
    one_line_error(capsys, code, "input 1 (values up to 1e+308) overflows float64")
    assert not run.exists()  # nothing left that would block a re-run


def _timed_csv(path: Path, times: list[float], separator: str = ",") -> Path:
    """Two experiments, a column ``run`` naming them and a time column ``t`` at ``times``."""
    header = separator.join(["run", "t", "pump", "level"])
    rows = [
        separator.join([run, f"{t!r}", f"{1 + k % 3}", f"{0.1 * k}"])
        for run in ("a", "b")
        for k, t in enumerate(times)
    ]
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    return path


def test_data_that_disagree_with_the_options_are_refused_not_guessed(tmp_path, capsys):
    """The sampling time is never guessed: a --dt beside a time column that steps otherwise,
    and steps that are not uniform, are refused in one line naming --time-column none, which
    reads the rows as samples every --dt; a file separated by ';' is named so."""
    columns = ["--inputs", "pump", "--outputs", "level", "--experiment-column", "run"]
    data = _timed_csv(tmp_path / "train.csv", [float(k) for k in range(40)])
    run = tmp_path / "run"
    argv = ["train", str(data), *columns, *TRAIN, "--out", str(run)]
    err = one_line_error(capsys, main([*argv, "--dt", "0.5"]), "--time-column none")
    assert "dt = 0.5 s was given, but time column 't' steps by 1 s" in err
    assert "samples every 0.5 s" in err and not run.exists()
    uneven = _timed_csv(tmp_path / "uneven.csv", [k + 0.3 * (k % 2) for k in range(40)])
    argv = ["train", str(uneven), *columns, *TRAIN, "--out", str(run)]
    err = one_line_error(capsys, main([*argv, "--dt", "1"]), "'t' is not uniformly spaced")
    assert "(steps from 0.7 s to 1.3 s)" in err and "(CLI: --time-column none)" in err
    err = one_line_error(capsys, main(argv), "(CLI: --time-column none --dt SECONDS)")
    assert not run.exists()
    semi = _timed_csv(tmp_path / "semi.csv", [float(k) for k in range(40)], separator=";")
    argv = ["train", str(semi), *columns, *TRAIN, "--out", str(run)]
    one_line_error(capsys, main(argv), "semi.csv: the header", "is separated by ';', not commas")
    assert not run.exists()


def test_a_fifo_as_data_is_named_and_never_opened(good, tmp_path, capsys):
    with unread_fifo(tmp_path / "pipe.csv") as fifo:
        out = tmp_path / "run"
        code = main(["train", str(fifo), *CSV, *TRAIN, "--out", str(out)])
        one_line_error(capsys, code, "pipe.csv is a FIFO (named pipe), not a regular file")
        assert not out.exists()
        code = main(["evaluate", str(good["run"]), "--data", str(fifo), *CSV])
        one_line_error(capsys, code, "pipe.csv is a FIFO (named pipe), not a regular file")


@pytest.mark.parametrize("case", sorted(NPZ_CORPUS))
def test_bad_npz_is_refused_by_train_and_evaluate(case, good, tmp_path, capsys):
    write, needle = NPZ_CORPUS[case]
    path = write(tmp_path)
    out = tmp_path / "run"
    one_line_error(capsys, main(["train", str(path), *TRAIN, "--out", str(out)]), needle)
    assert not out.exists()
    one_line_error(capsys, main(["evaluate", str(good["run"]), "--data", str(path)]), needle)


@pytest.mark.parametrize("case", sorted(DATASET_CORPUS))
def test_bad_dataset_metadata_is_refused_by_every_reader(case, good, tmp_path, capsys):
    write, needle = DATASET_CORPUS[case]
    folder = write(tmp_path, good["data"])
    out = tmp_path / "run"
    one_line_error(capsys, main(["train", str(folder), *TRAIN, "--out", str(out)]), needle)
    assert not out.exists()
    one_line_error(capsys, main(["evaluate", str(good["run"]), "--data", str(folder)]), needle)
    argv = ["analyze", "linear", "--window", "2", "--run", str(good["run"])]
    code = main([*argv, "--data", str(folder), "--out", str(tmp_path / "a"), "--no-progress"])
    one_line_error(capsys, code, needle)
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize("case", sorted(RUN_CORPUS))
def test_bad_run_folders_are_refused_by_every_reader(case, good, tmp_path, capsys):
    damage, needle = RUN_CORPUS[case]
    run = tmp_path / "run"
    shutil.copytree(good["run"], run)
    damage(run)
    before = files_under(run)
    one_line_error(capsys, main(["evaluate", str(run)]), needle)
    argv = ["analyze", "linear", "--window", "2", "--run", str(run), "--no-progress"]
    one_line_error(capsys, main([*argv, "--out", str(tmp_path / "a")]), needle)
    one_line_error(capsys, main(["reduce", str(run), "--compression", "0.5"]), needle)
    assert files_under(run) == before


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["train", "{data}", *TRAIN, "--threads", "0"], "--threads must be an integer >= 1"),
        (["train", "{data}", *TRAIN, "--threads", "-1"], "--threads must be an integer >= 1"),
        (["train", "{data}", *TRAIN, "--eval-horizon", "0"], "--eval-horizon must be"),
        (["train", "{data}", *TRAIN, "--val-fraction", "1.5"], "--val-fraction must be in"),
        (["train", "{data}", *TRAIN, "--dt", "0.1"], "is a canonid dataset"),
        (["evaluate", "{run}", "--eval-horizon", "0"], "--eval-horizon must be an integer >= 1"),
        (["evaluate", "{run}", "--data", "{data}", "--dt", "2"], "--dt apply to CSV and .npz"),
        (["evaluate", "{run}", "--split", "nope"], "no split 'nope'"),
        (["analyze", "linear", "--window", "2", "--seed", "-1"], "--seed must be an integer >= 0"),
        (["analyze", "linear", "--window", "2", "--tol", "0"], "--tol must be a positive"),
        (["analyze", "linear", "--window", "2", "--tol", "-1"], "--tol must be a positive"),
        (["analyze", "linear", "--window", "2", "--data", "{data}"], "--data applies to --run"),
        (
            ["analyze", "drone2d", "--window", "2", "--run", "{run}"],
            "number of inputs 1 (the run) vs 2 (drone2d)",
        ),
    ],
)
def test_bad_arguments_fail_in_one_line_before_any_work(argv, needle, good, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [a.format(data=good["data"], run=good["run"]) for a in argv]
    before = files_under(good["run"])
    one_line_error(
        capsys, main([*argv, "--out", str(out)] if argv[0] != "evaluate" else argv), needle
    )
    assert not out.exists() and files_under(good["run"]) == before


@pytest.mark.parametrize(
    "argv",
    [
        ["generate", "tank", "--no-progress"],
        ["train", "{data}", *TRAIN],
        ["analyze", "linear", "--window", "1", "--no-progress"],
        ["reproduce", "--profile", "tiny", "--no-progress"],
        ["reduce", "{run}", "--compression", "0.5"],
    ],
)
def test_an_output_folder_that_is_a_file_is_refused(argv, good, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("mine")
    argv = [a.format(data=good["data"], run=good["run"]) for a in argv]
    code = main([*argv, "--out", str(blocker)])
    one_line_error(capsys, code, f"--out {blocker} is a file; expected a folder")
    code = main([*argv, "--out", str(blocker / "below")])
    one_line_error(capsys, code, f"lies below the file {blocker}")
    assert blocker.read_text() == "mine"
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--out", ""])
    assert exit_info.value.code == 2
    assert "--out: expected a folder, got an empty string" in capsys.readouterr().err


@pytest.mark.parametrize("reason", [errno.ENOSPC, errno.EROFS])
def test_a_file_system_that_refuses_writes_gives_one_line(
    reason, good, tmp_path, capsys, monkeypatch
):
    real_replace = os.replace

    def refuse(src, dst):
        if str(dst).endswith("metrics.json"):
            raise OSError(reason, os.strerror(reason))
        return real_replace(src, dst)

    run = tmp_path / "run"
    shutil.copytree(good["run"], run)
    monkeypatch.setattr(os, "replace", refuse)
    code = main(["evaluate", str(run)])
    err = one_line_error(capsys, code, f"cannot write {run / 'evaluations'}", os.strerror(reason))
    assert "metrics.json" in err
    assert not [p for p in run.rglob("*") if p.name.endswith(".tmp")]
    assert not (run / "evaluations").exists()  # nothing half-written


def test_an_os_error_outside_our_writers_gives_one_line(good, tmp_path, capsys, monkeypatch):
    def refuse(self, *args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))

    monkeypatch.setattr(Path, "mkdir", refuse)
    code = main(["train", str(good["data"]), *TRAIN, "--out", str(tmp_path / "run")])
    one_line_error(capsys, code, f"{tmp_path / 'run'}: Read-only file system")


# ------------------------------------------------------------- random inputs (hypothesis)
def _clean_or_valid(path: Path, **options) -> None:
    """Loading ``path`` gives a valid dataset or a CanonidError; anything else fails the test."""
    try:
        dataset = load_data(path, **options)
    except CanonidError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    for trajs in dataset.splits.values():
        for tr in trajs:
            assert np.isfinite(tr.u).all() and np.isfinite(tr.y).all()
            assert tr.u.dtype == np.float64 and tr.T >= 1


FUZZ = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@FUZZ
@given(data=st.binary(max_size=600), suffix=st.sampled_from([".csv", ".npz"]))
def test_random_bytes_give_a_clean_error_or_valid_data(data, suffix, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / f"f{suffix}"
    path.write_bytes(data)
    _clean_or_valid(path, inputs=["u"], outputs=["y"], dt=1.0, experiment_column=None)


CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers().map(str),
    st.sampled_from(["", " ", "nan", "1e308", "-1e308", "1e309", '"1,2"', "x", "é", "\x00"]),
    st.text(max_size=4),
)


@FUZZ
@given(
    header=st.lists(st.sampled_from(["u", "y", "run", "u", ""]), min_size=0, max_size=4),
    rows=st.lists(st.lists(CELLS, min_size=0, max_size=4), max_size=12),
    grouped=st.booleans(),
)
def test_random_csv_text_gives_a_clean_error_or_valid_data(header, rows, grouped, tmp_path_factory):
    text = "\n".join(",".join(r) for r in [header, *rows])
    path = tmp_path_factory.mktemp("fuzz") / "f.csv"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    column = "run" if grouped else None
    _clean_or_valid(path, inputs=["u"], outputs=["y"], dt=1.0, experiment_column=column)


ARRAYS = st.dictionaries(
    st.sampled_from(["u", "y", "y_clean", "dt", "u_0", "y_0", "u_1", "y_clean_0", "x"]),
    st.one_of(
        st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=6).map(np.array),
        st.lists(st.lists(st.integers(-5, 5), min_size=2, max_size=2), max_size=6).map(np.array),
        st.integers(0, 4).map(lambda n: np.zeros((2, n, 1))),
        st.sampled_from([np.array(1.0), np.array([]), np.array(["a"]), np.array([1j])]),
    ),
    max_size=5,
)


@FUZZ
@given(arrays=ARRAYS, dt=st.sampled_from([None, 1.0, 0.5]))
@example(  # stacked experiments with a y_clean of another shape (found by this test)
    arrays={"u": np.zeros((2, 0, 1)), "y": np.zeros((2, 0, 1)), "y_clean": np.array([])}, dt=1.0
)
def test_random_npz_arrays_give_a_clean_error_or_valid_data(arrays, dt, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "f.npz"
    np.savez(path, **arrays)
    _clean_or_valid(path, dt=dt)


def test_reduce_into_a_training_run_names_it_a_training_run(good, capsys):
    before = files_under(good["run"])
    code = main(["reduce", str(good["run"]), "--compression", "0.5", "--out", str(good["run"])])
    one_line_error(capsys, code, f"{good['run']} already holds a training run")
    assert files_under(good["run"]) == before


def test_a_runner_that_cannot_start_prints_its_error_alone(tmp_path, capsys):
    """No progress bar before the error: the bar appears once the jobs run."""
    out = tmp_path / "data"
    code = main(["generate", "tank", "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)])
    one_line_error(capsys, code, "tcp://127.0.0.1:1' refused the connection")
    assert not out.exists()


JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 3) | st.floats(-2, 2) | st.text(max_size=3),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3)
    ),
    max_leaves=6,
)
HEADER_FIELDS = [
    "format_version",
    "checksum_sha256",
    "dt",
    "input_names",
    "output_names",
    "state_names",
    "counts",
    "trajectory_info",
    "metadata",
]


@FUZZ
@given(field=st.sampled_from(HEADER_FIELDS), value=JSON)
def test_random_dataset_json_fields_give_a_clean_error_or_valid_data(
    field, value, good, tmp_path_factory
):
    folder = tmp_path_factory.mktemp("fuzz") / "ds"
    shutil.copytree(good["data"], folder)
    meta = folder / "dataset.json"
    header = json.loads(meta.read_text())
    header[field] = value
    meta.write_text(json.dumps(header))
    _clean_or_valid(folder)
