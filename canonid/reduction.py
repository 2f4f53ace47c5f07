"""Model reduction of trained runs: one reduction, and the compression study of the paper.

**One reduction** (:func:`reduce_run`, ``canonid reduce RUN --compression R``) reads the trained
canonical model of run folder ``RUN`` and the data it was trained on (``RUN/run.json``: same
training and validation trajectories), trains the reduced model of :mod:`canonid.learning.reduction`
and writes a run folder of the same format as ``canonid train`` (so ``canonid evaluate`` works
on it unchanged): ``run.json``, the model (``config.json``, ``weights.pt``,
``normalisation.json``), ``checkpoint.pt``, ``history.csv``, ``training_curve.png``,
``metrics.json`` and ``rollouts.png`` (the reduced model on the test split; each figure ``.pdf``
or ``.svg`` instead with ``figure_format``), plus

* ``reduction.json`` — :class:`ReductionResult`: ``n̄``, ``dim z``, the auto-encoder's
  reconstruction MSE on the test split (normalised units, :func:`canonid.learning.reduction.
  reconstruction_mse`) and the 100-step rollout MSE (paper metric, physical units, every start
  of every test trajectory) of the reduced *and* the full model;
* ``reduced_vs_full.png`` — open-loop simulations of both models on three test records.

**The compression study** (:func:`compression_sweep`, ``canonid reduce RUN … --sweep``): for
every trained run (one per window ℓ), every rate ``r`` and every seed, one independent
:class:`ReductionJob`, run through :func:`canonid.runner.run_jobs` (serially, on local
processes or on a Dask cluster). A job whose folder already holds a finished ``reduction.json``
for the same recipe is not run again, and one with a checkpoint resumes from it, so an
interrupted study continues where it stopped (:class:`SweepPlan` says what runs). The study
writes ``sweep.json`` (every result),
``heatmap.png`` (reconstruction MSE over (ℓ, r), mean over seeds — the paper's Fig. 4) and
``reduced_mse.png`` (reduced model's 100-step MSE against ``n̄`` per ℓ, mean ± standard
deviation over seeds, the full model as a dashed line — the paper's Fig. 3). The seeds vary the
auto-encoder's initialisation and sub-window draws; the full model of each ℓ is the one given.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from canonid.jobs import Job, check_folder, check_run_folder, run_folder_lock
from canonid.kernel.catalog import COMPRESSION_RATES, EVAL_HORIZON
from canonid.kernel.dataset import as_trajectories
from canonid.kernel.errors import CheckpointError, DataError, OptionError
from canonid.kernel.io import atomic_write_figure, atomic_write_json, read_json
from canonid.learning import EpochReport, Model
from canonid.learning.evaluate import evaluate, simulate_records
from canonid.learning.model import check_same
from canonid.learning.nets import ReducedNet, check_reducible
from canonid.learning.reduction import (
    ReductionOptions,
    latent_size,
    reconstruction_mse,
    reduce_model,
)
from canonid.learning.training import CHECKPOINT_FILE, TrainOptions
from canonid.profiles import reduce_options
from canonid.runfolder import (
    METRICS_FILE,
    Recipe,
    ReductionRecipe,
    data_info,
    eval_defaults,
    evaluate_run,
    figure_file,
    load_run_model,
    load_splits,
    pick_split,
    read_metrics,
    read_recipe,
    recipe_of,
    write_history,
)
from canonid.runner import EpochBar, run_jobs

__all__ = [
    "DEFAULT_RATES",
    "REDUCTION_FILE",
    "ReduceRequest",
    "ReductionJob",
    "ReductionResult",
    "SweepPlan",
    "SweepResult",
    "compression_sweep",
    "rate_label",
    "reduce_one",
    "reduce_run",
    "reduce_runs",
    "run_reduction_job",
]

#: the paper's rates: 15 %, 30 %, …, 90 %
DEFAULT_RATES = COMPRESSION_RATES
REDUCTION_FILE = "reduction.json"
SWEEP_FILE = "sweep.json"
#: the compression study's figures (:func:`plot_heatmap`, :func:`plot_reduced_mse`)
FIGURES = ("heatmap", "reduced_mse")


def rate_label(rate: float) -> str:
    """``0.6`` → ``"r60"``, ``0.125`` → ``"r12.5"`` (folder names)."""
    return f"r{round(100 * rate, 6):g}"


@dataclass(frozen=True)
class ReductionJob(Job["ReductionResult"]):
    """One reduction: the run folder of a trained canonical model, the rate, the seed and where
    to write the reduced run. ``epochs`` and ``linear_skip`` override the profile's (``None``:
    keep it); ``threads`` sets torch's CPU
    threads for the job (then restores them); ``resume`` continues from ``out/checkpoint.pt``;
    ``command`` is recorded in the run's ``run.json`` (the command line that asked for it);
    ``figure_format`` is the figures' file format (not part of the recipe: a finished reduction
    is reused with the figures it wrote)."""

    source: str
    compression: float
    out: str
    profile: str = "quick"
    seed: int = 0
    epochs: int | None = None
    linear_skip: bool | None = None
    device: str = "cpu"
    threads: int | None = 1
    resume: bool = False
    command: tuple[str, ...] = ()
    figure_format: str = "png"

    @property
    def name(self) -> str:
        return f"{self.source} at r = {self.compression:g}, seed {self.seed}"

    @property
    def where(self) -> Path:
        return Path(self.out)

    def recipe(self) -> dict[str, Any]:
        return self.recipe_key()

    def cached(self) -> ReductionResult | None:
        """The finished ``reduction.json`` of the same recipe, if any (another recipe's is
        redone: its checkpoint check refuses a folder of another source or rate)."""
        path = self.where / REDUCTION_FILE
        if not path.is_file():
            return None
        done = ReductionResult.from_dict(
            read_json(path, what="reduction result"), where=str(self.where)
        )
        return done if done.recipe == self.recipe() else None

    def work(self) -> ReductionResult:
        """Reduce; continue from ``checkpoint.pt`` when the folder holds one."""
        resume = self.resume or (self.where / CHECKPOINT_FILE).is_file()
        return reduce_run(dataclasses.replace(self, resume=resume))

    def save(self, result: Any) -> ReductionResult:
        assert isinstance(result, ReductionResult)
        return result  # reduce_run wrote reduction.json

    def options(self) -> tuple[TrainOptions, ReductionOptions]:
        """The profile's ``reduce`` stage with this job's overrides."""
        return reduce_options(
            self.profile,
            epochs=self.epochs,
            linear_skip=self.linear_skip,
            seed=self.seed,
            device=self.device,
        )

    def recipe_key(self) -> dict[str, Any]:
        """What a finished run must match to be reused by a sweep: the source, the rate and
        every resolved option (but the device)."""
        train_opts, red_opts = self.options()
        return {
            "source_run": os.path.abspath(self.source),
            "compression": float(self.compression),
            "seed": self.seed,
            "profile": self.profile,
            "options": {
                **{k: v for k, v in train_opts.to_dict().items() if k != "device"},
                **red_opts.to_dict(),
            },
        }


@dataclass(frozen=True)
class ReductionResult:
    """The figures of one reduction (see the module docstring; MSEs on the split ``split``).

    Attributes:
        reconstruction_mse: auto-encoder error, normalised units.
        rollout_mse, full_rollout_mse: rollout MSE of the reduced and the full model (100 steps,
            fewer when the scored records are shorter: ``rollout_horizon``),
            physical units (against the measured outputs), on the split ``split``.
        rollout_mse_clean, full_rollout_mse_clean: the same against the noise-free outputs
            (``None`` when the data have none).
    """

    source: str
    out: str
    model: str
    window: int
    compression: float
    seed: int
    state_dim: int
    latent_dim: int
    reconstruction_mse: float
    rollout_mse: float
    full_rollout_mse: float
    rollout_mse_clean: float | None
    full_rollout_mse_clean: float | None
    rollout_horizon: int
    best_epoch: int
    epochs_run: int
    stopped: str
    seconds: float
    recipe: dict[str, Any]
    split: str = "test"

    @property
    def ratio(self) -> float:
        """Reduced over full 100-step MSE."""
        return self.rollout_mse / self.full_rollout_mse

    def to_dict(self) -> dict[str, Any]:
        return {"format": "canonid-reduction", **dataclasses.asdict(self)}

    def summary(self) -> str:
        """What ``canonid reduce --compression`` prints: the reduction, the scores of the
        reduced and the full model, the reduced run's metrics table and where it is."""
        from canonid.scoring import metrics_table

        return "\n".join(
            [
                f"{self.model} (ℓ = {self.window}) reduced at r = {self.compression:.0%}: "
                f"n̄ = {self.latent_dim} of dim z = {self.state_dim}; {self.stopped} after "
                f"{self.epochs_run} epochs (best at {self.best_epoch})",
                f"{self.rollout_horizon}-step rollout MSE on the {self.split} split: reduced "
                f"{self.rollout_mse:.4g}, full {self.full_rollout_mse:.4g} (ratio "
                f"{self.ratio:.3g}); reconstruction MSE {self.reconstruction_mse:.3g} "
                "(normalised)",
                metrics_table(read_metrics(Path(self.out) / METRICS_FILE)),
                f"run written to {self.out}",
            ]
        )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str) -> ReductionResult:
        fields = dataclasses.fields(cls)
        required = {f.name for f in fields if f.default is dataclasses.MISSING}
        if data.get("format") != "canonid-reduction" or not required <= set(data):
            raise CheckpointError(f"{where} is not a canonid reduction result")
        return cls(**{f.name: data[f.name] for f in fields if f.name in data})


