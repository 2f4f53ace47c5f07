"""Local optimisation shared by the sampled bounds: L-BFGS-B on a CasADi objective."""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from canonid.analysis.estimate import OutOfTime

__all__ = ["local_minima"]


def local_minima(
    objective: ca.SX,
    variables: ca.SX,
    starts: Iterable[np.ndarray],
    bounds: Sequence[tuple[float | None, float | None]],
    *,
    deadline: float = math.inf,
) -> list[np.ndarray]:
    """Minimise ``objective(variables)`` from each start (L-BFGS-B, CasADi gradient).

    Returns the end point of each run (inside ``bounds``); the caller re-evaluates them, so a
    run that fails to improve costs nothing but time. At ``deadline`` (``time.perf_counter()``)
    the run under way ends at the best point it has evaluated and no other run starts.
    """
    fg = ca.Function(
        "objective_gradient", [variables], [objective, ca.gradient(objective, variables)]
    )
    best: list[tuple[float, np.ndarray]] = []  # the best point of the run under way

    def value_and_gradient(z: np.ndarray) -> tuple[float, np.ndarray]:
        if time.perf_counter() > deadline:
            raise OutOfTime
        value, grad = fg(z)
        if np.isfinite(float(value)) and (not best or float(value) < best[0][0]):
            best[:] = [(float(value), np.array(z, dtype=np.float64))]
        return float(value), np.asarray(grad, dtype=np.float64).ravel()

    lo = np.array([b[0] if b[0] is not None else -np.inf for b in bounds])
    hi = np.array([b[1] if b[1] is not None else np.inf for b in bounds])
    ends = []
    for start in starts:
        if time.perf_counter() > deadline:
            break
        best.clear()
        try:
            with np.errstate(all="ignore"):
                res = minimize(
                    value_and_gradient, start, jac=True, method="L-BFGS-B", bounds=bounds
                )
            end = np.asarray(res.x, dtype=np.float64)
        except OutOfTime:
            end = best[0][1] if best else np.asarray(start, dtype=np.float64)
        ends.append(np.clip(end, lo, hi))
    return ends
