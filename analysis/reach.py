"""Certified box hulls of the states reachable from X under inputs in U.

Why this is needed. Lemma 1 of the paper (``F_i`` is ``γ_f^i``-Lipschitz) assumes X invariant,
``f(X, U) ⊆ X``. The analysis sets of the shipped systems are not (the tank on
``X = [0.05, 5]²``, ``U = [1, 3]`` reaches ``x1 ≈ 5.76`` and ``x2 ≈ 0.022``; the drone is
unstable). The proof of Proposition 2 only needs, at step ``i``, a Lipschitz constant of ``f``
on a convex set holding both ``F_i(x_{t−ℓ}, ū)`` and ``F_i(x̂_{t−ℓ}, ū)``. So the bound for
window ``ℓ`` uses γ_f certified on ``H_{ℓ−1} × U``, where

    H_0 = X,   H_{i+1} = hull(X ∪ f(H_i × U))

is a box (convex) that contains every state reachable from X in at most ``i`` steps. The image
``f(H_i × U)`` is enclosed in interval arithmetic on sub-boxes (split along the coordinates in
which ``f`` is nonlinear), so the hull is rigorous. When X is invariant, ``H_i = X`` and the
paper's statement is recovered.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.analysis.enclosure import RangeEnclosure, describe_flags
from canonid.analysis.estimate import Budget
from canonid.analysis.maps import varying_dims
from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["ImageEnclosure", "ReachableHulls", "enclose_image", "reach", "reachable_hulls"]


def _split(
    lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Halve each box (rows of ``lo``/``hi``) along its widest coordinate among ``mask``.

    Widths are measured relative to ``scale`` (the root box), so coordinates in different units
    are compared fairly. Returns the ``2·B`` children (first halves, then second halves).
    """
    rel = np.where(mask, (hi - lo) / scale, -1.0)
    k = np.argmax(rel, axis=1)
    rows = np.arange(lo.shape[0])
    mid = 0.5 * lo[rows, k] + 0.5 * hi[rows, k]
    lo1, hi1, lo2, hi2 = lo.copy(), hi.copy(), lo.copy(), hi.copy()
    hi1[rows, k] = mid
    lo2[rows, k] = mid
    return np.concatenate([lo1, lo2]), np.concatenate([hi1, hi2])


@dataclass(frozen=True)
class ImageEnclosure:
    """A certified enclosure of ``f(state_box × input_box)`` and how its search ended.

    Attributes:
        lo, hi: the enclosure, one entry per state (``−inf``/``+inf`` where no finite bound was
            found within the budget).
        boxes: boxes evaluated.
        stop: ``"tolerance reached"``, ``"box budget exhausted"`` or ``"time budget exhausted"``.
        seconds: wall time.
        unbounded: why the enclosure is not finite (the operation and the point), or ``None``.
    """

    lo: np.ndarray
    hi: np.ndarray
    boxes: int
    stop: str
    seconds: float
    unbounded: str | None = None

    @property
    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.lo)) and np.all(np.isfinite(self.hi)))


