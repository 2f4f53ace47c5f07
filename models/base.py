"""The one interface every true system implements.

Time convention (used by every layer): sample ``t`` holds the state ``x[t]``, the input ``u[t]``
and the output ``y[t] = h(x[t], u[t])`` (plus noise ``w[t]`` in a dataset); ``u[t]`` moves the
state on, ``x[t+1] = f(x[t], u[t])``. ``f`` and ``h`` are discrete-time maps; a system defined in
continuous time also exposes its ``ode`` and names the ``discretisation`` that turns it into ``f``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError, ShapeError
from canonid.kernel.io import jsonable
from canonid.kernel.validate import as_matrix, as_vector, require_finite
from canonid.models.sets import Box

__all__ = ["Linearisation", "SimResult", "System"]


@dataclass(frozen=True)
class SimResult:
    """Open-loop simulation of ``T`` steps of a true system (:meth:`System.simulate`, or
    ``N`` at once, :meth:`System.simulate_batch`, with a leading axis of ``N``).

    ``x[t]`` and ``y[t] = h(x[t], u[t])`` for ``t = 0 … T-1``; ``x_final = x[T]`` is the state
    after the last input.

    Not a :class:`~canonid.kernel.dataset.Trajectory`: it is what the system does, not a record
    of an experiment. ``y`` is noise-free (a trajectory's ``y`` is measured, its ``y_clean`` is
    this), the inputs stay with the caller, ``x_final`` lies one step past the ``T`` samples a
    trajectory holds, and the batched form is ``(N, T, ·)``. A record of it is
    ``Trajectory(u=u, y=sim.y + w, y_clean=sim.y, x=sim.x)`` for a measurement noise ``w``.
    """

    x: np.ndarray
    y: np.ndarray
    x_final: np.ndarray


@dataclass(frozen=True)
class Linearisation:
    """``f``, ``h`` and their Jacobians at ``N`` points ``(x_k, u_k)`` (:meth:`System.linearise`):
    ``f`` ``(N, n_x)``, ``h`` ``(N, n_y)``, ``f_x`` ``(N, n_x, n_x)``, ``f_u`` ``(N, n_x, n_u)``,
    ``h_x`` ``(N, n_y, n_x)``, ``h_u`` ``(N, n_y, n_u)``."""

    f: np.ndarray
    h: np.ndarray
    f_x: np.ndarray
    f_u: np.ndarray
    h_x: np.ndarray
    h_u: np.ndarray


class System(ABC):
    """A discrete-time system ``x⁺ = f(x, u)``, ``y = h(x, u)`` with its sets X, U, W.

    Subclasses write ``f`` and ``h`` symbolically (CasADi SX) in :meth:`_f_expr` and
    :meth:`_h_expr`; this base class builds the CasADi ``Function``s, checks the dimensions and
    offers validated numeric and batched evaluation.

    Attributes:
        name: registry name.
        dt: sampling time in seconds.
        X, U, W: boxes for the state, the input and the measurement noise on which the theory
            (γ_f, α_ℓ, Proposition 2) is evaluated. ``W`` is also the default bounded-noise box
            of generated datasets.
        f, h: CasADi ``Function``s with inputs ``(x, u)`` (column vectors).
        ode: continuous-time right-hand side ``ẋ = ode(x, u)`` or ``None``.
        discretisation: how ``f`` is obtained (``"explicit Euler"``, ``"exact"``, ...).
    """

    #: one-line description shown by ``canonid systems``
    description: str = ""
    #: set when the system is a simulated stand-in for a real one
    simulated_stand_in_for: str | None = None
    #: why certified analysis bounds are hard to get for this system (one sentence, or empty);
    #: ``canonid analyze`` shows it beside bounds its budget could not make finite or tight
    analysis_note: str = ""

    def __init__(
        self,
        *,
        name: str,
        dt: float,
        state_names: Sequence[str],
        state_units: Sequence[str],
        input_names: Sequence[str],
        input_units: Sequence[str],
        output_names: Sequence[str],
        output_units: Sequence[str],
        X: Box,
        U: Box,
        W: Box,
        discretisation: str,
        parameters: Mapping[str, Any],
    ) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise ShapeError(f"dt must be a positive finite number of seconds, got {dt}")
        self.name = name
        self.dt = float(dt)
        self.state_names = tuple(state_names)
        self.state_units = tuple(state_units)
        self.input_names = tuple(input_names)
        self.input_units = tuple(input_units)
        self.output_names = tuple(output_names)
        self.output_units = tuple(output_units)
        self.discretisation = discretisation
        self.parameters = dict(parameters)
        for label, names, units in (
            ("state", self.state_names, self.state_units),
            ("input", self.input_names, self.input_units),
            ("output", self.output_names, self.output_units),
        ):
            if len(names) != len(units) or not names:
                raise ShapeError(
                    f"{name}: {label} names {names} and units {units} must be non-empty and "
                    "of equal length"
                )
        for label, box, n in (("X", X, self.n_x), ("U", U, self.n_u), ("W", W, self.n_y)):
            if box.dim != n:
                raise SetError(f"{name}: set {label} has dimension {box.dim}, expected {n}")
        self.X, self.U, self.W = X, U, W

        x = ca.SX.sym("x", self.n_x)
        u = ca.SX.sym("u", self.n_u)
        self.f = ca.Function("f", [x, u], [self._f_expr(x, u)], ["x", "u"], ["x_next"])
        self.h = ca.Function("h", [x, u], [self._h_expr(x, u)], ["x", "u"], ["y"])
        ode = self._ode_expr(x, u)
        self.ode = None if ode is None else ca.Function("ode", [x, u], [ode], ["x", "u"], ["xdot"])
        if self.f.size1_out(0) != self.n_x or self.f.size2_out(0) != 1:
            raise ShapeError(f"{name}: f returns {self.f.size_out(0)}, expected ({self.n_x}, 1)")
        if self.h.size1_out(0) != self.n_y or self.h.size2_out(0) != 1:
            raise ShapeError(f"{name}: h returns {self.h.size_out(0)}, expected ({self.n_y}, 1)")
        self._maps: dict[tuple[str, int], ca.Function] = {}

    # ------------------------------------------------------------------ symbolic definition
    @abstractmethod
    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """Discrete-time transition ``x[t+1]`` as a CasADi expression of ``x[t]``, ``u[t]``."""

    @abstractmethod
    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """Output ``y[t]`` (noise-free) as a CasADi expression of ``x[t]``, ``u[t]``."""

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX | None:
        """Continuous-time right-hand side, or ``None`` for a discrete-time model."""
        return None

    # ------------------------------------------------------------------ dimensions
    @property
    def n_x(self) -> int:
        return len(self.state_names)

    @property
    def n_u(self) -> int:
        return len(self.input_names)

    @property
    def n_y(self) -> int:
        return len(self.output_names)

    # ------------------------------------------------------------------ numeric evaluation
    def step(self, x: Any, u: Any) -> np.ndarray:
        """``f(x, u)`` for one state and input, as a float64 vector of length ``n_x``."""
        xv = as_vector(x, self.n_x, f"{self.name}: state x")
        uv = as_vector(u, self.n_u, f"{self.name}: input u")
        return np.asarray(self.f(xv, uv), dtype=np.float64).reshape(self.n_x)

    def output(self, x: Any, u: Any) -> np.ndarray:
        """``h(x, u)`` for one state and input, as a float64 vector of length ``n_y``."""
        xv = as_vector(x, self.n_x, f"{self.name}: state x")
        uv = as_vector(u, self.n_u, f"{self.name}: input u")
        return np.asarray(self.h(xv, uv), dtype=np.float64).reshape(self.n_y)

    def _mapped(self, which: str, n: int) -> ca.Function:
        key = (which, n)
        if key not in self._maps:
            fun = self.f if which == "f" else self.h
            self._maps[key] = fun.map(n)
        return self._maps[key]

    def f_batch(self, x: Any, u: Any) -> np.ndarray:
        """``f`` on N rows at once (CasADi ``map``): ``x`` (N, n_x), ``u`` (N, n_u)."""
        xm = as_matrix(x, self.n_x, f"{self.name}: states x")
        um = as_matrix(u, self.n_u, f"{self.name}: inputs u", rows=xm.shape[0])
        out = self._mapped("f", xm.shape[0])(xm.T, um.T)
        return np.asarray(out, dtype=np.float64).T.reshape(xm.shape[0], self.n_x)

    def h_batch(self, x: Any, u: Any) -> np.ndarray:
        """``h`` on ``N`` rows at once: ``x`` is ``(N, n_x)``, ``u`` ``(N, n_u)``."""
        xm = as_matrix(x, self.n_x, f"{self.name}: states x")
        um = as_matrix(u, self.n_u, f"{self.name}: inputs u", rows=xm.shape[0])
        out = self._mapped("h", xm.shape[0])(xm.T, um.T)
        return np.asarray(out, dtype=np.float64).T.reshape(xm.shape[0], self.n_y)

    def linearise(self, x: Any, u: Any) -> Linearisation:
        """``f``, ``h`` and their Jacobians at the ``N`` rows of ``x`` ``(N, n_x)`` and ``u``
        ``(N, n_u)`` (CasADi's automatic differentiation, mapped over the rows)."""
        xm = as_matrix(x, self.n_x, f"{self.name}: states x")
        um = as_matrix(u, self.n_u, f"{self.name}: inputs u", rows=xm.shape[0])
        n = xm.shape[0]
        key = ("linearise", n)
        if key not in self._maps:
            xs, us = ca.SX.sym("x", self.n_x), ca.SX.sym("u", self.n_u)
            fx, hx = self.f(xs, us), self.h(xs, us)
            jacobians = [ca.jacobian(v, s) for v in (fx, hx) for s in (xs, us)]
            self._maps[key] = ca.Function("linearise", [xs, us], [fx, hx, *jacobians]).map(n)
        out = self._maps[key](xm.T, um.T)
        f, h, *jac = (np.asarray(o, dtype=np.float64) for o in out)
        rows = (self.n_x, self.n_x, self.n_y, self.n_y)
        cols = (self.n_x, self.n_u, self.n_x, self.n_u)
        f_x, f_u, h_x, h_u = (
            a.reshape(r, n, c).transpose(1, 0, 2) for a, r, c in zip(jac, rows, cols)
        )
        return Linearisation(f=f.T, h=h.T, f_x=f_x, f_u=f_u, h_x=h_x, h_u=h_u)

    def simulate(self, x0: Any, u: Any) -> SimResult:
        """Open-loop simulation from ``x0`` under inputs ``u`` of shape ``(T, n_u)``."""
        x0v = as_vector(x0, self.n_x, f"{self.name}: initial state x0")
        um = as_matrix(u, self.n_u, f"{self.name}: inputs u")
        res = self.simulate_batch(x0v[None, :], um[None, :, :])
        return SimResult(x=res.x[0], y=res.y[0], x_final=res.x_final[0])

    def simulate_batch(self, x0: Any, u: Any) -> SimResult:
        """``N`` open-loop simulations at once.

        ``x0`` is ``(N, n_x)`` and ``u`` is ``(N, T, n_u)``; the result holds ``x`` of shape
        ``(N, T, n_x)``, ``y`` of shape ``(N, T, n_y)`` and ``x_final`` of shape ``(N, n_x)``.
        """
        x0m = as_matrix(x0, self.n_x, f"{self.name}: initial states x0")
        ua = np.asarray(u, dtype=np.float64)
        n = x0m.shape[0]
        if ua.ndim != 3 or ua.shape[0] != n or ua.shape[2] != self.n_u:
            raise ShapeError(
                f"{self.name}: inputs u must have shape ({n}, T, {self.n_u}), got {ua.shape}"
            )
        require_finite(ua, f"{self.name}: inputs u")
        steps = ua.shape[1]
        xs = np.empty((n, steps, self.n_x))
        ys = np.empty((n, steps, self.n_y))
        fmap, hmap = self._mapped("f", n), self._mapped("h", n)
        xt = x0m.T
        for t in range(steps):
            ut = ua[:, t, :].T
            xs[:, t, :] = np.asarray(xt).T
            ys[:, t, :] = np.asarray(hmap(xt, ut)).T
            xt = fmap(xt, ut)
        return SimResult(x=xs, y=ys, x_final=np.asarray(xt, dtype=np.float64).T.copy())

    # ------------------------------------------------------------------ description
    def describe(self) -> dict[str, Any]:
        """A JSON-ready summary (dimensions, names, units, dt, sets, parameters)."""
        return {
            "name": self.name,
            "description": self.description,
            "simulated_stand_in_for": self.simulated_stand_in_for,
            "dt": self.dt,
            "discretisation": self.discretisation,
            "n_x": self.n_x,
            "n_u": self.n_u,
            "n_y": self.n_y,
            "states": [f"{n} [{u}]" for n, u in zip(self.state_names, self.state_units)],
            "inputs": [f"{n} [{u}]" for n, u in zip(self.input_names, self.input_units)],
            "outputs": [f"{n} [{u}]" for n, u in zip(self.output_names, self.output_units)],
            "X": self.X.to_dict(),
            "U": self.U.to_dict(),
            "W": self.W.to_dict(),
            "parameters": jsonable(self.parameters),
        }

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(name={self.name!r}, n_x={self.n_x}, n_u={self.n_u}, "
            f"n_y={self.n_y}, dt={self.dt:g})"
        )
