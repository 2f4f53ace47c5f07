"""γ: the uniform Lipschitz constant in ``x`` of a map ``g(x, u)`` over ``X × U`` (2-norm).

Used for ``γ_f`` (``g = f``) and ``γ_h`` (``g = h``). On a convex ``X`` the constant is
``sup_{X×U} ‖∂g/∂x‖₂`` (for the clipped tank, the supremum of the norms of Clarke's generalised
Jacobian, which the interval enclosure contains).

* :func:`lipschitz_lower` — a **lower bound**: the largest ‖∂g/∂x(x, u)‖₂ found by sampling
  (box corners included) and local maximisation of ``‖J d‖² / ‖d‖²`` over ``(x, u, d)``
  (L-BFGS-B, CasADi gradients).
* :func:`lipschitz_upper` — a **certified upper bound**: branch-and-bound over sub-boxes of
  ``X × U`` (split only along the coordinates the Jacobian depends on), each box bounded by the
  verified spectral norm (:func:`canonid.analysis.matrix_bounds.spectral_upper`) of its interval
  Jacobian (:class:`canonid.analysis.enclosure.Enclosure`); the boxes with the largest bound are
  refined first (a batch at a time) until ``upper − lower ≤ tol · lower`` or the budget ends.

A Jacobian that cannot be bounded near a point — the tank's ``√`` at 0 — raises
:class:`~canonid.kernel.errors.SetError` saying why: there γ is infinite, not a number to report.
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from canonid.analysis._local import local_minima
from canonid.analysis.enclosure import Enclosure, describe_flags
from canonid.analysis.estimate import Bracket, Budget, Estimate, OutOfTime
from canonid.analysis.interval import Interval
from canonid.analysis.maps import batched, jacobian_function, varying_dims
from canonid.analysis.matrix_bounds import spectral_upper
from canonid.kernel.errors import SetError
from canonid.models.sets import Box

__all__ = ["lipschitz_bracket", "lipschitz_lower", "lipschitz_upper"]

Progress = Callable[[str, float], None]


def _corners(lo: np.ndarray, hi: np.ndarray, limit: int = 256) -> np.ndarray:
    d = lo.size
    if 2**d <= limit:
        bits = np.array(list(itertools.product((0, 1), repeat=d)), dtype=bool)
    else:
        bits = np.random.default_rng(0).integers(0, 2, size=(limit, d)).astype(bool)
    return np.where(bits, hi, lo)


def _unbounded_error(
    quantity: str, fun: ca.Function, where: str, point: np.ndarray, n_x: int, why: str | None
) -> SetError:
    """The error for a Jacobian without a finite bound near ``point``.

    Without a known reason (a sampled point where the float Jacobian is not finite) the
    interval evaluator is run on the point itself to name the operation responsible.
    """
    if why is None:
        res = Enclosure(fun, wrt=0)(
            [Interval.point(point[None, :n_x]), Interval.point(point[None, n_x:])]
        )
        flags = int(res.jac_flags[0])
        why = describe_flags(flags) if flags else "it is not finite there"
    advice = (
        "The set is too large for float64: shrink it."
        if why.startswith("an overflow")
        else "Move the set away from the singularity (e.g. the tank's eps > 0, and inputs "
        "that keep the levels away from 0)."
    )
    return SetError(
        f"{quantity} is unbounded on {where}: near x = {_point(point[:n_x])}, "
        f"u = {_point(point[n_x:])} the Jacobian of {fun.name()} has no finite bound "
        f"({why}). {advice}"
    )


def _reason(flags: int) -> str:
    """Words for an unusable Jacobian enclosure (flags 0: finite entries whose norm overflows)."""
    return describe_flags(flags) if flags else "entries too large for a finite norm in float64"


def _point(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"


#: ``(x, u)`` rows → the Jacobians ``∂f/∂x`` there, ``(N, n_out, n_x)``: a fast numpy path for a
#: function whose SX graph is slow to evaluate (a wide learned network)
JacobianRows = Callable[[np.ndarray, np.ndarray], np.ndarray]


class _CasadiRows:
    """Point Jacobians ``∂fun/∂x`` by CasADi (a :data:`JacobianRows`), its SX Jacobian built at
    the first call — seconds for a large network, so only when a stage uses it, and once for
    the stages that share it; ``build_seconds`` says how long that took."""

    def __init__(self, fun: ca.Function) -> None:
        self.fun = fun
        self.build_seconds = 0.0
        self._jac: ca.Function | None = None

    def __call__(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        if self._jac is None:
            t0 = time.perf_counter()
            self._jac = jacobian_function(self.fun)
            self.build_seconds = time.perf_counter() - t0
        return batched(self._jac, x, u)[1]


#: points evaluated between two looks at the clock by a sampled bound (a 3 × 128 GRU model
#: takes ~35 ms a point through CasADi; a registered system or an MLP model microseconds)
_SAMPLE_CHUNK = 32


def _norms(rows: JacobianRows, pts: np.ndarray, n_x: int) -> np.ndarray:
    """``‖∂f/∂x‖₂`` at the rows of ``pts`` (the Jacobians from ``rows``)."""
    j = np.asarray(rows(pts[:, :n_x], pts[:, n_x:]), dtype=np.float64)
    if j.ndim == 2:
        j = j[:, :, None] if n_x == 1 else j[:, None, :]
    with np.errstate(invalid="ignore"):
        finite = np.all(np.isfinite(j), axis=(1, 2))
        out = np.full(pts.shape[0], np.inf)
        if finite.any():
            out[finite] = np.linalg.norm(j[finite], ord=2, axis=(1, 2))
    return out


def lipschitz_lower(
    fun: ca.Function,
    X: Box,
    U: Box,
    *,
    quantity: str = "gamma_f",
    window: int | None = None,
    budget: Budget | None = None,
    seed: int = 0,
    where: str = "X × U",
    jacobian: JacobianRows | None = None,
) -> Estimate:
    """Sampled and locally maximised ``sup ‖∂fun/∂x‖₂`` over ``X × U``: a **lower bound**.

    Args:
        fun: CasADi function of ``(x, u)``.
        X, U: boxes for ``x`` and ``u``.
        quantity, window: labels of the result (``"gamma_f"``/``"gamma_h"``).
        budget: ``samples`` random points (plus the corners), ``starts`` local maximisations;
            its ``seconds`` end the stage early (checked every few points and during each
            local search: ``details["stop"]`` says so and how far it got). The local searches
            start only while the time left exceeds what CasADi took to build the Jacobian,
            their set-up costing about as much.
        seed: random seed (same seed, same result).
        where: words naming the set, for error messages.
        jacobian: the Jacobians at many points at once, in place of CasADi's on ``fun`` (the
            same numbers, e.g. :meth:`canonid.models.learned.LearnedSystem.linearise`).

    Raises:
        SetError: the Jacobian is not finite at a sampled point (γ unbounded).
    """
    budget = budget or Budget()
    t0 = time.perf_counter()
    deadline = budget.deadline(t0)
    n_x = fun.nnz_in(0)
    rows = jacobian if jacobian is not None else _CasadiRows(fun)
    lo = np.concatenate([X.lo, U.lo])
    hi = np.concatenate([X.hi, U.hi])
    rng = np.random.default_rng(seed)
    pts = np.concatenate([_corners(lo, hi), rng.uniform(lo, hi, size=(budget.samples, lo.size))])
    total, norms = len(pts), np.empty(len(pts))
    done = 0  # the points evaluated, in order: the first chunk always
    while done < len(pts) and (done == 0 or time.perf_counter() <= deadline):
        chunk = pts[done : done + _SAMPLE_CHUNK]
        norms[done : done + len(chunk)] = _norms(rows, chunk, n_x)
        done += len(chunk)
    pts, norms = pts[:done], norms[:done]
    if not np.all(np.isfinite(norms)):
        i = int(np.flatnonzero(~np.isfinite(norms))[0])
        raise _unbounded_error(quantity, fun, where, pts[i], n_x, None)
    best = float(norms.max())
    best_pt = pts[int(np.argmax(norms))]
    ends: list[np.ndarray] = []
    set_up = getattr(rows, "build_seconds", 0.0)
    if time.perf_counter() + set_up < deadline:
        # local maximisation of ‖J d‖²/‖d‖² over (x, u, d), from the best samples
        x = ca.SX.sym("x", n_x)
        u = ca.SX.sym("u", fun.nnz_in(1))
        d = ca.SX.sym("d", n_x)
        jd = ca.jtimes(fun(x, u), x, d)
        starts = []
        for i in np.argsort(-norms)[: budget.starts]:
            j = np.asarray(rows(pts[i : i + 1, :n_x], pts[i : i + 1, n_x:])[0]).reshape(-1, n_x)
            starts.append(np.concatenate([pts[i], np.linalg.svd(j)[2][0]]))
        ends = local_minima(
            -ca.sumsqr(jd) / (ca.sumsqr(d) + 1e-300),
            ca.vertcat(x, u, d),
            starts,
            list(zip(lo, hi)) + [(None, None)] * n_x,
            deadline=deadline,
        )
    for end in ends:
        value = float(_norms(rows, end[None, : lo.size], n_x)[0])
        if np.isfinite(value) and value > best:
            best, best_pt = value, end[: lo.size]
    complete = done == total and len(ends) == min(budget.starts, done)
    complete = complete and time.perf_counter() <= deadline  # else the last search was cut
    stop = "all samples and local searches done" if complete else "time budget exhausted"
    return Estimate(
        quantity=quantity,
        value=best,
        kind="lower",
        sets={"X": X, "U": U},
        method="sampled + local max of ‖∂g/∂x‖₂ (CasADi, L-BFGS-B)",
        window=window,
        budget={"samples": budget.samples, "starts": budget.starts},
        seconds=time.perf_counter() - t0,
        details={
            "argmax": best_pt.tolist(),
            "seed": seed,
            "points_evaluated": done,
            "local_searches": len(ends),
            "stop": stop,
        },
    )


def _split(
    lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, mask: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    rel = np.where(mask, (hi - lo) / scale, -1.0)
    k = int(np.argmax(rel))
    mid = 0.5 * lo[k] + 0.5 * hi[k]
    hi1, lo2 = hi.copy(), lo.copy()
    hi1[k] = mid
    lo2[k] = mid
    return [(lo, hi1), (lo2, hi)]


def lipschitz_upper(
    fun: ca.Function,
    X: Box,
    U: Box,
    *,
    quantity: str = "gamma_f",
    window: int | None = None,
    lower: Estimate | None = None,
    tol: float = 0.05,
    budget: Budget | None = None,
    batch: int = 32,
    where: str = "X × U",
    progress: Progress | None = None,
    enclosure: Any | None = None,
    jacobian: JacobianRows | None = None,
) -> Estimate:
    """Certified upper bound of ``sup ‖∂fun/∂x‖₂`` over ``X × U`` by interval branch-and-bound.

    Args:
        fun: CasADi SX function of ``(x, u)``.
        X, U: boxes for ``x`` and ``u``.
        lower: a lower bound (from :func:`lipschitz_lower`) to stop early and prune with; box
            centres raise it further during the search.
        tol: stop when ``upper − lower ≤ tol · lower``.
        budget: ``boxes`` and ``seconds`` limit the search; the bound is valid whenever it stops.
            When the budget ends while a box still has no finite Jacobian enclosure, the result
            is the trivial bound ``inf`` (method ``"trivial: ..."``, ``details["why"]`` names the
            box and the operation).
        batch: boxes refined per round (the worst first).
        where: words naming the set, for error messages.
        progress: optional callback ``(message, fraction_done)``.
        enclosure: encloses ``fun`` and its Jacobian in ``x`` on boxes, called as
            :class:`~canonid.analysis.enclosure.Enclosure` is (default: that class on ``fun``'s SX
            graph; :class:`canonid.analysis.network_enclosure.NetworkEnclosure` is the fast one for
            an MLP model); its ``method`` attribute, if any, describes the bound.
        jacobian: point Jacobians for the box centres, as in :func:`lipschitz_lower`.

    Raises:
        SetError: a box around a point keeps an unbounded Jacobian enclosure down to width
            ~1e-9 (γ is infinite there: the message names the reason, e.g. √ at 0).
    """
    budget = budget or Budget()
    if not (tol >= 0):
        raise SetError(f"tol must be >= 0, got {tol}")
    t0 = time.perf_counter()
    deadline = budget.deadline(t0)
    n_x = fun.nnz_in(0)
    method = getattr(
        enclosure, "method", "certified: interval Jacobian branch-and-bound (outward rounding, arb)"
    )
    rows = jacobian if jacobian is not None else _CasadiRows(fun)
    lo0 = np.concatenate([X.lo, U.lo])
    hi0 = np.concatenate([X.hi, U.hi])
    try:  # the set-up walks the whole graph: minutes for a large network, so it counts too
        enclosure = enclosure or Enclosure(fun, wrt=0, deadline=deadline)
        dx, du = varying_dims(fun)
        if time.perf_counter() > deadline:
            raise OutOfTime
    except OutOfTime:
        return _out_of_time(quantity, X, U, window, budget, t0, where, "preparing the search")
    scale = np.where(hi0 > lo0, hi0 - lo0, 1.0)
    mask = np.concatenate([dx, du]) & (hi0 > lo0)
    best = lower.value if lower is not None else 0.0

    def singular_corner(
        lo: np.ndarray, hi: np.ndarray, dims: np.ndarray
    ) -> tuple[np.ndarray, int] | None:
        """A corner of the box (over the split coordinates) where the Jacobian enclosure of
        the single point is already unbounded: γ is infinite there, not just hard to bound."""
        corners = _corners(lo[dims], hi[dims], limit=16)
        points = np.tile(lo, (corners.shape[0], 1))
        points[:, dims] = corners
        res = enclosure([Interval.point(points[:, :n_x]), Interval.point(points[:, n_x:])])
        bad = np.flatnonzero(res.jac_flags != 0)
        return (points[bad[0]], int(res.jac_flags[bad[0]])) if bad.size else None

    def evaluate(boxes: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        nonlocal best
        blo = np.array([b[0] for b in boxes])
        bhi = np.array([b[1] for b in boxes])
        res = enclosure(
            [Interval(blo[:, :n_x], bhi[:, :n_x]), Interval(blo[:, n_x:], bhi[:, n_x:])]
        )
        assert res.jacobians is not None
        ub = spectral_upper(res.jacobians[0])
        flagged = res.jac_flags != 0
        ub = np.where(flagged, np.inf, ub)
        centre = 0.5 * blo + 0.5 * bhi
        norms = _norms(rows, centre, n_x)
        tiny = np.all(np.where(mask, (bhi - blo) / scale, 0.0) < 1e-9, axis=1)
        stuck = flagged & (tiny | (not mask.any()))
        if stuck.any() or not np.all(np.isfinite(norms)):
            i = int(np.flatnonzero(stuck | ~np.isfinite(norms))[0])
            why = describe_flags(int(res.jac_flags[i])) if flagged[i] else None
            raise _unbounded_error(quantity, fun, where, centre[i], n_x, why)
        for k in np.flatnonzero(flagged):
            singular = singular_corner(blo[k], bhi[k], mask)
            if singular is not None:
                point, flags = singular
                raise _unbounded_error(quantity, fun, where, point, n_x, describe_flags(flags))
        best = max(best, float(norms.max()))
        return ub

    counter = itertools.count()
    root = (lo0, hi0)
    heap: list[tuple[float, int, np.ndarray, np.ndarray]] = []
    try:
        ub0 = evaluate([root])[0]
    except OutOfTime:
        return _out_of_time(quantity, X, U, window, budget, t0, where, "the first box")
    heapq.heappush(heap, (-ub0, next(counter), lo0, hi0))
    evaluated = 1
    stop_reason = "tolerance reached"
    while heap:
        upper = -heap[0][0]
        if upper <= best * (1.0 + tol) or not mask.any():
            break
        exhausted = budget.exhausted(evaluated, t0)
        if exhausted:
            stop_reason = exhausted
            break
        popped = [heapq.heappop(heap) for _ in range(min(batch, len(heap)))]
        children = [c for _, _, lo, hi in popped for c in _split(lo, hi, scale, mask)]
        try:
            ubs = evaluate(children)
        except OutOfTime:  # the parents' bounds still hold: they go back, unsplit
            for item in popped:
                heapq.heappush(heap, item)
            stop_reason = "time budget exhausted"
            break
        evaluated += len(children)
        for (clo, chi), ub in zip(children, ubs):
            if ub > best:  # a box whose bound is below a value attained cannot hold the sup
                heapq.heappush(heap, (-float(ub), next(counter), clo, chi))
        if progress is not None and heap:
            gap = (-heap[0][0] - best) / max(best, 1e-300)
            progress(
                f"{quantity} bracket [{best:.4g}, {-heap[0][0]:.4g}]",
                max(min(1.0, tol / max(gap, 1e-300)), budget.used(evaluated, t0)),
            )
    upper = max(-heap[0][0], best) if heap else best
    details: dict[str, Any] = {
        "boxes": evaluated,
        "stop": stop_reason,
        "tol": tol,
        "lower_found": best,
        "split_dims": np.flatnonzero(mask).tolist(),
    }
    if np.isfinite(upper):
        details["relative_gap"] = (upper - best) / best if best > 0 else None
    else:
        # out of budget with a box whose Jacobian enclosure is still unusable (an overflow, or
        # an operation whose enclosure is not decided yet): the honest bound is the trivial one
        _, _, wlo, whi = heap[0]
        try:
            res = enclosure(
                [
                    Interval(wlo[None, :n_x], whi[None, :n_x]),
                    Interval(wlo[None, n_x:], whi[None, n_x:]),
                ]
            )
            meets = _reason(int(res.jac_flags[0]))
        except OutOfTime:  # past the deadline the evaluator stops at once
            meets = "no finite bound yet (the time ran out before the box was split further)"
        method = "trivial: no finite certified bound within the budget"
        details["why"] = (
            f"no finite upper bound on {where} within the budget ({stop_reason}): a box's "
            f"Jacobian enclosure meets {meets}"
        )
        details["worst_box"] = {
            "x": Box(wlo[:n_x], whi[:n_x]).to_dict(),
            "u": Box(wlo[n_x:], whi[n_x:]).to_dict(),
        }
    return Estimate(
        quantity=quantity,
        value=float(upper),
        kind="upper",
        sets={"X": X, "U": U},
        method=method,
        window=window,
        budget=budget.to_dict(),
        seconds=time.perf_counter() - t0,
        details=details,
    )


def _out_of_time(
    quantity: str,
    X: Box,
    U: Box,
    window: int | None,
    budget: Budget,
    t0: float,
    where: str,
    during: str,
) -> Estimate:
    """The trivial upper bound ``∞`` of a search whose time ran out before any box was bounded
    (a network too large for the interval evaluator within the budget)."""
    return Estimate(
        quantity=quantity,
        value=np.inf,
        kind="upper",
        sets={"X": X, "U": U},
        method="trivial: no finite certified bound within the budget",
        window=window,
        budget=budget.to_dict(),
        seconds=time.perf_counter() - t0,
        details={
            "boxes": 0,
            "stop": "time budget exhausted",
            "why": f"no certified bound on {where}: the time budget ran out while {during} "
            "(the interval evaluator walks the model's whole CasADi graph)",
        },
    )


def lipschitz_bracket(
    fun: ca.Function,
    X: Box,
    U: Box,
    *,
    quantity: str = "gamma_f",
    window: int | None = None,
    tol: float = 0.05,
    budget: Budget | None = None,
    seed: int = 0,
    where: str = "X × U",
    progress: Progress | None = None,
    enclosure: Any | None = None,
    jacobian: JacobianRows | None = None,
) -> Bracket:
    """The sampled lower bound and the certified upper bound together.

    The returned lower bound includes the values attained at box centres during the
    branch-and-bound (``details["lower_found"]`` of the upper bound), so it is the best point
    value found by either method.
    """
    # one CasADi Jacobian for both stages (built by the first that needs it)
    rows = jacobian if jacobian is not None else _CasadiRows(fun)
    low = lipschitz_lower(
        fun,
        X,
        U,
        quantity=quantity,
        window=window,
        budget=budget,
        seed=seed,
        where=where,
        jacobian=rows,
    )
    up = lipschitz_upper(
        fun,
        X,
        U,
        quantity=quantity,
        window=window,
        lower=low,
        tol=tol,
        budget=budget,
        where=where,
        progress=progress,
        enclosure=enclosure,
        jacobian=rows,
    )
    found = float(up.details.get("lower_found", low.value))
    if found > low.value:
        low = Estimate(
            quantity=low.quantity,
            value=found,
            kind="lower",
            sets=low.sets,
            method=low.method + " + branch-and-bound box centres",
            window=window,
            budget=low.budget,
            seconds=low.seconds,
            details=low.details,
        )
    return Bracket.reconcile(low, up)
