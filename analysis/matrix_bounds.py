"""Verified bounds on the singular values of interval matrices, batched over boxes.

Given an interval matrix ``[J]`` (shape ``(B, m, n)``) these return, per box,

* :func:`spectral_upper` — a float ``s`` with ``‖J‖₂ ≤ s`` for **every** ``J`` in ``[J]``;
* :func:`smin_lower` — a float ``s`` with ``σ_min(J) ≥ s`` for every ``J`` in ``[J]``, where
  ``σ_min`` is the smallest of the ``n`` singular values (0 when ``m < n``).

Two upper bounds are combined (the smaller is kept):

1. the magnitude matrix ``M = |[J]|`` (entry-wise largest absolute value): ``‖J‖₂ ≤ ‖M‖₂``, and
   ``‖M‖₂² = ρ(MᵀM) ≤ max_i (MᵀM v)_i / v_i`` for any positive ``v`` (Collatz–Wielandt), with
   ``v`` from a float power iteration and the quotient evaluated with upward rounding. It is
   tight when the sign pattern of ``J`` can be balanced by diagonal ±1 scalings (the tank's
   and the planar drone's Jacobians, whose non-zero patterns are forests).
2. midpoint–radius: ``[J] ⊆ Jc ± Δ`` gives ``‖J‖₂ ≤ ‖Jc‖₂ + ‖Δ‖₂``. ``‖Jc‖₂ ≤ μ`` is certified
   by an interval Cholesky factorisation of ``μ²I − JcᵀJc`` (it succeeds only for a positive
   definite matrix), ``μ`` slightly above the float SVD value. It is tight as boxes shrink,
   whatever the signs, and exact to ~1e-12 for a constant matrix (linear systems).

The lower bound is ``σ_min(Jc) − ‖Δ‖₂`` (Weyl), with ``σ_min(Jc) ≥ μ`` certified by the
Cholesky factorisation of ``JcᵀJc − μ²I``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from canonid.analysis.interval import Interval, _prod_bounds, _sum_lower, _sum_upper, interval_sum

__all__ = ["smin_lower", "spectral_upper"]

_POWER_ITERATIONS = 40


def _matvec_upper(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Upper bound of ``m @ v`` for non-negative ``m`` (B, r, c) and ``v`` (B, c)."""
    acc = np.zeros(m.shape[:2])
    for j in range(m.shape[2]):
        _, prod = _prod_bounds(m[:, :, j], v[:, j, None])
        acc = _sum_upper(acc, prod)
    return acc


def _perron_upper(m: np.ndarray) -> np.ndarray:
    """Rigorous upper bound of ``‖M‖₂`` for non-negative ``M`` (B, r, c) (Collatz–Wielandt)."""
    batch, _, cols = m.shape
    g = np.einsum("bki,bkj->bij", m, m)
    v = np.ones((batch, cols))
    for _ in range(_POWER_ITERATIONS):
        v = np.einsum("bij,bj->bi", g, v)
        scale = v.max(axis=1, keepdims=True)
        v = np.where(scale > 0, v / np.where(scale > 0, scale, 1.0), 1.0)
        v = np.maximum(v, 1e-250)
    mv = _matvec_upper(m, v)
    mtmv = _matvec_upper(np.transpose(m, (0, 2, 1)), mv)
    quot_hi = np.where(mtmv == 0, 0.0, np.nextafter(mtmv / v, np.inf))
    rho = quot_hi.max(axis=1)
    return np.where(rho == 0, 0.0, np.nextafter(np.sqrt(rho), np.inf))


def _gram(jc: np.ndarray) -> Interval:
    """Enclosure of ``JcᵀJc`` for a float matrix ``Jc`` (B, m, n)."""
    batch, rows, cols = jc.shape
    lo = np.zeros((batch, cols, cols))
    hi = np.zeros((batch, cols, cols))
    for k in range(rows):
        plo, phi = _prod_bounds(jc[:, k, :, None], jc[:, k, None, :])
        lo = _sum_lower(lo, plo)
        hi = _sum_upper(hi, phi)
    return Interval(lo, hi)


