"""Training spans and where scored data leave them (:mod:`canonid.coverage`): closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.coverage import (
    INFO_KEY,
    NOTED_BEYOND,
    UNVALIDATED_SHARE,
    VALIDATION_KEY,
    OutsideRange,
    outside_training_range,
    recorded_unvalidated,
    training_ranges,
    unvalidated,
    unvalidated_line,
)
from canonid.kernel.dataset import Trajectory

NAMES = {"input_names": ["pump"], "output_names": ["level", "flow"]}


def _traj(u, y):
    return Trajectory(u=np.asarray(u, float)[:, None], y=np.asarray(y, float))


def test_training_ranges_are_each_signals_extremes_over_every_record():
    a = _traj([1.0, 3.0, 2.0], [[0.5, 4.0], [0.7, 4.0], [0.6, 4.0]])
    b = _traj([0.5, 2.5], [[0.9, 4.0], [0.4, 4.0]])
    assert training_ranges([a, b]) == {"inputs": [[0.5, 3.0]], "outputs": [[0.4, 0.9], [4.0, 4.0]]}


def test_data_inside_the_spans_report_nothing_and_a_model_without_spans_is_unknown():
    train = [_traj([1.0, 3.0], [[0.0, 4.0], [1.0, 4.0]])]
    info = {INFO_KEY: training_ranges(train)}
    inside = [_traj([1.0, 2.0, 3.0], [[0.0, 4.0], [0.5, 4.0], [1.0, 4.0]])]
    assert outside_training_range(info, inside, **NAMES) == ()
    assert outside_training_range({}, inside, **NAMES) is None
    other = {INFO_KEY: {"inputs": [[0, 1], [0, 1]], "outputs": [[0, 1], [0, 1]]}}
    assert outside_training_range(other, inside, **NAMES) is None  # spans of other signals


def test_share_and_distance_outside_are_counted_on_both_sides():
    info = {INFO_KEY: {"inputs": [[1.0, 3.0]], "outputs": [[0.0, 1.0], [4.0, 4.0]]}}
    # pump: 4.0 is 1.0 above (half the span), 0.5 is 0.5 below; 2 of 5 samples outside;
    # flow: constant 4 in training, 4.25 once (no span to compare with)
    u = [4.0, 2.0, 0.5, 1.0, 3.0]
    y = [[0.5, 4.0], [0.5, 4.0], [0.5, 4.25], [0.5, 4.0], [0.5, 4.0]]
    found = outside_training_range(info, [_traj(u, y)], **NAMES)
    assert found == (
        OutsideRange("pump", "input", 1.0, 3.0, share=0.4, distance=1.0, beyond=0.5),
        OutsideRange("flow", "output", 4.0, 4.0, share=0.2, distance=0.25, beyond=None),
    )
    assert [OutsideRange.from_json(o.to_json()) for o in found] == list(found)
    assert found[0].describe() == (
        "input pump on 40 % of samples (training span [1, 3], up to 0.5 × its span beyond)"
    )
    assert found[1].describe().endswith("up to 0.25 beyond)")


def test_the_tables_name_a_signal_beyond_a_twentieth_of_its_span_or_off_a_constant_one():
    def outside(beyond):
        return OutsideRange("u", "input", 0.0, 1.0, share=0.1, distance=0.0, beyond=beyond)

    assert NOTED_BEYOND == 0.05
    assert [outside(b).noted for b in (0.01, 0.05, 0.0501, 2.0, None)] == [
        False,
        False,
        True,
        True,
        True,
    ]


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=30),
    st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=30),
)
def test_training_data_never_leave_their_own_span_and_the_share_counts_samples(train_u, new_u):
    train = [_traj(train_u, np.zeros((len(train_u), 2)))]
    info = {INFO_KEY: training_ranges(train)}
    assert outside_training_range(info, train, **NAMES) == ()
    found = outside_training_range(info, [_traj(new_u, np.zeros((len(new_u), 2)))], **NAMES)
    lo, hi = min(train_u), max(train_u)
    out = [v for v in new_u if v < lo or v > hi]
    assert found is not None
    if not out:
        assert found == ()
    else:
        (pump,) = found
        assert pump.share == pytest.approx(len(out) / len(new_u))
        assert pump.distance == pytest.approx(max(max(lo - v, v - hi) for v in out))


def test_training_levels_that_validation_never_shows_are_counted_against_its_span():
    """Training u over 0 … 9, validation u over 2 … 6: 5 of 10 training samples lie outside,
    the farthest 3 above (0.75 of the span); the outputs, equal in both, are not named."""
    train = [_traj(np.arange(10.0), np.full((10, 2), 4.0))]
    val = [_traj([2.0, 4.0, 6.0], np.full((3, 2), 4.0))]
    found = unvalidated(train, val, **NAMES)
    assert found == (OutsideRange("pump", "input", 2.0, 6.0, share=0.5, distance=3.0, beyond=0.75),)
    line = unvalidated_line(recorded_unvalidated({VALIDATION_KEY: [o.to_json() for o in found]}))
    assert line is not None and line.startswith("validation does not reach every level")
    assert "input pump on 50 % of the training samples (validation span [2, 6]" in line
    assert unvalidated(val, val, **NAMES) == ()
    # one training sample of 200 far outside: counted, not said (below UNVALIDATED_SHARE)
    spike = [_traj([4.0] * 199 + [30.0], np.full((200, 2), 4.0))]
    (far,) = unvalidated(spike, val, **NAMES)
    assert far.share == 0.005 < UNVALIDATED_SHARE and far.noted
    assert unvalidated_line([far]) is None
    assert unvalidated_line(()) is None and recorded_unvalidated({}) == ()
