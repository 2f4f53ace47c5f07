"""The standard benchmarks: official splits read from files in each benchmark's exact layout,
the CSV export, one-line errors, and ``canonid benchmark`` end to end on a synthetic Silverbox."""

from __future__ import annotations

import inspect
import json
import logging
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.io

from canonid.benchmark import score_parts
from canonid.cli import main
from canonid.datagen.benchmarks import BENCHMARKS, benchmark, load_benchmark
from canonid.datagen.loaders import split_train_val
from canonid.kernel.dataset import Dataset, as_trajectories
from canonid.kernel.errors import DataError
from canonid.learning import Model
from canonid.learning.data import Normalisation
from canonid.learning.evaluate import simulate_records
from canonid.learning.nets import build_net

# The official split of nonlinear_benchmarks 1.0.1, written out by hand from its benchmarks.py:
# per benchmark, (file, [start, stop)) of every training record and every test part, in order.
EXPECTED = {
    "silverbox": {
        "dt": 1 / 610.35,
        "train": [("SNLS80mV.mat", 40650, 105712)],
        "test": [
            ("multisine", "SNLS80mV.mat", 105712, 127400),
            ("arrow-full", "SNLS80mV.mat", 100, 40575),
            ("arrow-no-extrapolation", "SNLS80mV.mat", 100, 32100),
        ],
        "n_init": 50,
        "score": ("mV", 1000.0),
    },
    "cascaded-tanks": {
        "dt": 4.0,
        "train": [("dataBenchmark.mat", 0, 1024)],
        "test": [("validation", "dataBenchmark.mat", 0, 1024)],
        "n_init": 50,
        "score": ("V", 1.0),
    },
    "wiener-hammerstein": {
        "dt": 1 / 51200,
        "train": [("WienerHammerBenchMark.mat", 5200, 105200)],
        "test": [("test", "WienerHammerBenchMark.mat", 105200, 184000)],
        "n_init": 50,
        "score": ("mV", 1000.0),
    },
    "emps": {
        "dt": 1e-3,
        "train": [("DATA_EMPS.mat", 0, 600)],
        "test": [("DATA_EMPS_PULSES", "DATA_EMPS_PULSES.mat", 0, 500)],
        "n_init": 20,
        "score": ("mm", 1000.0),
    },
    "ced": {
        "dt": 0.02,
        "train": [("DATAUNIF.MAT", 0, 400), ("DATAUNIF.MAT", 0, 400)],
        "test": [
            ("low-amplitude", "DATAUNIF.MAT", 400, 500),
            ("high-amplitude", "DATAUNIF.MAT", 400, 500),
        ],
        "n_init": 10,
        "score": ("ticks/s", 1.0),
    },
    # not split by the package: the test records of the benchmark's zip, the training record
    # its users simulate (canonid's file name); n_init canonid's (the package sets none)
    "bouc-wen": {
        "dt": 1 / 750,
        "train": [("BoucWen_train.mat", 0, 2000)],
        "test": [("multisine", "multisine", 0, 600), ("sinesweep", "sinesweep", 0, 900)],
        "n_init": 50,
        "score": ("mm", 1000.0),
    },
    # the full-multisine records only: levels 1, 3, 5, 7 train, the Validation levels test
    "f16-gvt": {
        "dt": 1 / 400,
        "train": [(f"F16Data_FullMSine_Level{k}.mat", 0, 300 + 10 * k) for k in (1, 3, 5, 7)],
        "test": [
            (f"level-{k}", f"F16Data_FullMSine_Level{k}_Validation.mat", 0, 300 + 10 * k)
            for k in (2, 4, 6)
        ],
        "n_init": 50,
        "score": ("m/s²", 1.0),
    },
}


