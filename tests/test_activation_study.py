"""benchmarks/studies/one_record/activation_study.py: what it trains (the overflow benchmark's
defaults, tanh
units) and where."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

sys.path.insert(
    0, str(Path(__file__).resolve().parents[1] / "benchmarks" / "studies" / "one_record")
)

import activation_study as study
import validation_block_study as block


def test_train_runs_the_overflow_defaults_with_tanh_units_into_the_studys_folder(monkeypatch):
    asked = []
    monkeypatch.setattr(
        subprocess,
        "run",
        lambda cmd, check: asked.append(cmd) or subprocess.CompletedProcess(cmd, 0),
    )
    assert study.train(3) == 0
    (cmd,) = asked
    assert cmd[1:5] == ["-m", "canonid", "train", str(block.data_folder(3))]
    options = " ".join(cmd[5:])
    assert "--max-window 50 --seed 0 --threads 1" in options  # the benchmark's defaults
    assert f"--activation tanh --out {study.RUNS / 'tanh-d3'}" in options
    assert study.defaults_run(3) == block.defaults_run(3)  # SiLU: the benchmark's own run
