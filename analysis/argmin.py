"""The output-error state estimate of eq. 9: ``x̂_{t−ℓ} ∈ argmin_{x ∈ X} ‖ȳ − O_ℓ(x, ū)‖``.

Solved for many problems at once by a bounded, multi-start **projected Levenberg–Marquardt**
method: residuals ``r = O_ℓ(x, ū) − ȳ`` and Jacobians ``∂O_ℓ/∂x`` come from CasADi (one mapped
call per iteration for every problem and start), the step solves
``(JᵀJ + λ·diag) δ = −Jᵀr`` on the free coordinates (a coordinate at a bound whose gradient
points outwards is fixed), the new point is projected onto the box X and accepted if the
objective decreased. The best of the starts is kept.

The solver gives no global guarantee; :mod:`canonid.analysis.bound` therefore compares the objective
found with the objective at the true state and counts a trial whose found objective is larger
as a **solver failure** (the proof of Proposition 2 needs only
``‖ȳ − O(x̂)‖ ≤ ‖ȳ − O(x_{t−ℓ})‖``, so any point at least as good as the truth obeys the bound).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from canonid.analysis.maps import Horizon, batched
from canonid.kernel.errors import ShapeError
from canonid.models.sets import Box

__all__ = ["ArgminResult", "output_error_argmin"]


@dataclass(frozen=True)
class ArgminResult:
    """Best point per problem.

    Attributes:
        x: ``(N, n_x)`` minimisers found (in X).
        objective: ``(N,)`` values of ``½‖ȳ − O_ℓ(x̂, ū)‖²``.
        iterations: iterations run.
        starts: starts per problem.
    """

    x: np.ndarray
    objective: np.ndarray
    iterations: int
    starts: int


def output_error_argmin(
    horizon: Horizon,
    ybar: np.ndarray,
    ubar: np.ndarray,
    X: Box,
    *,
    starts: int = 8,
    rng: np.random.Generator,
    max_iter: int = 60,
) -> ArgminResult:
    """Minimise ``½‖ȳ_i − O_ℓ(x, ū_i)‖²`` over ``x ∈ X`` for each row ``i``.

    Args:
        horizon: ``O_ℓ`` of the system (:class:`canonid.analysis.maps.Horizon`).
        ybar: ``(N, ℓ·n_y)`` stacked measured outputs ``y_{t−ℓ}, …, y_{t−1}``.
        ubar: ``(N, ℓ·n_u)`` stacked inputs ``u_{t−ℓ}, …, u_{t−1}``.
        X: the box of admissible states.
        starts: random starts per problem (uniform in X; the true state is never used).
        rng: random generator for the starts.
        max_iter: Levenberg–Marquardt iterations.
    """
    n, m = horizon.system.n_x, horizon.n_obs
    ybar = np.asarray(ybar, dtype=np.float64)
    ubar = np.asarray(ubar, dtype=np.float64)
    if ybar.ndim != 2 or ybar.shape[1] != m:
        raise ShapeError(f"ybar must have shape (N, {m}), got {ybar.shape}")
    if ubar.shape != (ybar.shape[0], horizon.n_ubar):
        raise ShapeError(
            f"ubar must have shape ({ybar.shape[0]}, {horizon.n_ubar}), got {ubar.shape}"
        )
    if starts < 1:
        raise ShapeError(f"starts must be >= 1, got {starts}")
    count = ybar.shape[0]
    total = count * starts
    lo, hi = X.lo, X.hi
    x = rng.uniform(lo, hi, size=(total, n))
    y_rep = np.repeat(ybar, starts, axis=0)
    u_rep = np.repeat(ubar, starts, axis=0)

    def evaluate(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        obs, jac = batched(horizon.O_jacobian, points, u_rep)
        jac = jac.reshape(total, m, n)
        res = obs - y_rep
        return res, jac, 0.5 * np.einsum("ij,ij->i", res, res)

    res, jac, obj = evaluate(x)
    lam = np.full(total, 1e-3)
    eye = np.eye(n)
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 - reported
        grad = np.einsum("pij,pi->pj", jac, res)
        fixed = ((x <= lo) & (grad > 0)) | ((x >= hi) & (grad < 0))
        jf = jac * (~fixed)[:, None, :]
        gram = np.einsum("pij,pik->pjk", jf, jf)
        diag = np.einsum("pjj->pj", gram)
        damping = lam[:, None] * (diag + 1e-12 * diag.mean(axis=1, keepdims=True) + 1e-300)
        system_matrix = gram + damping[:, :, None] * eye + fixed[:, :, None] * eye
        rhs = -(grad * ~fixed)
        step = np.linalg.solve(system_matrix, rhs[:, :, None])[:, :, 0]
        cand = np.clip(x + step, lo, hi)
        res_c, jac_c, obj_c = evaluate(cand)
        better = obj_c < obj
        x = np.where(better[:, None], cand, x)
        res = np.where(better[:, None], res_c, res)
        jac = np.where(better[:, None, None], jac_c, jac)
        obj = np.where(better, obj_c, obj)
        lam = np.where(better, np.maximum(lam / 3.0, 1e-12), np.minimum(lam * 4.0, 1e12))
        if np.all(lam >= 1e12):
            break
    obj = obj.reshape(count, starts)
    best = np.argmin(obj, axis=1)
    x_best = x.reshape(count, starts, n)[np.arange(count), best]
    return ArgminResult(
        x=x_best, objective=obj[np.arange(count), best], iterations=iterations, starts=starts
    )