def _cholesky_pd(g: Interval) -> np.ndarray:
    """Per box: True when the interval Cholesky of ``g`` (B, n, n) succeeds.

    Success proves every symmetric matrix in ``g`` positive definite: each computed pivot
    encloses the exact pivot of every member matrix and all pivots were certainly positive.
    Column by column, the sums over earlier columns are vectorised (:func:`interval_sum`).
    """
    batch, n, _ = g.shape
    ok = np.ones(batch, dtype=bool)
    low_lo, low_hi = np.zeros((batch, n, n)), np.zeros((batch, n, n))
    for j in range(n):
        s = g[:, j:, j]  # (B, n − j): the pivot, then the column below it
        if j:
            below = Interval(low_lo[:, j + 1 :, :j], low_hi[:, j + 1 :, :j])
            row = Interval(low_lo[:, j : j + 1, :j], low_hi[:, j : j + 1, :j])
            pivot = interval_sum(row[:, 0].sq(), axis=1)  # sq: no dependency loss on L_jk²
            rest = interval_sum(below * row, axis=2)
            s = s - Interval(
                np.concatenate([pivot.lo[:, None], rest.lo], axis=1),
                np.concatenate([pivot.hi[:, None], rest.hi], axis=1),
            )
        ok &= s.lo[:, 0] > 0
        d_safe = Interval(np.where(ok, s.lo[:, 0], 1.0), np.where(ok, s.hi[:, 0], 1.0))
        root = d_safe.sqrt()
        low_lo[:, j, j], low_hi[:, j, j] = root.lo, root.hi
        col = s[:, 1:] / Interval(root.lo[:, None], root.hi[:, None])
        low_lo[:, j + 1 :, j], low_hi[:, j + 1 :, j] = col.lo, col.hi
    return ok & np.all(np.isfinite(g.lo) & np.isfinite(g.hi), axis=(1, 2))


def _certify_norm(jc: np.ndarray) -> np.ndarray:
    """Upper bound of ``‖Jc‖₂`` per box (float matrices), certified by Cholesky."""
    batch, _, cols = jc.shape
    sigma = np.linalg.norm(jc, ord=2, axis=(1, 2))
    out = np.full(batch, np.inf)
    gram = _gram(jc)
    eye = np.eye(cols)
    for slack in (1e-12, 1e-9, 1e-6):
        todo = ~np.isfinite(out)
        if not todo.any():
            break
        mu = sigma * (1.0 + slack) + 1e-300
        mu2_lo, mu2_hi = _prod_bounds(mu, mu)
        shift = Interval(mu2_lo[:, None, None] * eye, mu2_hi[:, None, None] * eye)
        ok = _cholesky_pd(shift - gram)
        out = np.where(todo & ok, mu, out)
    return out


def _certify_smin(jc: np.ndarray) -> np.ndarray:
    """Lower bound of ``σ_min(Jc)`` (over ``n`` singular values) per box, certified."""
    batch, rows, cols = jc.shape
    if rows < cols:
        return np.zeros(batch)
    sigma = np.linalg.svd(jc, compute_uv=False)[:, -1]
    out = np.zeros(batch)
    gram = _gram(jc)
    eye = np.eye(cols)
    for slack in (1e-10, 1e-7, 1e-4):
        todo = out == 0
        if not todo.any():
            break
        mu = sigma * (1.0 - slack)
        mu2_lo, mu2_hi = _prod_bounds(mu, mu)
        shift = Interval(mu2_lo[:, None, None] * eye, mu2_hi[:, None, None] * eye)
        ok = _cholesky_pd(gram - shift) & (mu > 0)
        out = np.where(todo & ok, mu, out)
    return out


def _mid_rad(j: Interval) -> tuple[np.ndarray, np.ndarray]:
    jc = j.mid
    with np.errstate(invalid="ignore", over="ignore"):
        rad = np.maximum(np.nextafter(j.hi - jc, np.inf), np.nextafter(jc - j.lo, np.inf))
    return jc, np.maximum(rad, 0.0)


