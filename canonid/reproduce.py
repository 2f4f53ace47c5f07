"""The paper's reproduction as one pipeline: datasets → Table 1 → analysis → compression → report.

:func:`reproduce` runs, for the systems, windows, models and seeds of a profile's
``reproduce`` stage (:mod:`canonid.profiles`, overridable per call):

1. **Datasets** — one per system, generated with :func:`canonid.datagen.generate.generate_dataset`
   into ``OUT/data/SYSTEM`` or reused when the dataset there was made from the same
   :class:`~canonid.datagen.generate.GenerationConfig` (its checksum is validated on loading).
2. **Jobs** — one :class:`TrainJob` per (system, model, window, seed) for Table 1 (the paper's
   network options), one per (system, model, window, seed) of the stage's ``defaults`` entry
   (canonid's default network options and the profile's ``train`` stage: the column of canonid's
   defaults beside Table 1) and one :class:`AnalysisJob` per analysed system, all independent,
   run through :func:`canonid.runner.run_jobs` serially, on ``workers`` local Dask processes or
   on a Dask cluster (``scheduler``): the same job list and the same results whichever way. Each
   job writes its folder and, last and atomically, ``result.json`` holding its recipe (what it
   was asked to do) and its result. A job whose ``result.json`` holds the same recipe is
   finished and is never run again; a training job interrupted mid-way continues from its
   checkpoint. A job that fails is retried once; one that still fails is named in the report and
   the error, never dropped.
3. **Learned-model checks** — the one-step residual and a state probe of Table 1's trained
   canonical models (Ours MLP/GRU, seed 0) against the analysis's certified constants
   (:mod:`canonid.analysis.learned`), for the windows both stages cover.
4. **Compression study** — :func:`canonid.reduction.compression_sweep` on the profile's Table-1
   canonical runs of seed 0 (heat-map and reduced-model figure); its jobs go through the same
   runner and are resumable too.
5. **Figures and report** — Table 1 against the paper's printed values (:mod:`canonid.paper`)
   as a figure and tables, one rollout figure per system, and ``report.md`` + ``report.html``
   (:mod:`canonid.report`) linking every artefact; ``reproduction.json`` holds every number.

Table 1's metric is :func:`canonid.learning.evaluate.evaluate`'s ``rollout_mse``: from every
``stride``-th start of every test trajectory, ℓ measured samples burn in and the model predicts
the next ``H`` (paper: 100) outputs in open loop; the mean squared error over rollouts, steps and
outputs, in physical units. The tables give it against the measured outputs ``y`` (noisy, as the
paper's data) and, separately, against the noise-free ``y_clean``.

Layout of ``OUT``::

    data/SYSTEM/dataset.npz|.json        the datasets
    runs/SYSTEM/MODEL-lL-sS/             one Table-1 job: canonid-train run folder + result.json
    runs/SYSTEM/MODEL-defaults-lL-sS/    one job of canonid's defaults column, the same files
    analysis/SYSTEM/                     analysis.json, bound_vs_window.png, result.json
    compression/SYSTEM/                  the compression study (sweep.json, figures)
    figures/                             table1_SYSTEM.png, rollouts_SYSTEM.png (or .pdf, .svg)
    reproduction.json, report.md, report.html
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import os
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

from canonid import learned
from canonid.analysis.report import AnalysisReport
from canonid.datagen.generate import FLIGHTS_PER_TASK, GenerationConfig, generate_dataset
from canonid.datagen.scenarios import scenario_names
from canonid.jobs import check_run_folder
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import CheckpointError, DataError, OptionError
from canonid.kernel.io import atomic_write_json, figure_name, jsonable, read_json
from canonid.learning import Model, model_names
from canonid.learning.presets import net_options
from canonid.paper import table1_value
from canonid.profiles import load_profile, stage_train_options
from canonid.profiles import profile as profile_stages
from canonid.reduction import SweepPlan, compression_sweep
from canonid.reproduce_jobs import (
    ANALYSIS_KEYS,
    DEFAULT_OPTIONS,
    PAPER_OPTIONS,
    RESULT_FILE,
    AnalysisJob,
    Job,
    JobOutcome,
    TrainJob,
    job_options,
    run_job,
)
from canonid.reproduce_report import write_report
from canonid.runner import JobsFailedError, run_jobs

__all__ = [
    "RESULT_FILE",
    "AnalysisJob",
    "DatasetInfo",
    "JobOutcome",
    "ReproduceRequest",
    "ReproduceSettings",
    "Reproduction",
    "TrainJob",
    "plan_jobs",
    "prepare_datasets",
    "reproduce",
    "run_job",
    "settings_from_profile",
    "table1_rows",
]

log = logging.getLogger(__name__)

SUMMARY_FILE = "reproduction.json"
#: the models whose regressor is a function of the canonical state (checked, reduced)
CANONICAL_MODELS = ("mlp", "gru")


# ------------------------------------------------------------------------------ settings
@dataclass(frozen=True)
class ReproduceSettings:
    """What one reproduction runs (a profile's ``reproduce`` stage with the caller's overrides).

    Attributes:
        profile: the profile name (budgets of every stage).
        systems: registered systems with a data scenario.
        windows: the windows ℓ of Table 1.
        models: model names (:func:`learning.model_names`).
        seeds: training seeds ``0 … seeds−1`` per (system, model, window).
        out: the output folder.
        stage: the profile's ``reproduce`` stage (data, train overrides, evaluation, analysis,
            compression, rollouts), as data.
        workers: local Dask worker processes (0: serial, in this process).
        scheduler: address of a Dask scheduler (instead of ``workers``).
        resume: continue the reproduction already in ``out``.
        progress: progress bars on stderr.
        device: torch device of the training jobs.
        command: the command line that asked for it (shown in the report).
        figure_format: the file format of every figure: the report's (``figures/``): ``png``,
            or ``pdf`` (with a PNG twin that the HTML page shows) or ``svg``; and the jobs'
            (runs, analyses, compression study), which the page shows (SVG) or links (PDF); a
            job finished before keeps the figures it wrote.
    """

    profile: str
    systems: tuple[str, ...]
    windows: tuple[int, ...]
    models: tuple[str, ...]
    seeds: int
    out: Path
    stage: Mapping[str, Any]
    workers: int = 0
    scheduler: str | None = None
    resume: bool = False
    progress: bool = True
    device: str = "auto"
    command: str | None = None
    figure_format: str = "png"

    def __post_init__(self) -> None:
        known = scenario_names()
        for system in self.systems:
            if system not in known:
                raise DataError(
                    f"system {system!r} has no data scenario; expected some of {sorted(known)}"
                )
        bad_models = [m for m in self.models if m not in model_names()]
        if bad_models:
            raise OptionError(f"unknown model(s) {bad_models}; expected some of {model_names()}")
        if any(isinstance(w, bool) or not isinstance(w, int) or w < 1 for w in self.windows):
            raise OptionError(f"windows must be integers >= 1, got {list(self.windows)}")
        if isinstance(self.seeds, bool) or not isinstance(self.seeds, int) or self.seeds < 1:
            raise OptionError(f"seeds must be an integer >= 1, got {self.seeds!r}")
        for name, values in (
            ("systems", self.systems),
            ("windows", self.windows),
            ("models", self.models),
        ):
            if not values or len(set(values)) != len(values):
                raise OptionError(f"{name} must be a non-empty list without repeats: {values}")
        if self.workers < 0:
            raise OptionError(f"workers must be an integer >= 0, got {self.workers}")
        figure_name("figure", self.figure_format)  # an unknown format, before any job


def settings_from_profile(
    profile: str,
    *,
    out: str | os.PathLike[str],
    systems: Sequence[str] | None = None,
    windows: Sequence[int] | None = None,
    models: Sequence[str] | None = None,
    seeds: int | None = None,
    workers: int = 0,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    device: str = "auto",
    command: str | None = None,
    figure_format: str = "png",
) -> ReproduceSettings:
    """:class:`ReproduceSettings` from profile ``profile``; ``None`` keeps the profile's value."""
    stage = load_profile(profile).reproduce
    if stage is None:
        raise OptionError(f"profile {profile!r} has no 'reproduce' stage")
    return ReproduceSettings(
        profile=profile,
        systems=tuple(systems or stage.systems),
        windows=tuple(windows or stage.windows),
        models=tuple(models or stage.models),
        seeds=int(seeds if seeds is not None else stage.seeds),
        out=Path(out),
        stage=profile_stages(profile)["reproduce"],
        workers=workers,
        scheduler=scheduler,
        resume=resume,
        progress=progress,
        device=device,
        command=command,
        figure_format=figure_format,
    )


