"""``kill -9`` during ``canonid train``, then ``canonid train --resume``: the same bytes as a run
that was never interrupted.

The kill is not timed from outside (that would make the test depend on the machine's speed): the
training process kills itself with SIGKILL at a fixed point, the second optimiser step of epoch 4,
after the checkpoint of epoch 3 and in the middle of work that the checkpoint does not hold. Only
that run is a process of its own; the uninterrupted run and the resumption run in the test's
process (a fresh process holds nothing the folder does not, and starting one costs seconds).
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from canonid.cli import main

ROOT = Path(__file__).resolve().parents[1]

#: ``python -c`` program: ``canonid ARGS`` that SIGKILLs itself at optimiser step ``STEP`` of
#: epoch ``EPOCH`` (argv[1], argv[2]); the rest of argv is the command line
KILLED_RUN = """
import os, signal, sys
import torch
from canonid.learning.training import _Run
from canonid.cli import main

epoch_now, steps = [0], [0]
kill_epoch, kill_step = int(sys.argv[1]), int(sys.argv[2])
train_epoch, adam_step = _Run.train_epoch, torch.optim.Adam.step

def counted_epoch(self, epoch):
    epoch_now[0], steps[0] = epoch, 0
    return train_epoch(self, epoch)

def counted_step(self, *args, **kwargs):
    steps[0] += 1
    if epoch_now[0] == kill_epoch and steps[0] == kill_step:
        os.kill(os.getpid(), signal.SIGKILL)
    return adam_step(self, *args, **kwargs)

_Run.train_epoch = counted_epoch
torch.optim.Adam.step = counted_step
sys.argv[1:] = sys.argv[3:]  # the command line as canonid would see it (run.json records it)
sys.exit(main())
"""

#: files whose bytes must not depend on the interruption; history.csv too but for its column of
#: wall-clock seconds per epoch (checkpoint.pt holds the same history, so it differs as well)
SAME_BYTES = (
    "weights.pt",
    "config.json",
    "normalisation.json",
    "metrics.json",
    "rollouts.png",
    "training_curve.png",
)


def _killed_canonid(*argv: str, kill: tuple[int, int]) -> subprocess.CompletedProcess:
    """``canonid ARGV`` in a process of its own that SIGKILLs itself at ``kill`` (epoch, step)."""
    return subprocess.run(
        [sys.executable, "-c", KILLED_RUN, *(str(k) for k in kill), *argv],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )


@pytest.mark.slow
def test_kill_9_during_training_then_resume_gives_the_same_bytes(tmp_path, monkeypatch):
    data = tmp_path / "tank"
    gen = ["generate", "tank", "--out", str(data), "--n-train", "3", "--n-val", "1"]
    assert main([*gen, "--n-test", "1", "--seed", "3", "--no-progress"]) == 0
    # window and branch fixed: one run (a killed search: tests/test_search.py)
    train = ["train", str(data), "--model", "mlp", "--window", "3", "--cubic", "0", "--profile"]
    train += ["tiny"]
    train += ["--epochs", "6", "--windows-per-epoch", "32", "--threads", "1", "--device", "cpu"]
    train += ["--no-progress"]  # 4 optimiser steps per epoch (batch 8), a checkpoint after each
    whole, killed = tmp_path / "whole", tmp_path / "killed"

    monkeypatch.setattr("sys.argv", ["canonid", *train, "--out", str(whole)])  # run.json's
    assert main([*train, "--out", str(whole)]) == 0
    cut = _killed_canonid(*train, "--out", str(killed), kill=(4, 2))
    assert cut.returncode == -signal.SIGKILL, cut.stderr[-2000:]
    assert not (killed / "metrics.json").exists()  # it died before the end,
    assert torch.load(killed / "checkpoint.pt", weights_only=True)["epoch"] == 3  # after epoch 3
    resume = ["train", "--resume", "--out", str(killed), "--threads", "1", "--device", "cpu"]
    monkeypatch.setattr("sys.argv", ["canonid", *resume, "--no-progress"])
    assert main([*resume, "--no-progress"]) == 0

    for name in SAME_BYTES:
        assert (killed / name).read_bytes() == (whole / name).read_bytes(), name
    assert _without_seconds(killed / "history.csv") == _without_seconds(whole / "history.csv")


def _without_seconds(path: Path) -> list[list[str]]:
    rows = [line.split(",") for line in path.read_text().splitlines()]
    keep = [i for i, name in enumerate(rows[0]) if name != "seconds"]
    assert len(keep) == len(rows[0]) - 1
    return [[row[i] for i in keep] for row in rows]