def enclose_image(
    system: System,
    state_box: Box,
    input_box: Box,
    *,
    tol: float = 1e-3,
    budget: Budget | None = None,
    batch: int = 64,
) -> ImageEnclosure:
    """A certified enclosure of ``f(state_box × input_box)``.

    Best-first refinement: each round halves the ``batch`` boxes whose enclosure sticks out
    furthest beyond the hull of the values of ``f`` at sampled points (box centres and the
    faces of the monotonicity test), until none sticks out by more than ``tol`` times the width
    of ``state_box`` or the budget (``boxes``, ``seconds``) is spent. The result is rigorous
    either way (the hull of every enclosure); the refinement only makes it tight. A box whose
    enclosure is still unusable (overflow, a division by a range holding 0, ...) when the budget
    ends makes the enclosure infinite in every component, and ``unbounded`` says why.

    Raises:
        SetError: ``f`` cannot be bounded on a box shrunk to width ~1e-9 (a singularity of
            ``f``, not a matter of budget).
    """
    budget = budget or Budget()
    t0 = time.perf_counter()
    enclosure = RangeEnclosure(system.f)
    dx, du = varying_dims(system.f)
    n = system.n_x
    lo = np.concatenate([state_box.lo, input_box.lo])[None, :]
    hi = np.concatenate([state_box.hi, input_box.hi])[None, :]
    scale = np.where(hi[0] > lo[0], hi[0] - lo[0], 1.0)
    mask = np.concatenate([dx, du]) & (hi[0] > lo[0])
    slack = tol * np.maximum(state_box.width, 1e-12)
    inner_lo = np.full(n, np.inf)
    inner_hi = np.full(n, -np.inf)
    act_lo = np.empty((0, lo.shape[1]))
    act_hi = np.empty((0, lo.shape[1]))
    act_flags = np.empty(0, dtype=np.int64)
    enc_lo = np.empty((0, n))
    enc_hi = np.empty((0, n))
    evaluated = 0
    stop = "tolerance reached"
    unbounded = None
    while True:
        enc, flags, points = enclosure(lo, hi)
        evaluated += lo.shape[0]
        flat = points.reshape(-1, points.shape[-1])
        with np.errstate(all="ignore"):
            fp = np.asarray(system.f_batch(flat[:, :n], flat[:, n:]))
        good = np.all(np.isfinite(fp), axis=1)
        if good.any():
            inner_lo = np.minimum(inner_lo, fp[good].min(axis=0))
            inner_hi = np.maximum(inner_hi, fp[good].max(axis=0))
        bad = flags != 0
        tiny = np.all(np.where(mask, (hi - lo) / scale, 0.0) < 1e-9, axis=1)
        stuck = bad & (tiny | (not mask.any()))
        if stuck.any():
            i = int(np.flatnonzero(stuck)[0])
            raise SetError(_cannot_bound(system, lo[i], hi[i], int(flags[i])))
        act_lo = np.concatenate([act_lo, lo])
        act_hi = np.concatenate([act_hi, hi])
        act_flags = np.concatenate([act_flags, flags.astype(np.int64)])
        enc_lo = np.concatenate([enc_lo, np.where(bad[:, None], -np.inf, enc.lo)])
        enc_hi = np.concatenate([enc_hi, np.where(bad[:, None], np.inf, enc.hi)])
        with np.errstate(invalid="ignore"):
            excess = np.maximum((inner_lo - enc_lo) / slack, (enc_hi - inner_hi) / slack).max(
                axis=1
            )
        excess = np.where(np.isnan(excess), np.inf, excess)
        if not mask.any() or not np.any(excess > 1.0):
            break
        exhausted = budget.exhausted(evaluated, t0)
        if exhausted:
            stop = exhausted
            break
        order = np.argsort(-excess)[:batch]
        order = order[excess[order] > 1.0]
        keep = np.ones(act_lo.shape[0], dtype=bool)
        keep[order] = False
        lo, hi = _split(act_lo[order], act_hi[order], scale, mask)
        act_lo, act_hi, act_flags = act_lo[keep], act_hi[keep], act_flags[keep]
        enc_lo, enc_hi = enc_lo[keep], enc_hi[keep]
    out_lo, out_hi = enc_lo.min(axis=0), enc_hi.max(axis=0)
    if not (np.all(np.isfinite(out_lo)) and np.all(np.isfinite(out_hi))):
        worst = int(np.argmax(~np.isfinite(enc_lo).all(axis=1) | ~np.isfinite(enc_hi).all(axis=1)))
        unbounded = (
            f"no finite enclosure of f within the budget ({stop}, {evaluated} boxes): "
            + _cannot_bound(system, act_lo[worst], act_hi[worst], int(act_flags[worst]))
        )
    return ImageEnclosure(
        lo=out_lo,
        hi=out_hi,
        boxes=evaluated,
        stop=stop,
        seconds=time.perf_counter() - t0,
        unbounded=unbounded,
    )


