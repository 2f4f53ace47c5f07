"""The field's standard benchmarks (nonlinearbenchmark.org) as
:class:`canonid.kernel.dataset.Dataset`.

Each entry of :data:`BENCHMARKS` reads the benchmark's own files, offline, and cuts the official
split as the ``nonlinear_benchmarks`` package (version 1.0.1, ``benchmarks.py``) defines it: the
same files, variable names, slices, ``n_init`` and scoring units. The dataset holds two splits,
``"train"`` (the official training records, for training *and* validation) and ``"test"`` (every
official test part, in the package's order); the metadata say which is which.

Index conventions (0-based Python slices ``[start, stop)`` of the record as stored in the file)
-----------------------------------------------------------------------------------------------
* **Silverbox** (``SNLS80mV``, ``V1`` = input, ``V2`` = output, 1 × 131,072; dt = 1/610.35 s):
  test "multisine" = the last 25 % of ``40650:127400``, i.e. ``105712:127400`` (training:
  ``40650:105712``, ``int(0.75 · 86,750)`` = 65,062 samples); test "arrow-full" = ``100:40575``;
  test "arrow-no-extrapolation" = its first 32,000 samples, ``100:32100``. ``n_init`` = 50.
* **Cascaded Tanks** (``dataBenchmark.mat``: ``uEst``, ``yEst``, ``uVal``, ``yVal``, ``Ts``):
  training = the whole estimation record, test = the whole validation record. ``n_init`` = 50.
* **Wiener–Hammerstein** (``WienerHammerBenchMark.mat``: ``uBenchMark``, ``yBenchMark``, ``fs``):
  training = ``5200:105200``, test = ``105200:184000``. ``n_init`` = 50.
* **EMPS** (``DATA_EMPS.mat`` and ``DATA_EMPS_PULSES.mat``, each ``vir`` = motor force (input),
  ``qm`` = measured position (output), ``t``; dt = ``t[1] − t[0]``): training = the whole
  ``DATA_EMPS`` record, test = the whole ``DATA_EMPS_PULSES`` record. ``n_init`` = 20.
* **CED** (``DATAUNIF.MAT``: ``u11``, ``z11`` low and ``u12``, ``z12`` high input amplitude;
  dt = 0.02 s): training = ``0:400`` of each experiment, test = ``400:`` of each. ``n_init`` = 10.

* **F-16 ground-vibration test** (``F16GVT_Files/BenchmarkData``; each record a ``.mat`` file with
  ``Force`` (1 × N, input, N), ``Acceleration`` (3 × N, outputs ``Acceleration1…3``, m/s²) and
  ``Fs`` (400 Hz); dt = 1/``Fs``, the same in every file): the full-multisine records only.
  Training = the whole records of levels 1, 3, 5, 7 (``F16Data_FullMSine_Level{1,3,5,7}.mat``);
  test parts ``level-2``, ``level-4``, ``level-6`` = the whole
  ``F16Data_FullMSine_Level{2,4,6}_Validation.mat`` records (the package's test files are those
  named ``Validation``). ``n_init`` = 50. The package's loader also holds the sine-sweep records
  and gives one accelerometer (``output_index``, default 0); here all three are outputs and a
  part's score is the RMSE over the three together.
* **Bouc–Wen** (``BoucWenFiles``; ``Test signals/Validation signals/uval_multisine.mat`` …: each
  file one 1 × N variable of its own name, input force in N, output displacement in m;
  dt = 1/750 s, the rate of the benchmark's simulator): test parts ``multisine``
  (``uval_multisine``, ``yval_multisine``) and ``sinesweep`` (``uval_sinesweep``,
  ``yval_sinesweep``), whole. The benchmark ships no training record (its users simulate one
  with its MATLAB integrator) and the package defines no split: training = the record
  ``BoucWen_train.mat`` (``u``, ``y`` as ``BoucWen_ExampleIntegration.m`` leaves them), whole.
  ``n_init`` = 50, canonid's choice (:data:`BOUC_WEN_N_INIT`).

Version 1.0.1 raised ``n_init`` from 5 to 50 (Cascaded Tanks) and from 4 to 10 (CED); the other
three are unchanged.

Scoring rule (the package's submission examples): a model may use the whole test input and the
first ``n_init`` measured outputs of each test part; the score is the RMSE of its simulation on
samples ``n_init …`` of the part, in the benchmark's scoring units (:attr:`Benchmark.score_units`,
the outputs' units times :attr:`Benchmark.score_scale`).

Published results (:attr:`Benchmark.baselines`): every row of the baseline study of Champneys et
al. (2024) and of the same paper's table of the best published results, as printed there (figure,
units, source), the lowest figure on each test part marked :attr:`Baseline.best`. That paper does
not cover Bouc–Wen and the F-16; no figure on their test parts under this protocol is entered.

Files are looked for in ``DIR/<the package's cache folder>/FILE`` (e.g.
``DIR/Silverbox/SilverboxFiles/SNLS80mV.mat``) and by their bare name in ``DIR``; Silverbox is
also read from its CSV export ``SNLS80mV.csv`` (columns ``V1``, ``V2``). ``DIR`` defaults to the
package's cache, ``~/.nonlinear_benchmarks``. MATLAB files are read with ``scipy.io.loadmat``
(no pickle).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from canonid.datagen.loaders import load_csv
from canonid.kernel.dataset import Dataset, Trajectory, dt_problem
from canonid.kernel.errors import DataError

__all__ = [
    "BENCHMARKS",
    "DEFAULT_DIR",
    "Baseline",
    "Benchmark",
    "baseline_rows",
    "baselines_markdown",
    "benchmark",
    "benchmark_names",
    "find_files",
    "load_benchmark",
]

#: where ``nonlinear_benchmarks`` caches its downloads on Linux
DEFAULT_DIR = Path("~/.nonlinear_benchmarks")

DEFINITION = "nonlinear_benchmarks 1.0.1 (benchmarks.py and submission_examples/)"
CHAMPNEYS = (
    "Champneys, Beintema, Tóth, Schoukens, Rogers, 'Baseline results for selected nonlinear "
    "system identification benchmarks' (2024, arXiv:2405.10779; result files in "
    "github.com/MDCHAMP/nonlinear_baselines)"
)


@dataclass(frozen=True)
class Baseline:
    """A published free-run simulation RMSE on one official test part.

    Attributes:
        method: the method, as its source names it.
        test: the official test part (one of :attr:`Benchmark.test_parts`).
        figure: the RMSE as the source prints it (``"0.10"`` keeps the source's digits).
        units: the benchmark's scoring units.
        source: where the figure is published.
        best: the lowest published figure on this test part (the bar to beat).
        note: what sets this one figure apart, where its source says so.
        rmse: ``figure`` as a number.
    """

    method: str
    test: str
    figure: str
    units: str
    source: str
    best: bool = False
    note: str = ""
    rmse: float = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "rmse", float(self.figure))


@dataclass(frozen=True)
class _Part:
    """One cut of a record: ``[start, stop)`` of ``(u, y)`` read from ``file``."""

    name: str
    u: np.ndarray
    y: np.ndarray
    file: str
    start: int
    stop: int


@dataclass(frozen=True)
class Benchmark:
    """One benchmark: where its files are, how its split is cut, how it is scored.

    Attributes:
        name: command-line name (``silverbox``).
        title: the benchmark's name on nonlinearbenchmark.org.
        folder: the package's cache folder of the files, relative to ``DIR``.
        files: the MATLAB files read.
        csv: CSV exports that may stand in for ``files`` (same record, same columns).
        page: where the files can be downloaded.
        input_names, output_names: signal names; ``units`` maps them to physical units.
        n_init: measured outputs of each test part a model may use (the official rule).
        test_parts: names of the official test parts, in the package's order.
        score_units, score_scale: the scoring unit and its factor from the output's unit.
        baselines: published scores (:class:`Baseline`) shown beside canonid's.
        reader: ``(found files by name) → (dt, training parts, test parts)``.
        made: files the benchmark's download does not hold, each with how its user makes it.
    """

    name: str
    title: str
    folder: str
    files: tuple[str, ...]
    csv: tuple[str, ...]
    page: str
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    units: Mapping[str, str | None]
    n_init: int
    test_parts: tuple[str, ...]
    score_units: str
    score_scale: float
    baselines: tuple[Baseline, ...]
    reader: Callable[[Mapping[str, Path]], tuple[float, list[_Part], list[_Part]]]
    made: Mapping[str, str] = field(default_factory=dict)

    def where_from(self, file: str) -> str:
        """How to get ``file``: how its user makes it, or where to download it."""
        return self.made.get(file) or f"download the {self.title} files from {self.page}"

    def candidates(self, file: str, directory: Path) -> list[Path]:
        """Where ``file`` is looked for under ``directory``, in order: in the package's layout
        (``file`` may name a sub-folder of :attr:`folder`, as Bouc–Wen's test files do), then
        by its bare name directly in ``directory``."""
        return [directory / self.folder / file, directory / Path(file).name]


# ------------------------------------------------------------------------------- file access
def _read_mat(path: Path, names: Sequence[str]) -> dict[str, np.ndarray]:
    """Variables ``names`` of a MATLAB file as float64 arrays, or a one-line :class:`DataError`."""
    from scipy.io import loadmat

    try:
        content = loadmat(str(path))
    except Exception as exc:  # scipy's parser fails in many ways on a file that is not MATLAB v5
        raise DataError(f"{path}: not a readable MATLAB v5 .mat file ({exc})") from None
    missing = [n for n in names if n not in content]
    if missing:
        found = sorted(k for k in content if not k.startswith("__"))
        raise DataError(f"{path}: no variable(s) {missing}; it holds {found}")
    return {n: _real(content[n], path, n) for n in names}


def _real(value: Any, path: Path, name: str) -> np.ndarray:
    """A MATLAB variable as float64: text, and complex values with an imaginary part other than
    zero, are refused rather than converted (``float('4.0')`` or dropping ``.imag`` would hide
    a wrong file)."""
    kind = getattr(value, "dtype", np.dtype(object)).kind
    if kind in "US":
        shown = "".join(str(v) for v in np.ravel(value))
        raise DataError(f"{path}: variable {name!r} is text ({shown!r:.40}); expected numbers")
    if kind == "c":
        imag = np.abs(value.imag)
        if np.any(imag != 0):
            raise DataError(
                f"{path}: variable {name!r} holds complex values (imaginary parts up to "
                f"{float(np.max(imag)):.3g}); expected real numbers"
            )
        value = value.real
    if kind not in "biufc":
        raise DataError(f"{path}: variable {name!r} is not numeric (MATLAB cell or struct)")
    return np.asarray(value, dtype=np.float64)


def _vector(arr: np.ndarray, path: Path, name: str) -> np.ndarray:
    """A ``(1, N)`` or ``(N, 1)`` variable as a finite ``(N,)`` vector."""
    if arr.ndim != 2 or min(arr.shape) != 1 or arr.size < 2:
        raise DataError(
            f"{path}: variable {name!r} must be a 1 × N or N × 1 vector, got {arr.shape}"
        )
    vec = arr.reshape(-1)
    if not np.all(np.isfinite(vec)):
        raise DataError(f"{path}: variable {name!r} holds non-finite values")
    return vec


def _scalar(arr: np.ndarray, path: Path, name: str) -> float:
    if arr.size != 1 or not math.isfinite(float(arr.reshape(-1)[0])) or arr.reshape(-1)[0] <= 0:
        raise DataError(f"{path}: variable {name!r} must be one positive number, got {arr!r}")
    return float(arr.reshape(-1)[0])


def _need(path: Path, name: str, vec: np.ndarray, samples: int) -> None:
    if len(vec) < samples:
        raise DataError(
            f"{path}: variable {name!r} has {len(vec)} samples; the official split needs at "
            f"least {samples}"
        )


def _pair(
    path: Path, arrays: Mapping[str, np.ndarray], u: str, y: str
) -> tuple[np.ndarray, np.ndarray]:
    uv, yv = _vector(arrays[u], path, u), _vector(arrays[y], path, y)
    if len(uv) != len(yv):
        raise DataError(f"{path}: {u!r} has {len(uv)} samples but {y!r} has {len(yv)}")
    return uv, yv


def _cut(name: str, u: np.ndarray, y: np.ndarray, path: Path, start: int, stop: int) -> _Part:
    return _Part(name, u[start:stop], y[start:stop], path.name, start, stop)


# ------------------------------------------------------------------------------- readers
SILVERBOX_DT = 1 / 610.35


def _silverbox(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    path = found["SNLS80mV.mat"]
    if path.suffix.lower() == ".csv":
        rec = load_csv(path, inputs=["V1"], outputs=["V2"], dt=SILVERBOX_DT).split("train")[0]
        u, y = rec.u[:, 0], rec.y[:, 0]
    else:
        u, y = _pair(path, _read_mat(path, ["V1", "V2"]), "V1", "V2")
    _need(path, "V1", u, 127_400)
    lo, hi = 40_650, 127_400
    cut = lo + int(0.75 * (hi - lo))
    train = [_cut("multisine-train", u, y, path, lo, cut)]
    test = [
        _cut("multisine", u, y, path, cut, hi),
        _cut("arrow-full", u, y, path, 100, 40_575),
        _cut("arrow-no-extrapolation", u, y, path, 100, 100 + 32_000),
    ]
    return SILVERBOX_DT, train, test


def _cascaded_tanks(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    path = found["dataBenchmark.mat"]
    arrays = _read_mat(path, ["uEst", "yEst", "uVal", "yVal", "Ts"])
    u_est, y_est = _pair(path, arrays, "uEst", "yEst")
    u_val, y_val = _pair(path, arrays, "uVal", "yVal")
    dt = _scalar(arrays["Ts"], path, "Ts")
    train = [_cut("estimation", u_est, y_est, path, 0, len(u_est))]
    return dt, train, [_cut("validation", u_val, y_val, path, 0, len(u_val))]


def _wiener_hammerstein(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    path = found["WienerHammerBenchMark.mat"]
    arrays = _read_mat(path, ["uBenchMark", "yBenchMark", "fs"])
    u, y = _pair(path, arrays, "uBenchMark", "yBenchMark")
    _need(path, "uBenchMark", u, 184_000)
    fs = _scalar(arrays["fs"], path, "fs")
    dt = 1.0 / fs
    if not math.isfinite(dt):
        raise DataError(
            f"{path}: variable 'fs' = {fs!r} gives no finite sampling time 1/fs; expected the "
            "sampling frequency in Hz (51200 for this benchmark)"
        )
    train = [_cut("train", u, y, path, 5_200, 105_200)]
    return dt, train, [_cut("test", u, y, path, 105_200, 184_000)]


EMPS_N_INIT = 20
#: how far a step of EMPS's clock ``t`` may be from ``t[1] − t[0]``, relative to it: rounding
#: (even of a clock stored in single precision) passes, a missing or repeated sample does not
EMPS_STEP_TOLERANCE = 1e-2


def _uniform(t: np.ndarray, dt: float, path: Path) -> None:
    """Refuse a clock ``t`` whose steps are not all ``dt`` (the step the official split uses)."""
    steps = np.diff(t)
    off = np.flatnonzero(np.abs(steps - dt) > EMPS_STEP_TOLERANCE * dt)
    if off.size:
        k = int(off[0]) + 1
        raise DataError(
            f"{path}: variable 't' is not uniformly sampled: t[{k}] − t[{k - 1}] = "
            f"{steps[k - 1]:.6g} s but t[1] − t[0] = {dt:.6g} s (every step within "
            f"{EMPS_STEP_TOLERANCE:.0%} of it expected)"
        )


def _emps(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    parts, dts = [], []
    for name, file in (
        ("DATA_EMPS", "DATA_EMPS.mat"),
        ("DATA_EMPS_PULSES", "DATA_EMPS_PULSES.mat"),
    ):
        path = found[file]
        arrays = _read_mat(path, ["qm", "t", "vir"])
        u, y = _pair(path, arrays, "vir", "qm")
        t = _vector(arrays["t"], path, "t")
        if len(t) != len(u):
            raise DataError(f"{path}: variable 't' has {len(t)} samples but 'vir' has {len(u)}")
        _need(path, "vir", u, EMPS_N_INIT + 1)
        dt = float(t[1] - t[0])
        if not dt > 0:
            raise DataError(f"{path}: variable 't' must increase, got t[1] − t[0] = {dt}")
        _uniform(t, dt, path)
        parts.append(_cut(name, u, y, path, 0, len(u)))
        dts.append(dt)
    if not math.isclose(dts[0], dts[1], rel_tol=1e-6):
        raise DataError(f"EMPS: the two records have different sampling times {dts}")
    return dts[0], [parts[0]], [parts[1]]


def _ced(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    path = found["DATAUNIF.MAT"]
    arrays = _read_mat(path, ["u11", "u12", "z11", "z12"])
    train, test = [], []
    for amp, (u_name, z_name) in (("low", ("u11", "z11")), ("high", ("u12", "z12"))):
        u, z = _pair(path, arrays, u_name, z_name)
        _need(path, u_name, u, 401)
        train.append(_cut(f"{amp}-amplitude-train", u, z, path, 0, 400))
        test.append(_cut(f"{amp}-amplitude", u, z, path, 400, len(u)))
    return 0.02, train, test


#: Bouc–Wen: the working sampling rate of the benchmark's simulator, 750 Hz (its test files hold
#: no clock; ``BoucWen_ExampleIntegration.m``, ``fs = 750``)
BOUC_WEN_DT = 1 / 750
#: measured outputs of each Bouc–Wen test part a model may use: neither the benchmark nor
#: ``nonlinear_benchmarks`` 1.0.1 sets one (the package lists Bouc–Wen among its benchmarks
#: without an official split); canonid takes the package's value for every other long record, 50
BOUC_WEN_N_INIT = 50
#: the training record: the benchmark ships none, its users simulate one with the benchmark's
#: MATLAB integrator; canonid reads the ``u`` and ``y`` that ``BoucWen_ExampleIntegration.m``
#: leaves, saved under this name (``save('BoucWen_train.mat', 'u', 'y')``)
BOUC_WEN_TRAIN = "BoucWen_train.mat"
#: where the benchmark's zip keeps its two official test records (input and output files)
BOUC_WEN_TESTS = "Test signals/Validation signals"
#: the official test parts, in the package's order, each an input and an output file
BOUC_WEN_PARTS = ("multisine", "sinesweep")


def _bouc_wen_files() -> tuple[str, ...]:
    tests = (f"{BOUC_WEN_TESTS}/{s}val_{part}.mat" for part in BOUC_WEN_PARTS for s in "uy")
    return (BOUC_WEN_TRAIN, *tests)


def _bouc_wen(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    path = found[BOUC_WEN_TRAIN]
    u, y = _pair(path, _read_mat(path, ["u", "y"]), "u", "y")
    train = [_cut("train", u, y, path, 0, len(u))]
    test = []
    for part in BOUC_WEN_PARTS:
        u_path = found[f"{BOUC_WEN_TESTS}/uval_{part}.mat"]
        y_path = found[f"{BOUC_WEN_TESTS}/yval_{part}.mat"]
        u_name, y_name = f"uval_{part}", f"yval_{part}"
        uv = _vector(_read_mat(u_path, [u_name])[u_name], u_path, u_name)
        yv = _vector(_read_mat(y_path, [y_name])[y_name], y_path, y_name)
        if len(uv) != len(yv):
            raise DataError(
                f"{y_path}: {y_name!r} has {len(yv)} samples but {u_name!r} "
                f"({u_path.name}) has {len(uv)}"
            )
        test.append(_Part(part, uv, yv, f"{u_path.name}, {y_path.name}", 0, len(uv)))
    return BOUC_WEN_DT, train, test


#: F-16 ground-vibration test, full-multisine records: the levels that train (the package's
#: training files: not ``Validation``, not ``SpecialOddMSine``) and the levels that test (the
#: ``_Validation`` files); the package also trains and tests on the sine-sweep records
#: (``F16Data_SineSw_*``), which this benchmark leaves out
F16_TRAIN_LEVELS = (1, 3, 5, 7)
F16_TEST_LEVELS = (2, 4, 6)
F16_N_INIT = 50
#: the three accelerometers of each record (``Acceleration``, 3 × N in the files)
F16_OUTPUTS = ("Acceleration1", "Acceleration2", "Acceleration3")


def _f16_file(level: int) -> str:
    tail = "_Validation" if level in F16_TEST_LEVELS else ""
    return f"F16Data_FullMSine_Level{level}{tail}.mat"


def _f16_record(path: Path, name: str) -> tuple[_Part, float]:
    """One F-16 record: ``Force`` (1 × N) in, ``Acceleration`` (3 × N) out, and ``1 / Fs``."""
    arrays = _read_mat(path, ["Force", "Acceleration", "Fs"])
    u = _vector(arrays["Force"], path, "Force")
    acc = arrays["Acceleration"]
    if acc.ndim != 2 or acc.shape[0] != len(F16_OUTPUTS):
        raise DataError(
            f"{path}: variable 'Acceleration' must be {len(F16_OUTPUTS)} × N (one row per "
            f"accelerometer), got {acc.shape}"
        )
    if not np.all(np.isfinite(acc)):
        raise DataError(f"{path}: variable 'Acceleration' holds non-finite values")
    if acc.shape[1] != len(u):
        raise DataError(
            f"{path}: 'Force' has {len(u)} samples but 'Acceleration' has {acc.shape[1]}"
        )
    fs = _scalar(arrays["Fs"], path, "Fs")
    return _cut(name, u, acc.T, path, 0, len(u)), 1.0 / fs


def _f16(found: Mapping[str, Path]) -> tuple[float, list[_Part], list[_Part]]:
    read = {
        level: _f16_record(found[_f16_file(level)], f"level-{level}")
        for level in (*F16_TRAIN_LEVELS, *F16_TEST_LEVELS)
    }
    dt = read[F16_TRAIN_LEVELS[0]][1]
    for part, step in read.values():
        if not math.isclose(step, dt, rel_tol=1e-9):
            raise DataError(
                f"{found[part.file]}: variable 'Fs' = {1 / step:g} Hz, but "
                f"{_f16_file(F16_TRAIN_LEVELS[0])} has {1 / dt:g} Hz; the records of one "
                "benchmark share one sampling rate"
            )
    train = [read[level][0] for level in F16_TRAIN_LEVELS]
    return dt, train, [read[level][0] for level in F16_TEST_LEVELS]


# ------------------------------------------------------------------------------- published results
#: the test parts of the published tables' columns, in their order: (benchmark, test part)
_COLUMNS = (
    ("silverbox", "multisine"),
    ("silverbox", "arrow-full"),
    ("silverbox", "arrow-no-extrapolation"),
    ("wiener-hammerstein", "test"),
    ("emps", "DATA_EMPS_PULSES"),
    ("cascaded-tanks", "validation"),
    ("ced", "low-amplitude"),
    ("ced", "high-amplitude"),
)

# Champneys et al. (2024), the baseline study: each method's figure per column of _COLUMNS, as
# printed in the paper, in each benchmark's scoring units
_CHAMPNEYS_ROWS: dict[str, tuple[str | None, ...]] = {
    "LTI state space": ("6.96", "14.4", "6.58", "43.4", "5.53", "0.588", "0.224", "0.384"),
    "LTI ARX": ("6.95", "14.2", "6.59", "43.4", "12.6", "0.685", "0.291", "0.331"),
    "polynomial NARX": ("0.640", "2.25", "0.571", "27.3", "5.17", "0.413", "0.10", "0.141"),
    "GP NARX": ("0.301", "0.60", "0.259", "23.1", "1690", "0.622", "0.102", "0.090"),
    "MLP NARX": ("2.80", "5.18", "2.40", "310", "133", "2.04", "0.142", "0.101"),
    "MLP FIR": ("18.9", "20.2", "15.3", "24.8", "121", "1.43", "0.122", "0.095"),
    "RNN": ("1.64", "4.88", "1.73", "6.87", "89.2", "0.543", "0.096", "0.235"),
    "GRU": ("1.49", "2.80", "0.947", "3.97", "220", "0.396", "0.286", "0.238"),
    "LSTM": ("1.50", "2.68", "0.960", "4.45", "74.1", "0.490", "0.303", "0.145"),
    "OLSTM": ("1.51", "2.38", "1.08", "4.55", "111", "0.471", "0.151", "0.259"),
}

# The same paper's table of the best published results: (method, its own source) → figure per
# column of _COLUMNS, None where the method has no published figure on that part
_BEST_PUBLISHED_ROWS: dict[tuple[str, str], tuple[str | None, ...]] = {
    ("DT SUBNET", "Beintema et al., 2021"): (
        "0.36", "1.4", "0.32", "0.241", None, "0.37", "0.169", "0.117",
    ),
    ("CT SUBNET", "Beintema et al., 2023"): (
        None, None, None, None, "4.61", "0.306", "0.115", "0.074",
    ),
    ("grey box", "Worden et al., 2018"): (None, None, None, None, None, "0.191", None, None),
    ("PNLSS", "Paduart et al., 2010; Relan et al., 2017"): (
        None, "0.26", None, "0.42", None, "0.45", None, None,
    ),
    ("TSEM", "Forgione and Piga, 2021a"): (None, None, None, None, None, "0.33", None, None),
    ("SCI", "Forgione and Piga, 2021a"): (None, None, None, None, None, "0.4", None, None),
    ("dynoNet", "Forgione and Piga, 2021b"): (
        None, None, None, "0.452", "2.64", None, None, None,
    ),
}  # fmt: skip

# what the paper says about single figures of the best-results table
_NOTES = {
    ("CT SUBNET", "ced"): "the minimum over about 20 runs, trained on a 300/200 split",
    ("dynoNet", "wiener-hammerstein"): (
        "the figure of Champneys et al.'s table; the dynoNet paper itself reports 1.2 mV"
    ),
}


#: what :func:`baselines_markdown` says of a benchmark without published figures
NO_BASELINES = "No published figure entered for this benchmark."


def _published(name: str, units: str) -> tuple[Baseline, ...]:
    """Every published figure on benchmark ``name``'s test parts, the lowest per part marked."""
    rows = [(method, CHAMPNEYS, figures) for method, figures in _CHAMPNEYS_ROWS.items()]
    rows += [
        (method, f"{ref}, as tabulated by Champneys et al. (2024, arXiv:2405.10779)", figures)
        for (method, ref), figures in _BEST_PUBLISHED_ROWS.items()
    ]
    found = [
        Baseline(method, test, figure, units, source, note=_NOTES.get((method, name), ""))
        for method, source, figures in rows
        for (bench, test), figure in zip(_COLUMNS, figures, strict=True)
        if bench == name and figure is not None
    ]
    lowest = {
        test: min(b.rmse for b in found if b.test == test) for test in {b.test for b in found}
    }
    return tuple(replace(b, best=True) if b.rmse == lowest[b.test] else b for b in found)


_REGISTRY = (
    Benchmark(
        name="cascaded-tanks",
        title="Cascaded Tanks",
        folder="Cascaded_Tanks/CascadedTanksFiles",
        files=("dataBenchmark.mat",),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/cascaded-tanks",
        input_names=("u",),
        output_names=("y",),
        units={"u": "V", "y": "V"},
        n_init=50,
        test_parts=("validation",),
        score_units="V",
        score_scale=1.0,
        baselines=(),  # entered below
        reader=_cascaded_tanks,
    ),
    Benchmark(
        name="silverbox",
        title="Silverbox",
        folder="Silverbox/SilverboxFiles",
        files=("SNLS80mV.mat",),
        csv=("SNLS80mV.csv",),
        page="https://www.nonlinearbenchmark.org/benchmarks/silverbox",
        input_names=("V1",),
        output_names=("V2",),
        units={"V1": "V", "V2": "V"},
        n_init=50,
        test_parts=("multisine", "arrow-full", "arrow-no-extrapolation"),
        score_units="mV",
        score_scale=1000.0,
        baselines=(),  # entered below
        reader=_silverbox,
    ),
    Benchmark(
        name="wiener-hammerstein",
        title="Wiener-Hammerstein",
        folder="WienerHammerBenchMark",
        files=("WienerHammerBenchMark.mat",),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/wiener-hammerstein",
        input_names=("u",),
        output_names=("y",),
        units={"u": "V", "y": "V"},
        n_init=50,
        test_parts=("test",),
        score_units="mV",
        score_scale=1000.0,
        baselines=(),  # entered below
        reader=_wiener_hammerstein,
    ),
    Benchmark(
        name="emps",
        title="EMPS",
        folder="EMPS",
        files=("DATA_EMPS.mat", "DATA_EMPS_PULSES.mat"),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/emps",
        input_names=("vir",),
        output_names=("qm",),
        units={"vir": "N", "qm": "m"},
        n_init=EMPS_N_INIT,
        test_parts=("DATA_EMPS_PULSES",),
        score_units="mm",
        score_scale=1000.0,
        baselines=(),  # entered below
        reader=_emps,
    ),
    Benchmark(
        name="ced",
        title="Coupled Electric Drives",
        folder="CED",
        files=("DATAUNIF.MAT",),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/coupled-electric-drives",
        input_names=("u",),
        output_names=("z",),
        units={"u": None, "z": "ticks/s"},
        n_init=10,
        test_parts=("low-amplitude", "high-amplitude"),
        score_units="ticks/s",
        score_scale=1.0,
        baselines=(),  # entered below
        reader=_ced,
    ),
    Benchmark(
        name="bouc-wen",
        title="Bouc-Wen",
        folder="BoucWen/BoucWenFiles",
        files=_bouc_wen_files(),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/bouc-wen",
        input_names=("u",),
        output_names=("y",),
        units={"u": "N", "y": "m"},
        n_init=BOUC_WEN_N_INIT,
        test_parts=BOUC_WEN_PARTS,
        score_units="mm",
        score_scale=1000.0,
        baselines=(),  # none entered: see the docs, "Published results"
        reader=_bouc_wen,
        made={
            BOUC_WEN_TRAIN: (
                "the benchmark ships no training record: simulate one with its "
                "BoucWen_ExampleIntegration.m (MATLAB) and save its u and y as "
                f"{BOUC_WEN_TRAIN}"
            )
        },
    ),
    Benchmark(
        name="f16-gvt",
        title="F-16 Ground Vibration Test",
        folder="F16/F16GVT_Files/BenchmarkData",
        files=tuple(_f16_file(level) for level in (*F16_TRAIN_LEVELS, *F16_TEST_LEVELS)),
        csv=(),
        page="https://www.nonlinearbenchmark.org/benchmarks/f-16-gvt",
        input_names=("Force",),
        output_names=F16_OUTPUTS,
        units={"Force": "N", **dict.fromkeys(F16_OUTPUTS, "m/s²")},
        n_init=F16_N_INIT,
        test_parts=tuple(f"level-{level}" for level in F16_TEST_LEVELS),
        score_units="m/s²",
        score_scale=1.0,
        baselines=(),  # none entered: see the docs, "Published results"
        reader=_f16,
    ),
)

#: the benchmarks by command-line name, each with its published results
BENCHMARKS: dict[str, Benchmark] = {
    b.name: replace(b, baselines=_published(b.name, b.score_units)) for b in _REGISTRY
}


def benchmark_names() -> list[str]:
    return list(BENCHMARKS)


def benchmark(name: str) -> Benchmark:
    """The registry entry ``name``, or a :class:`DataError` listing the names."""
    try:
        return BENCHMARKS[name]
    except KeyError:
        raise DataError(f"unknown benchmark {name!r}; choose one of {benchmark_names()}") from None


def baseline_rows(
    baselines: Sequence[Baseline], tests: Sequence[str]
) -> tuple[list[tuple[str, list[Baseline | None], str]], list[str]]:
    """``baselines`` as one row per method, in their order: (method, its figure on each of
    ``tests`` or ``None``, its citation ``[i]`` and note), and the sources the ``[i]`` number; a
    method with no figure on ``tests`` has no row."""
    sources = list(dict.fromkeys(b.source for b in baselines))
    figures = {(b.method, b.test): b for b in baselines}
    rows = []
    for method in dict.fromkeys(b.method for b in baselines):
        row = [figures.get((method, test)) for test in tests]
        if all(b is None for b in row):  # no figure on these parts
            continue
        # one method, one source: the row's first figure names it (and its note, if any)
        first = next(b for b in row if b is not None)
        cite = f"[{sources.index(first.source) + 1}]" + (f"; {first.note}" if first.note else "")
        rows.append((method, row, cite))
    return rows, sources


def baselines_markdown(name: str) -> str:
    """Benchmark ``name``'s published results as Markdown: a table with one row per method and
    one column per test part (the figures as published, the lowest per part in bold, – where a
    method has none), then the numbered list of the sources the last column refers to; of a
    benchmark without published figures, :data:`NO_BASELINES`."""
    bench = benchmark(name)
    if not bench.baselines:
        return NO_BASELINES
    rows, sources = baseline_rows(bench.baselines, bench.test_parts)
    head = ["method", *(f"{test} [{bench.score_units}]" for test in bench.test_parts), "source"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for method, row, cite in rows:
        cells = ["–" if b is None else f"**{b.figure}**" if b.best else b.figure for b in row]
        lines.append("| " + " | ".join([method, *cells, cite]) + " |")
    lines += ["", *(f"{i}. {source}" for i, source in enumerate(sources, 1))]
    return "\n".join(lines)


def _directory(directory: str | Path | None) -> Path:
    return (DEFAULT_DIR if directory is None else Path(directory)).expanduser()


def find_files(bench: Benchmark, directory: str | Path | None = None) -> dict[str, Path | None]:
    """For each of ``bench.files``, the first place it (or its CSV export) was found, or None."""
    root = _directory(directory)
    found: dict[str, Path | None] = {}
    for i, file in enumerate(bench.files):
        names = [file, *(bench.csv[i : i + 1])]
        hits = [p for n in names for p in bench.candidates(n, root) if p.is_file()]
        found[file] = hits[0] if hits else None
    return found


def load_benchmark(name: str, directory: str | Path | None = None) -> Dataset:
    """Read benchmark ``name`` from ``directory`` (default ``~/.nonlinear_benchmarks``) and cut
    its official split (see the module docstring); a missing file raises a one-line
    :class:`DataError` naming the file, where it was looked for and where to download it."""
    bench = benchmark(name)
    root = _directory(directory)
    found = find_files(bench, root)
    for i, (file, path) in enumerate(found.items()):
        if path is None:
            looked = [
                str(p) for n in (file, *bench.csv[i : i + 1]) for p in bench.candidates(n, root)
            ]
            raise DataError(
                f"{bench.name}: {file} not found (looked for {', '.join(looked)}); "
                f"{bench.where_from(file)}, as {root / bench.folder / file}"
            )
    paths = {file: path for file, path in found.items() if path is not None}
    dt, train, test = bench.reader(paths)
    problem = dt_problem(dt)
    if problem:
        raise DataError(f"{', '.join(map(str, paths.values()))}: {problem}")
    for part in test:
        if len(part.u) <= bench.n_init:
            raise DataError(
                f"{part.file}: test part {part.name!r} has {len(part.u)} samples, not more than "
                f"n_init = {bench.n_init}"
            )
    return _dataset(bench, dt, train, test, paths)


def _dataset(
    bench: Benchmark,
    dt: float,
    train: list[_Part],
    test: list[_Part],
    paths: Mapping[str, Path],
) -> Dataset:
    def traj(part: _Part, role: str) -> Trajectory:
        info: dict[str, Any] = {
            "part": part.name,
            "role": role,
            "file": part.file,
            "samples": [part.start, part.stop],
        }
        if role == "test":
            info["n_init"] = bench.n_init
        return Trajectory(u=part.u, y=part.y, info=info)

    metadata: dict[str, Any] = {
        "source": "benchmark",
        "benchmark": bench.name,
        "title": bench.title,
        "definition": DEFINITION,
        "files": [str(p) for p in paths.values()],
        "page": bench.page,
        "units": dict(bench.units),
        "n_init": bench.n_init,
        "test_parts": [p.name for p in test],
        "train_parts": [p.name for p in train],
        "score_units": bench.score_units,
        "score_scale": bench.score_scale,
    }
    return Dataset(
        splits={
            "train": tuple(traj(p, "train") for p in train),
            "test": tuple(traj(p, "test") for p in test),
        },
        dt=dt,
        input_names=bench.input_names,
        output_names=bench.output_names,
        metadata=metadata,
    )
