"""A lightly damped structure of three modes, as a ground-vibration test sees it: a shaker's force
in, three accelerometers out, every mode damped 1–2 %, and one joint that hardens (a cubic
spring). Its records are long: the slowest mode rings for about 2,000 samples.

Mechanics (continuous time)
---------------------------
A fixed base, then masses 1, 2, 3 in a line, joined by springs::

    base ─[k1]─ m1 ─[k2]─ m2 ─[k3 + cubic]─ m3          F on m1 (the shaker)

``q = (q1, q2, q3)`` are the displacements from rest [m], ``v = q̇`` the velocities [m/s]. Joint
``i`` stretches by ``d1 = q1``, ``d2 = q2 − q1``, ``d3 = q3 − q2`` and pulls back with ``k_i d_i``;
the joint between masses 2 and 3 adds the hardening term ``cubic · d3³``. The damping is modal:
``C = M Φ diag(2 ζ_j ω_j) Φᵀ M`` with ``ω_j`` and the mass-normalised mode shapes ``Φ`` (``Φᵀ M
Φ = I``) of the linear, undamped chain, so each mode ``j`` of the linear chain has exactly the
damping ratio ``ζ_j`` (a structure's measured modal damping, not a layout of dampers)::

    M q̈ = b F − K q − cubic · d3³ · (0, −1, 1) − C v,    b = (1, 0, 0)

with ``K = [[k1 + k2, −k2, 0], [−k2, k2 + k3, −k3], [0, −k3, k3]]`` and ``M = diag(m)``.

State, index conventions
------------------------
``x = (q1, q2, q3, v1, v2, v3)``: indices 0–2 the displacements [m], 3–5 the velocities [m/s],
mass ``i`` at index ``i − 1`` and ``i + 2``. Input ``u = F`` [N] on mass 1. Output ``y = (a1, a2,
a3) = q̈`` [m/s²], the velocity part of ``ode(x, u)`` (accelerometers on the masses); ``a1``
depends on ``F``: the system has feedthrough.

Linear part, modes
------------------
By default every mass is 1 kg and every spring 10,000 N/m. Equal masses and springs on a
fixed-free chain of ``n = 3`` give ``ω_j = 2 √(k/m) sin((2j − 1) π / (2(2n + 1)))``::

    mode  ω_j [rad/s]               f_j [Hz]  ζ_j     samples per period at dt = 5 ms
    1     200 sin(π/14)  =  44.504   7.083    1.0 %   28.2
    2     200 sin(3π/14) = 124.698  19.846    1.5 %   10.1
    3     200 sin(5π/14) = 180.194  28.679    2.0 %    7.0

The continuous poles of the linear chain are ``−ζ_j ω_j ± j ω_j √(1 − ζ_j²)``. The slowest mode
decays with the time constant ``1 / (ζ1 ω1) = 2.25 s`` = 449 samples (to 1 % in about 2,070
samples). The cubic joint stiffens ``k3`` by ``3 cubic d3²``: with the default ``cubic = 2e7
N/m³`` that is 30 % at ``|d3| = 7.1 mm``, about the largest stretch of the scenario's records
(its RMS is 1.6 mm); their accelerations differ from the linear chain's under the same force by
13–17 % of their RMS.

Discretisation
--------------
``substeps`` classical Runge–Kutta (RK4) steps of ``h = dt / substeps`` per sample, ``F`` held.
On the linear part the discrete eigenvalues are ``R(λ h)^substeps`` with ``R(z) = 1 + z + z²/2 +
z³/6 + z⁴/24`` instead of ``exp(λ dt)``. With the default ``dt = 5 ms`` and 4 substeps, the
fastest mode has ``|λ h| = 0.225`` and RK4 damps it by about ``|λ h|⁶ / 144 = 9e-7`` per substep
beyond the true decay, 0.02 % of its damping (``ζ3 ω3 h = 4.5e-3``): the modal damping of the
records is the one written here. (One RK4 step per sample would add 20 % to mode 3's damping.)
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["Vibration"]

_TRIPLE = tuple[float, float, float]


def _triple(value: _TRIPLE, name: str, low: float, high: float = math.inf) -> _TRIPLE:
    values = tuple(float(v) for v in value)
    if len(values) != 3 or not all(math.isfinite(v) and low < v < high for v in values):
        bound = f"in ({low:g}, {high:g})" if math.isfinite(high) else f"> {low:g}"
        raise SetError(f"vibration: {name} must be three finite numbers {bound}, got {value}")
    return values


def stiffness_matrix(k: _TRIPLE) -> np.ndarray:
    """``K`` of the fixed-free chain with joint stiffnesses ``k`` (module docstring)."""
    k1, k2, k3 = k
    return np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])


def modes(mass: _TRIPLE, k: _TRIPLE) -> tuple[np.ndarray, np.ndarray]:
    """``(ω, Φ)``: the undamped natural frequencies [rad/s], ascending, and the mass-normalised
    mode shapes (columns, ``Φᵀ M Φ = I``) of the linear chain."""
    root = 1.0 / np.sqrt(np.asarray(mass))
    eig, shapes = np.linalg.eigh(root[:, None] * stiffness_matrix(k) * root[None, :])
    return np.sqrt(eig), root[:, None] * shapes


class Vibration(System):
    """Three modes of a fixed-free chain, modal damping, a cubic joint between masses 2 and 3,
    force on mass 1, three accelerations measured (module docstring: equations, index
    conventions, modes, discretisation).

    Args:
        mass: ``(m1, m2, m3)`` in kg.
        stiffness: ``(k1, k2, k3)`` of the base joint and the two joints between masses, N/m.
        damping_ratio: ``(ζ1, ζ2, ζ3)`` of the linear chain's modes, slowest first, each in
            [0, 1).
        cubic: hardening coefficient of the joint between masses 2 and 3, N/m³ (0: linear).
        rate_hz: sampling rate, Hz.
        substeps: RK4 steps per sample.
        force_max: U = [−force_max, force_max] N.
        position_box, velocity_box: half-widths of X for the displacements [m] and the
            velocities [m/s].
        noise: half-width of W on each acceleration, m/s².
    """

    description = (
        "Lightly damped 3-mode structure (modal damping 1-2 %), cubic joint, shaker force in, "
        "3 accelerations out, RK4 (4 substeps) at 200 Hz"
    )

    def __init__(
        self,
        *,
        mass: _TRIPLE = (1.0, 1.0, 1.0),
        stiffness: _TRIPLE = (1.0e4, 1.0e4, 1.0e4),
        damping_ratio: _TRIPLE = (0.01, 0.015, 0.02),
        cubic: float = 2.0e7,
        rate_hz: float = 200.0,
        substeps: int = 4,
        force_max: float = 60.0,
        position_box: float = 0.03,
        velocity_box: float = 2.0,
        noise: float = 0.3,
    ) -> None:
        self.mass = _triple(mass, "mass", 0.0)
        self.stiffness = _triple(stiffness, "stiffness", 0.0)
        zeta = tuple(float(v) for v in damping_ratio)
        if len(zeta) != 3 or not all(0.0 <= v < 1.0 for v in zeta):
            raise SetError(
                f"vibration: damping_ratio must be three numbers in [0, 1), got {damping_ratio}"
            )
        self.damping_ratio: _TRIPLE = (zeta[0], zeta[1], zeta[2])
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise SetError(f"vibration: substeps must be an integer >= 1, got {substeps!r}")
        for label, value, least in (
            ("cubic", cubic, ">= 0"),
            ("rate_hz", rate_hz, "> 0"),
            ("force_max", force_max, "> 0"),
            ("position_box", position_box, "> 0"),
            ("velocity_box", velocity_box, "> 0"),
            ("noise", noise, ">= 0"),
        ):
            if not (math.isfinite(value) and (value >= 0 if least == ">= 0" else value > 0)):
                raise SetError(f"vibration: {label} must be a finite number {least}, got {value}")
        self.cubic, self.substeps = float(cubic), substeps
        omega, shapes = modes(self.mass, self.stiffness)
        nyquist = math.pi * rate_hz
        if omega[-1] >= nyquist:
            raise SetError(
                f"vibration: the fastest mode ({omega[-1] / (2 * math.pi):.4g} Hz) must lie below "
                f"Nyquist ({rate_hz / 2:g} Hz)"
            )
        M = np.diag(self.mass)
        self.omega = omega
        self.K = stiffness_matrix(self.stiffness)
        self.C = M @ shapes @ np.diag(2.0 * np.asarray(self.damping_ratio) * omega) @ shapes.T @ M
        p, v = position_box, velocity_box
        super().__init__(
            name="vibration",
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
            discretisation=f"RK4, {substeps} steps per sample, input held",
            parameters={
                "mass": self.mass,
                "stiffness": self.stiffness,
                "damping_ratio": self.damping_ratio,
                "damping": "modal, C = M Phi diag(2 zeta omega) Phi^T M",
                "cubic": self.cubic,
                "force_on": "m1",
                "cubic_joint": "m2-m3",
                "substeps": substeps,
            },
        )

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        q, v = x[0:3], x[3:6]
        d3 = x[2] - x[1]
        restoring = ca.mtimes(ca.DM(self.K), q) + self.cubic * d3**3 * ca.DM([0.0, -1.0, 1.0])
        force = ca.vertcat(u[0], 0.0, 0.0) - restoring - ca.mtimes(ca.DM(self.C), v)
        return ca.vertcat(v, force / ca.DM(self.mass))

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
        return self._rhs(x, u)[3:6]

    def _rhs(self, x: ca.SX, u: ca.SX) -> ca.SX:
        ode = self._ode_expr(x, u)
        assert ode is not None
        return ode

    def poles(self) -> np.ndarray:
        """The six continuous poles [rad/s] of the linear chain, ``−ζ_j ω_j ± j ω_j √(1 −
        ζ_j²)`` (closed form of the modal damping)."""
        zeta = np.asarray(self.damping_ratio)
        damped = self.omega * np.sqrt(1.0 - zeta**2)
        return np.concatenate([-zeta * self.omega + 1j * damped, -zeta * self.omega - 1j * damped])
