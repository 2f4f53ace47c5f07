"""Short trainings side by side (canonid.jobs.candidate_pool): the window screen's candidates
and the cubic test's arms, trained in worker processes of one torch thread each, give what they
give one after the other with one thread — the same table, the same losses — and a run with
one thread, or with trainings too short to repay a worker, starts none."""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
from concurrent.futures import Executor, ProcessPoolExecutor

import pytest
import torch

from canonid.jobs import POOL_MIN_STEPS, _one_thread, candidate_pool
from canonid.kernel.errors import WorkerError
from canonid.learning.search import candidate_table, search
from canonid.learning.training import TrainOptions
from tests.learning_helpers import damped_split

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


def _rows(found):
    return [dataclasses.replace(row, cpu_seconds=0.0) for row in found.rows]


def test_the_search_in_workers_chooses_what_it_chooses_alone(workers, one_thread, tmp_path):
    train, val = damped_split()
    kw = dict(model="mlp", table=candidate_table((2, 4, 6), (0, 2)), options=OPTS, net_options=NET)
    alone, _, _ = search(train, val, **kw, run_dir=tmp_path / "alone")
    side_by_side, _, _ = search(train, val, **kw, run_dir=tmp_path / "side", executor=workers)
    assert _rows(side_by_side) == _rows(alone) and side_by_side.chosen == alone.chosen
    assert all(row.cpu_seconds > 0 for row in side_by_side.rows)  # each worker's own CPU time


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


def test_canonid_train_searches_in_workers_as_with_one_thread(tmp_path, monkeypatch, capsys):
    """`canonid train DATA` with two threads: the search's rows (but their CPU times) and the
    choice are those of `--threads 1` (the pool's threshold lowered for tiny data)."""
    import canonid.jobs
    from canonid.cli import main
    from canonid.kernel.dataset import Dataset
    from canonid.kernel.io import read_json
    from tests.test_search import _system

    parts = {"train": _system(7, 2, 300), "val": _system(8, 1, 200)}
    data = Dataset(splits=parts, dt=1.0, input_names=("u",), output_names=("y",))
    path = data.save(tmp_path / "data.npz")
    fast = ["--profile", "tiny", "--epochs", "9", "--no-progress", "--device", "cpu"]
    fast += ["--window", "2,4", "--hidden", "8"]
    monkeypatch.setattr(canonid.jobs, "POOL_MIN_STEPS", 1)
    tables = []
    for threads in ("1", "2"):
        run = tmp_path / f"threads-{threads}"
        assert main(["train", str(path), "--out", str(run), *fast, "--threads", threads]) == 0
        table = read_json(run / "search.json")
        for row in table["rows"]:
            row["cpu_seconds"] = 0.0
        tables.append(table)
    assert tables[0] == tables[1] and len(tables[0]["candidates"]) == 4


def _die() -> None:
    os._exit(9)  # as the system's out-of-memory killer ends a process: no exception, no cleanup


def test_a_worker_killed_mid_candidate_is_one_clear_error():
    """A worker that dies (killed, e.g. out of memory) is a WorkerError saying what happened and
    what to do, not a traceback of the process pool."""
    with pytest.raises(WorkerError, match=r"ended abruptly .* --threads 1"):
        with candidate_pool(2, steps=POOL_MIN_STEPS, candidates=2) as pool:
            assert pool is not None
            pool.submit(_die).result()
