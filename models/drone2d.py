"""Planar drone (paper §V-A): a quadrotor restricted to the vertical plane.

State ``(px, pz, θ, ṗx, ṗz, θ̇)``, inputs the rotor speeds ``(Ω1, Ω2)`` in rad/s, output the pose
``y = (px, pz, θ)`` (+ noise in a dataset)::

    p̈x = −(kT/m)(Ω1² + Ω2²) sin θ − (γ/m)(Ω1 + Ω2) ṗx
    p̈z =  (kT/m)(Ω1² + Ω2²) cos θ − (γ/m)(Ω1 + Ω2) ṗz − g
    θ̈  =  (kT L / J)(Ω2² − Ω1²)

with kT = 4e-4, γ = 1e-9, L = 0.15, m = 1, J = 2.7e-3, g = 9.81, discretised by explicit Euler at
30 Hz: ``x[t+1] = x[t] + dt · ode(x[t], u[t])``. Hover speed √(mg / 2kT) ≈ 110.7 rad/s. The
open-loop system is unstable.
"""

from __future__ import annotations

import math

import casadi as ca

from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["Drone2D"]


class Drone2D(System):
    """Planar quadrotor with two rotors.

    Args:
        kT, gamma, L, m, J, g: physical parameters (paper values by default).
        rate_hz: sampling rate of the Euler discretisation.
        omega_max: upper edge of U for each rotor speed (rad/s). The default, 250 rad/s, gives a
            thrust of about 5 g, well above what tracking needs.
        noise: half-widths of W for (px [m], pz [m], θ [rad]).
    """

    description = "Planar drone (paper §V-A), explicit Euler at 30 Hz, unstable open loop"

    def __init__(
        self,
        *,
        kT: float = 4e-4,
        gamma: float = 1e-9,
        L: float = 0.15,
        m: float = 1.0,
        J: float = 2.7e-3,
        g: float = 9.81,
        rate_hz: float = 30.0,
        omega_max: float = 250.0,
        position_box: float = 3.0,
        angle_box: float = math.pi / 2,
        velocity_box: float = 5.0,
        rate_box: float = 10.0,
        noise: tuple[float, float, float] = (0.01, 0.01, 0.01),
    ) -> None:
        self.kT, self.gamma, self.L, self.m, self.J, self.g = kT, gamma, L, m, J, g
        p, a, v, r = position_box, angle_box, velocity_box, rate_box
        super().__init__(
            name="drone2d",
            dt=1.0 / rate_hz,
            state_names=("px", "pz", "theta", "vx", "vz", "omega"),
            state_units=("m", "m", "rad", "m/s", "m/s", "rad/s"),
            input_names=("Omega1", "Omega2"),
            input_units=("rad/s", "rad/s"),
            output_names=("px", "pz", "theta"),
            output_units=("m", "m", "rad"),
            X=Box([-p, -p, -a, -v, -v, -r], [p, p, a, v, v, r]),
            U=Box([0.0, 0.0], [omega_max, omega_max]),
            W=Box.symmetric(list(noise)),
            discretisation="explicit Euler",
            parameters={"kT": kT, "gamma": gamma, "L": L, "m": m, "J": J, "g": g},
        )

    @property
    def hover_speed(self) -> float:
        """Rotor speed √(mg / 2kT) at which both rotors together balance gravity."""
        return math.sqrt(self.m * self.g / (2.0 * self.kT))

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        theta, vx, vz, omega = x[2], x[3], x[4], x[5]
        o1, o2 = u[0], u[1]
        thrust = self.kT / self.m * (o1**2 + o2**2)
        drag = self.gamma / self.m * (o1 + o2)
        ax = -thrust * ca.sin(theta) - drag * vx
        az = thrust * ca.cos(theta) - drag * vz - self.g
        alpha = self.kT * self.L / self.J * (o2**2 - o1**2)
        return ca.vertcat(vx, vz, omega, ax, az, alpha)

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        ode = self._ode_expr(x, u)
        assert ode is not None
        return x + self.dt * ode

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return x[0:3]