def _load_source(source: Path) -> tuple[Model, Recipe]:
    model = load_run_model(source)  # a run being trained: its writer named
    recipe = read_recipe(source)
    check_reducible(model.name)
    return model, recipe


def reduce_one(job: ReductionJob, *, progress: bool = True) -> ReductionResult:
    """:func:`reduce_run` into a checked output folder, with a progress bar over its epochs
    (``progress``) that names the phase: ``Ĥ`` frozen, then fine-tuned."""
    check_folder(Path(job.out))
    train_opts, red_opts = reduce_options(
        job.profile, epochs=job.epochs, linear_skip=job.linear_skip
    )
    frozen = red_opts.frozen_epochs(train_opts.epochs)
    bar = EpochBar("reduce", enabled=progress)

    def show(report: EpochReport) -> None:
        phase = "Ĥ frozen" if report.epoch <= frozen else "Ĥ fine-tuned"
        val = "-" if report.val_loss is None else f"{report.val_loss:.3g}"
        recon = report.parts.get("reconstruction", float("nan"))
        bar.show(
            report.epoch,
            report.epochs,
            f"{phase}, H={report.horizon}, recon={recon:.3g}, val rollout={val} "
            f"(best {report.best_val_loss:.3g} at {report.best_epoch})",
        )

    try:
        return reduce_run(job, callback=show)
    finally:
        bar.close()