def _signal(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A random input and a first-order response (something a model can learn)."""
    u = rng.normal(size=n) * 0.1
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.9 * y[k - 1] + 0.1 * u[k - 1]
    return u, y


def write_benchmark(name: str, root: Path, *, flat: bool = False, seed: int = 0) -> dict:
    """Write benchmark ``name``'s files with its official variable names and shapes (the
    package's cache layout, or all in ``root`` when ``flat``); return the full records."""
    rng = np.random.default_rng(seed)
    folder = root if flat else root / benchmark(name).folder
    folder.mkdir(parents=True, exist_ok=True)
    col = lambda a: np.asarray(a)[:, None]  # noqa: E731 — N × 1, as MATLAB stores them
    records: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if name == "silverbox":
        u, y = _signal(rng, 131_072)
        scipy.io.savemat(folder / "SNLS80mV.mat", {"V1": u[None, :], "V2": y[None, :]})
        records["SNLS80mV.mat"] = (u, y)
    elif name == "cascaded-tanks":
        (ue, ye), (uv, yv) = _signal(rng, 1024), _signal(rng, 1024)
        scipy.io.savemat(
            folder / "dataBenchmark.mat",
            {"uEst": col(ue), "yEst": col(ye), "uVal": col(uv), "yVal": col(yv), "Ts": [[4.0]]},
        )
        records["dataBenchmark.mat"] = (ue, ye)
        records["validation"] = (uv, yv)
    elif name == "wiener-hammerstein":
        u, y = _signal(rng, 188_000)
        scipy.io.savemat(
            folder / "WienerHammerBenchMark.mat",
            {"uBenchMark": col(u), "yBenchMark": col(y), "fs": [[51200.0]]},
        )
        records["WienerHammerBenchMark.mat"] = (u, y)
    elif name == "emps":
        for file, n in (("DATA_EMPS.mat", 600), ("DATA_EMPS_PULSES.mat", 500)):
            u, y = _signal(rng, n)
            t = np.arange(n) * 1e-3
            mat = {"qm": col(y), "qg": col(y + 0.01), "t": col(t), "vir": col(u)}
            scipy.io.savemat(folder / file, mat)
            records[file] = (u, y)
    elif name == "ced":
        (u1, z1), (u2, z2) = _signal(rng, 500), _signal(rng, 500)
        scipy.io.savemat(
            folder / "DATAUNIF.MAT",
            {"u11": col(u1), "u12": col(u2), "z11": col(z1), "z12": col(z2)},
        )
        records["low"], records["high"] = (u1, z1), (u2, z2)
    elif name == "bouc-wen":
        u, y = _signal(rng, 2000)  # the record BoucWen_ExampleIntegration.m leaves: N × 1
        scipy.io.savemat(folder / "BoucWen_train.mat", {"u": col(u), "y": col(y)})
        records["BoucWen_train.mat"] = (u, y)
        tests = folder if flat else folder / "Test signals" / "Validation signals"
        tests.mkdir(parents=True, exist_ok=True)
        for part, n in (("multisine", 600), ("sinesweep", 900)):
            u, y = _signal(rng, n)  # one 1 × N variable per file, named as the file
            scipy.io.savemat(tests / f"uval_{part}.mat", {f"uval_{part}": u[None, :]})
            scipy.io.savemat(tests / f"yval_{part}.mat", {f"yval_{part}": y[None, :]})
            records[part] = (u, y)
    elif name == "f16-gvt":
        for k in range(1, 8):
            file = f"F16Data_FullMSine_Level{k}{'_Validation' if k % 2 == 0 else ''}.mat"
            scipy.io.savemat(folder / file, _f16_content(rng, 300 + 10 * k))
            content = scipy.io.loadmat(folder / file)
            records[file] = (content["Force"][0], content["Acceleration"].T)
    return records


def _f16_content(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """One F-16 record as the benchmark's .mat files hold it: ``Force`` and ``Voltage`` 1 × N,
    ``Acceleration`` 3 × N (one row per accelerometer), ``Fs`` 1 × 1."""
    u, y = _signal(rng, n)
    acc = np.stack([y, -0.5 * y, 2.0 * y + 0.01 * rng.normal(size=n)])
    return {"Force": u[None, :], "Voltage": 0.1 * u[None, :], "Acceleration": acc, "Fs": [[400.0]]}


def _record(name: str, records: dict, file: str, index: int, role: str):
    """The full record a part was cut from (CED and Cascaded Tanks hold two per file)."""
    if name == "ced":
        return records[("low", "high")[index]]
    if name == "cascaded-tanks" and role == "test":
        return records["validation"]
    return records[file]


@pytest.mark.parametrize("name", list(BENCHMARKS))
def test_official_slices_n_init_and_units(tmp_path, name):
    records = write_benchmark(name, tmp_path)
    ds = load_benchmark(name, tmp_path)
    expected, bench = EXPECTED[name], BENCHMARKS[name]
    assert ds.dt == pytest.approx(expected["dt"], rel=1e-12)
    assert ds.metadata["n_init"] == bench.n_init == expected["n_init"]
    assert (ds.metadata["score_units"], ds.metadata["score_scale"]) == expected["score"]
    assert set(ds.metadata["units"]) == {*ds.input_names, *ds.output_names}
    assert ds.counts() == {"train": len(expected["train"]), "test": len(expected["test"])}
    assert len(ds.output_names) == (3 if name == "f16-gvt" else 1)
    for i, (tr, (file, start, stop)) in enumerate(zip(ds.split("train"), expected["train"])):
        u, y = _record(name, records, file, i, "train")
        np.testing.assert_array_equal(tr.u[:, 0], u[start:stop])
        np.testing.assert_array_equal(tr.y, y[start:stop].reshape(stop - start, -1))
        assert tr.info["samples"] == [start, stop]
    parts = ds.split("test")
    assert [p.info["part"] for p in parts] == [e[0] for e in expected["test"]]
    assert ds.metadata["test_parts"] == list(bench.test_parts)
    for i, (part, (_, file, start, stop)) in enumerate(zip(parts, expected["test"])):
        u, y = _record(name, records, file, i, "test")
        np.testing.assert_array_equal(part.u[:, 0], u[start:stop])
        np.testing.assert_array_equal(part.y, y[start:stop].reshape(stop - start, -1))
        assert part.info["n_init"] == bench.n_init


def test_files_are_also_found_directly_in_the_folder(tmp_path):
    records = write_benchmark("ced", tmp_path, flat=True)
    ds = load_benchmark("ced", tmp_path)
    np.testing.assert_array_equal(ds.split("test")[1].y[:, 0], records["high"][1][400:])


def test_silverbox_csv_export_gives_the_same_data_as_the_mat_file(tmp_path):
    records = write_benchmark("silverbox", tmp_path / "mat")
    u, y = records["SNLS80mV.mat"]
    # the export's layout: quoted header, a trailing empty column
    lines = ['"V1","V2",', *(f"{a!r},{b!r}," for a, b in zip(u.tolist(), y.tolist()))]
    (tmp_path / "csv").mkdir()
    (tmp_path / "csv" / "SNLS80mV.csv").write_text("\n".join(lines) + "\n")
    from_mat, from_csv = (
        load_benchmark("silverbox", tmp_path / "mat"),
        load_benchmark("silverbox", tmp_path / "csv"),
    )
    assert from_mat.dt == from_csv.dt and from_mat.counts() == from_csv.counts()
    for split in ("train", "test"):
        for a, b in zip(from_mat.split(split), from_csv.split(split)):
            np.testing.assert_array_equal(a.u, b.u)
            np.testing.assert_array_equal(a.y, b.y)
            assert {**a.info, "file": "SNLS80mV.csv"} == b.info


def test_a_missing_file_names_it_where_it_was_looked_for_and_the_download_page(tmp_path):
    with pytest.raises(DataError) as err:
        load_benchmark("wiener-hammerstein", tmp_path)
    text = str(err.value)
    assert "WienerHammerBenchMark.mat not found" in text and "\n" not in text
    assert str(tmp_path / "WienerHammerBenchMark" / "WienerHammerBenchMark.mat") in text
    assert "nonlinearbenchmark.org/benchmarks/wiener-hammerstein" in text


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ({"u11": np.ones((500, 1)), "u12": np.ones((500, 1)), "z11": np.ones((500, 1))}, "'z12'"),
        (
            {k: np.ones((500, 2)) for k in ("u11", "u12", "z11", "z12")},
            r"'u11' must be a 1 × N or N × 1 vector, got \(500, 2\)",
        ),
        ({k: np.ones((300, 1)) for k in ("u11", "u12", "z11", "z12")}, "needs at least 401"),
        (
            {
                "u11": np.ones((500, 1)),
                "u12": np.ones((500, 1)),
                "z11": np.ones((499, 1)),
                "z12": np.ones((500, 1)),
            },
            "'u11' has 500 samples but 'z11' has 499",
        ),
        (
            {
                "u11": np.full((500, 1), np.nan),
                "u12": np.ones((500, 1)),
                "z11": np.ones((500, 1)),
                "z12": np.ones((500, 1)),
            },
            "non-finite",
        ),
    ],
)
def test_a_malformed_file_gives_a_one_line_error_naming_it(tmp_path, content, message):
    scipy.io.savemat(tmp_path / "DATAUNIF.MAT", content)
    with pytest.raises(DataError, match=message) as err:
        load_benchmark("ced", tmp_path)
    assert "DATAUNIF.MAT" in str(err.value) and "\n" not in str(err.value)


