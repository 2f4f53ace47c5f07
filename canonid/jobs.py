"""One job abstraction for the batches of :func:`canonid.runner.run_jobs`: Table-1 training,
system analyses, reductions and the candidates of ``canonid train --window auto``; and the
worker processes in which short trainings run side by side (:func:`candidate_pool`).

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

:func:`run_folder_lock` is the one lock of a run folder: every command that writes one (``train``
and ``--resume``, ``benchmark``, ``reduce``, the candidates of ``--window auto``, ``evaluate``)
holds it while it writes, so a second writer is refused in one line naming the holder instead
of mixing its files with the first one's.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shlex
import socket
import sys
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from concurrent.futures import Executor
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from canonid.kernel.errors import CheckpointError, OptionError, OutputError, WorkerError
from canonid.kernel.io import (
    atomic_write_json,
    confined,
    guarded,
    jsonable,
    read_json,
    remove_stale_temporaries,
)

__all__ = [
    "LOCK_FILE",
    "POOL_MIN_STEPS",
    "RESULT_FILE",
    "Job",
    "JobOutcome",
    "StoredJob",
    "available_cores",
    "candidate_pool",
    "check_folder",
    "check_run_folder",
    "finished",
    "is_canonid_folder",
    "resume_target",
    "run_folder_lock",
    "run_job",
    "store",
    "torch_threads",
    "writer_of",
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


#: the fewest optimiser steps per short training for which :func:`candidate_pool` starts worker
#: processes: a worker imports torch first (a second or two of CPU), which a training of a few
#: hundred steps of the default network repays many times, and a test's single-epoch one does not
POOL_MIN_STEPS = 200


def available_cores() -> int:
    """The CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def candidate_pool(
    threads: int | None, *, steps: int, candidates: int, device: str = "cpu"
) -> Iterator[Executor | None]:
    """Worker processes of one torch thread each, for independent short trainings that train
    side by side (the candidates of a search's rung, the members): one per thread the run
    may use (``threads``; default every core), at most ``candidates``; ``None`` — train them one
    after the other in this process — with one thread or when each trains for fewer than
    :data:`POOL_MIN_STEPS` optimiser steps (``steps``), or when they may train on a GPU
    (``device`` not ``cpu`` on a machine with one: the GPU is shared by one process, not by a
    context per worker). A candidate in a worker gives what it gives alone with ``--threads 1``.
    Workers start at the first candidate (spawned: a fresh interpreter, no state of this one's
    threads) and stop when the block ends."""
    workers = min(threads if threads is not None else available_cores(), candidates)
    if workers < 2 or steps < POOL_MIN_STEPS or (device != "cpu" and _gpu()):
        yield None
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_one_thread,
    )
    try:
        yield pool
    except BrokenProcessPool as exc:
        pool.shutdown(wait=False, cancel_futures=True)
        raise WorkerError(
            f"a worker process of the {workers} that train side by side ended abruptly (killed "
            "by the system, most often for lack of memory); run the command again with "
            "--threads 1 to train one candidate at a time in this process, or with more memory"
        ) from exc
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)  # Ctrl-C reaches the workers too
        raise
    pool.shutdown(wait=True)


def _gpu() -> bool:
    import torch

    return torch.cuda.is_available()


def _one_thread() -> None:
    """A candidate worker's start: one torch thread (the cores are the workers'), and on Linux
    the end of the worker with its parent (a killed command leaves no training running)."""
    import torch

    torch.set_num_threads(1)
    if sys.platform.startswith("linux"):
        import ctypes
        import signal

        try:  # prctl(PR_SET_PDEATHSIG, SIGTERM)
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)
        except (AttributeError, OSError):  # no prctl here: the worker ends after its candidate
            pass


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


def resume_target(resume: str | bool | None, out: Path | None) -> tuple[Path | None, Path | None]:
    """The run to continue and the new run's folder, from ``--resume [RUN]`` and ``--out``:
    ``--resume`` continues the run in ``--out`` (then there is no new folder); the former
    spelling ``--resume RUN`` the run in RUN; without ``--resume``, ``--out`` is the new run's."""
    if resume is None or resume is False:
        return None, out
    if resume is not True:  # --resume RUN
        return Path(resume), out
    if out is None:
        raise OptionError("--resume continues the run in --out: give --out RUN")
    return out, None


#: the lock file of a run folder (:func:`run_folder_lock`): it stays, empty but while held
LOCK_FILE = ".canonid.lock"
#: the names whose ``format`` field marks a folder as canonid's (a run written before the lock)
_CANONID_FILES = ("run.json", "candidates.json", RESULT_FILE)
#: the run folders this process holds: real path -> (pid, thread) of the holder; the thread that
#: holds a folder may take it again (``benchmark`` holds its folder and trains into it)
_HELD: dict[str, tuple[int, int]] = {}


