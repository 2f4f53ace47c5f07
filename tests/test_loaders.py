"""User data loaders: CSV, .npz arrays and Input_output_data-shaped objects → the same Dataset."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.datagen.loaders import (
    data_checksum,
    from_io_data,
    load_csv,
    load_data,
    load_npz,
    split_train_val,
)
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError
from canonid.kernel.io import write_npz


@pytest.fixture
def experiments(rng):
    """Three experiments of different lengths, 2 inputs and 1 output."""
    return [(rng.normal(size=(T, 2)), rng.normal(size=(T, 1))) for T in (12, 9, 15)]


def write_csv(path, rows, header):
    lines = [",".join(header)] + [
        ",".join(repr(float(v)) if not isinstance(v, str) else v for v in row) for row in rows
    ]
    path.write_text("\n".join(lines) + "\n")


def same_arrays(a: Dataset, b: Dataset) -> None:
    ta, tb = a.split("train"), b.split("train")
    assert len(ta) == len(tb)
    for x, y in zip(ta, tb):
        np.testing.assert_array_equal(x.u, y.u)
        np.testing.assert_array_equal(x.y, y.y)
    assert a.dt == b.dt


def test_csv_with_an_experiment_column_equals_one_file_per_experiment(tmp_path, experiments):
    rows = []
    for k, (u, y) in enumerate(experiments):
        for t in range(len(u)):
            rows.append([f"run{k}", u[t, 0], y[t, 0], u[t, 1], t * 0.5])  # t in seconds
        write_csv(
            tmp_path / f"e{k}.csv",
            [[u[t, 0], u[t, 1], y[t, 0]] for t in range(len(u))],
            ["pump", "valve", "level"],
        )
    write_csv(tmp_path / "all.csv", rows, ["exp", "pump", "level", "valve", "t"])
    one = load_csv(
        tmp_path / "all.csv",
        inputs=["pump", "valve"],
        outputs=["level"],
        dt=0.5,
        experiment_column="exp",
    )
    many = load_csv(
        [tmp_path / f"e{k}.csv" for k in range(3)],
        inputs=["pump", "valve"],
        outputs=["level"],
        dt=0.5,
    )
    arrays = Dataset.from_arrays([u for u, _ in experiments], [y for _, y in experiments], dt=0.5)
    same_arrays(one, many)
    same_arrays(one, arrays)
    assert one.input_names == ("pump", "valve") and one.output_names == ("level",)
    assert one.metadata["experiments"][1] == "all.csv:exp=run1"
    # the dispatcher: a folder of CSV files, one experiment each, in name order
    (tmp_path / "all.csv").unlink()
    folder = load_data(tmp_path, inputs=["pump", "valve"], outputs=["level"], dt=0.5)
    same_arrays(folder, many)


def test_npz_layouts_and_io_data_objects_equal_the_arrays(tmp_path, experiments):
    arrays = Dataset.from_arrays([u for u, _ in experiments], [y for _, y in experiments], dt=0.1)
    pairs = {f"{k}_{i}": a for i, (u, y) in enumerate(experiments) for k, a in (("u", u), ("y", y))}
    write_npz(tmp_path / "pairs.npz", {**pairs, "dt": np.array(0.1)})
    same_arrays(load_npz(tmp_path / "pairs.npz"), arrays)
    same_arrays(load_data(tmp_path / "pairs.npz"), arrays)
    equal = [(u[:9], y[:9]) for u, y in experiments]
    write_npz(
        tmp_path / "stacked.npz",
        {"u": np.stack([u for u, _ in equal]), "y": np.stack([y for _, y in equal])},
    )
    same_arrays(
        load_npz(tmp_path / "stacked.npz", dt=0.1),
        Dataset.from_arrays([u for u, _ in equal], [y for _, y in equal], dt=0.1),
    )
    objs = [
        SimpleNamespace(u=u, y=y[:, 0], sampling_time=0.1, state_initialization_window_length=7)
        for u, y in experiments
    ]
    io = from_io_data(objs)
    same_arrays(io, arrays)
    assert io.metadata["n_init"] == 7
    single = from_io_data(objs[0])
    assert len(single.split("train")) == 1


def test_a_saved_dataset_is_read_by_the_dispatcher(tmp_path, experiments):
    arrays = Dataset.from_arrays([u for u, _ in experiments], [y for _, y in experiments], dt=1.0)
    arrays.save(tmp_path / "d" / "dataset.npz")
    same_arrays(load_data(tmp_path / "d"), arrays)
    same_arrays(load_data(tmp_path / "d" / "dataset.npz"), arrays)


def test_the_data_checksum_follows_the_contents_not_the_path(tmp_path, experiments):
    arrays = Dataset.from_arrays([u for u, _ in experiments], [y for _, y in experiments], dt=1.0)
    npz = arrays.save(tmp_path / "d" / "dataset.npz")
    recorded = data_checksum(tmp_path / "d")
    assert data_checksum(npz) == data_checksum(npz.with_suffix(".json")) == recorded
    folder = tmp_path / "csv"
    folder.mkdir()
    for i, (u, y) in enumerate(experiments):
        write_csv(folder / f"e{i}.csv", np.hstack([u, y]), ["u1", "u2", "y"])
    before = {p: data_checksum(p) for p in (folder, folder / "e0.csv")}
    moved = tmp_path / "moved.csv"
    moved.write_bytes((folder / "e0.csv").read_bytes())
    assert data_checksum(moved) == before[folder / "e0.csv"]
    write_csv(folder / "e0.csv", np.hstack(experiments[0]) + 1.0, ["u1", "u2", "y"])
    assert all(data_checksum(p) != before[p] for p in before)
    with pytest.raises(DataError, match="not found"):
        data_checksum(tmp_path / "missing.csv")


def test_split_by_experiment_or_by_fraction_of_one_record(experiments):
    ds = Dataset.from_arrays([u for u, _ in experiments], [y for _, y in experiments], dt=1.0)
    split = split_train_val(ds, val_fraction=0.2)
    assert split.counts() == {"train": 2, "val": 1}
    np.testing.assert_array_equal(split.split("val")[0].u, experiments[2][0])
    one = Dataset.from_arrays(experiments[2][0], experiments[2][1], dt=1.0)
    cut = split_train_val(one, val_fraction=0.2)
    assert [tr.T for tr in cut.split("train")] == [12] and [tr.T for tr in cut.split("val")] == [3]
    np.testing.assert_array_equal(
        np.concatenate([cut.split("train")[0].y, cut.split("val")[0].y]), experiments[2][1]
    )
    with pytest.raises(DataError, match="already has a 'val' split"):
        split_train_val(split)


def test_bad_user_data_is_named(tmp_path, experiments):
    u, y = experiments[0]
    write_csv(tmp_path / "a.csv", [[u[t, 0], y[t, 0]] for t in range(len(u))], ["u", "y"])
    with pytest.raises(DataError, match=r"no column\(s\) \['flow'\]"):
        load_csv(tmp_path / "a.csv", inputs=["flow"], outputs=["y"], dt=1.0)
    with pytest.raises(DataError, match="dt must be from 1e-09"):
        load_csv(tmp_path / "a.csv", inputs=["u"], outputs=["y"], dt=0.0)
    with pytest.raises(DataError, match="given as both input and output"):
        load_csv(tmp_path / "a.csv", inputs=["u"], outputs=["u"], dt=1.0)
    (tmp_path / "b.csv").write_text("u,y\n1.0,2.0\n1.5,abc\n")
    with pytest.raises(DataError, match=r"b\.csv, line 3, column 'y': 'abc' is not a number"):
        load_csv(tmp_path / "b.csv", inputs=["u"], outputs=["y"], dt=1.0)
    (tmp_path / "c.csv").write_text("u,y\n1.0,2.0\n1.5,nan\n")
    with pytest.raises(DataError, match="line 3, column 'y': 'nan' is not finite"):
        load_csv(tmp_path / "c.csv", inputs=["u"], outputs=["y"], dt=1.0)
    with pytest.raises(DataError, match="need the sampling time"):
        load_data(tmp_path / "a.csv", inputs=["u"], outputs=["y"])
    # without column names the message lists the header's, so the user can pick them
    with pytest.raises(DataError, match=r"--inputs COL.*the header has 'u', 'y'"):
        load_data(tmp_path / "a.csv", dt=1.0)
    write_npz(tmp_path / "m.npz", {"u": np.zeros((5, 1)), "y": np.zeros((4, 1))})
    with pytest.raises(DataError, match="u has 5 samples but y has 4"):
        load_npz(tmp_path / "m.npz", dt=1.0)
    write_npz(tmp_path / "n.npz", {"u": np.zeros((5, 1)), "y": np.full((5, 1), np.nan)})
    with pytest.raises(DataError, match="non-finite"):
        load_npz(tmp_path / "n.npz", dt=1.0)
    with pytest.raises(DataError, match="no array 'dt'"):
        load_npz(tmp_path / "n.npz")
    with pytest.raises(DataError, match="different sampling times"):
        from_io_data([SimpleNamespace(u=u, y=y, sampling_time=s) for s in (0.1, 0.2)])
    with pytest.raises(DataError, match="has no attribute 'sampling_time'"):
        from_io_data([SimpleNamespace(u=u, y=y)])
    with pytest.raises(DataError, match="data file not found"):
        load_data(tmp_path / "missing.csv")


def test_csv_and_io_data_give_the_same_model_as_arrays(tmp_path):
    """Three routes into training (arrays, CSV, Input_output_data-like) → identical weights."""
    from learning_helpers import damped_siso, trajectories

    from canonid.learning import TrainOptions, fit

    data = trajectories(damped_siso(), 4, 30, noise=0.01, seed=5)
    us, ys = [d.u for d in data], [d.y for d in data]
    routes = {"arrays": Dataset.from_arrays(us, ys, dt=1.0)}
    for k, (u, y) in enumerate(zip(us, ys)):
        write_csv(tmp_path / f"e{k}.csv", np.hstack([u, y]).tolist(), ["u", "y"])
    routes["csv"] = load_data(tmp_path, inputs=["u"], outputs=["y"], dt=1.0)
    routes["io"] = from_io_data(
        [SimpleNamespace(u=u[:, 0], y=y[:, 0], sampling_time=1.0) for u, y in zip(us, ys)]
    )
    opts = TrainOptions(epochs=2, batch_size=4, horizon=5, lr=1e-3, device="cpu")
    weights = {}
    for name, ds in routes.items():
        split = split_train_val(ds, val_fraction=0.25)
        res = fit(
            split.split("train"),
            split.split("val"),
            model="mlp",
            window=3,
            options=opts,
            net_options={"hidden": [8]},
        )
        weights[name] = {k: v.numpy() for k, v in res.model.net.state_dict().items()}
    for name in ("csv", "io"):
        for key, value in weights["arrays"].items():
            np.testing.assert_array_equal(weights[name][key], value)


@settings(max_examples=25, deadline=None)
@given(
    dt=st.floats(1e-4, 1e3, allow_nan=False),
    start=st.floats(-1e3, 1e3, allow_nan=False),
    rows=st.integers(2, 40),
    decimals=st.sampled_from([None, 9]),
)
def test_the_time_column_gives_dt(tmp_path_factory, dt, start, rows, decimals):
    """Times written in full or rounded to 9 decimals: dt is their step, to the rounding."""
    path = tmp_path_factory.mktemp("timed") / "timed.csv"
    times = [start + k * dt for k in range(rows)]
    shown = [repr(t) if decimals is None else f"{t:.{decimals}f}" for t in times]
    write_csv(path, [[t, 1.0, 2.0] for t in shown], ["time", "u", "y"])
    data = load_csv(path, inputs=["u"], outputs=["y"])
    spread = 0 if decimals is None else 1e-9 / (rows - 1)
    assert data.dt == pytest.approx(dt, rel=1e-9, abs=2 * spread + 1e-12 * abs(start))
    assert data.metadata["time_column"] == "time" and data.metadata["dt_from"] == "time column"
    # a named time column, and none at all
    assert load_csv(path, inputs=["u"], outputs=["y"], time_column="time").dt == data.dt
    with pytest.raises(DataError, match="need the sampling time: give dt"):
        load_csv(path, inputs=["u"], outputs=["y"], time_column="")


def test_time_column_problems_are_named(tmp_path, caplog):
    path = tmp_path / "runs.csv"
    rows = [[t * 0.5, 1.0, 2.0] for t in range(5)] * 2  # two records, no experiment column
    write_csv(path, rows, ["t", "u", "y"])
    with caplog.at_level("WARNING"):
        data = load_csv(path, inputs=["u"], outputs=["y"])
    assert data.dt == 0.5 and data.counts() == {"train": 1}
    (message,) = [r.getMessage() for r in caplog.records]
    assert f"{path}, line 7: time column 't' goes back from 2 to 0" in message
    assert "joined into one record" in message and "--experiment-column" in message
    # uneven steps: refused, with dt given or not; switched off, the rows are samples every dt
    write_csv(path, [[t, 1.0, 2.0] for t in (0.0, 0.5, 1.0, 1.7)], ["time", "u", "y"])
    uneven = r"time column 'time' is not uniformly spaced \(steps from 0\.5 s to 0\.7 s\)"
    with pytest.raises(DataError, match=uneven + r".*--time-column none --dt SECONDS\)$"):
        load_csv(path, inputs=["u"], outputs=["y"])
    with pytest.raises(DataError, match=uneven + r".*every dt = 0\.5 s as given.*none\)$"):
        load_csv(path, inputs=["u"], outputs=["y"], dt=0.5)
    assert load_csv(path, inputs=["u"], outputs=["y"], dt=0.5, time_column="").dt == 0.5
    # a repeated time; a named time column that contradicts the dt given
    write_csv(path, [[t, 1.0, 2.0] for t in (0.0, 0.5, 0.5)], ["time", "u", "y"])
    where = re.escape(str(path))
    with pytest.raises(DataError, match=rf"{where}, line 4: time column 'time' repeats 0\.5"):
        load_csv(path, inputs=["u"], outputs=["y"])
    write_csv(path, [[t, 1.0, 2.0] for t in (0.0, 0.5, 1.0)], ["time", "u", "y"])
    with pytest.raises(DataError, match=r"dt = 2 s was given, but time column 'time' steps by"):
        load_csv(path, inputs=["u"], outputs=["y"], dt=2.0, time_column="time")


@pytest.mark.parametrize("named", [None, "time"])
def test_a_dt_that_disagrees_with_the_time_column_is_refused(tmp_path, named):
    """Found by its name or named, a time column decides: a dt given beside it must agree to
    the relative tolerance, or the column is switched off (time_column="")."""
    path = tmp_path / "timed.csv"
    write_csv(path, [[t * 0.5, 1.0, 2.0] for t in range(6)], ["time", "u", "y"])
    with pytest.raises(DataError) as refused:
        load_csv(path, inputs=["u"], outputs=["y"], dt=0.1, time_column=named)
    message = str(refused.value)
    assert "dt = 0.1 s was given, but time column 'time' steps by 0.5 s" in message
    assert message.endswith("samples every 0.1 s (CLI: --time-column none)"), message
    assert "\n" not in message
    # within the tolerance the dt given is kept; switched off, the rows are samples every dt
    assert load_csv(path, inputs=["u"], outputs=["y"], dt=0.50001, time_column=named).dt == 0.50001
    assert load_csv(path, inputs=["u"], outputs=["y"], dt=0.1, time_column="").dt == 0.1


@pytest.mark.parametrize(("separator", "name"), [(";", "';'"), ("\t", "tabs")])
def test_a_file_separated_otherwise_than_by_commas_is_named_so(tmp_path, separator, name):
    path = tmp_path / "semi.csv"
    rows = [
        separator.join(["t", "u", "y"]),
        *(separator.join([f"{k}", "1,5", "2,5"]) for k in range(4)),
    ]
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(DataError) as refused:
        load_csv(path, inputs=["u"], outputs=["y"])
    message = str(refused.value)
    assert (
        message.startswith(f"{path}: the header ")
        and f"is separated by {name}, not commas" in message
    )
    # a comma-separated header that lacks a column is named as before
    write_csv(path, [[1.0, 2.0]], ["u", "y;z"])
    with pytest.raises(DataError, match=r"no column\(s\) \['v'\]; the header has \['u', 'y;z'\]"):
        load_csv(path, inputs=["u"], outputs=["v"], dt=1.0)


def test_rows_of_one_experiment_must_be_contiguous(tmp_path):
    path = tmp_path / "mixed.csv"
    write_csv(path, [["a", 1.0, 2.0], ["b", 1.0, 2.0], ["a", 1.0, 2.0]], ["run", "u", "y"])
    where = re.escape(str(path))
    with pytest.raises(DataError, match=rf"{where}, line 4: experiment 'a' .* started on line 2"):
        load_csv(path, inputs=["u"], outputs=["y"], dt=1.0, experiment_column="run")


def test_a_csv_dataset_has_only_a_train_split_and_says_how_to_get_val(tmp_path):
    path = tmp_path / "one.csv"
    write_csv(path, [[1.0, 2.0]] * 10, ["u", "y"])
    data = load_data(path, inputs=["u"], outputs=["y"], dt=1.0)
    with pytest.raises(KeyError, match=r"no split 'val'; it has \['train'\].*split_train_val"):
        data.split("val")
    with pytest.raises(DataError):
        data.split("test")
    assert split_train_val(data).split("val")