def test_a_file_that_is_not_matlab_is_named(tmp_path):
    (tmp_path / "DATAUNIF.MAT").write_bytes(b"not a MATLAB file at all")
    with pytest.raises(DataError, match="not a readable MATLAB"):
        load_benchmark("ced", tmp_path)


def test_bouc_wen_files_are_also_found_by_their_bare_names(tmp_path):
    records = write_benchmark("bouc-wen", tmp_path, flat=True)
    ds = load_benchmark("bouc-wen", tmp_path)
    assert ds.split("test")[1].info["file"] == "uval_sinesweep.mat, yval_sinesweep.mat"
    np.testing.assert_array_equal(ds.split("test")[1].y[:, 0], records["sinesweep"][1])


def test_a_missing_bouc_wen_training_record_says_how_it_is_made(tmp_path):
    write_benchmark("bouc-wen", tmp_path)
    train = tmp_path / "BoucWen" / "BoucWenFiles" / "BoucWen_train.mat"
    train.unlink()
    with pytest.raises(DataError) as err:
        load_benchmark("bouc-wen", tmp_path)
    text = str(err.value)
    assert text.startswith("bouc-wen: BoucWen_train.mat not found") and "\n" not in text
    assert str(train) in text and "BoucWen_ExampleIntegration.m" in text


def test_a_missing_f16_level_is_named_with_the_download_page(tmp_path):
    write_benchmark("f16-gvt", tmp_path)
    folder = tmp_path / "F16" / "F16GVT_Files" / "BenchmarkData"
    (folder / "F16Data_FullMSine_Level4_Validation.mat").unlink()
    with pytest.raises(DataError) as err:
        load_benchmark("f16-gvt", tmp_path)
    text = str(err.value)
    assert "F16Data_FullMSine_Level4_Validation.mat not found" in text and "\n" not in text
    assert "nonlinearbenchmark.org/benchmarks/f-16-gvt" in text


