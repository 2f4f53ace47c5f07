"""A chain of three masses, lightly damped, with one hardening joint: 1 force in, 3 accelerations
out. Its slowest mode rings for hundreds of samples, so a model must look far back.

Mechanics (continuous time)
---------------------------
A fixed wall, then masses 1, 2, 3 in a line, each joint a spring and a damper in parallel::

    wall ─[k1 + cubic, c1]─ m1 ─[k2, c2]─ m2 ─[k3, c3]─ m3 ← F

``q = (q1, q2, q3)`` are the displacements from rest [m], ``v = q̇`` the velocities [m/s]. Joint
``i`` stretches by ``d1 = q1``, ``d2 = q2 − q1``, ``d3 = q3 − q2`` and pulls back with
``k_i d_i + c_i ḋ_i``; the wall joint adds the hardening term ``cubic · d1³``. The force ``F``
acts on the free mass 3::

    m1 q̈1 = −(k1 q1 + cubic q1³ + c1 v1) + k2 d2 + c2 ḋ2
    m2 q̈2 = −(k2 d2 + c2 ḋ2) + k3 d3 + c3 ḋ3
    m3 q̈3 = −(k3 d3 + c3 ḋ3) + F

State ``x = (q1, q2, q3, v1, v2, v3)``; output ``y = (a1, a2, a3) = (q̈1, q̈2, q̈3)``, the
accelerations of the three masses, the velocity part of ``ode(x, u)`` (accelerometers on the
masses). ``a3`` depends on ``F``: the system has feedthrough.

Linear part, modes
------------------
With ``cubic = 0`` the system is ``M q̈ + C q̇ + K q = b F`` with ``M = diag(m)``,
``K = [[k1+k2, −k2, 0], [−k2, k2+k3, −k3], [0, −k3, k3]]``, ``C`` the same with ``c`` for ``k``,
``b = e3``. By default every mass is ``m = 1 kg``, every spring ``k = 100 N/m`` and every damper
``c = 0.7 N·s/m``. Equal masses and springs on a fixed-free chain of ``n = 3`` give the closed
form ``ω_j = 2 √(k/m) sin((2j − 1) π / (2(2n + 1)))``, and ``C = (c/k) K`` (dampers proportional
to springs) gives modal damping ``ζ_j = (c/k) ω_j / 2``::

    mode  ω_j [rad/s]              f_j [Hz]  ζ_j              samples per period at dt = 0.02 s
    1     20 sin(π/14)  =  4.4504  0.7083    0.01558 (1.6 %)  70.6
    2     20 sin(3π/14) = 12.4698  1.9846    0.04364 (4.4 %)  25.2
    3     20 sin(5π/14) = 18.0194  2.8679    0.06307 (6.3 %)  17.4

The slowest mode decays with time constant ``1 / (ζ1 ω1) = 14.43 s`` = 721 samples (its
impulse response falls to 1 % after 4.6 time constants, about 3,300 samples); the fastest is
sampled 17.4 times per period. The hardening joint stiffens the wall spring by ``3 cubic q1²``:
with the default ``cubic = 1000 N/m³`` that is 30 % of ``k1`` at ``|q1| = 0.1 m``.

Discretisation
--------------
Classical Runge–Kutta (RK4) over ``dt = 0.02 s`` (50 Hz) with ``F`` held constant. On the linear
part the discrete eigenvalues are ``R(λ dt)`` with ``R(z) = 1 + z + z²/2 + z³/6 + z⁴/24``
instead of ``exp(λ dt)``; for the fastest mode ``|λ dt| = 0.36`` and the two differ by about
``|λ dt|⁵ / 120 = 5e-5`` (relative), far below its damping per step (``ζ3 ω3 dt = 0.023``).
"""

from __future__ import annotations

import math

import casadi as ca

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["MassChain"]

_TRIPLE = tuple[float, float, float]


def _triple(value: _TRIPLE, name: str, *, positive: bool) -> _TRIPLE:
    values = tuple(float(v) for v in value)
    ok = len(values) == 3 and all(
        math.isfinite(v) and (v > 0 if positive else v >= 0) for v in values
    )
    if not ok:
        bound = "> 0" if positive else ">= 0"
        raise SetError(f"masses: {name} must be three finite numbers {bound}, got {value}")
    return values  # type: ignore[return-value]


