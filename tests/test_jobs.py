"""The one job abstraction (:mod:`canonid.jobs`): cached by its stored result, threads set and
restored around the work, retried once by the runner."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import pytest
import torch

from canonid.jobs import RESULT_FILE, StoredJob, run_job
from canonid.kernel.errors import CheckpointError
from canonid.runner import run_jobs

CALLS: list[str] = []


@dataclass(frozen=True)
class CountJob(StoredJob):
    folder: str
    value: int
    fail_first: bool = False
    threads: int | None = 1
    kind: ClassVar[str] = "count"

    @property
    def name(self) -> str:
        return f"count {self.value}"

    def recipe(self) -> dict[str, Any]:
        return {"value": self.value}

    def work(self) -> dict[str, Any]:
        CALLS.append(self.name)
        if self.fail_first and CALLS.count(self.name) == 1:
            raise RuntimeError("first try fails")
        return {"square": self.value**2, "threads": torch.get_num_threads()}


def test_a_stored_result_of_the_same_recipe_is_reused(tmp_path):
    CALLS.clear()
    before = torch.get_num_threads()
    job = CountJob(str(tmp_path / "a"), 3, threads=1)
    first = run_job(job)
    assert first.ran and first.result == {"square": 9, "threads": 1}
    assert torch.get_num_threads() == before  # restored after the work
    assert (tmp_path / "a" / RESULT_FILE).is_file()
    again = run_job(job)
    assert not again.ran and again.result == first.result and CALLS == ["count 3"]
    with pytest.raises(CheckpointError, match=r"differs in \['value'\]"):
        run_job(CountJob(str(tmp_path / "a"), 4))


def test_the_runner_retries_a_failed_job_once(tmp_path):
    CALLS.clear()
    jobs = [CountJob(str(tmp_path / f"j{i}"), i, fail_first=i == 1) for i in range(3)]
    outcomes = run_jobs(run_job, jobs, progress=False)
    assert [o.result["square"] for o in outcomes] == [0, 1, 4]
    assert CALLS.count("count 1") == 2