def reduce_run(
    job: ReductionJob, *, callback: Callable[[EpochReport], None] | None = None
) -> ReductionResult:
    """Run one reduction and write its run folder (see the module docstring), holding the
    folder's lock (:func:`canonid.jobs.run_folder_lock`)."""
    with run_folder_lock(Path(job.out), new=not job.resume):
        return _reduce_locked(job, callback=callback)


def _reduce_locked(
    job: ReductionJob, *, callback: Callable[[EpochReport], None] | None = None
) -> ReductionResult:
    source, out = Path(job.source), Path(job.out)
    model, recipe = _load_source(source)
    latent = latent_size(model.net.state_dim, job.compression)  # refuses a bad rate early
    figure = out / figure_file("reduced_vs_full", job.figure_format)  # and a bad format
    train_opts, red_opts = job.options()
    key = {k: v for k, v in job.recipe_key().items() if k != "options"}  # in the checkpoint
    if job.resume:
        if not (out / CHECKPOINT_FILE).is_file():
            raise CheckpointError(f"{out} holds no {CHECKPOINT_FILE} to resume from")
        before = read_recipe(out)
        if not isinstance(before, ReductionRecipe):
            raise CheckpointError(f"{out} holds a training run, not a reduction to resume")
        check_same(dataclasses.asdict(before), key, what=f"run {out}")
    elif (out / CHECKPOINT_FILE).exists():
        there = recipe_of(out)
        raise CheckpointError(
            f"{out} already holds a reduction run; resume it or choose another output folder"
            if isinstance(there, ReductionRecipe)
            else f"{out} already holds a training run; choose another output folder"
        )
    dataset, train, val, test_name, data_path = load_splits(recipe)
    # records too short to score are refused before anything is trained or written
    horizon = eval_defaults(
        dataset.split(test_name),
        model.window,
        EVAL_HORIZON,
        where=f"{data_path} [{test_name}]",
        fit=True,
    )
    out.mkdir(parents=True, exist_ok=True)
    ReductionRecipe(
        **recipe.source(),
        regressor=model.name,
        window=model.window,
        latent_dim=latent,
        **key,
        train_options=train_opts.to_dict(),
        reduction_options=red_opts.to_dict(),
        command=job.command,
    ).write(out)
    t0 = time.perf_counter()
    fit = reduce_model(
        model,
        train,
        val,
        compression=job.compression,
        options=train_opts,
        reduction=red_opts,
        run_dir=out,
        resume=job.resume,
        callback=callback,
        info={
            "profile": job.profile,
            "source_run": str(source),
            **data_info(dataset, data_path, train, val),
        },
    )
    seconds = time.perf_counter() - t0
    write_history(out, fit.history, figure_format=job.figure_format)
    reduced = fit.model
    evaluation = evaluate_run(
        out,
        reduced,
        dataset,
        data_path=data_path,
        split=test_name,
        horizon=horizon,
        stride=1,
        n_init=None,
        figure_format=job.figure_format,
    )
    _, trajs = pick_split(dataset, test_name, where=data_path)
    n_init = evaluation.scores.n_init
    full = evaluate(model, trajs, horizon=horizon, stride=1, n_init=n_init)
    _plot_reduced_vs_full(
        model,
        reduced,
        trajs,
        figure,
        n_init=n_init,
        dt=dataset.dt,
        output_names=dataset.output_names,
    )
    result = ReductionResult(
        source=str(source),
        out=str(out),
        model=model.name,
        window=model.window,
        compression=float(job.compression),
        seed=job.seed,
        state_dim=model.net.state_dim,
        latent_dim=latent,
        reconstruction_mse=reconstruction_mse(reduced, trajs),
        rollout_mse=evaluation.rollout_mse,
        full_rollout_mse=full.measured.rollout_mse,
        rollout_mse_clean=evaluation.rollout_mse_clean,
        full_rollout_mse_clean=full.clean.rollout_mse if full.clean else None,
        rollout_horizon=horizon,
        best_epoch=fit.best_epoch,
        epochs_run=fit.epochs_run,
        stopped=fit.stopped,
        seconds=seconds,
        recipe=job.recipe_key(),
        split=test_name,
    )
    atomic_write_json(out / REDUCTION_FILE, result.to_dict())
    return result