def _f16_level3(rng, **changes) -> dict:
    content = _f16_content(rng, 330)
    content.update(changes)
    return {k: v for k, v in content.items() if v is not None}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"Acceleration": None}, r"no variable\(s\) \['Acceleration'\]"),
        ({"Acceleration": np.ones((2, 330))}, r"'Acceleration' must be 3 × N .*got \(2, 330\)"),
        ({"Acceleration": np.ones((3, 329))}, "'Force' has 330 samples but 'Acceleration' has 329"),
        ({"Force": np.ones((2, 330))}, r"'Force' must be a 1 × N or N × 1 vector"),
        ({"Fs": [[200.0]]}, "'Fs' = 200 Hz, but F16Data_FullMSine_Level1.mat has 400 Hz"),
    ],
)
def test_a_malformed_f16_record_gives_a_one_line_error_naming_it(tmp_path, changes, message):
    write_benchmark("f16-gvt", tmp_path, flat=True)
    rng = np.random.default_rng(3)
    scipy.io.savemat(tmp_path / "F16Data_FullMSine_Level3.mat", _f16_level3(rng, **changes))
    with pytest.raises(DataError, match=message) as err:
        load_benchmark("f16-gvt", tmp_path)
    assert "F16Data_FullMSine_Level3.mat" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("file", "content", "message"),
    [
        ("yval_multisine.mat", {"y": np.ones((1, 600))}, r"no variable\(s\) \['yval_multisine'\]"),
        (
            "yval_sinesweep.mat",
            {"yval_sinesweep": np.ones((1, 899))},
            r"'yval_sinesweep' has 899 samples but 'uval_sinesweep' \(uval_sinesweep.mat\) "
            "has 900",
        ),
        (
            "BoucWen_train.mat",
            {"u": np.ones((2000, 1)), "y": np.ones((1999, 1))},
            "'u' has 2000 samples but 'y' has 1999",
        ),
        (
            "uval_multisine.mat",
            {"uval_multisine": np.full((1, 600), np.inf)},
            "'uval_multisine' holds non-finite values",
        ),
    ],
)
def test_a_malformed_bouc_wen_file_gives_a_one_line_error_naming_it(
    tmp_path, file, content, message
):
    write_benchmark("bouc-wen", tmp_path, flat=True)
    scipy.io.savemat(tmp_path / file, content)
    with pytest.raises(DataError, match=message) as err:
        load_benchmark("bouc-wen", tmp_path)
    assert file in str(err.value) and "\n" not in str(err.value)


def test_a_test_part_no_longer_than_n_init_is_refused(tmp_path):
    write_benchmark("bouc-wen", tmp_path, flat=True)
    for s in "uy":
        scipy.io.savemat(
            tmp_path / f"{s}val_multisine.mat", {f"{s}val_multisine": np.ones((1, 50))}
        )
    with pytest.raises(DataError, match="'multisine' has 50 samples, not more than n_init = 50"):
        load_benchmark("bouc-wen", tmp_path)


def test_every_training_record_gives_its_tail_to_validation(tmp_path):
    write_benchmark("ced", tmp_path)
    split = split_train_val(load_benchmark("ced", tmp_path), val_fraction=0.2, record_tails=True)
    assert [t.T for t in split.split("train")] == [320, 320]
    assert [t.T for t in split.split("val")] == [80, 80]
    assert [t.info["samples"] for t in split.split("val")] == [[320, 400], [320, 400]]
    assert split.counts()["test"] == 2


def _untrained(window: int, data: Dataset) -> Model:
    net = build_net("mlp", window=window, n_u=1, n_y=1, hidden=[8])
    return Model(net, Normalisation.fit(data.split("train")))


def test_scores_never_see_outputs_after_n_init_and_match_the_formula(tmp_path):
    write_benchmark("cascaded-tanks", tmp_path)
    ds = load_benchmark("cascaded-tanks", tmp_path)
    bench, model = benchmark("cascaded-tanks"), _untrained(3, ds)
    scores, sims = score_parts(model, ds, bench)
    (part,) = ds.split("test")
    n, ell = bench.n_init, 3
    # the simulation from samples n_init−ℓ … n_init−1, by hand
    by_hand = model.predict(part.u[None, n - ell :], part.y[None, n - ell : n])[0]
    np.testing.assert_allclose(sims[0], by_hand, rtol=1e-12)
    assert scores[0].rmse == pytest.approx(np.sqrt(np.mean((by_hand - part.y[n:]) ** 2)))
    assert (scores[0].n_init, scores[0].n_scored, scores[0].units) == (50, 1024 - 50, "V")
    # measured outputs after n_init (and before n_init − ℓ) do not change the simulation
    y = part.y.copy()
    y[n:] += 1.0
    y[: n - ell] -= 1.0
    hidden = as_trajectories(SimpleNamespace(u=part.u, y=y))
    np.testing.assert_array_equal(simulate_records(model, hidden, n)[0], sims[0])


