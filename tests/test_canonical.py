"""The canonical state: ordering, the shift as matrices (Ā, B̄, S̄), windows cut from data."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.kernel.canonical import cut_windows, shift, shift_matrices, state_dim
from canonid.kernel.errors import ShapeError

dims = st.tuples(st.integers(1, 6), st.integers(1, 3), st.integers(1, 3))


@settings(max_examples=40, deadline=None)
@given(dims, st.integers(0, 2**31 - 1))
def test_shift_equals_the_shift_matrices(d, seed):
    ell, n_u, n_y = d
    rng = np.random.default_rng(seed)
    a_bar, b_bar, s_bar = shift_matrices(ell, n_u, n_y)
    n = state_dim(ell, n_u, n_y)
    assert a_bar.shape == (n, n) and b_bar.shape == (n, n_u) and s_bar.shape == (n, n_y)
    z, u, y = rng.normal(size=n), rng.normal(size=n_u), rng.normal(size=n_y)
    np.testing.assert_allclose(shift(z, u, y), a_bar @ z + b_bar @ u + s_bar @ y, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(dims, st.integers(0, 2**31 - 1))
def test_shift_equals_windows_cut_from_data(d, seed):
    ell, n_u, n_y = d
    rng = np.random.default_rng(seed)
    T = ell + 8
    u, y = rng.normal(size=(T, n_u)), rng.normal(size=(T, n_y))
    Z = cut_windows(u, y, ell)
    assert Z.shape == (T - ell + 1, ell * (n_u + n_y))
    for k in range(Z.shape[0] - 1):
        t = ell + k
        np.testing.assert_array_equal(shift(Z[k], u[t], y[t]), Z[k + 1])
    # batched shift over all rows at once
    np.testing.assert_array_equal(shift(Z[:-1], u[ell:], y[ell:]), Z[1:])


def test_ordering_is_oldest_pair_first():
    u = np.array([[10.0], [11.0], [12.0], [13.0]])
    y = np.array([[0.0, 0.5], [1.0, 1.5], [2.0, 2.5], [3.0, 3.5]])
    Z = cut_windows(u, y, 2)
    # z_2 = (u_0, y_0, u_1, y_1)
    np.testing.assert_array_equal(Z[0], [10, 0, 0.5, 11, 1, 1.5])
    np.testing.assert_array_equal(Z[-1], [12, 2, 2.5, 13, 3, 3.5])


def test_bad_windows():
    with pytest.raises(ShapeError, match="longer than the trajectory"):
        cut_windows(np.zeros((3, 1)), np.zeros((3, 1)), 5)
    with pytest.raises(ShapeError, match="integer >= 1"):
        shift_matrices(0, 1, 1)
    with pytest.raises(ShapeError, match=r"u has|shape"):
        cut_windows(np.zeros((5, 1)), np.zeros((4, 1)), 2)