@dataclass(frozen=True, kw_only=True)
class ReproduceRequest:
    """``canonid reproduce`` as asked: the arguments of :func:`settings_from_profile` (``None``
    keeps the profile's value), ``command`` the command line as its words."""

    profile: str
    out: Path
    systems: Sequence[str] | None = None
    windows: Sequence[int] | None = None
    models: Sequence[str] | None = None
    seeds: int | None = None
    workers: int = 0
    scheduler: str | None = None
    resume: bool = False
    progress: bool = True
    device: str = "auto"
    command: tuple[str, ...] = ()
    figure_format: str = "png"

    def settings(self) -> ReproduceSettings:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return settings_from_profile(**{**fields, "command": " ".join(self.command) or None})


# ------------------------------------------------------------------------------ datasets
@dataclass(frozen=True)
class DatasetInfo:
    """A dataset of the reproduction: where, from which configuration, made or reused."""

    system: str
    path: Path
    config: dict[str, Any]
    checksum: str
    counts: dict[str, int]
    reused: bool
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "path": str(self.path)}


def _generation_config(system: str, stage: Mapping[str, Any]) -> GenerationConfig:
    data = dict(stage.get("data", {}).get(system, {}))
    unknown = sorted(set(data) - {"seed", "counts", "noise", "T", "controller_options"})
    if unknown:
        raise OptionError(f"reproduce stage, data.{system}: unknown key(s) {unknown}")
    return GenerationConfig(
        system=system,
        seed=int(data.get("seed", 0)),
        counts=dict(data.get("counts", {})),
        noise=data.get("noise"),
        controller_options=dict(data.get("controller_options", {})),
        T=data.get("T"),
    )