def test_records_of_different_lengths_simulate_as_they_would_alone(tmp_path):
    write_benchmark("silverbox", tmp_path)
    ds = load_benchmark("silverbox", tmp_path)
    model = _untrained(4, ds)
    cut = zip(ds.split("test"), (900, 600, 200))
    parts = as_trajectories([SimpleNamespace(u=p.u[:n], y=p.y[:n]) for p, n in cut])
    together = simulate_records(model, parts, 50)
    for part, sim in zip(parts, together):
        (alone,) = simulate_records(model, [part], 50)
        assert sim.shape == (part.T - 50, 1)
        # the network computes in float32: batching changes the rounding, nothing else
        np.testing.assert_allclose(sim, alone, rtol=1e-5, atol=1e-8)


def test_a_window_beyond_n_init_is_refused_before_training(tmp_path, capsys):
    write_benchmark("cascaded-tanks", tmp_path)
    code = main(["benchmark", "cascaded-tanks", "--dir", str(tmp_path), "--window", "51"])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "n_init = 50" in err and "\n" not in err
    assert not (Path("runs") / "cascaded-tanks-mlp").exists()


def test_missing_files_on_the_command_line_are_one_line(tmp_path, capsys):
    assert main(["benchmark", "emps", "--dir", str(tmp_path), "--out", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("canonid benchmark: error: emps: DATA_EMPS.mat not found")
    assert "\n" not in err and not (tmp_path / "r").exists()


def test_list_shows_which_files_were_found(tmp_path, capsys):
    write_benchmark("ced", tmp_path)
    assert main(["benchmark", "--list", "--dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"CED/DATAUNIF.MAT: found: {tmp_path / 'CED' / 'DATAUNIF.MAT'}" in out
    assert "Silverbox/SilverboxFiles/SNLS80mV.mat (or SNLS80mV.csv): missing" in out
    assert all(f"{name}:" in out for name in BENCHMARKS)


@pytest.mark.slow
def test_benchmark_silverbox_end_to_end_is_a_normal_run(tmp_path, capsys):
    write_benchmark("silverbox", tmp_path / "files")
    run = tmp_path / "run"
    argv = ["benchmark", "silverbox", "--dir", str(tmp_path / "files"), "--profile", "tiny"]
    argv += ["--window", "5", "--no-progress", "--threads", "1"]
    # a narrow network started from the ARX fit (the data are linear): its simulation of the
    # 94,000 test samples stays finite and costs a fraction of the default 3 × 256's
    assert main([*argv, "--out", str(run), "--hidden", "16", "--linear", "arx"]) == 0
    out = capsys.readouterr().out
    # canonid's row above the published ones (three decimals, three significant digits below
    # 0.1: these linear data leave an error of about 1e-6 mV), the GRU's figures as published
    ours = re.search(r"^canonid \(mlp, ℓ = 5\) +(\S+) ", out, flags=re.M)
    assert ours and re.fullmatch(r"\d+\.\d{3}|\d\.\d\de-\d\d|0\.0*[1-9]\d\d", ours[1])
    assert re.search(r"^GRU +1\.49 +2\.80 +0\.947 +\[1\]$", out, flags=re.M)
    report = json.loads((run / "benchmark.json").read_text())
    assert [s["test"] for s in report["scores"]] == [
        "multisine",
        "arrow-full",
        "arrow-no-extrapolation",
    ]
    assert all(s["units"] == "mV" and s["n_init"] == 50 for s in report["scores"])
    assert report["window"] == 5 and report["baselines"]
    # training scored validation; canonid evaluate of the same test parts (all of them, in V)
    # agrees with the benchmark's scores
    assert json.loads((run / "metrics.json").read_text())["data"]["split"] == "val"
    assert main(["evaluate", str(run), "--stride", "1000"]) == 0
    (scored,) = (run / "evaluations").glob("*/metrics.json")
    metrics = json.loads(scored.read_text())
    n = np.array([s["n_scored"] for s in report["scores"]])
    rmse_v = np.array([s["rmse"] for s in report["scores"]]) / 1000.0
    assert metrics["n_init"] == 50 and metrics["n_scored_samples"] == n.sum()
    assert metrics["rmse"] == pytest.approx(np.sqrt(np.sum(n * rmse_v**2) / n.sum()), rel=1e-6)
    for name in report["scores"]:
        assert (run / f"benchmark-{name['test']}.png").stat().st_size > 0
    # each part names its signals outside the training part's span, in the file and the table
    from canonid.coverage import outside_training_range, training_ranges

    data = Dataset.load(run / "benchmark-data.npz")
    spans = {"training_range": training_ranges(data.split("train"))}
    names = {"input_names": data.input_names, "output_names": data.output_names}
    for part, score in zip(data.split("test"), report["scores"], strict=True):
        expected = outside_training_range(spans, [part], **names)
        assert expected is not None and score["outside"] == [o.to_json() for o in expected]
        said = f"test part '{score['test']}' leaves the training range" in out
        assert said == any(o.noted for o in expected)
    # and where training leaves the validation part's spans, as the model recorded it
    from canonid.coverage import recorded_unvalidated, unvalidated_line

    info = json.loads((run / "config.json").read_text())["info"]
    assert report["unvalidated"] == info["training_outside_validation"]
    line = unvalidated_line(recorded_unvalidated(info))
    assert line in out if line else "validation does not reach" not in out
    # a normal run: canonid evaluate reads its recipe and data
    recipe = json.loads((run / "run.json").read_text())
    assert recipe["data"] == str(run / "benchmark-data.npz") and recipe["window"] == 5
    net = recipe["net_options"]  # the options reached canonid train
    assert (net["hidden"], net["linear"]) == ([16], "arx")
    assert Dataset.load(recipe["data"]).counts() == {"train": 1, "val": 1, "test": 3}
    assert (
        main(["evaluate", str(run), "--split", "val", "--stride", "500", "--eval-horizon", "20"])
        == 0
    )


def test_train_options_reach_canonid_train_and_cannot_override_the_benchmark(tmp_path, capsys):
    from canonid.cli import build_parser
    from canonid.commands.benchmark import train_request

    given = build_parser("benchmark").parse_args(
        ["benchmark", "ced", "--epochs", "7", "--batch-size", "64", "--hidden", "16"]
    )
    request = train_request(["data.npz", "--model", "mlp", "--window", "3"], given)
    assert (request.epochs, request.batch_size, request.profile) == (7, 64, None)  # default
    assert request.hidden == (16,)
    write_benchmark("ced", tmp_path)
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--out", str(tmp_path / "r")]
    for data_option in ("--val", "--inputs", "--time-column"):  # the benchmark's own data
        with pytest.raises(SystemExit):
            main([*argv, data_option, "x"])
        assert "unrecognized argument" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()  # refused before anything was written


#: the one-line warning of the former --train-args
FORMER = "canonid benchmark: warning: --train-args is deprecated, use canonid train's options"


def test_the_former_train_args_still_reach_canonid_train_with_a_warning(tmp_path, capsys):
    from canonid.benchmark import train_args
    from canonid.cli import build_parser
    from canonid.commands.benchmark import train_request

    given = build_parser("benchmark").parse_args(
        ["benchmark", "ced", "--train-args=--epochs 7 --batch-size 64", "--epochs", "9"]
    )
    assert capsys.readouterr().err.startswith(FORMER)
    request = train_request(train_args(given.train_args), given)
    assert (request.epochs, request.batch_size) == (9, 64)  # the option given directly wins
    write_benchmark("ced", tmp_path)
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--out", str(tmp_path / "r")]
    assert main([*argv, "--train-args=--out elsewhere"]) == 1
    assert "--out set by canonid benchmark itself" in capsys.readouterr().err
    assert main([*argv, "--train-args", "--epochs x"]) == 1
    warning, err = capsys.readouterr().err.strip().split("\n")
    assert warning.startswith(FORMER)
    assert "canonid train rejected the options" in err and "'x'" in err
    assert not (tmp_path / "r").exists()  # refused before anything was written


def test_ced_with_the_default_profile_validates_on_its_short_tails_simulated(tmp_path, caplog):
    """CED's validation tails (80 samples here, as in the real files) are shorter than ℓ + the
    quick profile's 100-step rollouts: validation simulates each tail whole after the searched
    windows' burn-in (ℓ ≤ n_init = 10), nothing is cut, and the model records how it was
    validated."""
    write_benchmark("ced", tmp_path)
    run = tmp_path / "run"
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--out", str(run), "--no-progress"]
    with caplog.at_level(logging.WARNING, logger="canonid.learning.training"):
        assert main([*argv, "--threads", "1", "--epochs", "2"]) == 0
    assert not [r for r in caplog.records if "cut" in r.getMessage()]
    options = json.loads((run / "config.json").read_text())["info"]["training"]["options"]
    assert (options["val_measure"], options["val_n_init"]) == ("simulation", 10)
    report = json.loads((run / "benchmark.json").read_text())
    assert [s["test"] for s in report["scores"]] == ["low-amplitude", "high-amplitude"]


# ------------------------------------------------------------------ finishable, not half-written
def _folder_after(tmp_path: Path, argv: list[str], capsys, *needles: str) -> None:
    """``canonid benchmark ARGV`` into ``tmp_path/r`` is refused in one line holding the needles
    and leaves no folder."""
    code = main([*argv, "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip()
    if any(a.startswith("--train-args") for a in argv):  # the former spelling's warning first
        warning, _, err = err.partition("\n")
        assert warning.startswith(FORMER), warning
    assert code == 1 and "\n" not in err and "Traceback" not in err, err
    assert all(needle in err for needle in needles), err
    assert not (tmp_path / "r").exists()


def test_training_options_are_checked_before_the_data_are_written(tmp_path, capsys):
    write_benchmark("cascaded-tanks", tmp_path)
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path), "--model", "gru"]
    _folder_after(tmp_path, [*argv, "--activation", "tanh"], capsys, "--activation")
    _folder_after(tmp_path, [*argv, "--threads", "0"], capsys, "--threads")


@pytest.mark.parametrize("given", ["--mod gru", "--model=gru", "--prof tiny", "--se 3", "-h"])
def test_train_args_refuse_the_benchmarks_own_options_in_any_spelling(tmp_path, capsys, given):
    write_benchmark("cascaded-tanks", tmp_path)
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path), f"--train-args={given}"]
    _folder_after(tmp_path, argv, capsys, "set by canonid benchmark itself")


def test_train_args_take_no_abbreviation_and_no_data(tmp_path, capsys):
    write_benchmark("cascaded-tanks", tmp_path)
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path)]
    _folder_after(tmp_path, [*argv, "--train-args=--epo 3"], capsys, "--epo")
    _folder_after(tmp_path, [*argv, "--train-args=other.npz"], capsys, "'other.npz'")


