"""Linear time-invariant systems ``x⁺ = A x + B u``, ``y = C x + D u``: the analysis oracle.

For these the theory has closed forms (α_ℓ = σ_min of the observability matrix O_ℓ, γ_f = ‖A‖₂),
so they check every estimator of the analysis layer.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from canonid.kernel.errors import ShapeError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["LINEAR_EXAMPLES", "LinearSystem", "linear_example"]


def _matrix(value: Any, name: str) -> np.ndarray:
    arr = np.atleast_2d(np.asarray(value, dtype=np.float64))
    if arr.ndim != 2:
        raise ShapeError(f"linear system: {name} must be a matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ShapeError(f"linear system: {name} contains NaN or Inf")
    return arr


class LinearSystem(System):
    """A discrete-time LTI system.

    Args:
        A, B, C, D: the matrices (``D`` defaults to zero). Shapes must agree:
            A (n, n), B (n, m), C (p, n), D (p, m).
        dt: sampling time in seconds.
        X, U, W: the sets; by default ``[-1, 1]^n``, ``[-1, 1]^m`` and ``[-0.01, 0.01]^p``.
        name: registry or display name.
    """

    description = "Linear system x+ = Ax + Bu, y = Cx + Du (closed-form oracle for the analysis)"

    def __init__(
        self,
        A: Any,
        B: Any,
        C: Any,
        D: Any | None = None,
        *,
        dt: float = 1.0,
        X: Box | None = None,
        U: Box | None = None,
        W: Box | None = None,
        name: str = "linear",
    ) -> None:
        A, B, C = _matrix(A, "A"), _matrix(B, "B"), _matrix(C, "C")
        n, m, p = A.shape[0], B.shape[1], C.shape[0]
        D = np.zeros((p, m)) if D is None else _matrix(D, "D")
        expected = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}
        for key, mat in (("A", A), ("B", B), ("C", C), ("D", D)):
            if mat.shape != expected[key]:
                raise ShapeError(
                    f"linear system: {key} must have shape {expected[key]} to match "
                    f"A {A.shape}, B {B.shape}, C {C.shape}; got {mat.shape}"
                )
        self.A, self.B, self.C, self.D = A, B, C, D
        super().__init__(
            name=name,
            dt=dt,
            state_names=tuple(f"x{i + 1}" for i in range(n)),
            state_units=("-",) * n,
            input_names=tuple(f"u{i + 1}" for i in range(m)),
            input_units=("-",) * m,
            output_names=tuple(f"y{i + 1}" for i in range(p)),
            output_units=("-",) * p,
            X=X if X is not None else Box.symmetric(1.0, n),
            U=U if U is not None else Box.symmetric(1.0, m),
            W=W if W is not None else Box.symmetric(0.01, p),
            discretisation="exact (the model is defined in discrete time)",
            parameters={"A": A, "B": B, "C": C, "D": D},
        )

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return ca.mtimes(ca.DM(self.A), x) + ca.mtimes(ca.DM(self.B), u)

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return ca.mtimes(ca.DM(self.C), x) + ca.mtimes(ca.DM(self.D), u)


def _oscillator() -> LinearSystem:
    # lightly damped oscillator, poles 0.95·e^{±0.3j}, position measured
    r, w = 0.95, 0.3
    A = r * np.array([[np.cos(w), -np.sin(w)], [np.sin(w), np.cos(w)]])
    return LinearSystem(A, [[0.0], [1.0]], [[1.0, 0.0]], name="linear")


def _mimo() -> LinearSystem:
    A = np.array([[0.9, 0.2, 0.0], [-0.1, 0.8, 0.1], [0.0, 0.05, 0.7]])
    B = np.array([[1.0, 0.0], [0.0, 0.5], [0.3, 1.0]])
    C = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return LinearSystem(A, B, C, name="linear-mimo")


#: named examples, built on demand
LINEAR_EXAMPLES = {"linear": _oscillator, "linear-mimo": _mimo}


def linear_example(name: str = "linear") -> LinearSystem:
    """A named example: ``linear`` (SISO oscillator) or ``linear-mimo`` (3 states, 2×2)."""
    try:
        return LINEAR_EXAMPLES[name]()
    except KeyError:
        raise ShapeError(
            f"unknown linear example {name!r}; expected one of {sorted(LINEAR_EXAMPLES)}"
        ) from None