def _existing_dataset(folder: Path, config: GenerationConfig) -> Dataset | None:
    """The dataset in ``folder`` if it was generated from ``config`` (checksum validated on
    loading), ``None`` if there is none; another configuration is an error."""
    if not (folder / "dataset.json").is_file():
        return None
    dataset = Dataset.load(folder)
    found = dataset.metadata.get("generation")
    if found != config.to_json():
        raise DataError(
            f"{folder} holds a dataset generated with {found}, not {config.to_json()}; "
            "reproduce into another --out, or move that dataset away"
        )
    return dataset


def prepare_datasets(
    systems: Sequence[str],
    stage: Mapping[str, Any],
    folder: Path,
    *,
    runner: Callable[..., list[Any]],
) -> dict[str, DatasetInfo]:
    """Generate (or reuse) one dataset per system in ``folder/SYSTEM`` (module docstring)."""
    out: dict[str, DatasetInfo] = {}
    for system in systems:
        config = _generation_config(system, stage)
        target = folder / system
        t0 = time.perf_counter()
        dataset = _existing_dataset(target, config)
        reused = dataset is not None
        log.info("%s dataset in %s: %s", system, target, "reused" if reused else "generating")
        if dataset is None:
            run = functools.partial(runner, description=f"{system} flights", batch=FLIGHTS_PER_TASK)
            generate_dataset(config, target, run_jobs=run, resume=True)
            dataset = Dataset.load(target)
        header = read_json(target / "dataset.json", what="dataset metadata")
        out[system] = DatasetInfo(
            system=system,
            path=(target / "dataset.npz").resolve(),
            config=config.to_json(),
            checksum=str(header["checksum_sha256"]),
            counts=dataset.counts(),
            reused=reused,
            seconds=round(time.perf_counter() - t0, 3),
        )
    return out


