"""The canonical state z_t of the paper (eq. 3, 12), in numpy — shared by learning and analysis.

Ordering. With window ℓ and ``p = n_u + n_y``, the canonical state at time ``t`` is

    z_t = (u_{t−ℓ}, y_{t−ℓ}, u_{t−ℓ+1}, y_{t−ℓ+1}, …, u_{t−1}, y_{t−1}) ∈ R^{ℓ p},

pairs ``[u_i; y_i]`` stacked oldest first, so block ``k`` (0-based) of length ``p`` holds the pair
of time ``t−ℓ+k``. The shift is

    z_{t+1} = Ā z_t + B̄ u_t + S̄ y_t,
    Ā = A_ℓ ⊗ I_p,  B̄ = e_ℓ ⊗ [I_{n_u}; 0],  S̄ = e_ℓ ⊗ [0; I_{n_y}],

with ``A_ℓ`` the ℓ×ℓ up-shift matrix (ones on the super-diagonal: block k+1 moves to block k, the
oldest pair drops out) and ``e_ℓ`` the last unit vector of R^ℓ (the new pair enters last). The
paper writes ``e_{n_x−1} ⊗ I_{n_u}`` and ``e_{n_x} ⊗ I_{n_y}``, which do not fit dimensionally.
:func:`shift` computes the same thing without forming the Kronecker products.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix

__all__ = ["cut_windows", "shift", "shift_matrices", "state_dim"]


def _check_window(window: int) -> int:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ShapeError(f"window ℓ must be an integer >= 1, got {window!r}")
    return int(window)


def state_dim(window: int, n_u: int, n_y: int) -> int:
    """``dim z = ℓ (n_u + n_y)``."""
    return _check_window(window) * (n_u + n_y)


def shift_matrices(window: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The dense ``(Ā, B̄, S̄)`` of the module docstring (for reference and tests)."""
    ell = _check_window(window)
    p = n_u + n_y
    up_shift = np.eye(ell, k=1)
    e_last = np.zeros((ell, 1))
    e_last[-1, 0] = 1.0
    a_bar = np.kron(up_shift, np.eye(p))
    b_bar = np.kron(e_last, np.vstack([np.eye(n_u), np.zeros((n_y, n_u))]))
    s_bar = np.kron(e_last, np.vstack([np.zeros((n_u, n_y)), np.eye(n_y)]))
    return a_bar, b_bar, s_bar


def shift(z: np.ndarray, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``z_{t+1}`` from ``z_t`` ``(..., ℓp)``, ``u_t`` ``(..., n_u)`` and ``y_t`` ``(..., n_y)``.

    Drops the oldest pair and appends ``[u_t; y_t]``; batched over leading dimensions.
    """
    z, u, y = np.asarray(z), np.asarray(u), np.asarray(y)
    p = u.shape[-1] + y.shape[-1]
    if z.shape[-1] % p != 0 or z.shape[:-1] != u.shape[:-1] or z.shape[:-1] != y.shape[:-1]:
        raise ShapeError(
            f"shift: z {z.shape}, u {u.shape}, y {y.shape} do not fit z = (..., ℓ·(n_u+n_y))"
        )
    return np.concatenate([z[..., p:], u, y], axis=-1)


def cut_windows(u: np.ndarray, y: np.ndarray, window: int) -> np.ndarray:
    """All canonical states of one trajectory.

    ``u`` is ``(T, n_u)``, ``y`` is ``(T, n_y)``; returns ``Z`` of shape ``(T − ℓ + 1, ℓ p)`` where
    row ``k`` is ``z_t`` for ``t = ℓ + k``, built from samples ``t−ℓ … t−1``. The last row,
    ``t = T``, is the state after the final sample (it has no ``y_T`` to predict).
    """
    ell = _check_window(window)
    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if u.ndim == 1:
        u = u[:, None]
    if y.ndim == 1:
        y = y[:, None]
    u = as_matrix(u, u.shape[1], "u")
    y = as_matrix(y, y.shape[1], "y", rows=u.shape[0])
    if u.shape[0] < ell:
        raise ShapeError(f"window ℓ = {ell} is longer than the trajectory ({u.shape[0]} samples)")
    pairs = np.concatenate([u, y], axis=1)  # (T, p), row i = [u_i; y_i]
    windows = sliding_window_view(pairs, (ell, pairs.shape[1]))[:, 0]  # (T-ℓ+1, ℓ, p)
    return windows.reshape(windows.shape[0], -1).copy()