def is_canonid_folder(folder: Path) -> bool:
    """Whether ``folder`` was written by canonid: it holds :data:`LOCK_FILE`, or a
    ``run.json``, ``candidates.json`` or ``result.json`` whose ``format`` is canonid's."""
    if (folder / LOCK_FILE).is_file():
        return True
    for name in _CANONID_FILES:
        try:
            body = json.loads((folder / name).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(body, dict) and str(body.get("format", "")).startswith("canonid-"):
            return True
    return False


def check_run_folder(folder: Path, *, flag: str = "--out", own: tuple[str, ...] = ()) -> Path:
    """``folder`` if a new run may be written there: a new or empty folder, or one canonid
    wrote (:func:`is_canonid_folder`, or holding one of ``own``: the names the command writes
    there, e.g. ``dataset.json``); a folder holding other files is refused in one line,
    as the run's files would replace the user's files of the same names."""
    check_folder(folder, flag=flag)
    try:
        names = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    except OSError as exc:
        raise OutputError(f"{flag} {folder}: cannot read the folder ({exc.strerror})") from exc
    if names and not set(own) & set(names) and not is_canonid_folder(folder):
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        raise OutputError(
            f"{flag} {folder} is a folder with files canonid did not write ({shown}); a run "
            "would replace those of the same names: choose a new or empty folder"
        )
    return folder


@contextlib.contextmanager
def run_folder_lock(folder: Path, *, new: bool = False, flag: str = "--out") -> Iterator[Path]:
    """Hold the exclusive lock of run folder ``folder`` while the block writes it.

    The folder is made if missing (and removed again at the end, with the parents made for it,
    when nothing but the lock file was written). The lock is ``flock`` on :data:`LOCK_FILE`,
    taken without waiting: a folder another process holds is refused with an
    :class:`OutputError` naming that process (its pid, host, command and start, which the
    holder writes into the lock file); the kernel drops the lock when its holder ends, even by
    ``kill -9``. Once held, the temporary files that a killed writer left in the folder are
    removed. ``new``: the folder receives a new run, so a folder of the user's own files is
    refused (:func:`check_run_folder`), checked again under the lock.
    """
    (check_run_folder if new else check_folder)(folder, flag=flag)
    guarded(folder)  # below a run being written (members/sS, horizon-H): no link followed
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{flag} {folder}: {exc.strerror} (cannot create the folder)") from exc
    key = os.path.realpath(folder)
    me = (os.getpid(), threading.get_ident())
    if _HELD.get(key) == me:  # this thread holds it already (a benchmark trains into its folder)
        with confined(folder):
            yield folder
        return
    fd = _acquire(folder, flag=flag)
    _HELD[key] = me
    try:
        remove_stale_temporaries(folder, before=time.time())
        if new:
            check_run_folder(folder, flag=flag)  # another run may have been written meanwhile
        with confined(folder):  # no link below the folder is followed while it is written
            yield folder
    finally:
        del _HELD[key]
        try:
            if missing and [p.name for p in folder.iterdir()] == [LOCK_FILE]:
                (folder / LOCK_FILE).unlink()
                for made in missing:  # the folder first, then the parents made for it
                    made.rmdir()
        except OSError:
            pass  # something else lives there now: leave it
        finally:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)  # no holder: the file is empty until the next one
            os.close(fd)


def _acquire(folder: Path, *, flag: str) -> int:
    """The descriptor of ``folder``'s lock file, locked exclusively (see
    :func:`run_folder_lock`)."""
    path = folder / LOCK_FILE
    for _ in range(5):
        try:
            # O_NOFOLLOW: a symlink planted at the lock's name is refused, never written through
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            why = "it is a symbolic link" if exc.errno == errno.ELOOP else exc.strerror
            raise OutputError(f"{flag} {folder}: cannot open the lock file {path}: {why}") from exc
        links = os.fstat(fd).st_nlink
        if links > 1:  # a hard link to a file elsewhere: never locked, written or truncated
            os.close(fd)
            raise OutputError(
                f"{flag} {folder}: the lock file {path} has {links} hard links (the same file "
                "elsewhere too); remove it"
            )
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _holder(fd)
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise OutputError(f"{flag} {folder}: cannot lock {path}: {exc.strerror}") from exc
            raise OutputError(
                f"{folder} is being written by another canonid process ({holder}); wait for it "
                "to finish, or choose another folder"
            ) from None
        try:  # a holder that ended may have removed the file we opened: lock the one there
            same = os.stat(path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if same:
            _write_holder(fd)
            return fd
        os.close(fd)
    raise OutputError(f"{flag} {folder}: the lock file {path} keeps changing; try again")


def writer_of(folder: Path) -> str | None:
    """Who holds ``folder``'s lock now (pid, host, start and command, as a refused writer is
    told), or ``None`` when no process does; the lock file is opened read-only, never through
    a link, and nothing is written."""
    try:
        fd = os.open(folder / LOCK_FILE, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as exc:
        return _holder(fd) if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES) else None
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _write_holder(fd: int) -> None:
    """Record who holds the lock (what a refused writer is told)."""
    body = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "command": shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    data = (json.dumps(body, sort_keys=True) + "\n").encode("utf-8")
    os.ftruncate(fd, 0)
    os.pwrite(fd, data, 0)


def _holder(fd: int) -> str:
    """Who holds the lock, from the lock file: ``pid 12 on host, since …: canonid train …``."""
    try:
        body = json.loads(os.pread(fd, 1 << 16, 0).decode("utf-8"))
        return (
            f"pid {int(body['pid'])} on {body['host']}, since {body['started']}: {body['command']}"
        )
    except (OSError, ValueError, KeyError, TypeError):
        return "which has not yet said who it is"
