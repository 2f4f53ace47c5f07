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
  training = the whole estimation record, test = the whole validation record. ``n_init`` = 5.
* **Wiener–Hammerstein** (``WienerHammerBenchMark.mat``: ``uBenchMark``, ``yBenchMark``, ``fs``):
  training = ``5200:105200``, test = ``105200:184000``. ``n_init`` = 50.
* **EMPS** (``DATA_EMPS.mat`` and ``DATA_EMPS_PULSES.mat``, each ``vir`` = motor force (input),
  ``qm`` = measured position (output), ``t``; dt = ``t[1] − t[0]``): training = the whole
  ``DATA_EMPS`` record, test = the whole ``DATA_EMPS_PULSES`` record. ``n_init`` = 20.
* **CED** (``DATAUNIF.MAT``: ``u11``, ``z11`` low and ``u12``, ``z12`` high input amplitude;
  dt = 0.02 s): training = ``0:400`` of each experiment, test = ``400:`` of each. ``n_init`` = 4.

Scoring rule (the package's submission examples): a model may use the whole test input and the
first ``n_init`` measured outputs of each test part; the score is the RMSE of its simulation on
samples ``n_init …`` of the part, in the benchmark's scoring units (:attr:`Benchmark.score_units`,
the outputs' units times :attr:`Benchmark.score_scale`).

Files are looked for in ``DIR/<the package's cache folder>/FILE`` (e.g.
``DIR/Silverbox/SilverboxFiles/SNLS80mV.mat``) and in ``DIR/FILE``; Silverbox is also read from
its CSV export ``SNLS80mV.csv`` (columns ``V1``, ``V2``). ``DIR`` defaults to the package's cache,
``~/.nonlinear_benchmarks``. MATLAB files are read with ``scipy.io.loadmat`` (no pickle).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from canonid.datagen.loaders import load_csv
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import DataError

__all__ = [
    "BENCHMARKS",
    "DEFAULT_DIR",
    "Baseline",
    "Benchmark",
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
    """A published simulation RMSE on one official test part, in the scoring units."""

    method: str
    test: str
    rmse: float
    source: str


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

    def candidates(self, file: str, directory: Path) -> list[Path]:
        """Where ``file`` is looked for under ``directory``, in order."""
        return [directory / self.folder / file, directory / file]


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
    out = {}
    for n in names:
        try:
            out[n] = np.asarray(content[n], dtype=np.float64)
        except (TypeError, ValueError):
            raise DataError(f"{path}: variable {n!r} is not numeric") from None
    return out


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
    dt = 1.0 / _scalar(arrays["fs"], path, "fs")
    train = [_cut("train", u, y, path, 5_200, 105_200)]
    return dt, train, [_cut("test", u, y, path, 105_200, 184_000)]


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
        dt = float(t[1] - t[0])
        if not dt > 0:
            raise DataError(f"{path}: variable 't' must increase, got t[1] − t[0] = {dt}")
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


def _silverbox_baselines() -> tuple[Baseline, ...]:
    rows = {
        "multisine": {"GRU": 1.490, "LSTM": 1.504, "OLSTM": 1.515, "RNN": 1.640},
        "arrow-full": {"GRU": 2.802, "LSTM": 2.678},
        "arrow-no-extrapolation": {"GRU": 0.947, "LSTM": 0.960},
    }
    return tuple(
        Baseline(method, test, value, CHAMPNEYS)
        for test, methods in rows.items()
        for method, value in methods.items()
    )


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
        n_init=5,
        test_parts=("validation",),
        score_units="V",
        score_scale=1.0,
        baselines=(),
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
        baselines=_silverbox_baselines(),
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
        baselines=(),
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
        n_init=20,
        test_parts=("DATA_EMPS_PULSES",),
        score_units="mm",
        score_scale=1000.0,
        baselines=(),
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
        n_init=4,
        test_parts=("low-amplitude", "high-amplitude"),
        score_units="ticks/s",
        score_scale=1.0,
        baselines=(),
        reader=_ced,
    ),
)

#: the benchmarks by command-line name
BENCHMARKS: dict[str, Benchmark] = {b.name: b for b in _REGISTRY}


def benchmark_names() -> list[str]:
    return list(BENCHMARKS)


def benchmark(name: str) -> Benchmark:
    """The registry entry ``name``, or a :class:`DataError` listing the names."""
    try:
        return BENCHMARKS[name]
    except KeyError:
        raise DataError(f"unknown benchmark {name!r}; choose one of {benchmark_names()}") from None


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
                f"{bench.name}: {file} not found (looked for {', '.join(looked)}); download the "
                f"{bench.title} files from {bench.page} and unpack them into {root / bench.folder}"
            )
    paths = {file: path for file, path in found.items() if path is not None}
    dt, train, test = bench.reader(paths)
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
