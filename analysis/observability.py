"""α_ℓ: the uniform observability constant of Definition 2 (2-norms).

    α_ℓ = inf over ū ∈ U^ℓ and x ≠ x' in X of ‖O_ℓ(x, ū) − O_ℓ(x', ū)‖ / ‖x − x'‖,

with ``O_ℓ(x, ū)`` stacking ``h(x, u_1), h(F_1(x, u_1), u_2), …, h(F_{ℓ−1}(x, ū), u_ℓ)`` (see
:mod:`canonid.analysis.maps`). Estimators:

* :func:`alpha_upper` — two **upper bounds** of the infimum: the smallest sampled and locally
  minimised pair ratio, and the smallest ``σ_min(∂O_ℓ/∂x)`` (letting ``x' → x`` along the weakest
  direction gives a ratio → ``σ_min``, so ``α_ℓ ≤ inf σ_min``).
* :func:`alpha_lower` — a **certified lower bound**, the best of:

  - *dimension*: ``ℓ·n_y < n_x`` (on an X with interior) — ``O_ℓ(·, ū)`` cannot be injective,
    ``α_ℓ = 0`` exactly;
  - *unobserved state*: ``O_ℓ`` does not depend on some coordinate ``x_k`` at all (structurally,
    from the CasADi expression graph) while X is wider than a point in it — two states that
    differ only in ``x_k`` give the same outputs, ``α_ℓ = 0`` exactly (the quadrotor's IMU never
    sees the position);
  - *constant Jacobian*: when ``∂O_ℓ/∂x`` is a constant matrix ``M`` (checked symbolically —
    linear systems, the planar drone's ``O_2``), ``O_ℓ`` is affine in ``x`` and ``α_ℓ = σ_min(M)``
    exactly, certified by an interval Cholesky factorisation;
  - *pairs branch-and-bound*: pairs of boxes ``(A, B) ⊆ X × X`` with a box of ``ū``; a pair is
    bounded below by the mean-value bound ``σ_min([∂O/∂x] on hull(A ∪ B) × ū-box)`` and by the
    gap bound ``dist(0, [O(x, ū) − O(x', ū)]) / max ‖x − x'‖``; the pair with the smallest bound
    is refined first. Used where ``2·n_x + (#ū coordinates the Jacobian depends on)`` is small;
  - *monotonicity*: ``O_{ℓ+1}`` contains ``O_ℓ`` as its first block, so ``α_{ℓ+1} ≥ α_ℓ``; a
    certified bound for a shorter window carries over (``previous``).

Inputs ``ū`` are the stacked ``(u_1, …, u_ℓ)`` (``u_1`` applied at time ``t−ℓ``).
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from canonid.analysis._local import local_minima
from canonid.analysis.enclosure import Enclosure, RangeEnclosure, describe_flags
from canonid.analysis.estimate import Bracket, Budget, Estimate
from canonid.analysis.interval import Interval, _sum_upper, norm_lower, norm_upper, quotient_lower
from canonid.analysis.maps import Horizon, batched, check_window, varying_dims
from canonid.analysis.matrix_bounds import smin_lower
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["alpha_bracket", "alpha_lower", "alpha_upper", "input_box"]

Progress = Callable[[str, float], None]


def input_box(U: Box, window: int) -> Box:
    """``U^ℓ`` as one box over the stacked ``ū = (u_1, …, u_ℓ)``."""
    return Box(np.tile(U.lo, window), np.tile(U.hi, window))


def _sets(X: Box, U: Box) -> dict[str, Box]:
    return {"X": X, "U": U}


def _smin(j: np.ndarray) -> np.ndarray:
    """Smallest of the ``n`` singular values of each ``(m, n)`` matrix (0 when ``m < n``).

    A matrix with a non-finite entry (a Jacobian sampled at a singularity, e.g. the tank's √ at
    level 0) attains no ratio: its value is ``inf``, which keeps it out of every minimum.
    """
    out = np.full(j.shape[0], np.inf)
    with np.errstate(invalid="ignore"):
        finite = np.all(np.isfinite(j), axis=(1, 2))
    if j.shape[1] < j.shape[2]:
        out[finite] = 0.0
    elif finite.any():
        out[finite] = np.linalg.svd(j[finite], compute_uv=False)[:, -1]
    return out


def _short(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.4g}" for v in values) + "]"


def _nonfinite_note(hz: Horizon, point: np.ndarray, count: int, total: int) -> dict[str, object]:
    """The label of a sampled bound that skipped ``count`` of ``total`` points where the
    Jacobian is not finite, with the reason the interval evaluator gives at the first one."""
    n = hz.system.n_x
    res = Enclosure(hz.O, wrt=0)([Interval.point(point[None, :n]), Interval.point(point[None, n:])])
    flags = int(res.jac_flags[0])
    return {
        "nonfinite_samples": count,
        "samples": total,
        "nonfinite_reason": (describe_flags(flags) if flags else "it is not finite there")
        + f" (first at x = {_short(point[:n])}, ū = {_short(point[n:])}); those points are "
        "left out of the minimum, which stays an upper bound",
    }


def _interior_dim(X: Box) -> int:
    return int(np.count_nonzero(X.width > 0))


# ---------------------------------------------------------------------------------- upper bounds
def _upper(
    ell: int,
    X: Box,
    U: Box,
    value: float,
    method: str,
    budget: Budget,
    t0: float,
    details: dict[str, object],
) -> Estimate:
    return Estimate(
        quantity="alpha",
        value=max(value, 0.0),
        kind="upper",
        sets=_sets(X, U),
        method=method,
        window=ell,
        budget={"samples": budget.samples, "starts": budget.starts},
        seconds=time.perf_counter() - t0,
        details=details,
    )


def _uniform_rows(rng: np.random.Generator, boxes: Sequence[Box], count: int) -> np.ndarray:
    """``count`` rows, each the concatenation of one uniform point per box."""
    return np.concatenate([rng.uniform(b.lo, b.hi, size=(count, b.dim)) for b in boxes], axis=1)


def _upper_smin(
    hz: Horizon, X: Box, U: Box, budget: Budget, rng: np.random.Generator
) -> tuple[float, np.ndarray, dict[str, object]]:
    """Smallest ``σ_min(∂O/∂x)`` over samples and local minimisations of ``‖J d‖²/‖d‖²``;
    samples where the Jacobian is not finite are left out and counted in the returned notes."""
    n, ubox = hz.system.n_x, input_box(U, hz.window)
    pts = _uniform_rows(rng, (X, ubox), budget.samples)

    def jacobians(points: np.ndarray) -> np.ndarray:
        _, jac = batched(hz.O_jacobian, points[:, :n], points[:, n:])
        return jac.reshape(points.shape[0], hz.n_obs, n)

    values = _smin(jacobians(pts))
    skipped = np.flatnonzero(~np.isfinite(values))
    notes = {} if not skipped.size else _nonfinite_note(hz, pts[skipped[0]], skipped.size, len(pts))
    best = int(np.argmin(values))
    if hz.n_obs < n or not 0 < values[best] < np.inf:
        return float(values[best]), pts[best], notes
    x, ub, d = ca.SX.sym("x", n), ca.SX.sym("u", ubox.dim), ca.SX.sym("d", n)
    jd = ca.jtimes(hz.O(x, ub), x, d)
    order = np.argsort(values)[: budget.starts]
    order = order[np.isfinite(values[order])]
    weakest = np.linalg.svd(jacobians(pts[order]))[2][:, -1, :]  # right singular vectors
    ends = local_minima(
        ca.sumsqr(jd) / (ca.sumsqr(d) + 1e-300),
        ca.vertcat(x, ub, d),
        list(np.concatenate([pts[order], weakest], axis=1)),
        list(zip(X.lo, X.hi)) + list(zip(ubox.lo, ubox.hi)) + [(None, None)] * n,
    )
    every = np.concatenate([pts, np.array(ends)[:, : n + ubox.dim]])
    all_values = np.concatenate([values, _smin(jacobians(every[len(pts) :]))])
    best = int(np.argmin(all_values))
    return float(all_values[best]), every[best], notes


def _upper_pairs(
    hz: Horizon, X: Box, U: Box, budget: Budget, rng: np.random.Generator
) -> tuple[float, np.ndarray, dict[str, object]]:
    """Smallest pair ratio over samples and local minimisations of the squared ratio."""
    n, ubox = hz.system.n_x, input_box(U, hz.window)
    pairs = _uniform_rows(rng, (X, X, ubox), budget.samples)

    def ratios(p: np.ndarray) -> np.ndarray:
        (oa,) = batched(hz.O, p[:, :n], p[:, 2 * n :])
        (ob,) = batched(hz.O, p[:, n : 2 * n], p[:, 2 * n :])
        dist = np.linalg.norm(p[:, :n] - p[:, n : 2 * n], axis=1)
        safe = np.where(dist > 0, dist, 1.0)
        return np.where(dist > 0, np.linalg.norm(oa - ob, axis=1) / safe, np.inf)

    values = ratios(pairs)
    x1, x2, ub = ca.SX.sym("x1", n), ca.SX.sym("x2", n), ca.SX.sym("u", ubox.dim)
    ends = local_minima(
        ca.sumsqr(hz.O(x1, ub) - hz.O(x2, ub)) / (ca.sumsqr(x1 - x2) + 1e-300),
        ca.vertcat(x1, x2, ub),
        list(pairs[np.argsort(values)[: budget.starts]]),
        list(zip(X.lo, X.hi)) * 2 + list(zip(ubox.lo, ubox.hi)),
    )
    every = np.concatenate([pairs, np.array(ends)])
    all_values = np.concatenate([values, ratios(every[len(pairs) :])])
    best = int(np.argmin(all_values))
    return float(all_values[best]), every[best], {}


def alpha_upper(
    system: System,
    window: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    budget: Budget | None = None,
    seed: int = 0,
) -> list[Estimate]:
    """Two upper bounds of α_ℓ: inf ``σ_min(∂O_ℓ/∂x)`` and the smallest pair ratio.

    Each is the best of ``budget.samples`` random points (pairs) and ``budget.starts`` local
    minimisations (L-BFGS-B, CasADi gradients) started from the best ones. Both are values
    attained at points, so each is ≥ α_ℓ (up to float rounding).
    """
    ell = check_window(window)
    budget = budget or Budget()
    X, U = X or system.X, U or system.U
    hz = Horizon(system, ell)
    rng = np.random.default_rng(seed)
    searches = (
        (_upper_smin, "inf σ_min(∂O_ℓ/∂x), sampled + local min (CasADi, L-BFGS-B)", "argmin"),
        (
            _upper_pairs,
            "inf pair ratio ‖O(x,ū)−O(x',ū)‖/‖x−x'‖, sampled + local min",
            "argmin_pair",
        ),
    )
    results = []
    for search, method, key in searches:
        t0 = time.perf_counter()
        value, point, notes = search(hz, X, U, budget, rng)
        details = {key: point.tolist(), "seed": seed, **notes}
        results.append(_upper(ell, X, U, value, method, budget, t0, details))
    return results


# ---------------------------------------------------------------------------------- lower bounds
def _exact_zero(ell: int, X: Box, U: Box, reason: str, **details: Any) -> Estimate:
    """``α_ℓ = 0`` exactly, for ``reason``."""
    return Estimate(
        quantity="alpha",
        value=0.0,
        kind="lower",
        sets=_sets(X, U),
        method=f"exact: {reason}",
        window=ell,
        details={"exact": True, **details},
    )


def _dimension_zero(system: System, ell: int, X: Box, U: Box) -> Estimate | None:
    if ell * system.n_y >= _interior_dim(X):
        return None
    reason = f"ℓ·n_y = {ell * system.n_y} < n_x = {_interior_dim(X)}, O_ℓ(·,ū) is not injective"
    return _exact_zero(ell, X, U, reason)


def _state_jacobian(system: System, ell: int) -> ca.SX:
    """``∂O_ℓ/∂x`` as an SX expression of ``(x, ū)``."""
    hz = Horizon(system, ell)
    x = ca.SX.sym("x", system.n_x)
    ub = ca.SX.sym("u", hz.n_ubar)
    return ca.jacobian(hz.O(x, ub), x)


def _unobserved(system: System, ell: int, X: Box, U: Box, jac: ca.SX) -> Estimate | None:
    """``α_ℓ = 0`` when a column of ``∂O_ℓ/∂x`` is structurally zero where X has width."""
    column_nnz = np.diff(np.asarray(jac.sparsity().colind()))
    unseen = np.flatnonzero((column_nnz == 0) & (X.width > 0))
    if unseen.size == 0:
        return None
    names = [system.state_names[k] for k in unseen]
    reason = (
        f"O_ℓ(x,ū) does not depend on {', '.join(names)} (structurally), states differing "
        "only there give the same outputs"
    )
    return _exact_zero(ell, X, U, reason, unobserved_states=names)


def _constant_jacobian(system: System, ell: int, X: Box, U: Box, jac: ca.SX) -> Estimate | None:
    if not jac.is_constant():
        return None
    t0 = time.perf_counter()
    m = np.asarray(ca.DM(jac), dtype=np.float64)
    value = float(smin_lower(Interval.point(m[None, :, :]))[0])
    return Estimate(
        quantity="alpha",
        value=value,
        kind="lower",
        sets=_sets(X, U),
        method=(
            "exact: ∂O_ℓ/∂x is a constant matrix M (CasADi), "
            "α_ℓ = σ_min(M) certified by interval Cholesky"
        ),
        window=ell,
        seconds=time.perf_counter() - t0,
        details={"exact": True, "sigma_min_float": float(_smin(m[None])[0]), "matrix": m.tolist()},
    )


def _monotone(previous: Sequence[Estimate], ell: int, X: Box, U: Box) -> Estimate | None:
    usable = [
        e
        for e in previous
        if e.quantity == "alpha"
        and e.kind == "lower"
        and e.window is not None
        and e.window < ell
        and e.sets.get("X") == X
        and e.sets.get("U") == U
    ]
    if not usable:
        return None
    best = max(usable, key=lambda e: e.value)
    return Estimate(
        quantity="alpha",
        value=best.value,
        kind="lower",
        sets=_sets(X, U),
        method=f"monotone: α_ℓ ≥ α_{best.window} ({best.method})",
        window=ell,
        details={"from_window": best.window},
    )


class _Node(NamedTuple):
    """A pair of boxes ``A ∋ x``, ``B ∋ x'`` with a box of ``ū``; ``diag`` when ``A = B``."""

    a_lo: np.ndarray
    a_hi: np.ndarray
    b_lo: np.ndarray
    b_hi: np.ndarray
    u_lo: np.ndarray
    u_hi: np.ndarray
    diag: bool