@pytest.mark.parametrize("given", ["--dt 5", "--dt=5", "--inputs u", "--time-column t"])
def test_train_args_refuse_data_options_naming_them_not_the_internal_file(given, tmp_path, capsys):
    """Issue 54: ``--train-args '--dt 5'`` was refused naming ``benchmark-data.npz``, a file
    the user never gave."""
    write_benchmark("cascaded-tanks", tmp_path)
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path), f"--train-args={given}"]
    _folder_after(tmp_path, argv, capsys, "--train-args", given.split()[0].split("=")[0], "CSV")


def test_the_default_searches_only_windows_within_n_init(tmp_path, capsys):
    from canonid.learning.search import Search

    write_benchmark("ced", tmp_path)  # n_init = 10: the candidates ℓ ≥ 20 cannot be scored
    run = tmp_path / "r"
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--out", str(run)]
    argv += ["--profile", "tiny", "--threads", "1", "--no-progress", "--epochs", "1"]
    assert main(argv) == 0, capsys.readouterr().err
    search = Search.read(run)
    assert {c.window for c in search.candidates} == {10}  # ℓ = 10 alone, with or without cubic
    assert search.chosen is not None
    assert json.loads((run / "benchmark.json").read_text())["window"] == search.chosen.window
    assert main(argv) == 0  # run again: the recorded choice, nothing trained again
    assert Search.read(run) == search


