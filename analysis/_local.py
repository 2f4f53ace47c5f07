"""Local optimisation shared by the sampled bounds: L-BFGS-B on a CasADi objective."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import casadi as ca
import numpy as np
from scipy.optimize import minimize

__all__ = ["local_minima"]


def local_minima(
    objective: ca.SX,
    variables: ca.SX,
    starts: Iterable[np.ndarray],
    bounds: Sequence[tuple[float | None, float | None]],
) -> list[np.ndarray]:
    """Minimise ``objective(variables)`` from each start (L-BFGS-B, CasADi gradient).

    Returns the end point of each run (inside ``bounds``); the caller re-evaluates them, so a
    run that fails to improve costs nothing but time.
    """
    fg = ca.Function(
        "objective_gradient", [variables], [objective, ca.gradient(objective, variables)]
    )

    def value_and_gradient(z: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = fg(z)
        return float(value), np.asarray(grad, dtype=np.float64).ravel()

    ends = []
    for start in starts:
        with np.errstate(all="ignore"):
            res = minimize(value_and_gradient, start, jac=True, method="L-BFGS-B", bounds=bounds)
        lo = np.array([b[0] if b[0] is not None else -np.inf for b in bounds])
        hi = np.array([b[1] if b[1] is not None else np.inf for b in bounds])
        ends.append(np.clip(np.asarray(res.x, dtype=np.float64), lo, hi))
    return ends