class MassChain(System):
    """Three masses on springs and dampers, a cubic hardening spring at the wall, force on the
    free mass, accelerations measured (module docstring: equations, modes, discretisation).

    Args:
        mass: ``(m1, m2, m3)`` in kg.
        stiffness: ``(k1, k2, k3)`` of the wall joint and the two joints between masses, N/m.
        damping: ``(c1, c2, c3)`` of the same joints, N·s/m (zeros: the undamped chain).
        cubic: hardening coefficient of the wall joint, N/m³ (0: the linear chain).
        rate_hz: sampling rate of the RK4 discretisation.
        force_max: U = [−force_max, force_max] N.
        position_box, velocity_box: half-widths of X for the displacements [m] and the
            velocities [m/s].
        noise: half-width of W on each acceleration, m/s².
    """

    description = (
        "Chain of 3 masses, light damping (slowest mode 1.6 %), cubic spring at the wall, "
        "force in, 3 accelerations out, RK4 at 50 Hz"
    )

    def __init__(
        self,
        *,
        mass: _TRIPLE = (1.0, 1.0, 1.0),
        stiffness: _TRIPLE = (100.0, 100.0, 100.0),
        damping: _TRIPLE = (0.7, 0.7, 0.7),
        cubic: float = 1000.0,
        rate_hz: float = 50.0,
        force_max: float = 20.0,
        position_box: float = 0.6,
        velocity_box: float = 3.0,
        noise: float = 0.05,
    ) -> None:
        self.mass = _triple(mass, "mass", positive=True)
        self.stiffness = _triple(stiffness, "stiffness", positive=True)
        self.damping = _triple(damping, "damping", positive=False)
        for label, value, least in (
            ("cubic", cubic, ">= 0"),
            ("force_max", force_max, "> 0"),
            ("position_box", position_box, "> 0"),
            ("velocity_box", velocity_box, "> 0"),
            ("noise", noise, ">= 0"),
        ):
            if not (math.isfinite(value) and (value >= 0 if least == ">= 0" else value > 0)):
                raise SetError(f"masses: {label} must be a finite number {least}, got {value}")
        self.cubic = float(cubic)
        p, v = position_box, velocity_box
        super().__init__(
            name="masses",
            dt=1.0 / rate_hz,
            state_names=("q1", "q2", "q3", "v1", "v2", "v3"),
            state_units=("m", "m", "m", "m/s", "m/s", "m/s"),
            input_names=("F",),
            input_units=("N",),
            output_names=("a1", "a2", "a3"),
            output_units=("m/s^2", "m/s^2", "m/s^2"),
            X=Box([-p, -p, -p, -v, -v, -v], [p, p, p, v, v, v]),
            U=Box([-force_max], [force_max]),
            W=Box.symmetric(noise, 3),
            discretisation="RK4, input held over the step",
            parameters={
                "mass": self.mass,
                "stiffness": self.stiffness,
                "damping": self.damping,
                "cubic": self.cubic,
                "force_on": "m3",
                "cubic_joint": "wall-m1",
            },
        )

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        (m1, m2, m3), (k1, k2, k3), (c1, c2, c3) = self.mass, self.stiffness, self.damping
        q1, q2, q3, v1, v2, v3 = (x[i] for i in range(6))
        # tension of each joint (positive when stretched)
        t1 = k1 * q1 + self.cubic * q1**3 + c1 * v1
        t2 = k2 * (q2 - q1) + c2 * (v2 - v1)
        t3 = k3 * (q3 - q2) + c3 * (v3 - v2)
        a1 = (t2 - t1) / m1
        a2 = (t3 - t2) / m2
        a3 = (u[0] - t3) / m3
        return ca.vertcat(v1, v2, v3, a1, a2, a3)

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        h = self.dt
        k1 = self._rhs(x, u)
        k2 = self._rhs(x + 0.5 * h * k1, u)
        k3 = self._rhs(x + 0.5 * h * k2, u)
        k4 = self._rhs(x + h * k3, u)
        return x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return self._rhs(x, u)[3:6]

    def _rhs(self, x: ca.SX, u: ca.SX) -> ca.SX:
        ode = self._ode_expr(x, u)
        assert ode is not None
        return ode
