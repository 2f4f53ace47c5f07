"""Closed forms for linear systems ``x⁺ = Ax + Bu``, ``y = Cx + Du``: the oracle of the analysis.

* ``O_ℓ(x, ū) = 𝒪_ℓ x + 𝒯_ℓ ū`` with the observability matrix
  ``𝒪_ℓ = [C; CA; …; CA^{ℓ−1}]`` (``ℓ·n_y × n_x``, built here for any ``ℓ``: ``control.obsv``
  stops at ``n_x`` block rows) and the block lower-triangular Toeplitz matrix ``𝒯_ℓ`` of the
  Markov parameters (``D`` on the diagonal, ``CA^{i−j−1}B`` below it).
* ``α_ℓ = σ_min(𝒪_ℓ)``, the smallest of the ``n_x`` singular values (the pair ratio is
  ``‖𝒪_ℓ(x − x')‖ / ‖x − x'‖``); it is 0 when ``ℓ·n_y < n_x`` or ``(A, C)`` is unobservable in
  ``ℓ`` steps. ``numpy.linalg.svd`` of a wide matrix returns only ``ℓ·n_y`` values, so the
  missing ones (zeros) are accounted for explicitly.
* ``γ_f = ‖A‖₂`` and ``γ_h = ‖C‖₂``.
* :func:`canonical_regressor` — the exact map ``Ĥ(z_t, u_t)`` of the paper's Remark 1 (noise-free
  inverse ``O_ℓ^*`` taken as the least-squares solution): a plain numpy callable with the
  interface the identification layer exports, for testing the learned-model checks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from canonid.analysis.maps import check_window
from canonid.kernel.errors import ShapeError
from canonid.models.linear import LinearSystem

__all__ = [
    "alpha_exact",
    "canonical_regressor",
    "canonical_state_map",
    "gamma_exact",
    "observability_matrix",
    "toeplitz_matrix",
]


def observability_matrix(A: np.ndarray, C: np.ndarray, window: int) -> np.ndarray:
    """``[C; CA; …; CA^{ℓ−1}]``, shape ``(ℓ·n_y, n_x)``, for any ``ℓ ≥ 1`` (no cap at ``n_x``)."""
    ell = check_window(window)
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    C = np.atleast_2d(np.asarray(C, dtype=np.float64))
    if A.shape[0] != A.shape[1] or C.shape[1] != A.shape[0]:
        raise ShapeError(f"A must be square and C have n_x columns, got A {A.shape}, C {C.shape}")
    blocks = [C]
    for _ in range(ell - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def toeplitz_matrix(system: LinearSystem, window: int) -> np.ndarray:
    """``𝒯_ℓ`` with ``O_ℓ(x, ū) = 𝒪_ℓ x + 𝒯_ℓ ū``, shape ``(ℓ·n_y, ℓ·n_u)``.

    Block ``(i, j)`` (0-based, output of step ``i``, input ``u_{j+1}``) is ``D`` for ``i = j``,
    ``C A^{i−j−1} B`` for ``i > j`` and 0 above the diagonal.
    """
    ell = check_window(window)
    A, B, C, D = system.A, system.B, system.C, system.D
    p, m = C.shape[0], B.shape[1]
    out = np.zeros((ell * p, ell * m))
    markov = [D] + [C @ np.linalg.matrix_power(A, k) @ B for k in range(ell)]
    for i in range(ell):
        for j in range(i + 1):
            out[i * p : (i + 1) * p, j * m : (j + 1) * m] = markov[i - j]
    return out


def alpha_exact(A: np.ndarray, C: np.ndarray, window: int) -> float:
    """``α_ℓ = σ_min(𝒪_ℓ)`` over the ``n_x`` singular values (0 when ``ℓ·n_y < n_x``)."""
    obs = observability_matrix(A, C, window)
    rows, cols = obs.shape
    if rows < cols:
        return 0.0  # a wide matrix has n_x − ℓ·n_y zero singular values that svd omits
    return float(np.linalg.svd(obs, compute_uv=False)[-1])


def gamma_exact(A: np.ndarray) -> float:
    """``γ_f = ‖A‖₂`` (the Jacobian of ``f`` in ``x`` is ``A`` everywhere)."""
    return float(np.linalg.norm(np.atleast_2d(np.asarray(A, dtype=np.float64)), 2))


def _split_window(z: np.ndarray, window: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
    """``(ū, ȳ)`` from rows of ``z`` in the ``canonid.kernel.canonical`` ordering (pairs, oldest
    first)."""
    pairs = z.reshape(z.shape[0], window, n_u + n_y)
    ubar = pairs[:, :, :n_u].reshape(z.shape[0], window * n_u)
    ybar = pairs[:, :, n_u:].reshape(z.shape[0], window * n_y)
    return ubar, ybar


def canonical_state_map(system: LinearSystem, window: int) -> Callable[[np.ndarray], np.ndarray]:
    """``z_t ↦ x̂_t = F_ℓ(𝒪_ℓ^+(ȳ − 𝒯_ℓ ū), ū)``: the least-squares state estimate (batched).

    ``z`` has shape ``(N, ℓ(n_u+n_y))`` in the ``canonid.kernel.canonical`` ordering; returns ``(N,
    n_x)``. Needs ``𝒪_ℓ`` of full column rank.
    """
    ell = check_window(window)
    A, B = system.A, system.B
    n_u, n_y = system.n_u, system.n_y
    obs = observability_matrix(A, system.C, ell)
    if np.linalg.matrix_rank(obs) < system.n_x:
        raise ShapeError(f"O_{ell} has rank < n_x = {system.n_x}: the state is not determined")
    pinv = np.linalg.pinv(obs)
    toep = toeplitz_matrix(system, ell)
    a_ell = np.linalg.matrix_power(A, ell)
    # x_t = A^ℓ x_{t−ℓ} + Σ_k A^{ℓ−1−k} B u_{t−ℓ+k}
    reach = np.hstack([np.linalg.matrix_power(A, ell - 1 - k) @ B for k in range(ell)])

    def state(z: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(np.asarray(z, dtype=np.float64))
        if z.shape[1] != ell * (n_u + n_y):
            raise ShapeError(f"z must have {ell * (n_u + n_y)} columns, got {z.shape}")
        ubar, ybar = _split_window(z, ell, n_u, n_y)
        x_past = (ybar - ubar @ toep.T) @ pinv.T
        return x_past @ a_ell.T + ubar @ reach.T

    return state


def canonical_regressor(
    system: LinearSystem, window: int
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The exact ``Ĥ(z_t, u_t) = C x̂_t + D u_t`` with ``x̂_t`` from :func:`canonical_state_map`.

    A plain numpy callable ``H(z, u) -> y``: ``z`` ``(N, ℓ(n_u+n_y))``, ``u`` ``(N, n_u)``, ``y``
    ``(N, n_y)`` — the interface of the regressors the identification layer exports. On
    noise-free data it reproduces ``y_t`` exactly.
    """
    state = canonical_state_map(system, window)
    C, D = system.C, system.D

    def regressor(z: np.ndarray, u: np.ndarray) -> np.ndarray:
        x = state(z)
        u = np.asarray(u, dtype=np.float64).reshape(x.shape[0], system.n_u)
        return x @ C.T + u @ D.T

    return regressor
