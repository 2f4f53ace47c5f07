"""One runner for every batch of independent jobs (dataset flights, sweeps, reproduction).

API::

    run_jobs(fn, jobs, *, workers=0, scheduler=None, progress=True, description="jobs",
             on_result=None, tally=None, tally_name="failures", retries=1,
             connect_timeout=5.0, processes=True, batch=1) -> list

* ``workers=0`` and no ``scheduler``: the jobs run one after the other in this process.
* ``workers=N`` (N ≥ 1): a Dask ``LocalCluster`` of N single-threaded workers (processes, or
  threads with ``processes=False``) is started for the call and closed after it, with Dask's
  dashboard bookkeeping (:data:`LOCAL_CLUSTER_CONFIG`) turned down: with no dashboard to show
  them, the task profiler and the fast monitors only took CPU from the jobs.
* ``scheduler="tcp://host:8786"``: an existing Dask cluster; its workers must be able to import
  ``fn`` (install canonid there). An address that does not answer within ``connect_timeout``
  seconds raises :class:`RunnerError` before any job runs.

The three go through one loop: jobs are submitted to a ``concurrent.futures``-style executor (an
inline one, or ``dask.distributed.Client.get_executor``), a bounded number at a time, and are
collected as they complete. ``on_result(position, result)`` is called in this process as each
job finishes (generation writes its resumable parts there); the return value is the list of
results in job order. A job that raises is retried ``retries`` times (not for a
:class:`~canonid.kernel.errors.CanonidError`, which is deterministic); if it still fails, the
other jobs finish and :class:`JobsFailedError` lists every failed job with its error — a job is
never dropped silently. The progress bar (tqdm, on stderr) shows jobs done, the sum of
``tally(result)`` over finished jobs as ``tally_name`` (e.g. solver failures), failed attempts
and the ETA; ``progress=False`` switches it off. ``fn`` and the jobs must be picklable for the
Dask paths.

``batch=k`` (k > 1) sends up to k jobs in one Dask task, for many short jobs (dataset flights of
~0.15 s, where each task cost the main process ~3 ms of scheduler and client time): a task runs
its jobs one after the other and returns each job's result or error, which are then handled
job by job as above (``on_result``, retries, failures). Tasks are ``min(k, remaining jobs //
(2 · jobs in flight))`` jobs long, so that they shrink to single jobs towards the end and no
worker waits on a long last task. Serially, jobs always run one by one.
"""

from __future__ import annotations

import asyncio
import concurrent.futures as cf
import logging
import pickle
import signal
import socket
import sys
import threading
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

from tqdm.auto import tqdm

from canonid.kernel.errors import CanonidError

__all__ = [
    "LOCAL_CLUSTER_CONFIG",
    "EpochBar",
    "FailedJob",
    "JobsFailedError",
    "RunnerError",
    "run_jobs",
]

log = logging.getLogger(__name__)

#: Dask settings of the local clusters: no statistical profiler of the running tasks (it
#: samples their stacks every 10 ms for the dashboard), event-loop health ticks every second
#: (not 20 ms), system and memory monitors every 2 s and 1 s (not 0.5 s and 0.1 s): less CPU
#: spent beside the jobs on a small machine.
LOCAL_CLUSTER_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}

J = TypeVar("J")
R = TypeVar("R")


class RunnerError(CanonidError, RuntimeError):
    """The runner could not start (bad arguments, a scheduler that does not answer)."""


@dataclass(frozen=True)
class FailedJob:
    """A job that still failed after its retries."""

    position: int
    job: str
    error: str
    traceback: str


class JobsFailedError(CanonidError, RuntimeError):
    """Some jobs failed after their retries; ``failures`` says which and why."""

    def __init__(self, failures: Sequence[FailedJob], total: int) -> None:
        self.failures = tuple(failures)
        first = self.failures[0]
        super().__init__(
            f"{len(self.failures)} of {total} jobs failed after retrying; first: job "
            f"{first.position} ({first.job}): {first.error}"
        )


def _run_batch(
    fn: Callable[[Any], Any], jobs: Sequence[Any], travels: bool
) -> list[tuple[bool, Any, str]]:
    """The task of a batch: ``(True, result, "")`` or ``(False, error, traceback text)`` per
    job, in order; the traceback is formatted here because it does not survive pickling, and an
    error that must ``travel`` back from a worker but does not pickle is replaced by its text."""
    outcomes: list[tuple[bool, Any, str]] = []
    for job in jobs:
        try:
            outcomes.append((True, fn(job), ""))
        except Exception as exc:  # handled job by job in run_jobs, like a future's exception
            text = "".join(traceback.format_exception(exc))
            try:
                if travels:
                    pickle.loads(pickle.dumps(exc))
            except Exception:  # an error that cannot travel back: its type and text do
                exc = RuntimeError(f"{type(exc).__name__}: {exc}")
            outcomes.append((False, exc, text))
    return outcomes