def spectral_upper(j: Interval) -> np.ndarray:
    """Per box, a certified upper bound of ``sup ‖J‖₂`` over the interval matrix ``j``.

    ``j`` has shape ``(B, m, n)``; boxes with non-finite entries, or entries so large that the
    computation overflows, give ``inf``.
    """
    finite = np.all(j.finite, axis=(1, 2))
    safe = Interval(
        np.where(finite[:, None, None], j.lo, 0.0), np.where(finite[:, None, None], j.hi, 0.0)
    )
    with np.errstate(over="ignore", invalid="ignore"):
        magnitude = _perron_upper(safe.mag)
        jc, rad = _mid_rad(safe)
        exact = np.all(rad == 0, axis=(1, 2))
        radius_norm = np.where(exact, 0.0, _perron_upper(rad))
        centre_norm = _certify_norm(jc)
        combined = np.nextafter(centre_norm + radius_norm, np.inf)
    combined = np.where(exact, centre_norm, combined)
    upper = np.fmin(magnitude, combined)  # fmin: a NaN (overflow) on one side is ignored
    return np.where(finite & ~np.isnan(upper), upper, np.inf)


def _det(j: Interval, rows: tuple[int, ...], cols: tuple[int, ...]) -> Interval:
    """Interval determinant of the square sub-matrix ``j[:, rows][:, :, cols]`` (cofactors)."""
    if len(rows) == 1:
        return j[:, rows[0], cols[0]]
    total: Interval | None = None
    for k, c in enumerate(cols):
        minor = _det(j, rows[1:], cols[:k] + cols[k + 1 :])
        term = j[:, rows[0], c] * minor
        if total is None:
            total = term
        else:
            total = total + term if k % 2 == 0 else total - term
    assert total is not None
    return total


def _det_bound(j: Interval, sigma_max: np.ndarray) -> np.ndarray:
    """``σ_min ≥ sqrt(det(JᵀJ) / σ_max^(2(n−1)))`` with ``det(JᵀJ) = Σ_S det(J_S)²``.

    Cauchy–Binet sums over the ``n``-row subsets ``S``; ``det(JᵀJ)`` is the product of the
    ``n`` squared singular values, each at most ``σ_max²``. Exact for ``n = 2`` and tight where
    the Weyl bound is not (a wide entry that hardly moves ``σ_min``).
    """
    batch, rows, cols = j.shape
    acc = np.zeros(batch)
    for subset in itertools.combinations(range(rows), cols):
        acc = _sum_lower(acc, _det(j, subset, tuple(range(cols))).sq().lo)
    if cols == 1:
        root = np.sqrt(acc)
        return np.where(acc > 0, np.maximum(np.nextafter(root, -np.inf), 0.0), 0.0)
    denom = Interval.point(sigma_max).power(2 * (cols - 1)).hi
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.nextafter(acc / denom, -np.inf)
    q = np.where((acc > 0) & (denom > 0) & np.isfinite(q), q, 0.0)
    return np.where(q > 0, np.maximum(np.nextafter(np.sqrt(q), -np.inf), 0.0), 0.0)


def smin_lower(j: Interval) -> np.ndarray:
    """Per box, a certified lower bound of ``inf σ_min(J)`` over the interval matrix ``j``.

    ``σ_min`` is the smallest of the ``n`` singular values of the ``m × n`` matrix (0 when
    ``m < n``). The larger of two bounds is returned: Weyl's ``σ_min(Jc) − ‖Δ‖₂`` and, for
    ``n ≤ 4`` with at most 64 row subsets, the determinant bound of :func:`_det_bound`. Boxes
    with non-finite entries, or entries so large that the computation overflows, give 0.
    """
    batch, rows, cols = j.shape
    finite = np.all(j.finite, axis=(1, 2))
    safe = Interval(
        np.where(finite[:, None, None], j.lo, 0.0), np.where(finite[:, None, None], j.hi, 0.0)
    )
    if rows < cols:
        return np.zeros(batch)
    with np.errstate(over="ignore", invalid="ignore"):
        jc, rad = _mid_rad(safe)
        exact = np.all(rad == 0, axis=(1, 2))
        centre = _certify_smin(jc)
        radius_norm = np.where(exact, 0.0, _perron_upper(rad))
        lower = np.where(exact, centre, np.nextafter(centre - radius_norm, -np.inf))
        lower = np.where(np.isnan(lower), 0.0, lower)
        if cols <= 4 and math.comb(rows, cols) <= 64:
            lower = np.fmax(lower, _det_bound(safe, spectral_upper(safe)))
    return np.where(finite & ~np.isnan(lower), np.maximum(lower, 0.0), 0.0)
