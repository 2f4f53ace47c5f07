"""benchmarks/studies/one_record/validation_block_study.py: where it puts the validation block,
and the pieces."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(
    0, str(Path(__file__).resolve().parents[1] / "benchmarks" / "studies" / "one_record")
)

import validation_block_study as study

from canonid.kernel.dataset import Dataset, Trajectory


def test_the_block_balances_both_shares_and_a_tie_keeps_the_later_start():
    found = {0: (0.0, 0.3), 103: (0.1, 0.1), 206: (0.2, 0.0), 819: (0.1, 0.05)}
    assert study.chosen(found) == 819  # max 0.1 at 103 and 819: the later
    assert study.chosen({0: (0.5, 0.0), 103: (0.02, 0.01)}) == 103


def test_the_pieces_around_a_block_keep_only_those_long_enough():
    t = np.arange(1024.0)[:, None]
    whole = Trajectory(u=t, y=2 * t)
    train, val = study.cut(whole, 103)  # 0 … 102 is shorter than MIN_PIECE
    assert [p.T for p in train] == [1024 - 103 - study.BLOCK] and val.T == study.BLOCK
    assert val.u[0, 0] == 103 and train[0].u[0, 0] == 103 + study.BLOCK
    train, val = study.cut(whole, 1024 - study.BLOCK)  # the tail: the training part is whole
    assert [p.T for p in train] == [1024 - study.BLOCK]


def test_a_level_only_the_tail_lacks_moves_the_block_to_reach_it():
    """A record whose output rises to its top in the middle: the tail misses the top, a block
    over the middle reaches it, and training then still holds levels on both sides."""
    n = 1024
    y = np.concatenate([np.linspace(0, 1, n // 2), np.linspace(1, 0.5, n // 2)])[:, None]
    data = Dataset(
        splits={"train": [Trajectory(u=np.zeros((n, 1)), y=y)]},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
    )
    whole = data.split("train")[0]
    found = study.shares(data, whole)
    assert found[n - study.BLOCK][0] > 0.5  # the tail spans 0.5 … 0.6: most of training is out
    assert max(found[study.chosen(found)]) < max(found[n - study.BLOCK])
