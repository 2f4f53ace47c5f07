"""Short trainings side by side (canonid.jobs.candidate_pool): the window screen's candidates
and the cubic test's arms, trained in worker processes of one torch thread each, give what they
give one after the other with one thread — the same table, the same losses — and a run with
one thread, or with trainings too short to repay a worker, starts none."""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor

import pytest
import torch

from canonid.jobs import POOL_MIN_STEPS, _one_thread, candidate_pool
from canonid.kernel.errors import WorkerError
from canonid.learning.extrapolation import cubic_test
from canonid.learning.screen import screen_windows
from canonid.learning.training import TrainOptions, fit
from tests.learning_helpers import damped_split
from tests.test_cubic_branch import _bursty

OPTS = TrainOptions(
    epochs=60, batch_size=8, windows_per_epoch=16, horizon=6, val_horizon=10, val_every=2
)
NET = {"hidden": [8, 8], "cubic": 0}


@pytest.fixture(scope="module")
def workers():
    """Two spawned workers of one thread each, as candidate_pool starts them."""
    pool = ProcessPoolExecutor(
        max_workers=2, mp_context=multiprocessing.get_context("spawn"), initializer=_one_thread
    )
    yield pool
    pool.shutdown()


@pytest.fixture
def one_thread():
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


def _rows(screen):
    return [dataclasses.replace(row, cpu_seconds=0.0) for row in screen.candidates]


def test_the_screen_in_workers_chooses_what_it_chooses_alone(workers, one_thread):
    train, val = damped_split()
    kw = dict(windows=[2, 4, 6], options=OPTS, net_options=NET)
    seen: list[int] = []
    alone = screen_windows(train, val, **kw)
    side_by_side = screen_windows(
        train, val, **kw, executor=workers, progress=lambda i, row: seen.append(i)
    )
    assert _rows(side_by_side) == _rows(alone) and side_by_side.chosen == alone.chosen
    assert seen == [0, 1, 2]  # reported in the candidates' order
    assert all(row.cpu_seconds > 0 for row in side_by_side.candidates)  # each worker's own CPU time


def test_the_cubic_test_in_workers_gives_the_losses_of_its_arms_alone(workers, one_thread):
    opts = dataclasses.replace(OPTS, epochs=20)
    kw = dict(window=3, options=opts, net_options={"hidden": [8]}, fit=fit)
    alone = cubic_test(_bursty(1, 2, 900), **kw)
    side_by_side = cubic_test(_bursty(1, 2, 900), **kw, executor=workers)
    assert alone.plain_losses and alone.reason is None
    assert side_by_side == alone


def test_the_arms_are_submitted_pair_first_then_the_rest_at_once():
    from types import SimpleNamespace

    batches: list[int] = []

    class Counting(ThreadPoolExecutor):
        def submit(self, fn, *args, **kwargs):
            batches.append(args[-1])  # the seed
            return super().submit(fn, *args, **kwargs)

    def ratio_one(*args, **kwargs):  # never decisive: all three pairs
        return SimpleNamespace(best_val_loss=1.0)

    opts = TrainOptions(epochs=20, horizon=6, val_horizon=10, seed=4)
    with Counting(max_workers=2) as pool:
        test = cubic_test(
            _bursty(1, 2, 900),
            window=3,
            options=opts,
            net_options={},
            fit=ratio_one,
            executor=pool,
        )
    assert batches == [4, 4, 5, 5, 6, 6] and test.seeds == (4, 5, 6)


@pytest.mark.parametrize(
    ("threads", "steps", "candidates", "workers"),
    [
        (1, 10_000, 4, None),  # one thread: one after the other, as before
        (4, POOL_MIN_STEPS - 1, 4, None),  # too short to repay starting a worker
        (4, POOL_MIN_STEPS, 3, 3),  # no more workers than candidates
        (2, POOL_MIN_STEPS, 4, 2),  # no more workers than threads
    ],
)
def test_the_pool_has_one_worker_per_thread_when_it_pays(threads, steps, candidates, workers):
    with candidate_pool(threads, steps=steps, candidates=candidates) as pool:
        if workers is None:
            assert pool is None
        else:
            assert isinstance(pool, Executor) and pool._max_workers == workers
            assert not pool._processes  # none started before the first candidate