def _halves(lo: np.ndarray, hi: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut ``[lo, hi]`` at the middle of coordinate ``k``: the first half's upper corner and the
    second half's lower corner."""
    mid = 0.5 * lo[k] + 0.5 * hi[k]
    h1, l2 = hi.copy(), lo.copy()
    h1[k], l2[k] = mid, mid
    return h1, l2


class _PairSearch:
    """Bounds and splits of the pair nodes for the infimum of the pair ratio."""

    def __init__(self, system: System, ell: int, X: Box, U: Box) -> None:
        hz = Horizon(system, ell)
        self.n = system.n_x
        self.ubox = input_box(U, ell)
        self.m = hz.n_obs
        self.jac_enclosure = Enclosure(hz.O, wrt=0)
        x1 = ca.SX.sym("x1", self.n)
        x2 = ca.SX.sym("x2", self.n)
        ub = ca.SX.sym("u", self.ubox.dim)
        d = hz.O(x1, ub) - hz.O(x2, ub)
        e = ca.SX.sym("e", self.m)
        self.diff_enclosure = RangeEnclosure(ca.Function("D", [ca.vertcat(x1, x2), ub], [d]))
        # eᵀD for a unit vector e: ‖D‖ ≥ eᵀD keeps the correlation between the components
        self.proj_enclosure = RangeEnclosure(
            ca.Function("eD", [ca.vertcat(x1, x2), ca.vertcat(ub, e)], [ca.dot(e, d)])
        )
        self.O, self.O_jac = hz.O, hz.O_jacobian
        _, du = varying_dims(hz.O)
        self.xscale = np.where(X.width > 0, X.width, 1.0)
        self.uscale = np.where(self.ubox.width > 0, self.ubox.width, 1.0)
        self.xmask = X.width > 0
        self.umask = du & (self.ubox.width > 0)

    def _gap_bound(
        self,
        a_lo: np.ndarray,
        a_hi: np.ndarray,
        b_lo: np.ndarray,
        b_hi: np.ndarray,
        u_lo: np.ndarray,
        u_hi: np.ndarray,
    ) -> np.ndarray:
        """``dist(0, [O(x,ū) − O(x',ū)]) / max ‖x − x'‖`` over the pair (rounded down)."""
        lo = np.concatenate([a_lo, b_lo, u_lo], axis=1)
        hi = np.concatenate([a_hi, b_hi, u_hi], axis=1)
        enc, flags, _ = self.diff_enclosure(lo, hi)
        gap = np.where(enc.lo > 0, enc.lo, np.where(enc.hi < 0, -enc.hi, 0.0))
        gap_norm = norm_lower(np.where((flags == 0)[:, None], gap, 0.0))
        centre = enc.mid
        length = np.linalg.norm(centre, axis=1)
        unit = centre / np.where(length > 0, length, 1.0)[:, None]
        proj, pflags, _ = self.proj_enclosure(
            np.concatenate([lo, unit], axis=1), np.concatenate([hi, unit], axis=1)
        )
        gap_norm = np.maximum(gap_norm, np.where((pflags == 0) & (length > 0), proj.lo[:, 0], 0.0))
        far = np.maximum(_sum_upper(a_hi, -b_lo), _sum_upper(b_hi, -a_lo))
        return quotient_lower(gap_norm, norm_upper(far))

    def bounds(self, nodes: Sequence[_Node]) -> tuple[np.ndarray, np.ndarray]:
        """Per node: a certified lower bound of the ratio and a ratio attained at its centre."""
        a_lo, a_hi, b_lo, b_hi, u_lo, u_hi = (np.array(c) for c in list(zip(*nodes))[:6])
        diag = np.array([node.diag for node in nodes], dtype=bool)
        res = self.jac_enclosure(
            [Interval(np.minimum(a_lo, b_lo), np.maximum(a_hi, b_hi)), Interval(u_lo, u_hi)]
        )
        assert res.jacobians is not None
        lower = np.where(res.jac_flags == 0, smin_lower(res.jacobians[0]), 0.0)
        off = ~diag
        if off.any():
            gap = self._gap_bound(a_lo[off], a_hi[off], b_lo[off], b_hi[off], u_lo[off], u_hi[off])
            lower[off] = np.maximum(lower[off], gap)
        # values at points: σ_min at the centre, and the ratio between the two centres
        xa, xb, uc = 0.5 * (a_lo + a_hi), 0.5 * (b_lo + b_hi), 0.5 * (u_lo + u_hi)
        _, j = batched(self.O_jac, xa, uc)
        attained = _smin(j.reshape(-1, self.m, self.n))
        if off.any():
            (oa,) = batched(self.O, xa[off], uc[off])
            (ob,) = batched(self.O, xb[off], uc[off])
            dist = np.linalg.norm(xa[off] - xb[off], axis=1)
            ratio = np.linalg.norm(oa - ob, axis=1) / np.maximum(dist, 1e-300)
            attained[off] = np.minimum(attained[off], ratio)
        return lower, attained

    def split(self, node: _Node) -> list[_Node]:
        """Halve the widest coordinate (relative to X or U) of A, B or ū.

        A diagonal node ``(A, A)`` cut into ``A1, A2`` gives ``(A1, A1)``, ``(A2, A2)`` and
        ``(A1, A2)`` (the ratio is symmetric, so ``(A2, A1)`` is not needed).
        """
        wa = np.where(self.xmask, (node.a_hi - node.a_lo) / self.xscale, -1.0)
        wb = np.where(self.xmask, (node.b_hi - node.b_lo) / self.xscale, -1.0)
        wu = np.where(self.umask, (node.u_hi - node.u_lo) / self.uscale, -1.0)
        widest = [wa.max(), -1.0 if node.diag else wb.max(), wu.max() if wu.size else -1.0]
        which = int(np.argmax(widest))
        if which == 2:
            h1, l2 = _halves(node.u_lo, node.u_hi, int(np.argmax(wu)))
            return [node._replace(u_hi=h1), node._replace(u_lo=l2)]
        if which == 0:
            h1, l2 = _halves(node.a_lo, node.a_hi, int(np.argmax(wa)))
            if node.diag:
                return [
                    node._replace(a_hi=h1, b_hi=h1),
                    node._replace(a_lo=l2, b_lo=l2),
                    node._replace(a_hi=h1, b_lo=l2, diag=False),
                ]
            return [node._replace(a_hi=h1), node._replace(a_lo=l2)]
        h1, l2 = _halves(node.b_lo, node.b_hi, int(np.argmax(wb)))
        return [node._replace(b_hi=h1), node._replace(b_lo=l2)]


def _pairs_branch_and_bound(
    system: System,
    ell: int,
    X: Box,
    U: Box,
    *,
    tol: float,
    budget: Budget,
    upper: float,
    batch: int,
    progress: Progress | None,
) -> Estimate:
    t0 = time.perf_counter()
    search = _PairSearch(system, ell, X, U)
    ubox = search.ubox
    counter = itertools.count()
    best = upper

    def evaluate(nodes: list[_Node]) -> list[tuple[float, int, _Node]]:
        nonlocal best
        lower, attained = search.bounds(nodes)
        best = min(best, float(attained.min()))
        return [(float(lower[i]), next(counter), nodes[i]) for i in range(len(nodes))]

    heap = evaluate([_Node(X.lo, X.hi, X.lo, X.hi, ubox.lo, ubox.hi, True)])
    evaluated = 1
    stop = "tolerance reached"
    while heap:
        lower = min(heap[0][0], best)
        if best - lower <= tol * best:
            break
        exhausted = budget.exhausted(evaluated, t0)
        if exhausted:
            stop = exhausted
            break
        popped = [heapq.heappop(heap) for _ in range(min(batch, len(heap)))]
        children = [c for _, _, node in popped for c in search.split(node)]
        evaluated += len(children)
        for item in evaluate(children):
            if item[0] < best:  # a pair bounded below by a ratio already attained is irrelevant
                heapq.heappush(heap, item)
        if progress is not None and heap:
            progress(
                f"α_{ell} bracket [{heap[0][0]:.4g}, {best:.4g}]",
                budget.used(evaluated, t0),
            )
    lower = min(heap[0][0], best) if heap else best
    return Estimate(
        quantity="alpha",
        value=max(float(lower), 0.0),
        kind="lower",
        sets=_sets(X, U),
        method=(
            "certified: pairs-of-boxes branch-and-bound (mean-value σ_min + gap bounds, interval)"
        ),
        window=ell,
        budget=budget.to_dict(),
        seconds=time.perf_counter() - t0,
        details={"boxes": evaluated, "stop": stop, "tol": tol, "upper_found": best},
    )


def alpha_lower(
    system: System,
    window: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    previous: Sequence[Estimate] = (),
    upper: float | None = None,
    tol: float = 0.1,
    budget: Budget | None = None,
    max_pair_dims: int = 7,
    batch: int = 64,
    progress: Progress | None = None,
) -> Estimate:
    """The best certified lower bound of α_ℓ available (see the module docstring).

    Args:
        system, window: the system and ``ℓ``.
        X, U: the sets (default: the system's).
        previous: certified lower bounds for shorter windows on the same sets (monotonicity).
        upper: an upper bound of α_ℓ (stops the pair search within ``tol`` of it).
        tol: relative tolerance of the pair search.
        budget: ``boxes``/``seconds`` of the pair search.
        max_pair_dims: the pair search runs when ``2·n_x + #ū coordinates it must split`` is
            at most this; above, only the dimension, constant-Jacobian and monotone bounds apply.
        batch: pairs refined per round.
        progress: optional callback ``(message, fraction)``.
    """
    ell = check_window(window)
    X, U = X or system.X, U or system.U
    budget = budget or Budget()
    jac = _state_jacobian(system, ell)
    exact = (
        _unobserved(system, ell, X, U, jac)
        or _dimension_zero(system, ell, X, U)
        or _constant_jacobian(system, ell, X, U, jac)
    )
    if exact is not None:
        return exact
    candidates = []
    mono = _monotone(previous, ell, X, U)
    if mono is not None:
        candidates.append(mono)
    hz = Horizon(system, ell)
    _, du = varying_dims(hz.O)
    dims = 2 * _interior_dim(X) + int(np.count_nonzero(du & (input_box(U, ell).width > 0)))
    if dims <= max_pair_dims:
        if upper is None:
            upper = min(
                e.value
                for e in alpha_upper(system, ell, X=X, U=U, budget=Budget(samples=512, starts=2))
            )
        candidates.append(
            _pairs_branch_and_bound(
                system,
                ell,
                X,
                U,
                tol=tol,
                budget=budget,
                upper=upper,
                batch=batch,
                progress=progress,
            )
        )
    if not candidates:
        return Estimate(
            quantity="alpha",
            value=0.0,
            kind="lower",
            sets=_sets(X, U),
            method=(
                f"trivial (no certified bound: the pair search has {dims} > "
                f"{max_pair_dims} dimensions)"
            ),
            window=ell,
        )
    return max(candidates, key=lambda e: e.value)


def alpha_bracket(
    system: System,
    window: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    previous: Sequence[Estimate] = (),
    tol: float = 0.1,
    budget: Budget | None = None,
    max_pair_dims: int = 7,
    seed: int = 0,
    progress: Progress | None = None,
) -> Bracket:
    """The certified lower bound and the best sampled upper bound of α_ℓ."""
    uppers = alpha_upper(system, window, X=X, U=U, budget=budget, seed=seed)
    up = min(uppers, key=lambda e: e.value)
    low = alpha_lower(
        system,
        window,
        X=X,
        U=U,
        previous=previous,
        upper=up.value,
        tol=tol,
        budget=budget,
        max_pair_dims=max_pair_dims,
        progress=progress,
    )
    found = low.details.get("upper_found")
    if found is not None and found < up.value:
        up = Estimate(
            quantity="alpha",
            value=float(found),
            kind="upper",
            sets=up.sets,
            method="pair/σ_min value at a branch-and-bound box centre",
            window=up.window,
            seconds=up.seconds,
        )
    return Bracket.reconcile(low, up)
