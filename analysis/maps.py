"""The maps of the theory as CasADi SX functions: F_ℓ, O_ℓ and Jacobians, plus batched calls.

Conventions (paper eq. 4–5). For a window ``ℓ ≥ 1`` and inputs
``ū = (u_1, …, u_ℓ) ∈ U^ℓ`` stacked as one vector of length ``ℓ·n_u`` (``u_1`` first):

* ``F_1(x, u_1) = f(x, u_1)``, ``F_i(x, ū) = f(F_{i−1}(x, ū), u_i)``: ``F_ℓ`` propagates ``ℓ``
  steps, so with ``x = x_{t−ℓ}`` and ``ū = ū_{t−ℓ|t−1}`` it returns ``x_t``;
* ``O_ℓ(x, ū)`` stacks ``h(x, u_1), h(F_1(x, u_1), u_2), …, h(F_{ℓ−1}(x, ū), u_ℓ)`` — the
  noise-free outputs ``y_{t−ℓ}, …, y_{t−1}`` (length ``ℓ·n_y``, oldest first).

Every function here is an SX ``casadi.Function`` (so :class:`canonid.analysis.enclosure.Enclosure`
can walk it) with inputs ``(x, ubar)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from canonid.kernel.errors import ShapeError
from canonid.models.base import System

__all__ = ["Horizon", "batched", "check_window", "jacobian_function", "varying_dims"]


def check_window(window: object) -> int:
    """Return ``window`` as an int, or raise naming what was expected (ℓ ≥ 1)."""
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ShapeError(f"window ℓ must be an integer >= 1, got {window!r}")
    return int(window)


@dataclass(frozen=True)
class Horizon:
    """``F_ℓ`` and ``O_ℓ`` of ``system`` for one window ``ℓ``, built once (SX)."""

    system: System
    window: int

    def __post_init__(self) -> None:
        check_window(self.window)

    @cached_property
    def _symbols(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        s, ell = self.system, self.window
        x = ca.SX.sym("x", s.n_x)
        ubar = ca.SX.sym("ubar", ell * s.n_u)
        outputs = []
        state = x
        for i in range(ell):
            u_i = ubar[i * s.n_u : (i + 1) * s.n_u]
            outputs.append(s.h(state, u_i))
            state = s.f(state, u_i)
        return x, ubar, ca.vertcat(*outputs), state

    @cached_property
    def O(self) -> ca.Function:  # noqa: E743 - the paper's name
        """``O_ℓ(x, ubar)`` → ``(ℓ·n_y, 1)``."""
        x, ubar, obs, _ = self._symbols
        return ca.Function(f"O_{self.window}", [x, ubar], [obs], ["x", "ubar"], ["y_bar"])

    @cached_property
    def F(self) -> ca.Function:
        """``F_ℓ(x, ubar)`` → ``(n_x, 1)``: the state ``ℓ`` steps later."""
        x, ubar, _, state = self._symbols
        return ca.Function(f"F_{self.window}", [x, ubar], [state], ["x", "ubar"], ["x_next"])

    @cached_property
    def O_jacobian(self) -> ca.Function:
        """``(x, ubar)`` → ``(O_ℓ, ∂O_ℓ/∂x)``."""
        return jacobian_function(self.O)

    @property
    def n_ubar(self) -> int:
        return self.window * self.system.n_u

    @property
    def n_obs(self) -> int:
        return self.window * self.system.n_y


def jacobian_function(fun: ca.Function) -> ca.Function:
    """``(x, u)`` → ``(fun(x, u), ∂fun/∂x)`` as an SX function (``fun`` has inputs ``x, u``)."""
    x = ca.SX.sym("x", fun.nnz_in(0))
    u = ca.SX.sym("u", fun.nnz_in(1))
    value = fun(x, u)
    return ca.Function(f"{fun.name()}_jac", [x, u], [value, ca.jacobian(value, x)])


def varying_dims(fun: ca.Function) -> tuple[np.ndarray, np.ndarray]:
    """Which entries of ``x`` and of ``u`` the Jacobian ``∂fun/∂x`` depends on.

    Returns two boolean arrays (length ``n_x`` and ``n_u``). A branch-and-bound over boxes only
    needs to split those dimensions: the Jacobian enclosure does not change along the others.
    """
    x = ca.SX.sym("x", fun.nnz_in(0))
    u = ca.SX.sym("u", fun.nnz_in(1))
    jac = ca.vec(ca.jacobian(fun(x, u), x))
    if jac.is_constant() or jac.nnz() == 0:
        return np.zeros(x.numel(), dtype=bool), np.zeros(u.numel(), dtype=bool)
    dep = np.asarray(ca.which_depends(jac, ca.vertcat(x, u), 1, False), dtype=bool)
    return dep[: x.numel()], dep[x.numel() :]


def batched(fun: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
    """Evaluate ``fun`` on ``N`` rows at once (CasADi ``map``).

    ``args[i]`` has shape ``(N, nnz_in(i))``. Returns one float64 array per output: ``(N, rows)``
    for a column-vector output and ``(N, rows, cols)`` for a matrix output.
    """
    if len(args) != fun.n_in():
        raise ShapeError(f"{fun.name()}: expected {fun.n_in()} inputs, got {len(args)}")
    n = int(np.asarray(args[0]).shape[0])
    arrays: list[np.ndarray] = []
    for i, a in enumerate(args):
        arr = np.asarray(a, dtype=np.float64)
        if arr.ndim != 2 or arr.shape != (n, fun.nnz_in(i)):
            raise ShapeError(
                f"{fun.name()}: input {i} must have shape ({n}, {fun.nnz_in(i)}), got {arr.shape}"
            )
        arrays.append(arr.T)
    shapes = [(fun.size1_out(k), fun.size2_out(k)) for k in range(fun.n_out())]
    if n == 0:
        return [np.zeros((0, r) if c == 1 else (0, r, c)) for r, c in shapes]
    outs = fun.map(n)(*arrays)
    if not isinstance(outs, (list, tuple)):
        outs = [outs]
    result: list[np.ndarray] = []
    for out, (rows, cols) in zip(outs, shapes):
        arr = np.asarray(out, dtype=np.float64)
        if cols == 1:
            result.append(arr.T.reshape(n, rows))
        else:
            result.append(arr.reshape(rows, n, cols).transpose(1, 0, 2).copy())
    return result