# ------------------------------------------------------------------------------ jobs
def plan_jobs(settings: ReproduceSettings, datasets: Mapping[str, DatasetInfo]) -> list[Job]:
    """The reproduction's independent jobs, in a fixed order: the analyses first (the longest
    single jobs), then the column of canonid's defaults (the longest training jobs), then Table 1
    by system, model, window and seed. The list depends only on the settings and the datasets,
    never on how it is run.

    Table 1 trains the paper's network options with the stage's ``train`` overrides; the
    stage's ``defaults`` entry names the models and windows that also get canonid's default
    network options with the profile's ``train`` stage as it is (``canonid train``'s model),
    for the models and windows of this run only."""
    stage = settings.stage
    out = settings.out.resolve()
    overrides = dict(stage.get("train", {}))
    per_model = overrides.pop("per_model", {})
    per_system = overrides.pop("per_system", {})
    networks = stage.get("networks", {})
    evaluation = {"horizon": 100, "stride": 1, **stage.get("evaluation", {})}
    jobs: list[Job] = []
    for system in settings.systems:
        analysis = stage.get("analysis", {}).get(system)
        if analysis is None:
            continue
        unknown = sorted(set(analysis) - ANALYSIS_KEYS)
        if unknown:
            raise OptionError(f"reproduce stage, analysis.{system}: unknown key(s) {unknown}")
        jobs.append(
            AnalysisJob(
                system,
                str(out / "analysis" / system),
                dict(analysis),
                figure_format=settings.figure_format,
            )
        )

    def train_job(system: str, model: str, window: int, seed: int, options: str) -> TrainJob:
        run = f"{model}-l{window}-s{seed}"
        if options == PAPER_OPTIONS:
            merged = {**overrides, **per_system.get(system, {}), **per_model.get(model, {})}
            net = net_options(model, networks.get(system, {}).get(model, {}), paper=True)
        else:
            merged, net, run = {}, net_options(model), f"{model}-{options}-l{window}-s{seed}"
        # an explicit None in the stage switches an option off
        train = stage_train_options(
            settings.profile, {**merged, "seed": seed, "device": settings.device}
        )
        return TrainJob(
            system=system,
            model=model,
            window=window,
            seed=seed,
            data=str(datasets[system].path),
            data_sha256=datasets[system].checksum,
            folder=str(out / "runs" / system / run),
            profile=settings.profile,
            train_options=train.to_dict(),
            evaluation=evaluation,
            net_options=net,
            options=options,
            figure_format=settings.figure_format,
        )

    defaults = dict(stage.get("defaults", {}))
    unknown_models = sorted(set(defaults.get("models", ())) - set(model_names()))
    if unknown_models:
        raise OptionError(
            f"reproduce stage, defaults.models: unknown model(s) {unknown_models}; expected "
            f"some of {model_names()}"
        )
    default_models = [m for m in settings.models if m in defaults.get("models", ())]
    default_windows = [w for w in settings.windows if w in defaults.get("windows", ())]
    for system in settings.systems:
        for model in default_models:
            for window in default_windows:
                for seed in range(settings.seeds):
                    jobs.append(train_job(system, model, window, seed, DEFAULT_OPTIONS))
    for system in settings.systems:
        for model in settings.models:
            for window in settings.windows:
                for seed in range(settings.seeds):
                    jobs.append(train_job(system, model, window, seed, PAPER_OPTIONS))
    return jobs


