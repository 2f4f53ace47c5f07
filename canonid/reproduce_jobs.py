"""The independent jobs of a reproduction (:mod:`canonid.reproduce`): :class:`canonid.jobs.
StoredJob` s, whose ``folder/result.json`` holds their recipe and result (a job whose file holds
the same recipe is finished and never runs again).

* :class:`TrainJob` — one cell of Table 1 for one seed: a ``canonid train`` run folder, trained
  (or continued from its checkpoint) and scored on the test split; its ``options`` say whether
  the model is the paper's (:data:`PAPER_OPTIONS`, Table 1 itself) or canonid's defaults
  (:data:`DEFAULT_OPTIONS`, the column beside it).
* :class:`AnalysisJob` — the analysis of one system (:func:`canonid.analysis.report.analyze`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from canonid.analysis.estimate import Budget
from canonid.analysis.report import analyze
from canonid.jobs import RESULT_FILE, JobOutcome, StoredJob, finished, run_job, store
from canonid.kernel.errors import OptionError
from canonid.kernel.io import figure_name
from canonid.learning.search import SEARCH_FILE
from canonid.learning.training import CHECKPOINT_FILE
from canonid.models.registry import get_system
from canonid.models.sets import Box
from canonid.runfolder import RunRecipe, train_run

__all__ = [
    "ANALYSIS_KEYS",
    "DEFAULT_OPTIONS",
    "PAPER_OPTIONS",
    "RESULT_FILE",
    "AnalysisJob",
    "Job",
    "JobOutcome",
    "TrainJob",
    "finished",
    "job_options",
    "run_job",
    "store",
]

#: a Table-1 job's model: the paper's network options and the reproduce stage's budget ...
PAPER_OPTIONS = "paper"
#: ... or canonid's default network options and the profile's ``train`` stage
DEFAULT_OPTIONS = "defaults"


def job_options(outcome: JobOutcome) -> str:
    """A training job's options (its recipe names them unless they are the paper's)."""
    return str(outcome.recipe.get("options", PAPER_OPTIONS))


@dataclass(frozen=True)
class TrainJob(StoredJob):
    """One cell of Table 1 for one seed: train ``model`` with window ``window`` on the dataset,
    then score it on its test split. Picklable (sent to Dask workers, which must see ``folder``
    and ``data``: a shared file system on a cluster).

    The folder is a ``canonid train`` run folder (``run.json``, the model, ``checkpoint.pt``,
    ``history.csv``, ``training_curve.png``, ``metrics.json``, ``rollouts.png``; the figures in
    ``figure_format``, which is not part of the recipe: a finished job keeps the figures it
    wrote), so ``canonid evaluate``, ``canonid analyze --run`` and ``canonid reduce`` read it
    unchanged.
    """

    system: str
    model: str
    window: int
    seed: int
    data: str
    data_sha256: str
    folder: str
    profile: str
    train_options: Mapping[str, Any]
    evaluation: Mapping[str, Any]
    net_options: Mapping[str, Any] = field(default_factory=dict)
    options: str = PAPER_OPTIONS
    threads: int | None = 1
    figure_format: str = "png"
    kind: ClassVar[str] = "train"

    def __post_init__(self) -> None:
        if self.options not in (PAPER_OPTIONS, DEFAULT_OPTIONS):
            raise OptionError(
                f"TrainJob options must be {PAPER_OPTIONS!r} or {DEFAULT_OPTIONS!r}, "
                f"got {self.options!r}"
            )

    @property
    def name(self) -> str:
        model = self.model if self.options == PAPER_OPTIONS else f"{self.model} (canonid defaults)"
        return f"{self.system} {model} ℓ={self.window} seed {self.seed}"

    def recipe(self) -> dict[str, Any]:
        """What a finished job must match to be reused (the data by checksum, not by path); a
        paper-options job's recipe has no ``options`` key, as before that key existed, so an
        older reproduction resumes."""
        marked = {} if self.options == PAPER_OPTIONS else {"options": self.options}
        return {
            **marked,
            "system": self.system,
            "model": self.model,
            "window": self.window,
            "seed": self.seed,
            "data_sha256": self.data_sha256,
            "profile": self.profile,
            "train_options": dict(self.train_options),
            "evaluation": dict(self.evaluation),
            "net_options": dict(self.net_options),
        }

    def work(self) -> dict[str, Any]:
        """Train (or continue from the checkpoint) and evaluate; the ``canonid train`` run
        folder plus the fields of Table 1."""
        return _train_and_score(self, self.where)


def _train_and_score(job: TrainJob, folder: Path) -> dict[str, Any]:
    recipe = RunRecipe(
        data=job.data,
        model=job.model,
        window=job.window,
        net_options=dict(job.net_options),
        profile=job.profile,
        train_options=dict(job.train_options),
        command=("canonid", "reproduce", "(job)", job.name),
    )
    # a search (the defaults' cubic branch) may have started before the first checkpoint
    resume = (folder / CHECKPOINT_FILE).is_file() or (folder / SEARCH_FILE).is_file()
    run = train_run(  # Table 1 reads the test split after training: nothing is chosen on it
        recipe,
        folder,
        resume=resume,
        eval_horizon=int(job.evaluation["horizon"]),
        eval_stride=int(job.evaluation["stride"]),
        figure_format=job.figure_format,
        split="test",
    )
    scores, fitted = run.evaluation.scores, run.fit
    return {
        "rollout_mse": scores.measured.rollout_mse,
        "rollout_mse_clean": run.evaluation.rollout_mse_clean,
        "rmse": scores.measured.rmse,
        "nrmse": scores.measured.nrmse,
        "fit_percent": scores.measured.fit_percent,
        "n_rollouts": scores.n_rollouts,
        "split": run.evaluation.split,
        "epochs_run": fitted.epochs_run,
        "best_epoch": fitted.best_epoch,
        "best_val_loss": fitted.best_val_loss,
        "stopped": fitted.stopped,
        "resumed_from_checkpoint": resume,
        "seconds": run.seconds,
        "cpu_seconds": run.cpu_seconds,
    }


@dataclass(frozen=True)
class AnalysisJob(StoredJob):
    """The analysis of one system (:func:`canonid.analysis.report.analyze`): γ_f, γ_h, α_ℓ brackets
    and the Monte-Carlo check of Proposition 2 for each window, with the profile's budget; writes
    ``analysis.json`` and ``bound_vs_window.png`` (``figure_format``, not part of the recipe)
    into ``folder``."""

    system: str
    folder: str
    settings: Mapping[str, Any]
    seed: int = 0
    threads: int | None = None
    figure_format: str = "png"
    kind: ClassVar[str] = "analysis"

    @property
    def name(self) -> str:
        return f"{self.system} analysis"

    def recipe(self) -> dict[str, Any]:
        return {"system": self.system, "settings": dict(self.settings), "seed": self.seed}

    def work(self) -> dict[str, Any]:
        return _analyse(self, self.where)


ANALYSIS_KEYS = frozenset({"windows", "X", "U", "W", "trials", "budget_seconds", "boxes"})


def _box(value: Any, where: str) -> Any:
    if value is None:
        return None
    try:
        lo, hi = value
        return Box(lo, hi)
    except (TypeError, ValueError) as exc:
        raise OptionError(f"{where}: expected [[lower...], [upper...]], got {value!r}") from exc


def _analyse(job: AnalysisJob, folder: Path) -> dict[str, Any]:
    s = job.settings
    t0, cpu0 = time.perf_counter(), time.process_time()
    system = get_system(job.system)
    report = analyze(
        system,
        list(s["windows"]),
        X=_box(s.get("X"), f"analysis.{job.system}.X"),
        U=_box(s.get("U"), f"analysis.{job.system}.U"),
        W=_box(s.get("W"), f"analysis.{job.system}.W"),
        trials=int(s["trials"]),
        budget=Budget(seconds=float(s["budget_seconds"]), boxes=int(s["boxes"])),
        seed=job.seed,
    )
    folder.mkdir(parents=True, exist_ok=True)
    report.write_json(folder / "analysis.json")
    name = figure_name("bound_vs_window", job.figure_format)
    figure = report.figure(folder / name) if report.checks else None
    rows = []
    for r in report.results:
        c = r.check
        rows.append(
            {
                "window": r.window,
                "gamma_f": [r.gamma_f.lower.value, r.gamma_f.upper.value],
                "gamma_h": [r.gamma_h.lower.value, r.gamma_h.upper.value],
                "alpha": [r.alpha.lower.value, r.alpha.upper.value],
                "trials": c.trials if c else 0,
                "violations": c.violations if c else None,
                "solver_failures": c.solver_failures if c else None,
                "max_ratio": c.max_ratio if c else None,
                "max_error": c.max_error if c else None,
                "worst_case_bound": c.worst_case_bound if c else None,
            }
        )
    return {
        "windows": rows,
        "sets": {"X": report.X.to_dict(), "U": report.U.to_dict(), "W": report.W.to_dict()},
        "table": report.table(),
        "limitations": report.limitations,
        "figure": str(figure) if figure else None,
        "seconds": round(time.perf_counter() - t0, 3),
        "cpu_seconds": round(time.process_time() - cpu0, 3),
    }


Job = TrainJob | AnalysisJob