def test_a_window_list_tries_only_windows_within_n_init(tmp_path, capsys):
    write_benchmark("ced", tmp_path)
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--window", "2,5,20"]
    _folder_after(tmp_path, argv, capsys, "window ℓ = 20 exceeds ced's n_init = 10")
    run = tmp_path / "r"
    argv = ["benchmark", "ced", "--dir", str(tmp_path), "--window", "2,5", "--out", str(run)]
    argv += ["--profile", "tiny", "--threads", "1", "--no-progress", "--epochs", "1"]
    assert main(argv) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (run / "search").iterdir()) == ["l2", "l2-c16", "l5", "l5-c16"]


def test_a_finished_benchmark_run_again_gives_the_same_report_and_other_options_are_refused(
    tmp_path, capsys
):
    write_benchmark("cascaded-tanks", tmp_path / "files")
    run = tmp_path / "run"
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path / "files"), "--out", str(run)]
    argv += ["--profile", "tiny", "--threads", "1", "--no-progress"]
    assert main([*argv, "--epochs", "2"]) == 0
    report = (run / "benchmark.json").read_bytes()
    assert main([*argv, "--epochs", "2"]) == 0  # continues: nothing left to train
    assert (run / "benchmark.json").read_bytes() == report
    capsys.readouterr()
    code = main([*argv, "--epochs", "3"])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "\n" not in err and "train_options.epochs: 2 there, 3 here" in err
    assert f"--resume --out {run}" in err
    # --resume: canonid train's rule (more epochs may be asked for), then the scores
    assert main(["benchmark", "--resume", "--out", str(run), "--no-progress", "--epochs", "3"]) == 0
    assert json.loads((run / "run.json").read_text())["train_options"]["epochs"] == 3
    assert json.loads((run / "benchmark.json").read_text())["scores"]
    assert main(["benchmark", "--resume", "--out", str(run), "--model", "gru"]) == 1
    assert "--model cannot be given with --resume" in capsys.readouterr().err


def _count_events(event):
    """Call ``event(kind)`` at every optimiser step (``"step"``) and every file written
    atomically (``"write NAME"``, the temporary file complete but not yet renamed); returns
    the function that undoes it."""
    import contextlib
    import os

    import torch

    import canonid.kernel.io as kio

    replacing, adam_step = kio._replacing, torch.optim.Adam.step

    @contextlib.contextmanager
    def counted_replacing(path, **kwargs):
        with replacing(path, **kwargs) as fh:
            yield fh
            event("write " + os.path.basename(path))

    def counted_step(self, *args, **kwargs):
        event("step")
        return adam_step(self, *args, **kwargs)

    def undo():
        kio._replacing, torch.optim.Adam.step = replacing, adam_step

    kio._replacing, torch.optim.Adam.step = counted_replacing, counted_step
    return undo


