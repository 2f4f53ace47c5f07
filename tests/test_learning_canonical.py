"""The torch shift equals the shift matrices of canonid.kernel.canonical and windows cut from
data."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.kernel.canonical import cut_windows, shift_matrices
from canonid.kernel.errors import ShapeError
from canonid.learning.canonical import pairs_to_state, shift, state_to_pairs

dims = st.tuples(st.integers(1, 6), st.integers(1, 3), st.integers(1, 3))


@settings(max_examples=30, deadline=None)
@given(dims, st.integers(1, 5), st.integers(0, 2**31 - 1))
def test_torch_shift_equals_the_shift_matrices(d, batch, seed):
    ell, n_u, n_y = d
    rng = np.random.default_rng(seed)
    a_bar, b_bar, s_bar = shift_matrices(ell, n_u, n_y)
    z = rng.normal(size=(batch, ell * (n_u + n_y)))
    u, y = rng.normal(size=(batch, n_u)), rng.normal(size=(batch, n_y))
    expected = z @ a_bar.T + u @ b_bar.T + y @ s_bar.T
    got = shift(torch.from_numpy(z), torch.from_numpy(u), torch.from_numpy(y)).numpy()
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)


@settings(max_examples=30, deadline=None)
@given(dims, st.integers(0, 2**31 - 1))
def test_torch_windows_and_shift_equal_windows_cut_from_data(d, seed):
    ell, n_u, n_y = d
    rng = np.random.default_rng(seed)
    T = ell + 6
    u, y = rng.normal(size=(T, n_u)), rng.normal(size=(T, n_y))
    Z = cut_windows(u, y, ell)  # row k = z_{ℓ+k}
    ut, yt = torch.from_numpy(u), torch.from_numpy(y)
    # the burn-in window of samples 0 … ℓ−1 is z_ℓ
    z = pairs_to_state(ut[None, :ell], yt[None, :ell])
    np.testing.assert_array_equal(z[0].numpy(), Z[0])
    for k in range(T - ell):
        t = ell + k
        z = shift(z, ut[None, t], yt[None, t])
        np.testing.assert_array_equal(z[0].numpy(), Z[k + 1])
    pairs = state_to_pairs(torch.from_numpy(Z), n_u, n_y)
    assert pairs.shape == (Z.shape[0], ell, n_u + n_y)
    np.testing.assert_array_equal(pairs[0].numpy(), np.concatenate([u, y], axis=1)[:ell])


def test_shift_is_differentiable_in_the_appended_output():
    z = torch.zeros(2, 6)
    u = torch.ones(2, 1)
    y = torch.full((2, 2), 3.0, requires_grad=True)
    shift(z, u, y).sum().backward()
    assert y.grad is not None and torch.equal(y.grad, torch.ones(2, 2))


def test_bad_shapes_are_named():
    with pytest.raises(ShapeError, match="do not fit"):
        shift(torch.zeros(2, 7), torch.zeros(2, 1), torch.zeros(2, 2))
    with pytest.raises(ShapeError, match="same B and ℓ"):
        pairs_to_state(torch.zeros(2, 3, 1), torch.zeros(2, 4, 1))
    with pytest.raises(ShapeError, match="multiple of 3"):
        state_to_pairs(torch.zeros(2, 7), 1, 2)