def test_no_pool_where_the_trainings_may_use_a_gpu(monkeypatch):
    import canonid.jobs

    monkeypatch.setattr(canonid.jobs, "_gpu", lambda: True)
    for device in ("auto", "cuda"):
        with candidate_pool(4, steps=POOL_MIN_STEPS, candidates=4, device=device) as pool:
            assert pool is None
    with candidate_pool(4, steps=POOL_MIN_STEPS, candidates=4, device="cpu") as pool:
        assert pool is not None
    monkeypatch.setattr(canonid.jobs, "_gpu", lambda: False)  # `auto` on a machine without one
    with candidate_pool(4, steps=POOL_MIN_STEPS, candidates=4, device="auto") as pool:
        assert pool is not None


def test_a_worker_trains_with_one_thread(workers):
    assert workers.submit(torch.get_num_threads).result() == 1


def test_canonid_train_screens_in_workers_as_with_one_thread(tmp_path, monkeypatch, capsys):
    """`canonid train DATA` with two threads: the screen's table (but its CPU times) and the
    choice are those of `--threads 1` (the pool's threshold lowered for tiny data; the full
    run trains in the command's process with its threads)."""
    import canonid.jobs
    from canonid.cli import main
    from canonid.kernel.io import read_json
    from tests.test_window_screen import siso_file

    data = siso_file(tmp_path)
    fast = ["--profile", "tiny", "--epochs", "30", "--no-progress", "--device", "cpu"]
    monkeypatch.setattr(canonid.jobs, "POOL_MIN_STEPS", 1)
    tables = []
    for threads in ("1", "2"):
        run = tmp_path / f"threads-{threads}"
        assert main(["train", str(data), "--out", str(run), *fast, "--threads", threads]) == 0
        table = read_json(run / "window-screen.json")
        for row in [*table["candidates"], *table["full_runs"]]:
            row["cpu_seconds"] = 0.0
        tables.append(table)
    assert tables[0] == tables[1] and len(tables[0]["candidates"]) > 1


def _die() -> None:
    os._exit(9)  # as the system's out-of-memory killer ends a process: no exception, no cleanup


def test_a_worker_killed_mid_candidate_is_one_clear_error():
    """A worker that dies (killed, e.g. out of memory) is a WorkerError saying what happened and
    what to do, not a traceback of the process pool."""
    with pytest.raises(WorkerError, match=r"ended abruptly .* --threads 1"):
        with candidate_pool(2, steps=POOL_MIN_STEPS, candidates=2) as pool:
            assert pool is not None
            pool.submit(_die).result()


def test_the_cubic_branch_of_a_short_record_trains_beside_as_it_does_here(
    workers, one_thread, tmp_path
):
    from canonid.learning.training import CUBIC_ARM_DIR

    # records too short for the cubic test's peaks: both networks train fully, the branch in
    # a worker beside this process
    train, val = _bursty(1, 1, 150), _bursty(2, 1, 80)
    opts = dataclasses.replace(OPTS, epochs=12, horizon=50, val_horizon=60, device="cpu")
    net = {"hidden": [8], "feedthrough": False}
    here = fit(train, val, window=3, options=opts, net_options=net)
    beside = fit(
        train, val, window=3, options=opts, net_options=net, executor=workers, run_dir=tmp_path
    )
    assert beside.model.info["cubic_test"] == here.model.info["cubic_test"]
    assert beside.model.info["cubic_test"]["fallback"] is not None
    for a, b in zip(beside.model.net.parameters(), here.model.net.parameters(), strict=True):
        assert torch.equal(a, b)
    assert (tmp_path / CUBIC_ARM_DIR / "weights.pt").is_file()
    # the worker's CPU time is the run's too; here the process's own clock counted it
    assert beside.cpu_elsewhere > 0 and here.cpu_elsewhere == 0