def _cannot_bound(system: System, lo: np.ndarray, hi: np.ndarray, flags: int) -> str:
    centre = 0.5 * (lo + hi)
    n = system.n_x
    why = describe_flags(flags) if flags else "an overflow (non-finite enclosure)"
    point = ", ".join(f"{v:.6g}" for v in centre[:n])
    inputs = ", ".join(f"{v:.6g}" for v in centre[n:])
    return f"{system.name}: f cannot be bounded near x = [{point}], u = [{inputs}]: {why}"


@dataclass(frozen=True)
class ReachableHulls:
    """The hulls ``H_0 = X, H_1, …`` of the module docstring, as far as they are finite.

    Attributes:
        hulls: ``H_0 … H_k`` (``k ≤ steps``), each a certified finite box.
        steps: per computed step ``i = 1 … k`` (and the failed step ``k + 1`` if any): boxes
            evaluated, why the search stopped, seconds (JSON-ready records).
        requested: the number of steps asked for.
        unbounded: why ``H_{k+1}`` (and every later hull) has no finite certified box within
            the budget — typically interval wrapping, which grows the hull at every step until
            it overflows — or ``None`` when ``k = requested``.
    """

    hulls: tuple[Box, ...]
    steps: tuple[dict[str, Any], ...]
    requested: int
    unbounded: str | None = None

    def hull(self, step: int) -> Box | None:
        """``H_step``, or ``None`` when it has no finite certified box."""
        return self.hulls[step] if step < len(self.hulls) else None


def reach(
    system: System,
    steps: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    tol: float = 1e-3,
    budget: Budget | None = None,
) -> ReachableHulls:
    """``H_0 … H_steps`` (module docstring), stopping at the first hull that is not finite.

    Args:
        system: the true system (``f`` must be an SX function).
        steps: number of steps (``>= 0``).
        X, U: the sets (default: the system's).
        tol: relative tolerance of each step's enclosure (:func:`enclose_image`).
        budget: ``boxes`` and ``seconds`` of **each** step's enclosure (default
            :class:`~canonid.analysis.estimate.Budget()`: 20,000 boxes, no time limit).

    Raises:
        SetError: ``f`` is undefined or singular on a reachable box (not a matter of budget).
    """
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise SetError(f"steps must be an integer >= 0, got {steps!r}")
    X = X or system.X
    U = U or system.U
    hulls = [X]
    records: list[dict[str, Any]] = []
    current = X
    for step in range(1, steps + 1):
        try:
            image = enclose_image(system, current, U, tol=tol, budget=budget)
        except SetError as exc:
            raise SetError(
                f"states reachable from X = {X} under U = {U} in {step} step(s): {exc}"
            ) from None
        records.append(
            {
                "step": step,
                "boxes": image.boxes,
                "stop": image.stop,
                "seconds": round(image.seconds, 3),
            }
        )
        new_lo = np.minimum(current.lo, image.lo)
        new_hi = np.maximum(current.hi, image.hi)
        if not (np.all(np.isfinite(new_lo)) and np.all(np.isfinite(new_hi))):
            why = image.unbounded or "the enclosure overflows"
            return ReachableHulls(
                tuple(hulls),
                tuple(records),
                steps,
                f"H_{step} (states reachable from X in {step} step(s)) is not bounded: {why}",
            )
        current = Box(new_lo, new_hi)
        hulls.append(current)
    return ReachableHulls(tuple(hulls), tuple(records), steps)


def reachable_hulls(
    system: System,
    steps: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    tol: float = 1e-3,
    budget: Budget | None = None,
) -> list[Box]:
    """``[H_0, …, H_steps]`` as in the module docstring (``H_0 = X``); see :func:`reach`.

    Raises:
        SetError: when ``f`` is undefined or overflows on a reachable box, or a hull has no
            finite certified box within the budget.
    """
    result = reach(system, steps, X=X, U=U, tol=tol, budget=budget)
    if result.unbounded is not None:
        raise SetError(f"{system.name}: {result.unbounded}")
    return list(result.hulls)
