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

import numpy as np

from analysis.enclosure import RangeEnclosure, describe_flags
from analysis.maps import varying_dims
from models.base import System
from models.errors import SetError
from models.sets import Box

__all__ = ["enclose_image", "reachable_hulls"]


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


def enclose_image(
    system: System,
    state_box: Box,
    input_box: Box,
    *,
    tol: float = 1e-3,
    max_boxes: int = 4000,
    batch: int = 64,
) -> Box:
    """A certified box holding ``f(state_box × input_box)``.

    Best-first refinement: each round halves the ``batch`` boxes whose enclosure sticks out
    furthest beyond the hull of the values of ``f`` at sampled points (box centres and the
    faces of the monotonicity test), until none sticks out by more than ``tol`` times the width
    of ``state_box`` or ``max_boxes`` boxes have been evaluated. The result is rigorous either
    way (the hull of every enclosure); the refinement only makes it tight.
    """
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
    enc_lo = np.empty((0, n))
    enc_hi = np.empty((0, n))
    evaluated = 0
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
        stuck = bad & (tiny | (not mask.any()) | (evaluated >= max_boxes))
        if stuck.any():
            i = int(np.flatnonzero(stuck)[0])
            centre = 0.5 * (lo[i] + hi[i])
            raise SetError(
                f"{system.name}: f cannot be bounded near x = {centre[:n].tolist()}, "
                f"u = {centre[n:].tolist()}: {describe_flags(int(flags[i]))}"
            )
        act_lo = np.concatenate([act_lo, lo])
        act_hi = np.concatenate([act_hi, hi])
        enc_lo = np.concatenate([enc_lo, np.where(bad[:, None], -np.inf, enc.lo)])
        enc_hi = np.concatenate([enc_hi, np.where(bad[:, None], np.inf, enc.hi)])
        with np.errstate(invalid="ignore"):
            excess = np.maximum((inner_lo - enc_lo) / slack, (enc_hi - inner_hi) / slack).max(
                axis=1
            )
        excess = np.where(np.isnan(excess), np.inf, excess)
        if not mask.any() or evaluated >= max_boxes or not np.any(excess > 1.0):
            break
        order = np.argsort(-excess)[:batch]
        order = order[excess[order] > 1.0]
        keep = np.ones(act_lo.shape[0], dtype=bool)
        keep[order] = False
        lo, hi = _split(act_lo[order], act_hi[order], scale, mask)
        act_lo, act_hi = act_lo[keep], act_hi[keep]
        enc_lo, enc_hi = enc_lo[keep], enc_hi[keep]
    return Box(enc_lo.min(axis=0), enc_hi.max(axis=0))


def reachable_hulls(
    system: System,
    steps: int,
    *,
    X: Box | None = None,
    U: Box | None = None,
    tol: float = 1e-3,
    max_boxes: int = 20_000,
) -> list[Box]:
    """``[H_0, …, H_steps]`` as in the module docstring (``H_0 = X``).

    Args:
        system: the true system (``f`` must be an SX function).
        steps: number of steps (``>= 0``).
        X, U: the sets (default: the system's).
        tol, max_boxes: passed to :func:`enclose_image` for each step.

    Raises:
        SetError: when ``f`` is undefined or overflows on a reachable box, or the hull grows
            without bound.
    """
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise SetError(f"steps must be an integer >= 0, got {steps!r}")
    X = X or system.X
    U = U or system.U
    hulls = [X]
    current = X
    for step in range(1, steps + 1):
        try:
            image = enclose_image(system, current, U, tol=tol, max_boxes=max_boxes)
        except SetError as exc:
            raise SetError(
                f"states reachable from X = {X} under U = {U} in {step} step(s): {exc}"
            ) from None
        new_lo = np.minimum(current.lo, image.lo)
        new_hi = np.maximum(current.hi, image.hi)
        if not (np.all(np.isfinite(new_lo)) and np.all(np.isfinite(new_hi))):
            raise SetError(f"{system.name}: the reachable hull after {step} steps is unbounded")
        current = Box(new_lo, new_hi)
        hulls.append(current)
    return hulls
