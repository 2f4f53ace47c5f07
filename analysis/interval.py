"""Rigorous interval arithmetic in float64, batched over boxes with numpy.

Why not arb balls alone. python-flint's ``arb`` balls are rigorous but store radii with 30 bits
and centre every interval: ``[0, 1]`` becomes ``[−9.3e−10, 1.0000000019]``, so a clipped level
``max(x, 0)`` acquires a negative part and ``√`` of it is NaN. Interval B&B needs exact
endpoints at 0 and thousands of boxes per second, so intervals here are pairs of float64 arrays
``(lo, hi)`` with **outward rounding**:

* ``+ − × ÷ √`` are correctly rounded in IEEE 754 (numpy uses the hardware operations), so the
  exact result lies within half an ulp of the computed one; moving one ulp outward
  (``np.nextafter``) encloses it. Sums use the TwoSum error-free transformation to round only
  when the float sum is inexact, and products or quotients with a zero factor are exact, so exact
  zeros stay exact (a clipped level keeps its lower edge at 0).
* transcendental functions (``sin``, ``cos``, ``exp``, ``log``, ``tanh`` ...) are not correctly
  rounded by libm, so they go through python-flint's ``arb``, whose enclosures are rigorous; the
  result is rounded outward to float64.

Anything non-finite (an overflow, a division by an interval that contains 0) makes the result
unusable, and :attr:`Interval.finite` says so; callers treat such a box as unbounded.

Every array is batched: an interval of shape ``(B,)`` holds one scalar enclosure per box, and a
gradient enclosure has shape ``(B, n)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from flint import arb

__all__ = [
    "Interval",
    "arb_map",
    "interval_sum",
    "norm_lower",
    "norm_upper",
    "point_matmul",
    "quotient_lower",
]

_INF = np.inf


def _down(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, -_INF)


def _up(x: np.ndarray) -> np.ndarray:
    return np.nextafter(x, _INF)


def _sum_lower(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A float lower bound of the exact ``a + b`` (TwoSum: round down only when inexact)."""
    with np.errstate(invalid="ignore", over="ignore"):
        s = a + b
        bb = s - a
        err = (a - (s - bb)) + (b - bb)
        return np.where(err < 0, _down(s), s)


