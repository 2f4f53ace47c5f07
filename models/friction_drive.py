"""A drive with dry friction: an inertia turned by a motor's torque against viscous, Coulomb and
Stribeck friction. Torque in, speed out. At low speeds it sticks and breaks away; the sign of
the speed, which dry friction follows, is smoothed so that the dynamics stay Lipschitz.

Mechanics (continuous time)
---------------------------
``ω`` is the angular speed [rad/s], ``τ`` the motor torque [N·m]::

    J ω̇ = τ − b ω − F(ω)
    F(ω) = (T_c + (T_s − T_c) exp(−(ω / ω_s)²)) · tanh(ω / ε)

``J`` [kg·m²] is the inertia, ``b`` [N·m·s/rad] the viscous friction, ``T_c`` [N·m] the Coulomb
(sliding) friction, ``T_s ≥ T_c`` [N·m] the static (breakaway) friction, ``ω_s`` [rad/s] the
Stribeck speed over which the friction falls from ``T_s`` to ``T_c``, and ``ε`` [rad/s] the speed
over which ``tanh(ω / ε)`` goes from ``−1`` to ``1``: the smooth stand-in for ``sign(ω)``.
``F(ω)`` has the sign of ``ω`` (``ω F(ω) ≥ 0``: friction opposes the motion) and ``|F| ≤ T_s``.

State, index conventions
------------------------
``x = (ω,)``: index 0 the speed [rad/s]. Input ``u = τ`` [N·m]; output ``y = ω = x[0]`` [rad/s]
(no feedthrough).

Closed forms
------------
* Without dry friction (``T_c = T_s = 0``) the drive is linear, first order: pole ``−b / J``,
  steady speed ``τ / b`` under a constant torque.
* Under a constant torque ``|τ| < T_c`` it sticks: the steady speed solves ``τ = b ω + F(ω)`` and
  so ``|ω| < ε atanh(|τ| / T_c)``, a creep of a few ``ε``.
* Under a constant torque far above ``T_s`` it slides at ``ω = (τ − T_c) / b`` (where
  ``exp(−(ω/ω_s)²)`` and ``1 − tanh(ω/ε)`` are negligible).

Discretisation and the smoothing
--------------------------------
``substeps`` classical Runge–Kutta (RK4) steps of ``h = dt / substeps`` per sample, ``τ`` held.
Near ``ω = 0`` the friction's slope is ``F'(0) = T_s / ε``: the faster ``ε`` makes the sign, the
stiffer the equation (its local time constant is ``J / (b + T_s / ε)``). RK4 is stable for
``h |λ| < 2.78`` and accurate well below; construction requires ``h (b + T_s / ε) / J ≤ 1``, so a
smaller ``ε`` needs more substeps (the error names how many).

Parameters
----------
``J = 0.1 kg·m²``, ``b = 0.3 N·m·s/rad`` (mechanical time constant ``J / b = 0.33 s``),
``T_c = 1 N·m``, ``T_s = 1.5 N·m``, ``ω_s = 0.3 rad/s``, ``ε = 0.02 rad/s``; ``dt = 10 ms`` (100 Hz)
with 10 substeps: ``h (b + T_s / ε) / J = 0.75``. The scenario's multisine (RMS 2 N·m, up to 5
Hz) drives the speed up to 5–7 rad/s and through zero often; a third of the samples are stuck
(``|ω| < 0.1 rad/s``).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["FrictionDrive"]

#: the largest ``h (b + T_s / ε) / J`` allowed (RK4's stability limit is 2.78)
STIFFNESS_LIMIT = 1.0


class FrictionDrive(System):
    """An inertia with viscous, Coulomb and Stribeck friction, smoothed at zero speed; torque in,
    speed out (module docstring: equations, index conventions, closed forms, discretisation,
    parameters).

    Args:
        inertia: ``J``, kg·m².
        viscous: ``b``, N·m·s/rad.
        coulomb: ``T_c``, N·m (0 with ``static = 0``: no dry friction).
        static: ``T_s ≥ T_c``, N·m.
        stribeck_speed: ``ω_s``, rad/s.
        smoothing: ``ε``, rad/s: the speed scale of ``tanh(ω / ε)``.
        rate_hz: sampling rate, Hz.
        substeps: RK4 steps per sample.
        torque_max: U = [−torque_max, torque_max] N·m.
        speed_box: half-width of X, rad/s.
        noise: half-width of W, rad/s.
    """

    description = (
        "Drive with viscous, Coulomb and Stribeck friction (smoothed sign), torque in, speed "
        "out, RK4 (10 substeps) at 100 Hz"
    )

    def __init__(
        self,
        *,
        inertia: float = 0.1,
        viscous: float = 0.3,
        coulomb: float = 1.0,
        static: float = 1.5,
        stribeck_speed: float = 0.3,
        smoothing: float = 0.02,
        rate_hz: float = 100.0,
        substeps: int = 10,
        torque_max: float = 10.0,
        speed_box: float = 20.0,
        noise: float = 0.02,
    ) -> None:
        for label, value, least in (
            ("inertia", inertia, "> 0"),
            ("viscous", viscous, ">= 0"),
            ("coulomb", coulomb, ">= 0"),
            ("static", static, ">= 0"),
            ("stribeck_speed", stribeck_speed, "> 0"),
            ("smoothing", smoothing, "> 0"),
            ("rate_hz", rate_hz, "> 0"),
            ("torque_max", torque_max, "> 0"),
            ("speed_box", speed_box, "> 0"),
            ("noise", noise, ">= 0"),
        ):
            if not (math.isfinite(value) and (value >= 0 if least == ">= 0" else value > 0)):
                raise SetError(
                    f"friction-drive: {label} must be a finite number {least}, got {value}"
                )
        if static < coulomb:
            raise SetError(
                f"friction-drive: static friction ({static}) must be at least the Coulomb "
                f"friction ({coulomb})"
            )
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise SetError(f"friction-drive: substeps must be an integer >= 1, got {substeps!r}")
        stiffness = (viscous + static / smoothing) / inertia  # 1/s, the largest slope over J
        h = 1.0 / (rate_hz * substeps)
        if h * stiffness > STIFFNESS_LIMIT:
            needed = math.ceil(stiffness / (rate_hz * STIFFNESS_LIMIT))
            raise SetError(
                f"friction-drive: h (b + T_s / eps) / J = {h * stiffness:.3g} > "
                f"{STIFFNESS_LIMIT:g}: the smoothed friction is too stiff for RK4 at "
                f"{substeps} substeps; use substeps >= {needed} or a larger smoothing"
            )
        self.inertia, self.viscous = float(inertia), float(viscous)
        self.coulomb, self.static = float(coulomb), float(static)
        self.stribeck_speed, self.smoothing = float(stribeck_speed), float(smoothing)
        self.substeps = substeps
        super().__init__(
            name="friction-drive",
            dt=1.0 / rate_hz,
            state_names=("omega",),
            state_units=("rad/s",),
            input_names=("tau",),
            input_units=("N*m",),
            output_names=("omega",),
            output_units=("rad/s",),
            X=Box([-speed_box], [speed_box]),
            U=Box([-torque_max], [torque_max]),
            W=Box([-noise], [noise]),
            discretisation=f"RK4, {substeps} steps per sample, input held",
            parameters={
                "inertia": self.inertia,
                "viscous": self.viscous,
                "coulomb": self.coulomb,
                "static": self.static,
                "stribeck_speed": self.stribeck_speed,
                "smoothing": self.smoothing,
                "substeps": substeps,
            },
        )

    def _friction(self, omega: ca.SX) -> ca.SX:
        level = self.coulomb + (self.static - self.coulomb) * ca.exp(
            -((omega / self.stribeck_speed) ** 2)
        )
        return level * ca.tanh(omega / self.smoothing)

    def friction(self, omega: np.ndarray | float) -> np.ndarray:
        """``F(ω)`` of the module docstring, elementwise, N·m."""
        omega = np.asarray(omega, dtype=np.float64)
        level = self.coulomb + (self.static - self.coulomb) * np.exp(
            -((omega / self.stribeck_speed) ** 2)
        )
        return level * np.tanh(omega / self.smoothing)

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return (u[0] - self.viscous * x[0] - self._friction(x[0])) / self.inertia

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        h = self.dt / self.substeps
        for _ in range(self.substeps):
            k1 = self._rhs(x, u)
            k2 = self._rhs(x + 0.5 * h * k1, u)
            k3 = self._rhs(x + 0.5 * h * k2, u)
            k4 = self._rhs(x + h * k3, u)
            x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return x

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return x[0]

    def _rhs(self, x: ca.SX, u: ca.SX) -> ca.SX:
        ode = self._ode_expr(x, u)
        assert ode is not None
        return ode
