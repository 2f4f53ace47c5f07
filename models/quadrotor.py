"""Quadrotor (3-D), **simulated**: the runnable stand-in for the real Blackbird flights.

The paper's third benchmark is the Blackbird UAV dataset (real flights: four rotor speeds in, the
six IMU signals out, 50 Hz). Those files cannot be downloaded everywhere, so this module gives a
rigid-body quadrotor with the same inputs and outputs and the parameters of a Blackbird-class
vehicle. It is a simulation; numbers obtained with it are not Blackbird numbers.

Frames and state
----------------
World frame ``W``: z up, gravity ``g_W = (0, 0, −g)``. Body frame ``B``: x forward, y left, z
along the rotor thrust. The state (13) is

    x = (p, v, q, ω)
    p = (px, py, pz)       position of the centre of mass in W [m]
    v = (vx, vy, vz)       velocity in W [m/s]
    q = (qw, qx, qy, qz)   unit quaternion, rotation B → W (scalar first), R(q) its matrix
    ω = (wx, wy, wz)       body rates, in B [rad/s]

The attitude is a quaternion, so the dynamics have no Euler-angle singularity.

Inputs, rotors, X configuration
-------------------------------
``u = (Ω1, Ω2, Ω3, Ω4)`` are the rotor speeds [rad/s]. Rotor ``i`` gives the thrust
``T_i = k_T Ω_i²`` along body z and the drag torque ``s_i k_D Ω_i²`` about body z. Rotors are
numbered clockwise seen from above, starting front-left, at the corners of a square whose
centre-to-rotor distance is the arm length ``L`` (half-side ``a = L/√2``)::

        front (+x)
      1 (+a, +a)   2 (+a, −a)        s = (+1, −1, +1, −1): 1 and 3 spin one way, 2 and 4 the other
      4 (−a, +a)   3 (−a, −a)

so that, with ``T = Σ T_i`` and ``c = k_D / k_T``,

    τx = a (T1 − T2 − T3 + T4),  τy = a (−T1 − T2 + T3 + T4),  τz = k_D (Ω1² − Ω2² + Ω3² − Ω4²).

:meth:`Quadrotor.allocation_matrix` is this linear map from ``(Ω1², …, Ω4²)`` to ``(T, τ)``.
(The numbering follows the Blackbird vehicle sketch; whether its spin directions match
Blackbird's is not documented, and does not matter for the stand-in.)

Dynamics (continuous time)
--------------------------
    ṗ = v
    v̇ = g_W + R(q) ((T/m) e3 − D R(q)ᵀ v)
    q̇ = ½ q ⊗ (0, ω)
    ω̇ = J⁻¹ (τ − ω × J ω)

``D = diag(dx, dy, dz)`` is a linear rotor-drag term (mass-normalised, acting along the body
axes, as in quadrotor models with rotor drag). Without it the accelerometer would read exactly
``(0, 0, T/m)`` at all times and its x, y channels would carry no information. Rotor inertia,
motor dynamics and gyroscopic rotor torques are neglected.

Outputs: the IMU
----------------
    y = (acc, gyro)
    acc  = R(q)ᵀ (v̇ − g_W) = (T/m) e3 − D R(q)ᵀ v     specific force in B [m/s²]
    gyro = ω                                         body rates [rad/s]

At hover (level, at rest, ``T = m g``) the accelerometer reads ``(0, 0, +g)`` and the gyroscope
zero; in free fall (``Ω = 0``, at rest) the accelerometer reads zero. ``h`` depends on ``u``
(through ``T``): the system has feedthrough.

Discretisation
--------------
Classical Runge–Kutta (RK4) over ``dt = 0.02 s`` (50 Hz, the Blackbird rate of the paper) with
``u`` held constant, followed by one Newton step of quaternion renormalisation inside ``f``:

    q⁺ = q̃ (3 − ‖q̃‖²) / 2,    q̃ the quaternion after the RK4 step.

From a unit quaternion RK4 leaves ``‖q̃‖² = 1 + ε`` with ``|ε| ≈ (‖ω‖ dt)⁶ / 4608`` (about 1e-8
at 10 rad/s); the Newton step then gives ``‖q⁺‖² = 1 − ¾ ε² + O(ε³)``: unit norm to rounding,
step after step, with no drift (tests check it over long simulations). Unlike ``q̃ / ‖q̃‖`` the
map is a polynomial, smooth on the whole box X (including ``q = 0``), so ``f`` has a finite
Lipschitz constant on X.

Parameters (Blackbird-class vehicle) and their sources
------------------------------------------------------
* ``m = 0.915 kg`` — Blackbird vehicle mass (Antonini et al., "The Blackbird UAV dataset",
  IJRR 2020; the same value is used by public Blackbird processing code).
* ``L = 0.127 m`` arm length — from "adjacent motors 18 cm apart" on a square frame
  (0.18 / √2); the dataset description rounds it to 0.13 m.
* ``k_T = 2.07e-6 N s²`` — from the thrust coefficient ``C_T = 2.27e-8 N/rpm²`` quoted for the
  Blackbird vehicle, converted to (rad/s)² by the factor (60 / 2π)²; another public Blackbird
  processing script uses 2.03e-8 N/rpm², so treat it as ±10 %. Hover speed ≈ 1041 rad/s
  (≈ 9 900 rpm).
* ``J = diag(4.9e-3, 4.9e-3, 6.9e-3) kg m²`` — **estimate**. The digits 4.9 / 4.9 / 6.9 are those
  quoted for the Blackbird vehicle, whose scale is ambiguous in public sources (1e-2 is also
  quoted, with doubtful units); 1e-3 is the order of magnitude of every ~1 kg quadrotor with
  13 cm arms.
* ``k_D = 0.016 · k_T`` (m) drag-torque coefficient — **estimate** (typical ratio for small
  propellers; not published for Blackbird).
* ``D = diag(0.3, 0.3, 0.05) 1/s`` rotor drag — **estimate** (order of magnitude of identified
  values for quadrotors of this size; not published for Blackbird).
* ``Ω_max = 1800 rad/s`` — **estimate**: a thrust-to-weight ratio of about 3.
* ``g = 9.81 m/s²``.

Sets
----
* ``X``: ``|px|, |py|, |pz| ≤ 5 m``, ``|v| ≤ 8 m/s`` per axis (Blackbird flies up to 7 m/s),
  ``q ∈ [−1, 1]⁴`` (a box holding the unit sphere; ``f`` and ``h`` are meaningful for unit
  ``q``), ``|ω| ≤ 10 rad/s`` per axis.
* ``U = [0, Ω_max]⁴`` rad/s.
* ``W``: accelerometer ``±0.05 m/s²``, gyroscope ``±0.005 rad/s`` (bounded noise of the generated
  datasets, of the order of a MEMS IMU's white noise at 50 Hz).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["Quadrotor"]

_STATE_NAMES = ("px", "py", "pz", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "wx", "wy", "wz")

#: (60 / 2π)²: converts a coefficient per rpm² into one per (rad/s)²
_RPM2_TO_RADS2 = (60.0 / (2.0 * math.pi)) ** 2


def _rotation(q: ca.SX) -> ca.SX:
    """Rotation matrix B → W of the unit quaternion ``q = (qw, qx, qy, qz)``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def _quat_rate(q: ca.SX, omega: ca.SX) -> ca.SX:
    """``q̇ = ½ q ⊗ (0, ω)`` with ``ω`` in the body frame."""
    w, v = q[0], q[1:4]
    return 0.5 * ca.vertcat(-ca.dot(v, omega), w * omega + ca.cross(v, omega))


