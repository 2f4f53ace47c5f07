"""benchmarks/weight_decay_study.py: what it reads from the candidates' validation histories
(the best loss by an epoch), how it merges the device's collections and what it says."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import weight_decay_study as study


def record(system: str, samples: int, losses: dict[float, float], epochs: int = 100) -> dict:
    """A system's record whose every seed of decay ``w`` falls linearly to ``losses[w]``."""
    candidates = [
        {
            "label": f"weight_decay={w}, seed={s}",
            "history": [
                [e, 1.0 - e / epochs * (1.0 - loss * (1 + s / 10))] for e in range(0, epochs + 1, 5)
            ],
        }
        for w, loss in losses.items()
        for s in study.SEEDS
    ]
    return {"system": system, "window": 10, "train_samples": samples, "candidates": candidates}


def test_the_best_loss_by_an_epoch_reads_only_the_epochs_up_to_it():
    history = [[0, 1.0], [5, 0.5], [10, 0.7], [15, 0.2]]
    assert study.best_by(history, 10) == 0.5
    assert study.best_by(history, 15) == 0.2


def test_the_verdicts_follow_the_ratios_below_and_above_the_threshold():
    small = record("small", 800, {0.0: 0.5, 1e-5: 0.4, 1e-4: 0.45, 1e-3: 0.6})
    big = record("big", 50_000, {0.0: 0.4, 1e-5: 0.5, 1e-4: 0.6, 1e-3: 0.7})
    said = study._verdicts([small, big], 5_000)
    assert "Below 5,000 training samples it lowered both on small." in said
    assert "From 5,000 training samples it raised both on big." in said
    assert "No larger decay had a lower lowest loss than 1e-5 on a small record." in said
    worse = record("small", 800, {0.0: 0.5, 1e-5: 0.4, 1e-4: 0.3, 1e-3: 0.6})
    assert "No larger decay" not in study._verdicts([worse, big], 5_000)


def test_record_keeps_per_system_the_collection_that_reached_furthest(tmp_path, monkeypatch):
    import json

    short = record("small", 800, {0.0: 0.5, 1e-5: 0.4, 1e-4: 0.45, 1e-3: 0.6}, epochs=50)
    long = record("small", 800, {0.0: 0.3, 1e-5: 0.2, 1e-4: 0.25, 1e-3: 0.6}, epochs=100)
    files = []
    for i, found in enumerate((long, short)):
        files.append(tmp_path / f"c{i}.json")
        files[-1].write_text(json.dumps({"card": "X", "records": [found]}))
    written = {}
    monkeypatch.setattr(study, "SYSTEMS", {"small": ("-", 10)})
    monkeypatch.setattr(study, "STUDY_FILE", tmp_path / "study.json")
    monkeypatch.setattr(study, "_train_samples", lambda name: 800)
    monkeypatch.setattr(study, "_write_section", lambda body: written.setdefault("body", body))
    assert study.record(files) == 0
    kept = json.loads((tmp_path / "study.json").read_text())
    assert study._reached(kept["records"][0]) == 100 and kept["card"] == "X"
    assert "| small | 800 | 10 | 100 |" in written["body"]
