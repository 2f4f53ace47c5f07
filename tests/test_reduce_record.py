"""benchmarks/reduce_record.py: the Reduction page's tables, from a reduction's and a sweep's
files."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import reduce_record


def _write(path: Path, body: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(body), encoding="utf-8")


def test_one_reduction_against_its_full_model_as_the_reduction_scored_both(tmp_path):
    source, folder = tmp_path / "full", tmp_path / "reduced"
    _write(source / "metrics.json", {"clean": {"fit_percent": 98.184}})
    _write(folder / "run.json", {"source_run": str(source)})
    _write(
        folder / "metrics.json",
        {"n_rollouts": 1820, "rollout_horizon": 100, "n_init": 50, "clean": {"fit_percent": 98.0}},
    )
    _write(
        folder / "reduction.json",
        {
            "source": "full",  # as given on the command line: run.json has the absolute path
            "window": 10,
            "state_dim": 20,
            "latent_dim": 9,
            "compression": 0.6,
            "rollout_mse": 7.5e-4,
            "rollout_mse_clean": 6.0e-4,
            "full_rollout_mse": 5.0e-4,
            "full_rollout_mse_clean": 4.0e-4,
            "epochs_run": 150,
            "best_epoch": 140,
            "seconds": 85.2,
        },
    )
    lines = reduce_record.single_lines(folder)
    assert "| full Ours (MLP), ℓ = 10 | 20 | 5.000e-04 | 4.000e-04 | 98.18 |" in lines
    assert "| reduced, r = 60 % | 9 | 7.500e-04 | 6.000e-04 | 98.00 |" in lines
    assert lines[-1].startswith("Reduced over full: 1.5× (measured), 1.5× (noise-free)")


def test_a_sweep_is_one_row_per_window_and_rate_in_order(tmp_path):
    row = {
        "state_dim": 20,
        "reconstruction_mse_mean": 1e-5,
        "rollout_mse_std": 1e-6,
        "full_rollout_mse": 4e-4,
        "seeds": 2,
    }
    summary = [
        {**row, "window": 10, "compression": 0.6, "latent_dim": 9, "rollout_mse_mean": 5e-4},
        {**row, "window": 5, "compression": 0.3, "latent_dim": 8, "rollout_mse_mean": 3e-4},
    ]
    _write(tmp_path / "sweep.json", {"summary": summary})
    lines = reduce_record.sweep_lines(tmp_path / "sweep.json")
    assert "over 2 seed(s)" in lines[0]
    assert lines[-2].startswith("| 5 | 30 % | 8 / 20 |") and lines[-2].endswith("| 0.75 |")
    assert lines[-1].startswith("| 10 | 60 % | 9 / 20 |") and lines[-1].endswith("| 1.25 |")
