"""Selection on validation: ``canonid train … --window auto`` (and ``--hidden auto``).

Every candidate — a window ℓ of :data:`canonid.training.WINDOW_CANDIDATES` that the data allow,
times a width of :data:`canonid.training.WIDTH_CANDIDATES` with ``--hidden auto`` — is one
:class:`CandidateJob`: a ``canonid train`` run folder ``RUN/candidates/<name>`` trained with the
same options and seed, run through :func:`canonid.runner.run_jobs` (serially, on local processes or
on a Dask cluster). The candidate with the lowest best validation loss (normalised output-error
rollouts on the validation split; the test split plays no part) is chosen and its run becomes the
run folder's model: its ``run.json``, model files, history, metrics and figures are copied into
``RUN``, so ``canonid evaluate RUN``, ``canonid analyze --run RUN`` and ``canonid export RUN`` read
it. The table of candidates is ``RUN/candidates.json`` (:class:`Selection`) and
``RUN/candidates.md``.

A candidate whose folder holds a finished ``result.json`` of the same recipe (the data by
checksum, not by path) is not trained again, and one with a checkpoint continues from it:
running the same selection again continues an interrupted one.
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from canonid.datagen.loaders import data_checksum
from canonid.jobs import StoredJob, run_job
from canonid.kernel.errors import CheckpointError, DataError, OptionError
from canonid.kernel.io import (
    FIGURE_FORMATS,
    atomic_copy,
    atomic_copy_tree,
    atomic_write_json,
    atomic_write_text,
    read_json,
)
from canonid.learning import NETS
from canonid.learning.training import CHECKPOINT_FILE, CUBIC_ARM_DIR
from canonid.runfolder import (
    FIGURES,
    HISTORY_FILE,
    METRICS_FILE,
    RUN_FILE,
    RunRecipe,
    figure_file,
    load_splits,
    train_run,
)
from canonid.runner import run_jobs

__all__ = [
    "CANDIDATES_DIR",
    "CANDIDATES_FILE",
    "Candidate",
    "CandidateJob",
    "Selection",
    "adopt",
    "allowed_windows",
    "plan_candidates",
    "select",
]

CANDIDATES_FILE = "candidates.json"
CANDIDATES_TABLE = "candidates.md"
CANDIDATES_DIR = "candidates"
SELECTION_FORMAT = "canonid-candidates"
#: the files of the chosen candidate's run that become the run folder's (not its checkpoint:
#: a selection continues by running it again, a candidate by resuming its own folder), its
#: figures in whichever format they were written
ADOPTED = (
    RUN_FILE,
    "config.json",
    "weights.pt",
    "normalisation.json",
    HISTORY_FILE,
    METRICS_FILE,
    *(figure_file(name, fmt) for name in FIGURES for fmt in FIGURE_FORMATS),
)


def candidate_name(window: int, hidden: Sequence[int] | None) -> str:
    """``l10`` or ``l10-h128x3`` (folder names)."""
    if hidden is None:
        return f"l{window}"
    if len(set(hidden)) == 1:
        return f"l{window}-h{hidden[0]}x{len(hidden)}"
    return f"l{window}-h{'-'.join(str(w) for w in hidden)}"


@dataclass(frozen=True)
class CandidateJob(StoredJob):
    """One candidate: train ``run_recipe`` into ``folder`` and score it (:func:`train_run`).
    ``data_sha256`` and ``val_sha256`` are the checksums of its data and validation file
    (:func:`canonid.datagen.loaders.data_checksum`): a stored result is reused for the same
    contents, wherever the files lie, and never for other contents at the same path."""

    folder: str
    run_recipe: RunRecipe
    data_sha256: str
    val_sha256: str | None = None
    eval_horizon: int | None = None
    figure_format: str = "png"
    threads: int | None = None
    kind: ClassVar[str] = "candidate"

    @property
    def hidden(self) -> list[int] | None:
        """The hidden widths set in the recipe (``None``: the network's default)."""
        option = NETS[self.run_recipe.model].hidden_option
        if option is None or option not in self.run_recipe.net_options:
            return None
        return list(self.run_recipe.net_options[option])

    @property
    def name(self) -> str:
        """The folder's name (:func:`candidate_name`)."""
        return self.where.name

    def recipe(self) -> dict[str, Any]:
        """The run's recipe with its data and validation file by checksum, not by path, without
        the command line that asked for it, and the scoring."""
        body = self.run_recipe.to_dict()
        for key in ("command", "data", "val"):
            del body[key]
        return {
            **body,
            "data_sha256": self.data_sha256,
            "val_sha256": self.val_sha256,
            "eval_horizon": self.eval_horizon,
        }

    def work(self) -> dict[str, Any]:
        result = train_run(
            self.run_recipe,
            self.where,
            resume=(self.where / CHECKPOINT_FILE).is_file(),
            eval_horizon=self.eval_horizon,
            figure_format=self.figure_format,
        )
        return {
            "window": self.run_recipe.window,
            "hidden": self.hidden,
            "best_val_loss": result.fit.best_val_loss,
            "best_epoch": result.fit.best_epoch,
            "epochs_run": result.fit.epochs_run,
            "stopped": result.fit.stopped,
            "rollout_mse": result.evaluation.rollout_mse,
            "rollout_mse_clean": result.evaluation.rollout_mse_clean,
            "split": result.evaluation.split,
            "seconds": result.seconds,
        }


@dataclass(frozen=True)
class Candidate:
    """One row of the table of candidates (losses normalised, MSEs in physical units)."""

    name: str
    folder: str
    window: int
    hidden: list[int] | None
    best_val_loss: float
    best_epoch: int
    epochs_run: int
    stopped: str
    rollout_mse: float
    rollout_mse_clean: float | None
    split: str
    seconds: float


@dataclass(frozen=True)
class Selection:
    """The candidates of a selection and the chosen one (lowest ``best_val_loss``; the first
    listed among equals)."""

    candidates: list[Candidate]
    chosen: str
    criterion: str = "best_val_loss"

    @property
    def best(self) -> Candidate:
        return next(c for c in self.candidates if c.name == self.chosen)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": SELECTION_FORMAT,
            "version": 1,
            "criterion": self.criterion,
            "chosen": self.chosen,
            "candidates": [dataclasses.asdict(c) for c in self.candidates],
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> Selection:
        if not isinstance(data, Mapping) or data.get("format") != SELECTION_FORMAT:
            raise CheckpointError(f"{where} is not a canonid table of candidates")
        try:
            rows = [Candidate(**row) for row in data["candidates"]]
            return cls(rows, str(data["chosen"]), str(data["criterion"]))
        except (KeyError, TypeError) as exc:
            raise CheckpointError(f"{where}: malformed table of candidates ({exc})") from exc

    @classmethod
    def read(cls, run_dir: Path) -> Selection:
        path = run_dir / CANDIDATES_FILE
        return cls.from_dict(read_json(path, what="table of candidates"), where=str(path))

    def table(self, *, markdown: bool = True) -> str:
        """The candidates, the chosen one marked: a Markdown table (``candidates.md``), or plain
        text in aligned columns (the terminal). The rollout MSE is the score on the split each
        candidate was scored on (test, or validation when the data have none)."""
        splits = "/".join(sorted({c.split for c in self.candidates}))
        head = ("candidate", "ℓ", "hidden", "best validation loss (normalised)", "at epoch")
        rows = [(*head, f"rollout MSE ({splits})", "y_clean", "chosen")]
        for c in self.candidates:
            hidden = "default" if c.hidden is None else "×".join(str(w) for w in c.hidden)
            clean = "-" if c.rollout_mse_clean is None else f"{c.rollout_mse_clean:.3g}"
            mark = ("**yes**" if markdown else "yes") if c.name == self.chosen else ""
            fit = (c.name, str(c.window), hidden, f"{c.best_val_loss:.4g}", str(c.best_epoch))
            rows.append((*fit, f"{c.rollout_mse:.3g}", clean, mark))
        if markdown:
            lines = [f"| {' | '.join(r)} |" for r in rows]
            return "\n".join([lines[0], "|---" * len(rows[0]) + "|", *lines[1:]])
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


def allowed_windows(base: RunRecipe, windows: Sequence[int], *, screen: bool = False) -> list[int]:
    """The ``windows`` that the data of ``base`` allow: every training and validation record
    holds ℓ + 1 samples, the longest ones the training and validation rollouts after ℓ (for
    the ``screen``, half the validation rollout: :func:`canonid.learning.screen.fitting_windows`),
    and a scored record ℓ + 1; none allowed is a :class:`DataError`."""
    from canonid.learning.screen import fitting_windows

    dataset, train, val, test_name, _ = load_splits(base)
    data_path = base.data
    opts = base.options()
    scored = list(dataset.split(test_name))
    if screen:
        kept = fitting_windows(train, val, windows, opts)
    else:
        kept = [
            ell
            for ell in windows
            if min(t.T for t in [*train, *val]) >= ell + 1
            and max(t.T for t in train) >= ell + opts.horizon
            and max(t.T for t in val) >= ell + opts.rollout_horizon
        ]
    kept = [ell for ell in kept if max(t.T for t in scored) >= ell + 1]
    if not kept:
        rollouts = "half of " * screen + f"validation rollouts {opts.rollout_horizon}"
        raise DataError(
            f"{data_path}: no candidate window of {list(windows)} fits the records (shortest "
            f"training or validation record {min(t.T for t in [*train, *val])} samples, longest "
            f"validation record {max(t.T for t in val)}, training rollouts {opts.horizon}, "
            f"{rollouts})"
        )
    return kept


def plan_candidates(
    base: RunRecipe,
    run_dir: Path,
    *,
    windows: Sequence[int],
    widths: Sequence[Sequence[int] | None] = (None,),
    eval_horizon: int | None = None,
    figure_format: str = "png",
    threads: int | None = None,
) -> list[CandidateJob]:
    """One job per (window, width), in that order, each in ``run_dir/candidates/<name>``;
    a width of ``None`` keeps ``base``'s network options."""
    hidden_option = NETS[base.model].hidden_option
    data_sha256 = data_checksum(base.data)
    val_sha256 = None if base.val is None else data_checksum(base.val)
    jobs = []
    for ell in windows:
        for width in widths:
            net = dict(base.net_options)
            if width is not None:
                if hidden_option is None:
                    raise OptionError(f"{base.model} has no hidden widths to choose")
                net[hidden_option] = list(width)
            recipe = dataclasses.replace(base, window=int(ell), net_options=net)
            name = candidate_name(int(ell), None if width is None else list(width))
            jobs.append(
                CandidateJob(
                    folder=str(run_dir / CANDIDATES_DIR / name),
                    run_recipe=recipe,
                    data_sha256=data_sha256,
                    val_sha256=val_sha256,
                    eval_horizon=eval_horizon,
                    figure_format=figure_format,
                    threads=threads,
                )
            )
    return jobs


def select(
    jobs: Sequence[CandidateJob],
    run_dir: Path,
    *,
    workers: int = 0,
    scheduler: str | None = None,
    progress: bool = True,
) -> Selection:
    """Run the candidates through :func:`canonid.runner.run_jobs`, choose the lowest best
    validation loss, make its run the model of ``run_dir`` and write the table of candidates
    (see the module docstring). A candidate folder of another recipe is refused before any
    candidate runs."""
    for job in jobs:
        job.cached()
    outcomes = run_jobs(
        run_job,
        list(jobs),
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        description="candidates",
    )
    rows = [
        Candidate(name=job.name, folder=job.folder, **outcome.result)
        for job, outcome in zip(jobs, outcomes)
    ]
    best = min(rows, key=lambda c: c.best_val_loss)  # the first of equals
    selection = Selection(rows, best.name)
    adopt(Path(best.folder), run_dir)
    atomic_write_json(run_dir / CANDIDATES_FILE, selection.to_dict())
    atomic_write_text(
        run_dir / CANDIDATES_TABLE,
        f"# Candidates (chosen on {selection.criterion}: {best.name})\n\n{selection.table()}\n",
    )
    return selection


def adopt(source: Path, run_dir: Path, *, checkpoint: bool = False) -> None:
    """Copy the chosen candidate's run files into ``run_dir`` (each replaced atomically);
    ``checkpoint``: its checkpoint too, first, so that ``--resume`` continues the adopted run
    (the window screen's full runs, :func:`canonid.training.train`), and its cubic branch's
    folder (:data:`~canonid.learning.training.CUBIC_ARM_DIR`) with it, which that resume
    continues too."""
    if checkpoint:  # replaced whole: the branch of the run adopted over is no longer it
        if (source / CUBIC_ARM_DIR).is_dir():
            atomic_copy_tree(source / CUBIC_ARM_DIR, run_dir / CUBIC_ARM_DIR)
        else:
            shutil.rmtree(run_dir / CUBIC_ARM_DIR, ignore_errors=True)
    for name in ((CHECKPOINT_FILE,) if checkpoint else ()) + ADOPTED:
        if (source / name).is_file():
            atomic_copy(source / name, run_dir / name)