# ------------------------------------------------------------------------------ tables
@dataclass(frozen=True)
class Table1Cell:
    """One (system, model, window, options) of Table 1 over the seeds (MSE in physical units).

    ``std`` is the sample standard deviation over seeds (``None`` with one seed); ``options``:
    the paper's model (:data:`~canonid.reproduce_jobs.PAPER_OPTIONS`, Table 1 itself) or
    canonid's defaults (:data:`~canonid.reproduce_jobs.DEFAULT_OPTIONS`, the column beside it);
    ``paper``: the paper's printed value of the model at that window, either way."""

    system: str
    model: str
    window: int
    seeds: int
    mean: float
    std: float | None
    mean_clean: float | None
    std_clean: float | None
    paper: float | None
    options: str = PAPER_OPTIONS


def _mean_std(values: Sequence[float]) -> tuple[float, float | None]:
    arr = np.asarray(values, dtype=np.float64)
    return float(arr.mean()), (float(arr.std(ddof=1)) if arr.size > 1 else None)


def _paper_runs(outcomes: Sequence[JobOutcome]) -> list[JobOutcome]:
    """The training jobs of Table 1 itself (the paper's model), which the checks and the
    compression study read."""
    return [o for o in outcomes if o.kind == "train" and job_options(o) == PAPER_OPTIONS]


def table1_rows(outcomes: Sequence[JobOutcome]) -> list[Table1Cell]:
    """Mean and spread over seeds of every (system, model, window, options) among the training
    jobs."""
    groups: dict[tuple[str, str, int, str], list[dict[str, Any]]] = {}
    for o in outcomes:
        if o.kind == "train":
            key = (o.recipe["system"], o.recipe["model"], int(o.recipe["window"]), job_options(o))
            groups.setdefault(key, []).append(o.result)
    cells = []
    for (system, model, window, options), results in groups.items():
        mean, std = _mean_std([r["rollout_mse"] for r in results])
        clean = [r["rollout_mse_clean"] for r in results if r["rollout_mse_clean"] is not None]
        mean_c, std_c = _mean_std(clean) if len(clean) == len(results) else (None, None)
        cells.append(
            Table1Cell(
                system,
                model,
                window,
                len(results),
                mean,
                std,
                mean_c,
                std_c,
                table1_value(system, model, window),
                options,
            )
        )
    return cells


# ------------------------------------------------------------------------------ the pipeline
@dataclass
class Reproduction:
    """What :func:`reproduce` did and wrote."""

    settings: ReproduceSettings
    datasets: dict[str, DatasetInfo]
    outcomes: list[JobOutcome]
    table1: list[Table1Cell]
    learned: dict[str, dict[str, list[dict[str, Any]]]]
    compression: dict[str, Any]
    figures: dict[str, str]
    report_md: Path
    report_html: Path
    summary: Path
    seconds: dict[str, float] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)

    @property
    def jobs_run(self) -> int:
        """Jobs executed by this call (the others were finished before)."""
        return sum(o.ran for o in self.outcomes)

    def overview(self) -> str:
        """What ``canonid reproduce`` prints: the jobs run now and where the report is."""
        return (
            f"reproduction ({self.settings.profile} profile): {len(self.outcomes)} jobs, "
            f"{self.jobs_run} run now, {len(self.outcomes) - self.jobs_run} already finished\n"
            f"report: {self.report_html.resolve()}\n        {self.report_md.resolve()}"
        )

    def to_dict(self, machine: Mapping[str, Any]) -> dict[str, Any]:
        """The body of ``reproduction.json``."""
        s = self.settings
        return {
            "format": "canonid-reproduction",
            "settings": {
                "profile": s.profile,
                "systems": s.systems,
                "windows": s.windows,
                "models": s.models,
                "seeds": s.seeds,
                "stage": s.stage,
                "workers": s.workers,
                "scheduler": s.scheduler,
                "command": s.command,
                "figure_format": s.figure_format,
            },
            "machine": dict(machine),
            "datasets": {k: v.to_dict() for k, v in self.datasets.items()},
            "table1": [
                {**dataclasses.asdict(c), "units": "physical units squared"} for c in self.table1
            ],
            "jobs": [dataclasses.asdict(o) for o in self.outcomes],
            "learned_checks": self.learned,
            "compression": self.compression,
            "figures": self.figures,
            "report": {"markdown": str(self.report_md), "html": str(self.report_html)},
            "seconds": self.seconds,
            "failures": self.failures,
        }


