"""benchmarks/horizon_study.py: what it reads from run folders (validation only) and how it sets
the two training horizons, a ramped run and a candidate's NMPC loop beside each other."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import horizon_study as study


def run_folder(
    root: Path,
    name: str,
    loss: float,
    *,
    epoch: int = 500,
    horizon: int = 50,
    curriculum: int = 50,
    cpu: float | None = 100.0,
    model: str = "mlp",
) -> Path:
    """A run folder as ``canonid train`` writes it, with only what the study reads."""
    folder = root / name
    folder.mkdir(parents=True)
    training = {
        "best_val_loss": loss,
        "best_epoch": epoch,
        "options": {"horizon": horizon, "curriculum_epochs": curriculum},
    }
    (folder / "config.json").write_text(json.dumps({"info": {"training": training}}))
    (folder / "run.json").write_text(
        json.dumps({"window": 10, "model": model, "net_options": {"linear": "skip"}})
    )
    if cpu is not None:
        (root / f"{name}.json").write_text(json.dumps({"cpu_seconds": cpu}))
    return folder


@pytest.fixture
def out(tmp_path, monkeypatch):
    monkeypatch.setattr(study, "ROOT", tmp_path)
    monkeypatch.setattr(study, "OUT", tmp_path / "runs" / "horizon-study")
    monkeypatch.setattr(study, "write_section", lambda *a, **k: None)
    return tmp_path / "runs" / "horizon-study"


def rows(text: str, first: str) -> list[list[str]]:
    return [
        [c.strip() for c in line.strip("|").split("|")]
        for line in text.splitlines()
        if line.startswith(f"| {first} ")
    ]


def test_a_system_is_tabled_only_with_both_horizons_and_its_ratio_is_h10_over_h50(out, capsys):
    run_folder(out, "tank-h50", 2e-4, cpu=600)
    run_folder(out, "tank-h10", 3e-4, horizon=10, cpu=150)
    run_folder(out, "masses-h50", 1e-4)  # no H = 10 run: not tabled
    assert study.record([], [], write=False) == 0
    text = capsys.readouterr().out
    (tank,) = rows(text, "tank")
    assert tank[5] == "1.50" and tank[6:] == ["600", "150"]
    assert tank[3] == "0.0002 (500)" and tank[4] == "0.0003 (500)"
    assert not rows(text, "masses")


def test_nothing_recorded_is_an_error_not_an_empty_table(out, capsys):
    out.mkdir(parents=True)
    assert study.record([], [], write=False) == 1
    assert "no pair of full runs" in capsys.readouterr().err


def test_a_ramped_run_is_set_against_the_h50_run_of_its_system(out, capsys):
    run_folder(out, "tank-h50", 2e-4)
    run_folder(out, "tank-h10", 3e-4, horizon=10)
    run_folder(out, "tank-ramp300", 1e-4, curriculum=300, cpu=400)
    study.record([], [], write=False)
    (ramp,) = [r for r in rows(capsys.readouterr().out, "tank") if r[1] == "300"]
    assert ramp[2:] == ["0.0001 (500)", "0.50", "400"]


def test_a_loop_row_reads_validation_from_the_run_and_the_loop_from_the_benchmark(out, capsys):
    run_folder(out, "drone2d-id-h50", 0.18)
    run_folder(out, "drone2d-id-h10", 0.15, horizon=10)
    folder = run_folder(out, "drone2d-id-ramp300", 0.12, curriculum=300)
    evaluation = folder / "evaluations" / "data-1234abcd-val-h20-stride5"
    evaluation.mkdir(parents=True)
    (evaluation / "metrics.json").write_text(json.dumps({"rollout_mse": 6.25e-4}))
    loop = {
        "run": "runs/horizon-study/drone2d-id-ramp300",
        "data": "drone2d-id",
        "rows": {
            "true model": {"rmse": 0.03, "rmses": [0.03] * 4, "left_X": []},
            "learned model": {"rmse": 2.7, "rmses": [2.7] * 4, "left_X": [20, 25, 30]},
        },
        "responses": {"rotor difference": {"rest": {"ratios": [-0.189, 0.77]}}},
    }
    other = {**loop, "data": "drone2d"}  # the paper's design: not a candidate here
    loops = out / "loop.json"
    loops.write_text(json.dumps({"a": loop, "b": other}))
    study.record([], [loops], write=False)
    (row,) = rows(capsys.readouterr().out, "Ours (MLP), H = 50 reached over 300 epochs")
    assert row[2:] == ["0.12", "0.000625", "90.00", "3 of 4", "-0.189"]
