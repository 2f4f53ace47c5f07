"""Scores of a trained model on a standard benchmark's official test parts, by the official rule.

The rule (``nonlinear_benchmarks``): a model may use the whole input of a test part and only its
first ``n_init`` measured outputs; the score is the RMSE of its simulation on the remaining
samples, in the benchmark's scoring units.

How the indices are cut, for a canonical model of window ℓ on a test part of ``T`` samples
(requires ℓ ≤ ``n_init``; :func:`canonid.learning.evaluate.simulate_records`):

* burn-in: the measured samples ``n_init−ℓ … n_init−1`` (inputs and outputs) build the first
  state ``z_{n_init}``; these are the last ℓ of the ``n_init`` samples the rule allows;
* simulation: samples ``n_init … T−1`` are predicted in open loop from the inputs alone;
* score: ``RMSE = sqrt(mean over t = n_init … T−1 and the outputs of (ŷ[t] − y[t])²)``, times
  the scoring factor (1000 for V → mV, m → mm). Samples ``0 … n_init−1`` are never scored, so
  the score does not depend on ℓ's burn-in position, only on the model.

:func:`run_benchmark` (``canonid benchmark``) writes a ``canonid train`` run folder (``evaluate``,
``analyze --run`` and ``reduce`` take it) plus ``benchmark-data.npz`` / ``.json``, the benchmark
as a canonid dataset and the data the run trained on (split ``train``: the first 80 %, or
``1 − val_fraction``, of every official training record; ``val``: the rest of each record;
``test``: the official test parts in order); ``benchmark.json``, the scores
(:class:`BenchmarkReport`) and the published baselines shown; and ``benchmark-PART.png`` (or
``.pdf``, ``.svg``), the simulation of each test part. Training is ``canonid train``'s, every
default included; an interrupted benchmark is finished by ``resume`` (``canonid train
--resume``'s rule: only what a resumed run may change is given), or, for one release, by the same
call again, with a deprecation warning.
"""

from __future__ import annotations

import dataclasses
import math
import os
import shlex
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from canonid.coverage import (
    OutsideRange,
    outside_training_range,
    recorded_unvalidated,
    unvalidated_line,
)
from canonid.datagen.benchmarks import BENCHMARKS, Baseline, Benchmark
from canonid.datagen.loaders import data_checksum
from canonid.kernel.catalog import DEFAULT_MODEL, DEFAULT_VAL_FRACTION, model_label
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import CheckpointError, OptionError
from canonid.kernel.io import (
    atomic_write_figure,
    atomic_write_json,
    figure_name,
    jsonable,
    read_json,
)
from canonid.profiles import DEFAULT_PROFILE
from canonid.training import TrainRequest

if TYPE_CHECKING:
    from canonid.learning import Model

__all__ = [
    "BENCHMARKS",
    "BenchmarkReport",
    "BenchmarkRequest",
    "PartScore",
    "benchmark_list",
    "benchmark_summary",
    "check_window",
    "parse_window",
    "plot_part",
    "report_table",
    "run_benchmark",
    "score_parts",
    "train_args",
]

REPORT_FILE = "benchmark.json"
#: the benchmark as a canonid dataset, the data the run trains on
DATA_FILE = "benchmark-data.npz"
#: the one-line warning of an interrupted run continued without --resume (a former behaviour)
CONTINUED = (
    "canonid benchmark: warning: continuing the run in {run_dir} without --resume is "
    "deprecated, use --resume --out {run_dir}"
)
#: samples shown in the zoomed panel of a test part's figure
ZOOM_SAMPLES = 500


@dataclass(frozen=True)
class PartScore:
    """The official score of one test part.

    Attributes:
        test: the part's name (``multisine``).
        rmse: simulation RMSE over samples ``n_init … T−1``, in ``units``.
        units: the benchmark's scoring units (``mV``).
        n_init: measured samples given to the model (never scored).
        n_scored: samples scored (``T − n_init``).
        outside: the part's signals outside the model's training span
            (:func:`canonid.coverage.outside_training_range`; ``None``: the model recorded none).
    """

    test: str
    rmse: float
    units: str
    n_init: int
    n_scored: int
    outside: tuple[OutsideRange, ...] | None = None