def _sum_upper(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        s = a + b
        bb = s - a
        err = (a - (s - bb)) + (b - bb)
        return np.where(err > 0, _up(s), s)


def _prod_bounds(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper float bounds of the exact product ``x·y`` (exact when a factor is 0)."""
    with np.errstate(invalid="ignore", over="ignore"):
        p = x * y
    exact = (x == 0) | (y == 0)
    return np.where(exact, p, _down(p)), np.where(exact, p, _up(p))


@dataclass(frozen=True)
class Interval:
    """The enclosure ``[lo, hi]`` (element-wise), arrays of any common shape."""

    lo: np.ndarray
    hi: np.ndarray

    # ------------------------------------------------------------------ construction
    @classmethod
    def point(cls, value: np.ndarray | float) -> Interval:
        v = np.asarray(value, dtype=np.float64)
        return cls(v, v.copy())

    @classmethod
    def from_bounds(cls, lo: np.ndarray | float, hi: np.ndarray | float) -> Interval:
        lo_a = np.asarray(lo, dtype=np.float64)
        hi_a = np.asarray(hi, dtype=np.float64)
        lo_a, hi_a = np.broadcast_arrays(lo_a, hi_a)
        return cls(lo_a.copy(), hi_a.copy())

    # ------------------------------------------------------------------ queries
    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.lo.shape)

    @property
    def finite(self) -> np.ndarray:
        """True where both ends are finite numbers (no NaN, no ±inf)."""
        return np.isfinite(self.lo) & np.isfinite(self.hi)

    @property
    def mag(self) -> np.ndarray:
        """Largest absolute value in the interval (exact)."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    @property
    def mid(self) -> np.ndarray:
        """A point inside the interval (the rounded midpoint, clipped into it)."""
        with np.errstate(over="ignore", invalid="ignore"):
            m = 0.5 * self.lo + 0.5 * self.hi
        return np.clip(m, self.lo, self.hi)

    def contains_zero(self) -> np.ndarray:
        return (self.lo <= 0) & (self.hi >= 0)

    def __getitem__(self, key: Any) -> Interval:
        return Interval(self.lo[key], self.hi[key])

    # ------------------------------------------------------------------ arithmetic
    def __add__(self, other: Interval) -> Interval:
        return Interval(_sum_lower(self.lo, other.lo), _sum_upper(self.hi, other.hi))

    def __sub__(self, other: Interval) -> Interval:
        return Interval(_sum_lower(self.lo, -other.hi), _sum_upper(self.hi, -other.lo))

    def __neg__(self) -> Interval:
        return Interval(-self.hi, -self.lo)

    def __mul__(self, other: Interval) -> Interval:
        products = []
        exact_zero = True
        for x in (self.lo, self.hi):
            for y in (other.lo, other.hi):
                with np.errstate(invalid="ignore", over="ignore"):
                    p = x * y
                products.append(p)
                exact_zero = exact_zero & ~((p == 0) & (x != 0) & (y != 0))  # no underflow
        lo = _nanmin(products)
        hi = _nanmax(products)
        # one ulp outward of the extreme rounded product encloses every exact product (rounding
        # is monotone); a zero extreme stays exact when every zero product has a zero factor
        return Interval(
            np.where((lo == 0) & exact_zero, 0.0, _down(lo)),
            np.where((hi == 0) & exact_zero, 0.0, _up(hi)),
        )

    def __truediv__(self, other: Interval) -> Interval:
        """Quotient; where the divisor contains 0 the result is ``[−inf, inf]``."""
        quotients = []
        exact_zero = True
        for x in (self.lo, self.hi):
            for y in (other.lo, other.hi):
                with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
                    q = x / y
                quotients.append(q)
                exact_zero = exact_zero & ~((q == 0) & (x != 0))  # no underflow
        lo = _nanmin(quotients)
        hi = _nanmax(quotients)
        lo = np.where((lo == 0) & exact_zero, 0.0, _down(lo))
        hi = np.where((hi == 0) & exact_zero, 0.0, _up(hi))
        zero = np.broadcast_to(other.contains_zero(), lo.shape)
        return Interval(np.where(zero, -_INF, lo), np.where(zero, _INF, hi))

    def scale(self, c: float) -> Interval:
        """Multiplication by an exact float constant."""
        return self * Interval.point(c)

    def sq(self) -> Interval:
        """``x²`` without the dependency loss of ``x·x`` (never negative)."""
        a_lo, a_hi = _prod_bounds(self.lo, self.lo)
        b_lo, b_hi = _prod_bounds(self.hi, self.hi)
        lo = np.where(self.lo >= 0, a_lo, np.where(self.hi <= 0, b_lo, 0.0))
        hi = np.maximum(a_hi, b_hi)
        return Interval(np.maximum(lo, 0.0), hi)

    def sqrt(self) -> Interval:
        """``√x`` on the non-negative part (callers flag ``lo < 0`` as a domain error)."""
        lo_arg = np.maximum(self.lo, 0.0)
        with np.errstate(invalid="ignore"):
            s_lo = np.sqrt(lo_arg)
            s_hi = np.sqrt(self.hi)
        lo = np.where(lo_arg == 0, 0.0, np.maximum(_down(s_lo), 0.0))
        hi = np.where(self.hi == 0, 0.0, _up(s_hi))
        return Interval(lo, hi)

    def abs(self) -> Interval:
        lo = np.where(self.lo >= 0, self.lo, np.where(self.hi <= 0, -self.hi, 0.0))
        return Interval(lo, self.mag)

    def maximum(self, other: Interval) -> Interval:
        return Interval(np.maximum(self.lo, other.lo), np.maximum(self.hi, other.hi))

    def minimum(self, other: Interval) -> Interval:
        return Interval(np.minimum(self.lo, other.lo), np.minimum(self.hi, other.hi))

    def hull(self, other: Interval) -> Interval:
        """The smallest interval holding both (element-wise)."""
        return Interval(np.minimum(self.lo, other.lo), np.maximum(self.hi, other.hi))

    def where(self, mask: np.ndarray, other: Interval) -> Interval:
        """``self`` where ``mask`` is true, ``other`` elsewhere."""
        return Interval(np.where(mask, self.lo, other.lo), np.where(mask, self.hi, other.hi))

    def power(self, p: int) -> Interval:
        """``x**p`` for an integer ``p >= 0`` (exact monotonicity rules, outward rounding)."""
        if p == 0:
            return Interval.point(np.ones_like(self.lo))
        if p == 1:
            return self
        if p % 2 == 0:
            return _power_nonneg(self.abs(), p)
        # an odd power is increasing: x**p has the sign of x at each end
        low = _power_nonneg(Interval(np.abs(self.lo), np.abs(self.lo)), p)
        high = _power_nonneg(Interval(np.abs(self.hi), np.abs(self.hi)), p)
        lo = np.where(self.lo >= 0, low.lo, -low.hi)
        hi = np.where(self.hi >= 0, high.hi, -high.lo)
        return Interval(lo, hi)


def _power_nonneg(m: Interval, p: int) -> Interval:
    """``m**p`` for ``m >= 0`` by repeated squaring (products of non-negative intervals are
    monotone, so each rounded product keeps the enclosure)."""
    acc = Interval.point(np.ones_like(m.lo))
    base, k = m, p
    while k:
        if k & 1:
            acc = acc * base
        k >>= 1
        if k:
            base = base.sq()
    return acc


#: unit roundoff and the smallest subnormal of float64
_UNIT = 2.0**-53
_ETA = 2.0**-1074


def _gamma(n: int) -> float:
    """``γ_n = n u / (1 − n u)``: a float sum or dot product of length ``n`` errs by at most
    ``γ_n`` times the same sum of absolute values (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed., §3.1), plus ``n η`` for underflowing products (§3.5)."""
    return n * _UNIT / (1.0 - n * _UNIT)


def interval_sum(x: Interval, axis: int) -> Interval:
    """``Σ x`` along ``axis``, enclosed: the float sums of the ends widened by ``γ`` times the
    sums of their absolute values (vectorised; the factor ``1 + 4γ`` covers computing the
    widening itself)."""
    g = _gamma(x.lo.shape[axis] + 2)
    with np.errstate(invalid="ignore", over="ignore"):
        lo, hi = np.sum(x.lo, axis=axis), np.sum(x.hi, axis=axis)
        err_lo = np.sum(np.abs(x.lo), axis=axis) * (g * (1.0 + 4.0 * g))
        err_hi = np.sum(np.abs(x.hi), axis=axis) * (g * (1.0 + 4.0 * g))
        return Interval(_down(lo - err_lo), _up(hi + err_hi))


def point_matmul(w: np.ndarray, x: Interval) -> Interval:
    """``W x`` enclosed for a float matrix ``W`` (inner dimension ``n``) and an interval ``x``
    of shape ``(B, n)`` (vectors; gives ``(B, m)``) or ``(B, n, d)`` (matrices; ``(B, m, d)``).

    With ``x ⊆ c ± r``: ``C ± R``, ``C = fl(W c)``, ``R = (fl(|W| r) + γ fl(|W| |c|)) (1 + 3γ)
    + n η`` rounded up, ``γ = γ_{n+2}`` (:func:`_gamma`; the factor covers computing ``R``).
    """
    with np.errstate(invalid="ignore", over="ignore"):
        c = 0.5 * x.lo + 0.5 * x.hi
        r = np.maximum(np.maximum(_sum_upper(x.hi, -c), _sum_upper(c, -x.lo)), 0.0)
        abs_w = np.abs(w)
        if c.ndim == 2:
            centre, rad, mag = c @ w.T, r @ abs_w.T, np.abs(c) @ abs_w.T
        else:
            centre, rad, mag = w @ c, abs_w @ r, abs_w @ np.abs(c)
        n = w.shape[1]
        g = _gamma(n + 2)
        total = _up((rad + g * mag) * (1.0 + 3.0 * g) + n * _ETA)
        return Interval(_sum_lower(centre, -total), _sum_upper(centre, total))


def _nanmin(arrays: list[np.ndarray]) -> np.ndarray:
    out = arrays[0]
    for a in arrays[1:]:
        out = np.minimum(out, a)  # propagates NaN: an undefined product poisons the bound
    return out


def _nanmax(arrays: list[np.ndarray]) -> np.ndarray:
    out = arrays[0]
    for a in arrays[1:]:
        out = np.maximum(out, a)
    return out


def arb_map(func: Callable[[arb], arb], x: Interval) -> Interval:
    """Apply a transcendental ``func`` rigorously through python-flint's ``arb``.

    Each interval ``[lo, hi]`` becomes the arb ball holding both (exact) ends, ``func`` gives a
    rigorous enclosure, and its ends are rounded outward to float64. Non-finite input or output
    gives ``[−inf, inf]`` (NaN for an undefined result), which callers treat as unbounded.
    """
    lo = np.asarray(x.lo, dtype=np.float64)
    hi = np.asarray(x.hi, dtype=np.float64)
    out_lo = np.empty(lo.shape)
    out_hi = np.empty(lo.shape)
    flat_lo, flat_hi = lo.ravel(), hi.ravel()
    res_lo, res_hi = out_lo.ravel(), out_hi.ravel()
    for i in range(flat_lo.size):
        a, b = float(flat_lo[i]), float(flat_hi[i])
        if not (np.isfinite(a) and np.isfinite(b)):
            res_lo[i], res_hi[i] = -_INF, _INF
            continue
        ball = arb(a) if a == b else arb(a).union(arb(b))
        r = func(ball)
        if not r.is_finite():
            res_lo[i], res_hi[i] = np.nan, np.nan
            continue
        res_lo[i] = float(r.lower())
        res_hi[i] = float(r.upper())
    # float() rounds to nearest: one ulp outward encloses the exact arb ends
    return Interval(_down(out_lo), _up(out_hi))


def norm_lower(v: np.ndarray) -> np.ndarray:
    """A float lower bound of the Euclidean norm of each row of a non-negative ``v`` (B, n)."""
    acc = np.zeros(v.shape[0])
    for j in range(v.shape[1]):
        sq, _ = _prod_bounds(v[:, j], v[:, j])
        acc = _sum_lower(acc, sq)
    root = np.sqrt(acc)
    return np.where(acc == 0, 0.0, np.maximum(_down(root), 0.0))


def norm_upper(v: np.ndarray) -> np.ndarray:
    """A float upper bound of the Euclidean norm of each row of a non-negative ``v`` (B, n)."""
    acc = np.zeros(v.shape[0])
    for j in range(v.shape[1]):
        _, sq = _prod_bounds(v[:, j], v[:, j])
        acc = _sum_upper(acc, sq)
    return np.where(acc == 0, 0.0, _up(np.sqrt(acc)))


def quotient_lower(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A float lower bound of ``a / b`` for ``a >= 0``, ``b > 0``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        q = a / b
    return np.where(a == 0, 0.0, _down(q))