class Quadrotor(System):
    """Simulated rigid-body quadrotor with IMU outputs (the Blackbird stand-in).

    See the module docstring for frames, equations, the discretisation and the source of every
    parameter.

    Args:
        m: mass [kg].
        arm_length: centre-to-rotor distance ``L`` [m] (X configuration, half-side ``L/√2``).
        kT: thrust coefficient [N s²] (thrust ``kT Ω²`` per rotor, ``Ω`` in rad/s).
        kD: drag-torque coefficient [N m s²]; default ``0.016 · kT``.
        J: principal moments of inertia (Jx, Jy, Jz) [kg m²].
        drag: mass-normalised linear rotor drag (dx, dy, dz) along the body axes [1/s].
        g: gravity [m/s²].
        rate_hz: sampling rate of the RK4 discretisation.
        omega_max: upper edge of U for each rotor [rad/s].
        position_box, velocity_box, rate_box: half-widths of X for p [m], v [m/s], ω [rad/s].
        noise: half-widths of W for the accelerometer [m/s²] and the gyroscope [rad/s].
    """

    description = "Quadrotor 3-D, SIMULATED rigid body (quaternion attitude), IMU out, RK4 at 50 Hz"
    simulated_stand_in_for = "Blackbird UAV dataset (real flights)"
    analysis_note = (
        "13 states and 4 inputs; f multiplies quaternion components (R(q) in the velocity, "
        "q ⊗ ω in the attitude) and renormalises with the cubic q(3 − ‖q‖²)/2, through four "
        "RK4 stages, so interval arithmetic, which treats every occurrence of a variable as "
        "independent, wraps: enclosures on boxes of X are loose, the hull of reachable states "
        "grows at every step of a window, and tightening them means splitting boxes in 17 "
        "dimensions; the IMU does not measure position, so α_ℓ = 0 for every ℓ"
    )

    def __init__(
        self,
        *,
        m: float = 0.915,
        arm_length: float = 0.127,
        kT: float = 2.27e-8 * _RPM2_TO_RADS2,
        kD: float | None = None,
        J: tuple[float, float, float] = (4.9e-3, 4.9e-3, 6.9e-3),
        drag: tuple[float, float, float] = (0.3, 0.3, 0.05),
        g: float = 9.81,
        rate_hz: float = 50.0,
        omega_max: float = 1800.0,
        position_box: float = 5.0,
        velocity_box: float = 8.0,
        rate_box: float = 10.0,
        noise: tuple[float, float] = (0.05, 0.005),
    ) -> None:
        kD = 0.016 * kT if kD is None else kD
        for label, value in (("m", m), ("arm_length", arm_length), ("kT", kT), ("kD", kD)):
            if not (np.isfinite(value) and value > 0):
                raise SetError(f"quadrotor: {label} must be a positive number, got {value}")
        if len(J) != 3 or any(not (j > 0) for j in J):
            raise SetError(f"quadrotor: J must be three positive moments of inertia, got {J}")
        if len(drag) != 3 or any(not (d >= 0) for d in drag):
            raise SetError(f"quadrotor: drag must be three coefficients >= 0, got {drag}")
        self.m, self.arm_length, self.kT, self.kD, self.g = m, arm_length, kT, kD, g
        self.J = tuple(float(j) for j in J)
        self.drag = tuple(float(d) for d in drag)
        self.omega_max = float(omega_max)
        if not self.omega_max > self.hover_speed:
            raise SetError(
                f"quadrotor: omega_max = {omega_max} rad/s cannot lift the vehicle (hover needs "
                f"{self.hover_speed:.1f} rad/s)"
            )
        if len(noise) != 2 or any(not (n >= 0) for n in noise):
            raise SetError(
                "quadrotor: noise must be two half-widths >= 0 (accelerometer [m/s^2], "
                f"gyroscope [rad/s]), got {noise}"
            )
        p, v, r = position_box, velocity_box, rate_box
        acc_noise, gyro_noise = noise
        super().__init__(
            name="quadrotor",
            dt=1.0 / rate_hz,
            state_names=_STATE_NAMES,
            state_units=("m",) * 3 + ("m/s",) * 3 + ("-",) * 4 + ("rad/s",) * 3,
            input_names=("Omega1", "Omega2", "Omega3", "Omega4"),
            input_units=("rad/s",) * 4,
            output_names=("acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z"),
            output_units=("m/s^2",) * 3 + ("rad/s",) * 3,
            X=Box(
                [-p] * 3 + [-v] * 3 + [-1.0] * 4 + [-r] * 3, [p] * 3 + [v] * 3 + [1.0] * 4 + [r] * 3
            ),
            U=Box([0.0] * 4, [self.omega_max] * 4),
            W=Box.symmetric([acc_noise] * 3 + [gyro_noise] * 3),
            discretisation="RK4, then one Newton step of quaternion renormalisation",
            parameters={
                "m": m,
                "arm_length": arm_length,
                "kT": kT,
                "kD": kD,
                "J": self.J,
                "drag": self.drag,
                "g": g,
                "omega_max": self.omega_max,
                "rotor_layout": "X, clockwise from front-left, spin signs (+1, -1, +1, -1)",
                "simulated": True,
            },
        )

    # ------------------------------------------------------------------ helpers
    @property
    def hover_speed(self) -> float:
        """Rotor speed ``√(m g / 4 k_T)`` at which the four rotors balance gravity [rad/s]."""
        return math.sqrt(self.m * self.g / (4.0 * self.kT))

    def allocation_matrix(self) -> np.ndarray:
        """The 4×4 map ``(Ω1², Ω2², Ω3², Ω4²) ↦ (T, τx, τy, τz)`` (invertible)."""
        a = self.arm_length / math.sqrt(2.0)
        kT, kD = self.kT, self.kD
        return np.array(
            [
                [kT, kT, kT, kT],
                [a * kT, -a * kT, -a * kT, a * kT],
                [-a * kT, -a * kT, a * kT, a * kT],
                [kD, -kD, kD, -kD],
            ]
        )

    def hover_state(self, position: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """Level attitude, at rest, at ``position``: the state kept by ``hover_speed`` inputs."""
        return np.array([*position, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

    # ------------------------------------------------------------------ symbolic model
    def _wrench(self, u: ca.SX) -> tuple[ca.SX, ca.SX]:
        """Total thrust ``T`` and body torque ``τ`` of the rotor speeds ``u``."""
        w = ca.DM(self.allocation_matrix()) @ (u * u)
        return w[0], w[1:4]

    def _specific_force(self, x: ca.SX, thrust: ca.SX) -> ca.SX:
        """``(T/m) e3 − D R(q)ᵀ v``: what the accelerometer measures, in the body frame."""
        v_body = _rotation(x[6:10]).T @ x[3:6]
        drag = ca.DM(self.drag) * v_body
        return ca.vertcat(-drag[0], -drag[1], thrust / self.m - drag[2])

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        q, omega = x[6:10], x[10:13]
        thrust, torque = self._wrench(u)
        acc = _rotation(q) @ self._specific_force(x, thrust) + ca.DM([0.0, 0.0, -self.g])
        J = ca.DM(self.J)
        omega_dot = (torque - ca.cross(omega, J * omega)) / J
        return ca.vertcat(x[3:6], acc, _quat_rate(q, omega), omega_dot)

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        dt = self.dt

        def ode(xs: ca.SX) -> ca.SX:
            out = self._ode_expr(xs, u)
            assert out is not None
            return out

        k1 = ode(x)
        k2 = ode(x + 0.5 * dt * k1)
        k3 = ode(x + 0.5 * dt * k2)
        k4 = ode(x + dt * k3)
        xn = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        q = xn[6:10]
        q = q * (3 - ca.dot(q, q)) / 2
        return ca.vertcat(xn[0:6], q, xn[10:13])

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        thrust, _ = self._wrench(u)
        return ca.vertcat(self._specific_force(x, thrust), x[10:13])