#: ``python -c`` program: ``canonid ARGS`` that SIGKILLs itself at its event number argv[1]
#: (an event as :func:`_count_events` counts them)
KILLED_BENCHMARK = f"""
import os, signal, sys
from canonid.cli import main

{inspect.getsource(_count_events)}

kill_at, events = int(sys.argv[1]), []

def event(kind):
    events.append(kind)
    if len(events) == kill_at:
        os.kill(os.getpid(), signal.SIGKILL)

_count_events(event)
sys.argv[1:] = sys.argv[2:]  # the command line as canonid would see it (run.json records it)
sys.exit(main())
"""


def _scores(run: Path) -> dict:
    """``metrics.json`` but for the path of the data scored (in the run's own folder)."""
    metrics = json.loads((run / "metrics.json").read_text())
    return {**metrics, "data": {**metrics["data"], "path": None}}


def _killed_benchmark(argv: list[str], *, kill_at: int):
    """``canonid ARGV`` in a process of its own that SIGKILLs itself at event ``kill_at``."""
    import subprocess
    import sys

    return subprocess.run(
        [sys.executable, "-c", KILLED_BENCHMARK, str(kill_at), *argv],
        capture_output=True,
        text=True,
        timeout=600,
        env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )


@pytest.mark.slow
def test_a_benchmark_killed_at_random_points_finishes_with_the_same_report(tmp_path, monkeypatch):
    """kill -9 at random events (a seeded draw over every optimiser step and file write of an
    uninterrupted run), then the same command again, or ``--resume`` once training has
    checkpointed: ``benchmark.json`` and the weights have the bytes of the uninterrupted run
    (``benchmark.json`` records no timing), and no temporary file is left. The runs that are
    killed are processes of their own; the others run in this process (a fresh process holds
    nothing the folder does not, and starting one costs seconds)."""
    import signal

    write_benchmark("cascaded-tanks", tmp_path / "files")
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path / "files"), "--profile", "tiny"]
    argv += ["--threads", "1", "--no-progress", "--epochs", "3", "--device", "cpu"]
    whole, events = tmp_path / "whole", []
    undo = _count_events(events.append)
    try:
        monkeypatch.setattr("sys.argv", ["canonid", *argv, "--out", str(whole)])  # run.json's
        assert main([*argv, "--out", str(whole)]) == 0
    finally:
        undo()
    rng = np.random.default_rng(29)
    points = [int(k) for k in rng.choice(np.arange(1, len(events) + 1), size=3, replace=False)]
    after_checkpoint = events.index("write checkpoint.pt") + 2
    points.append(int(rng.integers(after_checkpoint, len(events) + 1)))
    for i, point in enumerate(points):
        out = tmp_path / f"killed-{point}"
        cut = _killed_benchmark([*argv, "--out", str(out)], kill_at=point)
        assert cut.returncode == -signal.SIGKILL, (events[point - 1], cut.stderr[-2000:])
        again = [*argv, "--out", str(out)]
        if i == len(points) - 1:  # the last one by --resume
            again = ["benchmark", "--resume", "--out", str(out), "--threads", "1", "--no-progress"]
        monkeypatch.setattr("sys.argv", ["canonid", *again])  # what run.json records
        assert main(again) == 0, events[point - 1]
        for name in ("benchmark.json", "weights.pt", "normalisation.json"):
            assert (out / name).read_bytes() == (whole / name).read_bytes(), (point, name)
        assert _scores(out) == _scores(whole), point
        assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")], point


def test_range_of_parts_tables_every_test_part_against_the_training_span(tmp_path):
    """benchmarks/studies/range_of_parts/range_of_parts.py: rows for every test part of the
    benchmarks whose files are
    found, in the package's layout or in a folder of the benchmark's name."""
    import sys

    sys.path.insert(
        0, str(Path(__file__).resolve().parents[1] / "benchmarks" / "studies" / "range_of_parts")
    )
    import range_of_parts

    cache, flat = tmp_path / "cache", tmp_path / "flat"
    write_benchmark("silverbox", cache)
    write_benchmark("ced", flat / "ced", flat=True)
    for name, root, files in (("silverbox", cache, cache), ("ced", flat, flat / "ced")):
        rows = [r.split(" | ") for r in range_of_parts.table(root) if r.startswith(f"| {name} |")]
        expected = {p.info["part"] for p in load_benchmark(name, files).split("test")}
        assert {r[1] for r in rows} == expected
        assert all(r[-1] in ("yes |", "no |") for r in rows)
    # Silverbox's training part against its validation part (the generated sets are not here)
    rows = [r for r in range_of_parts.validation_table(cache) if r.startswith("| silverbox |")]
    assert rows and all(r.endswith(("| yes |", "| no |")) for r in rows)