def run_reduction_job(job: ReductionJob) -> ReductionResult:
    """The runner's job function: reuse a finished result for the same recipe, resume an
    interrupted one, else reduce (with ``job.threads`` torch threads)."""
    return job.run()


@dataclass(frozen=True)
class SweepResult:
    """The compression study: every :class:`ReductionResult` and the figures written."""

    results: list[ReductionResult]
    folder: Path
    heatmap: Path
    reduced_mse: Path

    def rows(self) -> list[dict[str, Any]]:
        """Mean and standard deviation over seeds per (source run, rate)."""
        groups: dict[tuple[str, float], list[ReductionResult]] = {}
        for r in self.results:
            groups.setdefault((r.source, r.compression), []).append(r)
        out = []
        for (source, rate), rs in groups.items():
            rec = np.array([r.reconstruction_mse for r in rs])
            mse = np.array([r.rollout_mse for r in rs])
            out.append(
                {
                    "source": source,
                    "model": rs[0].model,
                    "window": rs[0].window,
                    "compression": rate,
                    "state_dim": rs[0].state_dim,
                    "latent_dim": rs[0].latent_dim,
                    "seeds": len(rs),
                    "reconstruction_mse_mean": float(rec.mean()),
                    "reconstruction_mse_std": float(rec.std()),
                    "rollout_mse_mean": float(mse.mean()),
                    "rollout_mse_std": float(mse.std()),
                    "full_rollout_mse": rs[0].full_rollout_mse,
                }
            )
        return out

    def table(self) -> str:
        """A Markdown table of :meth:`rows`."""
        lines = [
            f"| run | ℓ | r | n̄ / dim z | reconstruction MSE (normalised, "
            f"{scored_on(self.results)}) | 100-step MSE reduced | full | seeds |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for row in self.rows():
            lines.append(
                f"| {Path(row['source']).name} | {row['window']} | {row['compression']:.0%} | "
                f"{row['latent_dim']} / {row['state_dim']} | "
                f"{row['reconstruction_mse_mean']:.3g} ± {row['reconstruction_mse_std']:.2g} | "
                f"{row['rollout_mse_mean']:.3g} ± {row['rollout_mse_std']:.2g} | "
                f"{row['full_rollout_mse']:.3g} | {row['seeds']} |"
            )
        return "\n".join(lines)

    def summary(self) -> str:
        """What ``canonid reduce --sweep`` prints: :meth:`table` and where the files are."""
        return (
            f"{self.table()}\nfigures: {self.heatmap}, {self.reduced_mse}; results: "
            f"{self.folder / SWEEP_FILE}"
        )


@dataclass(frozen=True)
class SweepPlan:
    """What a compression study runs: every (run, rate, seed) of these, each job writing to
    ``out/<run folder name>-r<rate>-s<seed>``.

    Attributes:
        runs: run folders of trained Ours (MLP/GRU) models, typically one per window ℓ.
        out: folder of the study (one sub-folder per job, ``sweep.json`` and the figures).
        rates: compression rates in (0, 1) (default 15 %, 30 %, …, 90 %).
        seeds: auto-encoder seeds.
        profile, epochs, linear_skip, device, threads, command, figure_format: of every job
            (see :class:`ReductionJob`); the study's figures take ``figure_format`` too.
    """

    runs: tuple[str, ...]
    out: str
    rates: tuple[float, ...] = DEFAULT_RATES
    seeds: tuple[int, ...] = (0, 1, 2)
    profile: str = "quick"
    epochs: int | None = None
    linear_skip: bool | None = None
    device: str = "cpu"
    threads: int | None = 1
    command: tuple[str, ...] = ()
    figure_format: str = "png"

    def jobs(self) -> list[ReductionJob]:
        """The jobs, in (run, rate, seed) order; bad rates, repeated values and runs that are
        not canonical models are refused before any job starts."""
        sources = [Path(r) for r in self.runs]
        rates, seeds = list(self.rates), list(self.seeds)
        if not sources or not rates or not seeds:
            raise DataError("a sweep needs at least one run, one rate and one seed")
        names = [s.name for s in sources]
        if len(set(names)) != len(names):
            raise DataError(f"the runs of a sweep need distinct folder names, got {names}")
        if len(set(seeds)) != len(seeds) or len(set(rates)) != len(rates):
            raise DataError(f"rates and seeds must not repeat: rates {rates}, seeds {seeds}")
        for source in sources:
            model, _ = _load_source(source)
            for rate in rates:
                latent_size(model.net.state_dim, rate)
        base = Path(self.out)
        return [
            ReductionJob(
                source=str(source),
                compression=float(rate),
                out=str(base / f"{source.name}-{rate_label(rate)}-s{seed}"),
                profile=self.profile,
                seed=int(seed),
                epochs=self.epochs,
                linear_skip=self.linear_skip,
                device=self.device,
                threads=self.threads,
                command=self.command,
                figure_format=self.figure_format,
            )
            for source in sources
            for rate in rates
            for seed in seeds
        ]


def compression_sweep(
    plan: SweepPlan,
    *,
    workers: int = 0,
    scheduler: str | None = None,
    progress: bool = True,
) -> SweepResult:
    """Run the compression study ``plan`` through :func:`canonid.runner.run_jobs` (``workers``,
    ``scheduler``, ``progress`` are its options) and write ``sweep.json`` and the two figures
    into ``plan.out`` (see the module docstring)."""
    jobs = plan.jobs()
    folder = check_run_folder(Path(plan.out), own=(SWEEP_FILE, *(Path(j.out).name for j in jobs)))
    heatmap, reduced_mse = (folder / figure_file(n, plan.figure_format) for n in FIGURES)
    folder.mkdir(parents=True, exist_ok=True)
    results = run_jobs(
        run_reduction_job,
        jobs,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        description="reductions",
    )
    sweep = SweepResult(
        results=results,
        folder=folder,
        heatmap=plot_heatmap(results, heatmap),
        reduced_mse=plot_reduced_mse(results, reduced_mse),
    )
    atomic_write_json(
        folder / SWEEP_FILE,
        {
            "format": "canonid-sweep",
            "kind": "compression",
            "plan": dataclasses.asdict(plan),
            "summary": sweep.rows(),
            "results": [r.to_dict() for r in results],
        },
    )
    return sweep


@dataclass(frozen=True, kw_only=True)
class ReduceRequest:
    """``canonid reduce`` as asked: one reduction of ``runs[0]`` at rate ``compression`` into
    ``out`` (default ``RUN-r<rate>`` beside the run), or with ``sweep`` the compression study of
    ``runs`` over ``rates`` (default :data:`DEFAULT_RATES`) and ``seeds`` seeds from ``seed``
    into ``out`` (default ``runs/compression-sweep``), on ``workers`` / ``scheduler`` (each job
    on ``threads`` torch threads, default 1). ``profile``, ``epochs``, ``linear_skip``,
    ``device``, ``resume`` (one reduction only), ``command`` and ``figure_format``: see
    :class:`ReductionJob`."""

    runs: Sequence[Path]
    compression: float | None = None
    sweep: bool = False
    profile: str = "quick"
    out: Path | None = None
    epochs: int | None = None
    linear_skip: bool | None = None
    seed: int = 0
    device: str = "cpu"
    threads: int | None = None
    resume: bool = False
    rates: Sequence[float] | None = None
    seeds: int = 3
    workers: int = 0
    scheduler: str | None = None
    progress: bool = True
    command: tuple[str, ...] = ()
    figure_format: str = "png"


def reduce_runs(request: ReduceRequest) -> ReductionResult | SweepResult:
    """One reduction (:func:`reduce_one`) or the compression study (:func:`compression_sweep`)
    as ``request`` asks; the options that do not fit the mode are refused."""
    if request.sweep:
        if request.resume:
            raise OptionError("--resume is for one reduction; a sweep always resumes its jobs")
        if request.seeds < 1:
            raise OptionError(f"--seeds must be >= 1, got {request.seeds}")
        plan = SweepPlan(
            runs=tuple(str(r) for r in request.runs),
            out=str(request.out or Path("runs") / "compression-sweep"),
            rates=tuple(request.rates or DEFAULT_RATES),
            seeds=tuple(range(request.seed, request.seed + request.seeds)),
            profile=request.profile,
            epochs=request.epochs,
            linear_skip=request.linear_skip,
            device=request.device,
            threads=request.threads if request.threads is not None else 1,
            command=request.command,
            figure_format=request.figure_format,
        )
        return compression_sweep(
            plan, workers=request.workers, scheduler=request.scheduler, progress=request.progress
        )
    if len(request.runs) != 1:
        raise OptionError(f"--compression reduces one RUN, got {len(request.runs)} (use --sweep)")
    if request.compression is None:
        raise OptionError("give --compression R (one reduction) or --sweep (the study)")
    source = Path(request.runs[0])
    job = ReductionJob(
        source=str(source),
        compression=request.compression,
        out=str(request.out or source.parent / f"{source.name}-{rate_label(request.compression)}"),
        profile=request.profile,
        seed=request.seed,
        epochs=request.epochs,
        linear_skip=request.linear_skip,
        device=request.device,
        threads=request.threads,
        resume=request.resume,
        command=request.command,
        figure_format=request.figure_format,
    )
    return reduce_one(job, progress=request.progress)


# ---------------------------------------------------------------------- figures
def _save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    fig.tight_layout()
    return atomic_write_figure(path, fig, dpi=120)


def scored_on(results: Sequence[ReductionResult]) -> str:
    """The split the results were scored on, for a label: ``test``, or ``val`` where the data
    hold no test split (both, joined by "/", when the runs differ)."""
    return "/".join(sorted({r.split for r in results}))


def _run_label(results: Sequence[ReductionResult], source: str) -> str:
    first = next(r for r in results if r.source == source)
    windows = [r.window for r in results if r.source != source]
    clash = first.window in windows
    return f"ℓ = {first.window}" + (f" ({Path(source).name})" if clash else "")


def _sources_by_window(results: Sequence[ReductionResult]) -> list[str]:
    firsts: dict[str, ReductionResult] = {}
    for r in results:
        firsts.setdefault(r.source, r)
    return sorted(firsts, key=lambda s: (firsts[s].window, s))


def plot_heatmap(results: Sequence[ReductionResult], path: str | os.PathLike[str]) -> Path:
    """Reconstruction MSE (normalised units, mean over seeds) over window ℓ (rows) and rate r
    (columns), log colour scale, each cell annotated (the paper's Fig. 4)."""
    sources = _sources_by_window(results)
    rates = sorted({r.compression for r in results})
    grid = np.full((len(sources), len(rates)), np.nan)
    for i, source in enumerate(sources):
        for j, rate in enumerate(rates):
            vals = [
                r.reconstruction_mse for r in results if (r.source, r.compression) == (source, rate)
            ]
            if vals:
                grid[i, j] = float(np.mean(vals))
    positive = grid[np.isfinite(grid) & (grid > 0)]
    norm = LogNorm(vmin=positive.min(), vmax=positive.max()) if positive.size else None
    fig = Figure(figsize=(1.2 * len(rates) + 2.5, 0.7 * len(sources) + 1.8))
    ax = fig.subplots()
    image = ax.imshow(np.where(grid > 0, grid, np.nan), cmap="viridis", norm=norm, aspect="auto")
    for i in range(len(sources)):
        for j in range(len(rates)):
            if np.isfinite(grid[i, j]):
                # dark text on the light (yellow) end of viridis, white on the dark end
                light = norm is not None and grid[i, j] > 0 and norm(grid[i, j]) > 0.6
                colour = "k" if light else "w"
                ax.text(
                    j, i, f"{grid[i, j]:.2g}", ha="center", va="center", fontsize=8, color=colour
                )
    ax.set_xticks(range(len(rates)), [f"{r:.0%}" for r in rates])
    ax.set_yticks(range(len(sources)), [_run_label(results, s) for s in sources])
    ax.set_xlabel("compression rate r")
    seeds = len({r.seed for r in results})
    spread = "one seed" if seeds == 1 else f"mean of {seeds} seeds"
    split = scored_on(results)
    ax.set_title(f"auto-encoder reconstruction MSE ({split}, normalised; {spread})", fontsize=9)
    fig.colorbar(image, ax=ax)
    return _save(fig, path)


def plot_reduced_mse(results: Sequence[ReductionResult], path: str | os.PathLike[str]) -> Path:
    """100-step rollout MSE of the reduced model against its state size ``n̄``, one line per
    window ℓ with mean ± standard deviation over seeds; the full model's MSE (state size
    ``dim z``) as a dashed line of the same colour (the paper's Fig. 3)."""
    fig = Figure(figsize=(7, 4.2))
    ax = fig.subplots()
    for k, source in enumerate(_sources_by_window(results)):
        mine = [r for r in results if r.source == source]
        sizes = sorted({r.latent_dim for r in mine})
        stats = [np.array([r.rollout_mse for r in mine if r.latent_dim == n]) for n in sizes]
        colour = f"C{k % 10}"
        ax.errorbar(
            sizes,
            [s.mean() for s in stats],
            yerr=[s.std() for s in stats],
            marker="o",
            ms=4,
            capsize=3,
            color=colour,
            label=f"{_run_label(results, source)} (dim z = {mine[0].state_dim})",
        )
        ax.axhline(mine[0].full_rollout_mse, color=colour, ls="--", lw=0.9)
    ax.set_yscale("log")
    ax.set_xlabel("reduced state size n̄")
    ax.set_ylabel(f"100-step rollout MSE ({scored_on(results)}, physical units)")
    seeds = len({r.seed for r in results})
    spread = "one seed" if seeds == 1 else f"mean ± std over {seeds} seeds"
    ax.set_title(f"reduced model vs state size ({spread}; dashed: full model)", fontsize=9)
    ax.legend(fontsize=8)
    return _save(fig, path)


def _plot_reduced_vs_full(
    full: Model,
    reduced: Model,
    trajs: Sequence[Any],
    path: Path,
    *,
    n_init: int,
    dt: float,
    output_names: Sequence[str],
    count: int = 3,
) -> Path:
    """Open-loop simulations of the full and the reduced model from sample ``n_init`` on the
    first ``count`` test records, one row per output."""
    records = [s for s in as_trajectories(trajs, what="test data") if s.T > n_init][:count]
    sims_full = simulate_records(full, records, n_init)
    sims_red = simulate_records(reduced, records, n_init)
    n_y = full.n_y
    fig = Figure(figsize=(4.2 * len(records), 2.4 * n_y))
    axes = fig.subplots(n_y, len(records), squeeze=False, sharex="col")
    assert isinstance(reduced.net, ReducedNet)
    latent = reduced.net.latent_dim
    for j, (rec, yf, yr) in enumerate(zip(records, sims_full, sims_red)):
        t = np.arange(rec.T) * dt
        for i in range(n_y):
            ax = axes[i, j]
            ax.plot(t, rec.y[:, i], ".", ms=2, color="0.55", label="measured")
            ax.plot(
                t[n_init:],
                yf[:, i],
                color="C0",
                lw=1.2,
                label=f"full (dim z = {full.net.state_dim})",
            )
            ax.plot(
                t[n_init:], yr[:, i], color="C3", lw=1.2, ls="--", label=f"reduced (n̄ = {latent})"
            )
            ax.axvline(t[n_init], color="0.3", ls=":", lw=0.8)
            if j == 0:
                ax.set_ylabel(output_names[i])
            if i == n_y - 1:
                ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(
        f"{type(full.net).label}, ℓ = {full.window}: full vs reduced model, open loop", fontsize=10
    )
    return _save(fig, path)
