"""benchmarks/demo_record.py: the Results page's Table 1 and compression rows, from a demo run's
``reproduction.json``."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import demo_record


def _cell(model: str, options: str, window: int, mean: float, clean: float | None) -> dict:
    return {
        "system": "tank",
        "model": model,
        "options": options,
        "window": window,
        "mean": mean,
        "mean_clean": clean,
        "paper": 9.3e-5,
    }


def test_table1_rows_are_in_the_papers_scale_and_only_the_papers_options_have_its_column():
    rows = [
        _cell("mlp", "defaults", 10, 2.056e-4, 7.482e-5),
        _cell("mlp", "paper", 10, 3.898e-4, 2.502e-4),
        _cell("arx", "paper", 5, 5.987e-2, None),
        {**_cell("mlp", "paper", 10, 1.0, 1.0), "system": "drone2d"},  # not the tank: left out
    ]
    lines = demo_record.table1_lines(rows)
    assert lines[2:] == [
        "| ARX (linear) | 5 | 598.7 | — | 0.93 |",
        "| Ours (MLP), canonid defaults | 10 | 2.056 | 0.7482 | — |",
        "| Ours (MLP), paper options | 10 | 3.898 | 2.502 | 0.93 |",
    ]


def test_compression_rows_give_the_reduced_over_the_full_model():
    rows = [
        {
            "compression": c,
            "latent_dim": n,
            "state_dim": 20,
            "rollout_mse_mean": r,
            "full_rollout_mse": 4e-4,
        }
        for c, n, r in ((0.6, 9, 5e-4), (0.3, 15, 3e-4))
    ]
    assert demo_record.compression_lines(rows)[2:] == [
        "| 30 % | 15 of 20 | 3 | 4 | 0.75 |",
        "| 60 % | 9 of 20 | 5 | 4 | 1.25 |",
    ]


def test_each_system_is_written_in_the_papers_scale_into_its_own_section():
    assert demo_record.scale("tank") == 1e-4 and demo_record.scale("drone2d") == 1e-2
    assert demo_record.section("tank") == "make demo: Table 1 and compression"
    assert demo_record.section("drone2d") == "Reproduce, quick profile: drone2d"
    row = _cell("masti", "paper", 10, 0.4304, 0.4305)
    assert demo_record.table1_lines([{**row, "system": "drone2d"}], "drone2d")[2:] == [
        "| Masti et al. | 10 | 43.04 | 43.05 | 0.0093 |"
    ]