@dataclass(frozen=True)
class BenchmarkReport:
    """What ``canonid benchmark`` writes to ``benchmark.json``; ``unvalidated``: where the
    training part leaves the validation part's spans (:func:`canonid.coverage.unvalidated`, as
    the model recorded it)."""

    benchmark: str
    title: str
    definition: str
    files: list[str]
    model: str
    window: int
    profile: str
    validation: str
    scores: list[PartScore]
    baselines: list[Baseline]
    rule: str
    unvalidated: tuple[OutsideRange, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The ``benchmark.json`` body; a score that is not finite (a simulation that blew up)
        is written ``null``, as JSON has no inf or NaN."""
        return jsonable({"schema": 1, **asdict(self)})


RULE = (
    "simulation from the whole test input and the measured outputs n_init−ℓ … n_init−1; RMSE "
    "over samples n_init … T−1 of each official test part, in the scoring units"
)


def check_window(window: int, bench: Benchmark) -> None:
    """Refuse a window the official rule cannot feed: ℓ measured outputs must fit in n_init."""
    if window > bench.n_init:
        raise OptionError(
            f"window ℓ = {window} exceeds {bench.name}'s n_init = {bench.n_init}: the official "
            f"rule gives a model only the first {bench.n_init} measured outputs of a test part; "
            f"choose --window ≤ {bench.n_init}"
        )


def score_parts(
    model: Model, dataset: Dataset, bench: Benchmark
) -> tuple[list[PartScore], list[np.ndarray]]:
    """Official scores of ``model`` on every test part of ``dataset`` (see the module
    docstring), with the simulated outputs of samples ``n_init … T−1`` of each part."""
    from canonid.learning.evaluate import simulate_records

    check_window(model.window, bench)
    parts = dataset.split("test")
    sims = simulate_records(model, parts, bench.n_init)
    scores = []
    for part, sim in zip(parts, sims, strict=True):
        err = sim - part.y[bench.n_init :]
        rmse = float(np.sqrt(np.mean(err**2))) * bench.score_scale
        scores.append(
            PartScore(
                test=str(part.info.get("part", "")),
                rmse=rmse,
                units=bench.score_units,
                n_init=bench.n_init,
                n_scored=int(err.shape[0]),
                outside=outside_training_range(
                    model.info,
                    [part],
                    input_names=dataset.input_names,
                    output_names=dataset.output_names,
                ),
            )
        )
    return scores, sims


def plot_part(
    path: str | os.PathLike[str],
    part: Trajectory,
    sim: np.ndarray,
    *,
    bench: Benchmark,
    dt: float,
    score: PartScore,
    model_label: str,
) -> Path:
    """Measured and simulated output of one test part (whole, then its first samples) and the
    error, in the scoring units, with the ``n_init`` samples the model was given shaded; of
    several outputs (the F-16's accelerometers) the first is drawn, the title's RMSE is all's."""
    from matplotlib.figure import Figure

    scale, units, n_init = bench.score_scale, bench.score_units, bench.n_init
    t = np.arange(part.T) * dt
    zoom = min(part.T, n_init + ZOOM_SAMPLES)
    fig = Figure(figsize=(9, 7))
    top, mid, bottom = fig.subplots(3, 1)
    for ax, stop in ((top, part.T), (mid, zoom)):
        ax.plot(t[:stop], part.y[:stop, 0] * scale, lw=0.6, color="0.3", label="measured")
        ax.plot(
            t[n_init:stop], sim[: stop - n_init, 0] * scale, lw=0.6, color="C1", label=model_label
        )
        ax.axvspan(0, t[n_init], color="0.85", lw=0)
        ax.set_ylabel(f"{bench.output_names[0]} [{units}]")
    mid.set_title(f"the first {zoom} samples", fontsize=8)
    bottom.plot(t[n_init:], (sim[:, 0] - part.y[n_init:, 0]) * scale, lw=0.5, color="C3")
    bottom.axvspan(0, t[n_init], color="0.85", lw=0)
    bottom.set_ylabel(f"error [{units}]")
    bottom.set_xlabel("time [s]")
    outputs = f" of the {len(bench.output_names)} outputs" if len(bench.output_names) > 1 else ""
    top.set_title(
        f"{bench.title}, test '{score.test}': RMSE{outputs} {score.rmse:.4g} {units} over "
        f"{score.n_scored} samples after n_init = {n_init} (shaded)",
        fontsize=9,
    )
    top.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return atomic_write_figure(path, fig, dpi=110)


#: where the docs say how the published figures were made and how canonid's differ
PROTOCOL_DOCS = 'docs "Standard benchmarks", "Published results"'


def report_table(report: BenchmarkReport) -> str:
    """canonid's scores and the published baselines, one row per method and one column per
    test part, in the scoring units: each published figure as its source prints it, the lowest
    per part marked ``*``, each method's source numbered below."""
    from canonid.datagen.benchmarks import baseline_rows

    tests = [s.test for s in report.scores]
    units = report.scores[0].units if report.scores else ""
    n_init = report.scores[0].n_init if report.scores else 0
    rows, sources = baseline_rows(report.baselines, tests)
    ours = [_shown(s.rmse) for s in report.scores]
    cells = [
        ("method", *tests, "source"),
        (f"canonid ({report.model}, ℓ = {report.window})", *ours, "this run"),
        *(
            (method, *("-" if b is None else b.figure + "*" * b.best for b in row), cite)
            for method, row, cite in rows
        ),
    ]
    widths = [max(len(r[i]) for r in cells) for i in range(len(cells[0]) - 1)]
    lines = ["  ".join([*(c.ljust(w) for c, w in zip(r, widths)), r[-1]]) for r in cells]
    head = (
        f"{report.title} ({report.definition}): {report.model} ℓ = {report.window}, profile "
        f"{report.profile}; simulation RMSE [{units}] after the first n_init = {n_init} "
        "measured samples of each test part"
    )
    outside = [
        f"test part {s.test!r} leaves the training range: "
        + "; ".join(o.describe() for o in s.outside if o.noted)
        for s in report.scores
        if s.outside and any(o.noted for o in s.outside)
    ]
    if not sources:
        return "\n".join(
            [head, *lines, *outside, "published baselines: none entered for this benchmark"]
        )
    tail = [
        *outside,
        "* the lowest published figure on the test part",
        *(f"[{i}] {source}" for i, source in enumerate(sources, 1)),
        f"how the published figures were made and how canonid's differ: {PROTOCOL_DOCS}",
    ]
    return "\n".join([head, *lines, *tail])


def _shown(rmse: float) -> str:
    """A score as the table prints it: three decimals, or three significant digits below 0.1
    (an F-16 score in m/s² keeps its digits)."""
    if not math.isfinite(rmse):
        return "not finite"
    return f"{rmse:.3f}" if rmse >= 0.1 else f"{rmse:.3g}"


def benchmark_summary(report: BenchmarkReport, run_dir: Path) -> str:
    """What ``canonid benchmark`` prints: :func:`report_table`, what validation does not reach
    (:func:`canonid.coverage.unvalidated_line`) and where the scores are."""
    unseen = unvalidated_line(report.unvalidated)
    return "\n".join(
        [
            report_table(report),
            *([unseen] if unseen else []),
            f"scores written to {run_dir / REPORT_FILE}",
        ]
    )


#: canonid train options that the benchmark sets itself (and help, which would exit)
RESERVED_TRAIN_OPTIONS = (
    "--model",
    "--window",
    "--profile",
    "--out",
    "--seed",
    "--threads",
    "--figure-format",
    "--resume",
    "--val",
    "-h",
    "--help",
)


def train_args(text: str, *, progress: bool = True) -> list[str]:
    """``--train-args``: further ``canonid train`` options, split like a shell; the options the
    benchmark sets (:data:`RESERVED_TRAIN_OPTIONS`) are refused, also when abbreviated
    (``--mod``) or joined to their value (``--model=gru``, ``-hx``). Without ``progress``
    (the benchmark's ``--no-progress``) training shows no progress bar either."""
    try:
        extra = shlex.split(text)
    except ValueError as exc:
        raise OptionError(f"--train-args: cannot split {text!r} ({exc})") from None
    taken = [a for a in extra if _reserved(a)]
    if taken:
        raise OptionError(
            f"--train-args: {', '.join(taken)} set by canonid benchmark itself; give them as "
            "its own options"
        )
    from canonid.data_options import DATA_FLAGS

    loader = [a for a in extra if a.split("=")[0] in DATA_FLAGS.values()]
    if loader:  # CSV options: the benchmark's data carry their own dt and signals
        raise OptionError(
            f"--train-args: {', '.join(loader)} read CSV data; a benchmark's data carry their "
            "own sampling time and signals, so canonid benchmark takes none of these"
        )
    return extra if progress else [*extra, "--no-progress"]


def _reserved(arg: str) -> bool:
    """Whether ``arg`` names (or abbreviates) an option the benchmark sets itself."""
    name = arg.split("=")[0]
    if name.startswith("--val-") or (name.startswith("-h") and not name.startswith("--")):
        return True
    # an abbreviation the train parser would take for one of them, were abbreviations allowed
    return (
        len(name) > 2
        and name.startswith("--")
        and any(o.startswith(name) for o in RESERVED_TRAIN_OPTIONS)
    )


def parse_window(text: str | None) -> int | Literal["auto"] | tuple[int, ...] | None:
    """``--window``: as ``canonid train`` reads it (:func:`canonid.training.parse_window`);
    ``None``: the benchmark's default, the search."""
    from canonid.training import parse_window as train_window

    return train_window(text)


#: the options a resumed run takes from its run.json instead: field → command-line flag
_FIXED_ON_RESUME = {
    "files": "--dir",
    "model": "--model",
    "window": "--window",
    "profile": "--profile",
    "out": "--out",
    "seed": "--seed",
    "val_fraction": "--val-fraction",
}


@dataclass(frozen=True, kw_only=True)
class BenchmarkRequest:
    """A benchmark run: train on benchmark ``name``'s official training part (from ``files``,
    default the package's cache) with ``model`` (default ``mlp``), ``window`` (an integer, a
    tuple or ``"auto"``; default ``"auto"``, the search over the candidate windows ≤ n_init) and
    ``profile`` (default
    :data:`~canonid.profiles.DEFAULT_PROFILE`) as ``train`` asks (its data, model, window,
    profile, folder, seed and threads are the benchmark's), with the last ``val_fraction``
    (default 0.2) of every training record validating; score every official test part.

    ``resume``: continue the benchmark run in that folder as ``canonid train --resume`` does
    (``train`` may then hold only what a resumed run may change, and the options the run
    recorded are not given), then score it; ``name``, if given, must be the run's benchmark.
    ``figure_format``: the file format of every figure of the run (training's and one per test
    part, ``benchmark-PART.png``). Checked when built."""

    name: str | None = None
    files: Path | None = None
    model: str | None = None
    window: int | Literal["auto"] | tuple[int, ...] | None = None
    profile: str | None = None
    out: Path | None = None
    seed: int | None = None
    threads: int | None = None
    val_fraction: float | None = None
    train: TrainRequest = field(default_factory=TrainRequest)
    resume: Path | None = None
    figure_format: str = "png"

    def __post_init__(self) -> None:
        if self.resume is not None:
            given = [f for k, f in _FIXED_ON_RESUME.items() if getattr(self, k) is not None]
            if given:
                raise OptionError(
                    f"{', '.join(given)} cannot be given with --resume: the run continues as "
                    "its run.json records it"
                )
        elif self.name is None:
            raise OptionError(
                f"give a benchmark NAME ({', '.join(BENCHMARKS)}), --resume --out RUN or --list"
            )
        if self.train.data is not None:  # DATA is the benchmark's
            raise OptionError(f"--train-args: {self.train.data!r} is not an option")
        figure_name("benchmark", self.figure_format)  # an unknown format, before any work


def run_benchmark(request: BenchmarkRequest) -> tuple[BenchmarkReport, Path]:
    """Train and score ``request`` (see :class:`BenchmarkRequest`); write the run folder with
    ``benchmark-data.npz``, ``benchmark.json`` and a figure per test part; return the report and
    the folder.

    Everything is checked before anything is written, and the folder's lock is held
    throughout. A folder that holds this benchmark's run from an earlier, interrupted call of
    the same command is continued (its training resumed from its checkpoint, then scored); one
    started with other options or other data is refused, naming the differences.
    """
    from canonid.datagen.benchmarks import benchmark, load_benchmark
    from canonid.datagen.loaders import split_train_val
    from canonid.jobs import check_run_folder, run_folder_lock
    from canonid.learning.search import SEARCH_FILE
    from canonid.learning.training import CHECKPOINT_FILE
    from canonid.training import check_request, windows_up_to

    if request.resume is not None:
        return _resume(request)
    assert request.name is not None  # checked when the request was built
    bench = benchmark(request.name)
    model = request.model or DEFAULT_MODEL
    window = request.window if request.window is not None else "auto"
    listed = (window,) if isinstance(window, int) else () if window == "auto" else window
    for ell in listed:
        check_window(ell, bench)
    # the search tries only the windows the official rule can feed
    candidates = (
        windows_up_to(bench.n_init, f"{bench.name}'s n_init =")
        if window == "auto"
        else request.train.window_candidates
    )
    run_dir = request.out or Path("runs") / f"{bench.name}-{model}"
    wanted = dataclasses.replace(
        request.train,
        data=str(run_dir / DATA_FILE),
        model=model,
        window=window,
        window_candidates=candidates,
        profile=request.profile or DEFAULT_PROFILE,
        out=run_dir,
        seed=request.seed,
        threads=request.threads,
        figure_format=request.figure_format,
    )
    check_run_folder(run_dir)
    started = any((run_dir / name).exists() for name in (CHECKPOINT_FILE, SEARCH_FILE))
    if not started:  # a run to continue is checked under the lock
        check_request(wanted)  # every training option, before the files are read
    dataset = load_benchmark(bench.name, request.files)
    split = split_train_val(
        dataset,
        val_fraction=(
            DEFAULT_VAL_FRACTION if request.val_fraction is None else request.val_fraction
        ),
        record_tails=True,
    )
    checksum = _checksum(split)
    with run_folder_lock(run_dir, new=True):
        todo = _continue_or_start(wanted, run_dir, checksum)
        if todo.resume is not None:  # --resume says so; the same command alone, for one release
            print(CONTINUED.format(run_dir=run_dir), file=sys.stderr)
            return _train_and_score(todo, run_dir, bench)
        check_request(todo)  # every training option, before the data are written
        data = run_dir / DATA_FILE
        # the JSON is written last: without it the data file is not complete
        wrote = not data.with_suffix(".json").is_file() or data_checksum(data) != checksum
        if wrote:
            split.save(data)
        try:
            return _train_and_score(todo, run_dir, bench)
        except BaseException:
            if wrote and not any(  # no training to continue: no data left either
                (run_dir / name).exists() for name in (CHECKPOINT_FILE, SEARCH_FILE)
            ):
                data.unlink(missing_ok=True)
                data.with_suffix(".json").unlink(missing_ok=True)
            raise


def _continue_or_start(wanted: TrainRequest, run_dir: Path, checksum: str) -> TrainRequest:
    """What to train into ``run_dir``, whose lock the caller holds: ``wanted`` when no training
    has started there (or none got to its first checkpoint), else the resumption of the run
    there when it is the same run (the same recipe, the same data: ``checksum``)."""
    from canonid.learning.search import SEARCH_FILE
    from canonid.learning.training import CHECKPOINT_FILE
    from canonid.runfolder import RUN_FILE, RunRecipe
    from canonid.training import same_run

    recorded = RunRecipe.read(run_dir) if (run_dir / RUN_FILE).is_file() else None
    if recorded is not None and recorded.data_sha256 not in (None, checksum):
        raise CheckpointError(
            f"{run_dir} holds a benchmark run trained on other data than the benchmark files "
            f"give now ({DATA_FILE}); choose another --out"
        )
    if not any((run_dir / name).is_file() for name in (CHECKPOINT_FILE, SEARCH_FILE)):
        return wanted
    same_run(wanted, run_dir)
    return TrainRequest(
        resume=run_dir,
        threads=wanted.threads,
        progress=wanted.progress,
        command=wanted.command,
        figure_format=wanted.figure_format,
    )


def _checksum(split: Dataset) -> str:
    """The checksum of ``split`` saved as a canonid dataset (what ``run.json`` records)."""
    import tempfile

    with tempfile.TemporaryDirectory() as scratch:
        return data_checksum(split.save(Path(scratch) / DATA_FILE, durable=False))


def _resume(request: BenchmarkRequest) -> tuple[BenchmarkReport, Path]:
    """``--resume --out RUN``: continue the benchmark run in RUN (see :class:`BenchmarkRequest`)."""
    from canonid.datagen.benchmarks import benchmark
    from canonid.jobs import run_folder_lock
    from canonid.runfolder import RunRecipe
    from canonid.training import check_request

    run_dir = request.resume
    assert run_dir is not None
    todo = dataclasses.replace(
        request.train,
        resume=run_dir,
        threads=request.threads,
        out=None,
        figure_format=request.figure_format,
    )
    check_request(todo)
    recipe = RunRecipe.read(run_dir)
    name = _benchmark_of(recipe.data, run_dir)
    if request.name is not None and benchmark(request.name).name != name:
        raise OptionError(
            f"--resume --out {run_dir}: a run of benchmark {name}, not {request.name}"
        )
    with run_folder_lock(run_dir, flag="--resume"):
        return _train_and_score(todo, run_dir, benchmark(name))


def _benchmark_of(data: str, run_dir: Path) -> str:
    """The benchmark whose data ``data`` are (``run_dir``'s recorded ``benchmark-data``)."""
    if Path(data).name != DATA_FILE:
        raise CheckpointError(f"{run_dir} is not a canonid benchmark run (it trained on {data})")
    header = read_json(Path(data).with_suffix(".json"), what="benchmark data")
    name = header.get("metadata", {}).get("benchmark") if isinstance(header, dict) else None
    if name not in BENCHMARKS:
        raise CheckpointError(f"{data}: not the data of a canonid benchmark (no known 'benchmark')")
    return str(name)


def _train_and_score(
    todo: TrainRequest, run_dir: Path, bench: Benchmark
) -> tuple[BenchmarkReport, Path]:
    """Train (or resume) ``todo`` into ``run_dir``, then score the model on the official test
    parts of the run's data (a line in the run's ledger of test reads first,
    :func:`canonid.runfolder.record_test_read`) and write ``benchmark.json`` and the figures."""
    from canonid.learning import Model
    from canonid.runfolder import (
        TEST_SPLIT,
        RunRecipe,
        check_test_ledger,
        record_test_read,
        run_data,
    )
    from canonid.training import train

    check_test_ledger(run_dir)  # a ledger that would be refused, before the training
    train(todo)
    model = Model.load(run_dir)
    recipe = RunRecipe.read(run_dir)
    split, _ = run_data(recipe)  # the run's data, checked by checksum
    checksum = recipe.data_sha256 or data_checksum(recipe.data)
    record_test_read(
        run_dir, command="benchmark", split=TEST_SPLIT, data=recipe.data, sha256=checksum
    )
    scores, sims = score_parts(model, split, bench)
    report = BenchmarkReport(
        benchmark=bench.name,
        title=bench.title,
        definition=str(split.metadata["definition"]),
        files=list(split.metadata["files"]),
        model=recipe.model,
        window=model.window,
        profile=recipe.profile,
        validation=str(split.metadata["validation_split"]),
        scores=scores,
        baselines=list(bench.baselines),
        rule=RULE,
        unvalidated=recorded_unvalidated(model.info),
    )
    for part, sim, score in zip(split.split("test"), sims, scores, strict=True):
        plot_part(
            run_dir / figure_name(f"benchmark-{score.test}", todo.figure_format),
            part,
            sim,
            bench=bench,
            dt=split.dt,
            score=score,
            model_label=f"{model_label(model.name)}, ℓ = {model.window}",
        )
    atomic_write_json(run_dir / REPORT_FILE, report.to_json())
    return report, run_dir


def benchmark_list(files: Path | None) -> str:
    """The benchmarks, their official rule and where their files are (or where to get them)."""
    from canonid.datagen.benchmarks import find_files

    lines = []
    for bench in BENCHMARKS.values():
        lines.append(
            f"{bench.name}: {bench.title}; n_init = {bench.n_init}; scored in "
            f"{bench.score_units}; test parts: {', '.join(bench.test_parts)}"
        )
        for file, path in find_files(bench, files).items():
            alt = f" (or {', '.join(bench.csv)})" if bench.csv else ""
            where = f"found: {path}" if path else f"missing; {bench.where_from(file)}"
            lines.append(f"  {bench.folder}/{file}{alt}: {where}")
    return "\n".join(lines)