def _check_out(settings: ReproduceSettings) -> None:
    check_run_folder(settings.out, own=(SUMMARY_FILE, "runs", "analysis", "data", "figures"))
    started = [settings.out / name for name in (SUMMARY_FILE, "runs", "analysis")]
    if not settings.resume and any(path.exists() for path in started):
        raise CheckpointError(
            f"{settings.out} already holds a reproduction; add --resume to continue it (finished "
            "jobs are kept) or choose another --out"
        )


def reproduce(settings: ReproduceSettings) -> Reproduction:
    """Run the whole reproduction (module docstring); returns what was done and written.

    Raises :class:`canonid.runner.JobsFailedError` after the report is written when jobs failed
    twice (the report names them); the finished jobs are kept for ``resume``."""
    _check_out(settings)
    settings.out.mkdir(parents=True, exist_ok=True)
    seconds: dict[str, float] = {}
    runner = functools.partial(
        run_jobs,
        workers=settings.workers,
        scheduler=settings.scheduler,
        progress=settings.progress,
    )
    t0 = time.perf_counter()
    datasets = prepare_datasets(
        settings.systems, settings.stage, settings.out / "data", runner=runner
    )
    seconds["datasets"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    jobs = plan_jobs(settings, datasets)
    outcomes, failures = _run_all(jobs, settings)
    seconds["jobs"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    learned = learned_checks(outcomes, datasets)
    seconds["learned_checks"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    compression = compression_study(settings, outcomes)
    seconds["compression"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    table = table1_rows(outcomes)
    summary_path = settings.out / SUMMARY_FILE
    host = machine()
    md, html, figures = write_report(
        out=settings.out,
        settings=settings,
        machine=host,
        datasets=datasets,
        outcomes=outcomes,
        table=table,
        learned=learned,
        compression=compression,
        failures=failures,
        seconds=seconds,
        summary_path=summary_path,
    )
    seconds["report"] = time.perf_counter() - t0
    result = Reproduction(
        settings=settings,
        datasets=datasets,
        outcomes=outcomes,
        table1=table,
        learned=learned,
        compression=compression,
        figures=figures,
        report_md=md,
        report_html=html,
        summary=summary_path,
        seconds=seconds,
        failures=[f"{f.job}: {f.error}" for f in failures],
    )
    atomic_write_json(summary_path, jsonable(result.to_dict(host)))
    if failures:
        raise JobsFailedError(failures, len(jobs))
    return result


def _run_all(
    jobs: Sequence[Job], settings: ReproduceSettings
) -> tuple[list[JobOutcome], list[Any]]:
    """Run the jobs not finished yet; finished ones are read back, never re-run."""
    outcomes: dict[int, JobOutcome] = {}
    todo: list[int] = []
    for i, job in enumerate(jobs):
        done = job.cached()
        if done is not None:
            outcomes[i] = done
        else:
            todo.append(i)
    log.info("%d of %d jobs finished before, %d to run", len(outcomes), len(jobs), len(todo))
    failures: list[Any] = []
    if todo:
        try:
            results = run_jobs(
                run_job,
                [jobs[i] for i in todo],
                workers=settings.workers,
                scheduler=settings.scheduler,
                progress=settings.progress,
                description="reproduce jobs",
            )
        except JobsFailedError as exc:
            failures = [dataclasses.replace(f, position=todo[f.position]) for f in exc.failures]
            failed = {f.position for f in failures}
            for i in todo:
                done = jobs[i].cached()
                if done is not None and i not in failed:
                    outcomes[i] = done
        else:
            outcomes.update(zip(todo, results))
    return [outcomes[i] for i in sorted(outcomes)], failures


# ------------------------------------------------------------------------------ checks
def learned_checks(
    outcomes: Sequence[JobOutcome], datasets: Mapping[str, DatasetInfo]
) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """Checks of :mod:`canonid.analysis.learned` on the test split with the certified constants, for
    each analysed system (:meth:`canonid.analysis.report.AnalysisReport.learned_checks`):
    ``"residual"`` — one record per trained canonical model of Table 1 (the paper's options),
    seed 0, whose window the analysis
    covers (its one-step residual against the noise-induced level); ``"probe"`` — one record
    per such window (an affine probe z_t → x_t against Proposition 2's bound; it depends on the
    data and ℓ only, not on a model)."""
    out: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for a in (o for o in outcomes if o.kind == "analysis"):
        system = a.recipe["system"]
        report = AnalysisReport.from_json(Path(a.folder) / "analysis.json")
        windows = {r.window for r in report.results}
        dataset = Dataset.load(datasets[system].path)
        runs = [
            o
            for o in _paper_runs(outcomes)
            if o.recipe["system"] == system
            and o.recipe["model"] in CANONICAL_MODELS
            and o.recipe["seed"] == 0
            and o.recipe["window"] in windows
        ]
        models = [Model.load(o.folder).export() for o in runs]
        where = str(datasets[system].path)
        checks = learned.learned_checks(report, models, dataset, split="test", where=where)
        residuals = [
            {
                "model": o.recipe["model"],
                "window": o.recipe["window"],
                "run": o.folder,
                **residual.to_dict(),
            }
            for o, residual in zip(runs, checks.residuals)
        ]
        out[system] = {"residual": residuals, "probe": [p.to_dict() for p in checks.probes]}
    return out


def compression_study(
    settings: ReproduceSettings, outcomes: Sequence[JobOutcome]
) -> dict[str, Any]:
    """The compression study per system (:func:`canonid.reduction.compression_sweep`) on the
    Table-1 runs (the paper's options) of seed 0 that the profile's ``compression`` entry
    names; a dict per system
    with the sweep's folder, figures and rows, or a ``"skipped"`` reason."""
    spec = dict(settings.stage.get("compression", {}))
    if not spec:
        return {"skipped": "the profile has no compression entry"}
    out: dict[str, Any] = {}
    for system in settings.systems:
        runs = [
            o.folder
            for o in _paper_runs(outcomes)
            if o.recipe["system"] == system
            and o.recipe["seed"] == 0
            and o.recipe["model"] in spec.get("models", CANONICAL_MODELS)
            and o.recipe["window"] in spec.get("windows", settings.windows)
        ]
        if not runs:
            out[system] = {"skipped": "no trained run matches the profile's compression entry"}
            continue
        plan = SweepPlan(
            runs=tuple(runs),
            out=str(settings.out.resolve() / "compression" / system),
            rates=tuple(spec.get("rates", ())) or SweepPlan.rates,
            seeds=tuple(spec.get("seeds", (0,))),
            profile=settings.profile,
            epochs=spec.get("epochs"),
            device=settings.device,
            figure_format=settings.figure_format,
        )
        sweep = compression_sweep(
            plan,
            workers=settings.workers,
            scheduler=settings.scheduler,
            progress=settings.progress,
        )
        out[system] = {
            "folder": str(sweep.folder),
            "heatmap": str(sweep.heatmap),
            "reduced_mse": str(sweep.reduced_mse),
            "rows": sweep.rows(),
        }
    return out


def machine() -> dict[str, Any]:
    """The machine and software a reproduction ran on (for the report)."""
    info: dict[str, Any] = {
        "host": platform.node(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }
    try:
        info["load_average"] = [round(v, 2) for v in os.getloadavg()]
    except OSError:
        info["load_average"] = None
    for package in ("canonid", "torch", "numpy", "casadi", "dask"):
        try:
            info[package] = version(package)
        except PackageNotFoundError:
            info[package] = None
    try:
        import torch

        info["cuda"] = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    except ImportError:  # pragma: no cover - torch is a dependency
        info["cuda"] = None
    return info