def _batch_size(remaining: int, window: int, batch: int) -> int:
    """Jobs in the next task: up to ``batch``, fewer as the queue runs out (module docs)."""
    return max(1, min(batch, remaining // (2 * window)))


class _InlineExecutor(cf.Executor):
    """Runs each submitted call at once, in this thread; returns a finished future."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future[Any]:
        future: cf.Future[Any] = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:  # reported through the future, like any executor
            future.set_exception(exc)
        return future


@contextmanager
def _dask_logs_at_warning() -> Iterator[None]:
    """Dask's scheduler logs every connection at INFO; keep them out of the user's terminal
    unless debug logging is on."""
    logger = logging.getLogger("distributed")
    old = logger.level
    _dask_at_warning()
    try:
        yield
    finally:
        logger.setLevel(old)


def _dask_at_warning() -> None:
    if logging.getLogger().getEffectiveLevel() > logging.DEBUG:
        logging.getLogger("distributed").setLevel(logging.WARNING)


def _probe_scheduler(address: str, timeout: float) -> None:
    """Open and close one Dask connection (handshake included) to ``address`` in a thread of
    its own, raising :class:`RunnerError` within about ``timeout`` seconds if it fails.

    Done before ``Client(address)`` because a client whose construction fails hangs for tens
    of seconds when it is garbage-collected.
    """
    from distributed.comm import connect
    from distributed.comm.addressing import get_address_host_port, parse_address

    try:  # the form first: a malformed address is no timeout
        if parse_address(address)[0] in ("tcp", "tls"):
            get_address_host_port(address)
    except ValueError as exc:
        raise RunnerError(
            f"the Dask scheduler address {address!r} is malformed ({exc}); expected the address "
            "of a running scheduler, e.g. tcp://host:8786"
        ) from None

    async def handshake() -> None:
        if parse_address(address)[0] in ("tcp", "tls"):  # refused: fail now, not after timeout
            socket.create_connection(get_address_host_port(address), timeout=timeout).close()
        comm = await connect(address, timeout=timeout)
        await comm.close()

    try:
        with cf.ThreadPoolExecutor(1) as pool:
            pool.submit(asyncio.run, asyncio.wait_for(handshake(), timeout + 1)).result(
                timeout=timeout + 2
            )
    except Exception as exc:  # any failure (refused, timeout, garbage, bad address) is one error
        what = (
            "refused the connection (nothing listens there)"
            if isinstance(exc, ConnectionRefusedError)
            else f"did not answer within {timeout:g} s"
        )
        raise RunnerError(
            f"the Dask scheduler at {address!r} {what} ({type(exc).__name__}: {exc}); "
            "expected the address of a running scheduler, e.g. tcp://host:8786"
        ) from exc


@contextmanager
def _ctrl_c_deferred() -> Iterator[list[bool]]:
    """Start a local cluster with Ctrl-C deferred: the yielded list turns true when it was
    pressed, and a start-up failure it caused becomes the KeyboardInterrupt.

    In this process a handler only notes the key (raising in the middle of Dask's start-up
    leaves a half-built cluster that cannot be closed; ignoring it, as before, lost it).
    SIGINT is also blocked in this thread meanwhile: worker processes started from threads
    created now inherit the blocked signal and never see Ctrl-C (those started otherwise
    ignore it from :func:`dask_setup` on), so that it interrupts only this process.
    """
    pressed: list[bool] = []
    if threading.current_thread() is not threading.main_thread():
        yield pressed
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pressed.append(True))
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})

    def restore() -> None:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)  # a pending Ctrl-C is noted here
        signal.signal(signal.SIGINT, previous)

    try:
        yield pressed
    except Exception:
        restore()
        if pressed:
            raise KeyboardInterrupt from None
        raise
    restore()


@contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt here, as Ctrl-C does, so that the cluster is closed on
    the way out instead of leaving its worker processes and semaphores behind."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt("terminated (SIGTERM)")

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def dask_setup(worker: Any) -> None:
    """Dask preload of the local workers (this module): they ignore Ctrl-C, so that it
    interrupts only the main process, which then closes the cluster cleanly."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def cluster_executor(
    workers: int, scheduler: str | None, *, connect_timeout: float, processes: bool
) -> Iterator[tuple[cf.Executor, int]]:
    """An executor and how many jobs to keep in flight on it."""
    if scheduler is None and workers == 0:
        yield _InlineExecutor(), 1
        return

    with _dask_logs_at_warning():
        cluster = None
        if scheduler is not None:
            from dask.distributed import Client

            _probe_scheduler(scheduler, connect_timeout)
            client = Client(scheduler, timeout=connect_timeout, set_as_default=False)
        else:
            with _ctrl_c_deferred() as pressed, warnings.catch_warnings():
                # imported here: the threads Dask starts at import inherit the blocked SIGINT
                import dask
                from dask.distributed import Client, LocalCluster

                _dask_at_warning()  # the first import sets Dask's configured levels
                # the scheduler's HTTP server moves to a free port when 8787 is taken: not news
                warnings.filterwarnings("ignore", message="Port .* is already in use")
                # read when the scheduler, nannies and workers are built (workers get a copy)
                with dask.config.set(LOCAL_CLUSTER_CONFIG):
                    cluster = LocalCluster(
                        n_workers=workers,
                        threads_per_worker=1,
                        processes=processes,
                        dashboard_address=None,
                        silence_logs=logging.CRITICAL,  # job errors come back through futures
                        preload=[__name__] if processes else [],
                    )
                    client = Client(cluster, set_as_default=False)
            if pressed:
                client.close()
                cluster.close()
                raise KeyboardInterrupt
        try:
            with _sigterm_interrupts():
                threads = sum(client.nthreads().values()) or 1
                yield client.get_executor(pure=False), 2 * threads
        except KeyboardInterrupt:
            # closing a cluster mid-job makes Dask log cancelled tasks as errors: not news
            logging.getLogger("distributed").setLevel(logging.CRITICAL)
            raise
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def run_jobs(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    *,
    workers: int = 0,
    scheduler: str | None = None,
    progress: bool = True,
    description: str = "jobs",
    on_result: Callable[[int, R], None] | None = None,
    tally: Callable[[R], int] | None = None,
    tally_name: str = "failures",
    retries: int = 1,
    connect_timeout: float = 5.0,
    processes: bool = True,
    batch: int = 1,
) -> list[R]:
    """Run ``fn(job)`` for every job; see the module docstring for the three ways and the
    failure rules. Returns the results in job order."""
    if workers < 0 or int(workers) != workers:
        raise RunnerError(f"workers must be an integer >= 0, got {workers!r}")
    if scheduler is not None and workers:
        raise RunnerError("give either workers (a local cluster) or a scheduler address, not both")
    if retries < 0:
        raise RunnerError(f"retries must be >= 0, got {retries}")
    if batch < 1 or int(batch) != batch:
        raise RunnerError(f"batch must be an integer >= 1, got {batch!r}")
    if scheduler is not None and not scheduler.strip():
        raise RunnerError("the scheduler address is empty (expected e.g. tcp://host:8786)")

    total = len(jobs)
    results: list[Any] = [None] * total
    attempts = [0] * total
    failed: list[FailedJob] = []
    tallied = 0
    retried = 0
    if total == 0:
        return []
    bar = None  # shown once the executor runs, so that a failed start prints one line
    try:
        with cluster_executor(
            int(workers), scheduler, connect_timeout=connect_timeout, processes=processes
        ) as (executor, window):
            bar = tqdm(total=total, desc=description, unit="job", disable=not progress, leave=True)
            queue = list(range(total - 1, -1, -1))  # pop() from the end: job order
            inline = isinstance(executor, _InlineExecutor)
            most = 1 if inline else int(batch)
            running: dict[cf.Future[Any], list[int]] = {}
            while queue or running:
                while queue and len(running) < window:
                    size = _batch_size(len(queue), window, most)
                    positions = [queue.pop() for _ in range(size)]
                    for position in positions:
                        attempts[position] += 1
                    task = executor.submit(_run_batch, fn, [jobs[p] for p in positions], not inline)
                    running[task] = positions
                done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
                for future in sorted(done, key=lambda f: running[f][0]):
                    positions = running.pop(future)
                    exc = future.exception()
                    if exc is None:
                        outcomes = future.result()
                    else:  # the task itself failed (e.g. its worker died): each of its jobs did
                        text = "".join(traceback.format_exception(exc))
                        outcomes = [(False, exc, text)] * len(positions)
                    for position, (ok, value, text) in zip(positions, outcomes, strict=True):
                        if not ok:
                            # canonid's own errors are deterministic: a retry would fail the same
                            if attempts[position] <= retries and not isinstance(
                                value, CanonidError
                            ):
                                retried += 1
                                log.warning("job %d failed (%s); retrying", position, value)
                                queue.append(position)
                            else:
                                failed.append(_failure(position, jobs[position], value, text))
                                bar.update(1)
                        else:
                            results[position] = value
                            if on_result is not None:
                                on_result(position, value)
                            if tally is not None:
                                tallied += int(tally(value))
                            bar.update(1)
                    bar.set_postfix(
                        {tally_name: tallied, "retried": retried, "failed": len(failed)},
                        refresh=False,
                    )
    finally:
        if bar is not None:
            bar.close()
    if failed:
        raise JobsFailedError(sorted(failed, key=lambda f: f.position), total)
    return results


def _failure(position: int, job: Any, exc: BaseException, text: str) -> FailedJob:
    name = getattr(job, "name", None) or repr(job)[:80]
    return FailedJob(
        position=position, job=str(name), error=f"{type(exc).__name__}: {exc}", traceback=text
    )


class EpochBar:
    """A progress bar over the epochs of one training, created at the first :meth:`show` (never
    when disabled), so that an error raised before any work is done prints alone, as one line."""

    def __init__(self, desc: str, *, enabled: bool, **options: Any) -> None:
        self.desc, self.enabled, self.options = desc, enabled, options
        self._bar: Any = None

    def show(self, epoch: int, total: int, postfix: str) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            self._bar = tqdm(
                total=total, desc=self.desc, unit="epoch", file=sys.stderr, **self.options
            )
        self._bar.n = epoch
        self._bar.set_postfix_str(postfix)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
