"""benchmarks/studies/small_data/small_data.py's cut of Silverbox's training part: the first N
samples of the
official training part, their last 20 % validating, the official test parts untouched."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from test_benchmarks import write_benchmark

from canonid.datagen.benchmarks import load_benchmark

sys.path.insert(
    0, str(Path(__file__).resolve().parents[1] / "benchmarks" / "studies" / "small_data")
)

import small_data


def test_the_cut_is_the_training_parts_first_samples_and_validates_their_last_fifth(tmp_path):
    write_benchmark("silverbox", tmp_path)
    full = load_benchmark("silverbox", tmp_path)
    short = small_data.cut(full, 1000)
    (record,), (train,), (val,) = full.split("train"), short.split("train"), short.split("val")
    assert (train.T, val.T) == (800, 200)
    for field in ("u", "y"):
        kept = np.concatenate([getattr(train, field), getattr(val, field)])
        np.testing.assert_array_equal(kept, getattr(record, field)[:1000])
    assert [t.info["part"] for t in short.split("test")] == list(full.metadata["test_parts"])
    for cut_part, part in zip(short.split("test"), full.split("test"), strict=True):
        np.testing.assert_array_equal(cut_part.y, part.y)
