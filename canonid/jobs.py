"""One job abstraction for the batches of :func:`canonid.runner.run_jobs`: Table-1 training,
system analyses, reductions and the candidates of ``canonid train --window auto``.

A job is a frozen dataclass (picklable, so Dask can send it to a worker) with a ``name``, a
``folder``, a ``recipe()`` — everything that determines its result — and ``run()``, written here
once: ``run`` returns the stored result when the folder holds one for the same recipe
(:meth:`Job.cached`), else does the job's :meth:`Job.work` with ``threads`` torch CPU threads
(restored afterwards) and stores its result (:meth:`Job.save`). The runner retries a job that
raised once and shows the progress.

:class:`StoredJob` stores its result in ``folder/result.json`` (:func:`store`), written last and
atomically (so a file that exists is complete); a ``result.json`` of another recipe is an error:
the folder belongs to another run. :func:`check_folder` refuses an output folder that a file
stands in the way of, before any job runs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from canonid.kernel.errors import CheckpointError, OutputError
from canonid.kernel.io import atomic_write_json, jsonable, read_json

__all__ = [
    "RESULT_FILE",
    "Job",
    "JobOutcome",
    "StoredJob",
    "check_folder",
    "finished",
    "run_job",
    "store",
    "torch_threads",
]

RESULT_FILE = "result.json"
RESULT_FORMAT = "canonid-reproduce-job"

R = TypeVar("R")


@dataclass(frozen=True)
class JobOutcome:
    """What a :class:`StoredJob` returns: its kind, its recipe, its result (JSON-ready) and
    whether it ran now (``False``: read back from a finished ``result.json``)."""

    kind: str
    name: str
    folder: str
    recipe: dict[str, Any]
    result: dict[str, Any]
    ran: bool


def finished(folder: Path, recipe: Mapping[str, Any]) -> JobOutcome | None:
    """The outcome stored in ``folder/result.json`` if it holds ``recipe``; ``None`` if there
    is none; a result of another recipe is an error (the folder belongs to another run)."""
    path = folder / RESULT_FILE
    if not path.is_file():
        return None
    stored = read_json(path, what="job result")
    if not isinstance(stored, dict) or stored.get("format") != RESULT_FORMAT:
        raise CheckpointError(f"{path} is not a canonid job result")
    if stored.get("recipe") != jsonable(dict(recipe)):
        differs = sorted(
            k
            for k in {*recipe, *stored.get("recipe", {})}
            if stored.get("recipe", {}).get(k) != jsonable(recipe.get(k))
        )
        raise CheckpointError(
            f"{path} was made with another recipe (differs in {differs}); write into another "
            "--out, or remove that folder"
        )
    return JobOutcome(
        kind=stored["kind"],
        name=stored["name"],
        folder=str(folder),
        recipe=stored["recipe"],
        result=stored["result"],
        ran=False,
    )


def store(kind: str, name: str, folder: Path, recipe: Mapping[str, Any], result: Any) -> JobOutcome:
    """Write ``folder/result.json`` (recipe and result, atomically: the job's last act)."""
    body = {
        "format": RESULT_FORMAT,
        "kind": kind,
        "name": name,
        "recipe": jsonable(dict(recipe)),
        "result": jsonable(result),
    }
    atomic_write_json(folder / RESULT_FILE, body)
    return JobOutcome(kind, name, str(folder), body["recipe"], body["result"], ran=True)


class torch_threads:
    """Set torch's CPU threads for a job, then restore them (a job must not starve its
    neighbours on a shared machine, nor leave a worker changed); ``None`` leaves them."""

    def __init__(self, threads: int | None) -> None:
        self.threads = threads
        self.previous: int | None = None

    def __enter__(self) -> None:
        if self.threads is not None:
            import torch

            self.previous = torch.get_num_threads()
            torch.set_num_threads(self.threads)

    def __exit__(self, *exc: object) -> None:
        if self.previous is not None:
            import torch

            torch.set_num_threads(self.previous)


class Job(ABC, Generic[R]):
    """A job of :func:`canonid.runner.run_jobs` (see the module docstring). Subclasses are
    frozen dataclasses with a field ``threads``."""

    threads: int | None

    @property
    @abstractmethod
    def name(self) -> str:
        """A short human name (progress and failure reports)."""

    @property
    @abstractmethod
    def where(self) -> Path:
        """The job's folder."""

    @abstractmethod
    def recipe(self) -> dict[str, Any]:
        """Everything that determines the result (what a stored result must match)."""

    @abstractmethod
    def cached(self) -> R | None:
        """The result stored in the folder for this recipe, else ``None``."""

    @abstractmethod
    def work(self) -> Any:
        """Do the job's work into its folder; what :meth:`save` stores."""

    @abstractmethod
    def save(self, result: Any) -> R:
        """Store ``result`` in the folder; the job's return value."""

    def run(self) -> R:
        """The stored result for this recipe, else the job done now and stored."""
        done = self.cached()
        if done is not None:
            return done
        with torch_threads(self.threads):
            result = self.work()
        return self.save(result)


class StoredJob(Job[JobOutcome]):
    """A job whose result is a JSON mapping stored in ``folder/result.json`` with its kind;
    subclasses have a field ``folder``."""

    kind: ClassVar[str]
    folder: str

    @property
    def where(self) -> Path:
        return Path(self.folder)

    def cached(self) -> JobOutcome | None:
        return finished(self.where, self.recipe())

    def save(self, result: Any) -> JobOutcome:
        return store(self.kind, self.name, self.where, self.recipe(), result)


def run_job(job: Job[R]) -> R:
    """Run one job (the function :func:`canonid.runner.run_jobs` sends to workers)."""
    return job.run()


def check_folder(path: Path, *, flag: str = "--out") -> Path:
    """``path`` if it is a folder or can become one; else :class:`OutputError` naming the file
    in the way (``path`` itself or one of its parents), checked before any work is done."""
    for part in (path, *path.parents):
        if part.exists():
            if not part.is_dir():
                what = "is a file" if part == path else f"lies below the file {part}"
                raise OutputError(f"{flag} {path} {what}; expected a folder")
            break
    return path
