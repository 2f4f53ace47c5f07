"""Cascaded position → attitude → rate controller for the simulated quadrotor.

The standard structure of multirotor autopilots, evaluated once per sample (50 Hz) on the true
state ``x[t]`` of :class:`canonid.models.quadrotor.Quadrotor`:

1. **Position** (PID with feedforward). With ``e_p = p_ref − p`` and ``e_v = v_ref − v``,

       a_cmd = a_ff + Kp e_p + Kd e_v + Ki Σ e_p dt + R D Rᵀ v,

   where ``a_ff`` is the reference acceleration (central differences of ``v_ref``) and the last
   term cancels the model's rotor drag. The horizontal part of ``a_cmd`` is scaled down so the
   tilt stays below ``max_tilt_deg`` and its vertical part is kept above ``−(1 − min_thrust_g)·g``
   (the vehicle never commands less than ``min_thrust_g`` of its weight).
2. **Attitude** (geometric, on SO(3)). The desired body z axis is ``b3 = (a_cmd + g e3)/‖·‖``;
   with the reference yaw ψ, ``b2 = b3 × (cos ψ, sin ψ, 0) / ‖·‖``, ``b1 = b2 × b3`` and
   ``R_d = [b1 b2 b3]``. The attitude error ``e_R = ½ vee(R_dᵀ R − Rᵀ R_d)`` and the reference
   yaw rate ``ψ̇`` (central differences of the unwrapped yaw) give the rate command
   ``ω_cmd = −K_att e_R + ψ̇ Rᵀ e3``, clipped to ``±max_rate``. The collective thrust is the
   projection ``T = m (a_cmd + g e3) · R e3``.
3. **Rate**: ``τ = J K_rate (ω_cmd − ω) + ω × J ω``.
4. **Mixing**: ``(Ω1², …, Ω4²) = M⁻¹ (T, τ)`` with the model's allocation matrix ``M``; each
   ``Ω_i²`` is clipped to ``[Ω_min², Ω_max²]`` (U's edges), then ``Ω_i = √Ω_i²``. Clipping is
   recorded in ``ControlStep.info["saturated"]``.

Reference rows (``(T, 7)``): ``(px, py, pz, vx, vy, vz, yaw)`` in the world frame [m, m/s, rad];
row ``t`` is the target at sample ``t``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix, as_vector
from canonid.models.quadrotor import Quadrotor

__all__ = ["REFERENCE_COLUMNS", "CascadeGains", "QuadrotorCascade"]

#: what the columns of a quadrotor reference hold
REFERENCE_COLUMNS = ("px", "py", "pz", "vx", "vy", "vz", "yaw")


@dataclass(frozen=True)
class CascadeGains:
    """Gains and limits of :class:`QuadrotorCascade` (per axis x, y, z where a triple).

    Attributes:
        kp: position gain [1/s²].
        kd: velocity gain [1/s].
        ki: integral gain on the position error [1/s³].
        integral_limit: clamp of each integral state [m s].
        k_att: attitude gain: rate command per radian of attitude error [1/s].
        k_rate: rate-loop gain [1/s].
        max_tilt_deg: largest tilt of the commanded thrust from the vertical [deg].
        max_rate: clip of the rate command [rad/s].
        min_thrust_g: smallest commanded thrust as a fraction of the weight.
    """

    kp: tuple[float, float, float] = (2.0, 2.0, 3.0)
    kd: tuple[float, float, float] = (2.5, 2.5, 3.0)
    ki: tuple[float, float, float] = (0.1, 0.1, 0.2)
    integral_limit: float = 0.5
    k_att: tuple[float, float, float] = (7.0, 7.0, 3.0)
    k_rate: tuple[float, float, float] = (18.0, 18.0, 8.0)
    max_tilt_deg: float = 35.0
    max_rate: float = 6.0
    min_thrust_g: float = 0.3


def _vee(m: np.ndarray) -> np.ndarray:
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


def _rotation(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


class QuadrotorCascade(Controller):
    """Cascaded position/attitude/rate controller with mixing to rotor speeds (module docstring).

    Args:
        system: the quadrotor it flies (its mass, inertia, drag, allocation matrix and U).
        gains: gains and limits; :class:`CascadeGains` defaults when omitted.
    """

    name = "quadrotor-cascade"

    def __init__(self, system: Quadrotor, *, gains: CascadeGains | None = None) -> None:
        if not isinstance(system, Quadrotor):
            raise ShapeError(
                "QuadrotorCascade flies a canonid.models.quadrotor.Quadrotor, got "
                f"{type(system).__name__}"
            )
        self.system = system
        self.gains = gains or CascadeGains()
        self._mix_inv = np.linalg.inv(system.allocation_matrix())
        self._J = np.asarray(system.J)
        self._D = np.asarray(system.drag)
        self._u_sq_lo = system.U.lo**2
        self._u_sq_hi = system.U.hi**2
        self._reference = np.zeros((0, len(REFERENCE_COLUMNS)))
        self._a_ff = np.zeros((0, 3))
        self._yaw_rate = np.zeros(0)
        self._integral = np.zeros(3)

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        """Start a flight on ``reference`` ``(T, 7)`` (see :data:`REFERENCE_COLUMNS`)."""
        ref = as_matrix(reference, len(REFERENCE_COLUMNS), "quadrotor reference")
        as_vector(x0, self.system.n_x, "quadrotor initial state x0")
        self._reference = ref
        dt = self.system.dt
        if len(ref) > 1:
            self._a_ff = np.gradient(ref[:, 3:6], dt, axis=0)
            self._yaw_rate = np.gradient(np.unwrap(ref[:, 6]), dt)
        else:
            self._a_ff, self._yaw_rate = np.zeros((1, 3)), np.zeros(1)
        self._integral = np.zeros(3)

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        if not 0 <= t < len(self._reference):
            raise ShapeError(
                f"sample t = {t} is outside the reference of {len(self._reference)} rows "
                "(call reset() with the flight's reference first)"
            )
        g = self.gains
        sys_ = self.system
        x = np.asarray(x, dtype=np.float64)
        p, v, q, omega = x[0:3], x[3:6], x[6:10], x[10:13]
        ref = self._reference[t]
        R = _rotation(q)

        # 1. position loop
        e_p, e_v = ref[0:3] - p, ref[3:6] - v
        self._integral = np.clip(
            self._integral + e_p * sys_.dt, -g.integral_limit, g.integral_limit
        )
        drag_comp = R @ (self._D * (R.T @ v))
        a_cmd = (
            self._a_ff[t]
            + np.asarray(g.kp) * e_p
            + np.asarray(g.kd) * e_v
            + np.asarray(g.ki) * self._integral
            + drag_comp
        )
        a_cmd, tilt_limited = self._limit(a_cmd)
        force = sys_.m * (a_cmd + np.array([0.0, 0.0, sys_.g]))

        # 2. attitude loop
        b3 = force / np.linalg.norm(force)
        yaw = ref[6]
        b2 = np.cross(b3, np.array([np.cos(yaw), np.sin(yaw), 0.0]))
        b2 /= np.linalg.norm(b2)
        R_d = np.column_stack((np.cross(b2, b3), b2, b3))
        e_R = 0.5 * _vee(R_d.T @ R - R.T @ R_d)
        omega_cmd = np.clip(
            -np.asarray(g.k_att) * e_R + self._yaw_rate[t] * R[2, :], -g.max_rate, g.max_rate
        )
        thrust = max(float(force @ R[:, 2]), 0.0)

        # 3. rate loop
        torque = self._J * (np.asarray(g.k_rate) * (omega_cmd - omega)) + np.cross(
            omega, self._J * omega
        )

        # 4. mixing, saturation to U
        omega_sq = self._mix_inv @ np.concatenate(([thrust], torque))
        clipped = np.clip(omega_sq, self._u_sq_lo, self._u_sq_hi)
        saturated = bool(np.any(clipped != omega_sq))
        return ControlStep(
            u=np.sqrt(clipped),
            info={"saturated": saturated, "tilt_limited": tilt_limited},
        )

    def _limit(self, a_cmd: np.ndarray) -> tuple[np.ndarray, bool]:
        """Keep the vertical thrust share >= min_thrust_g and the tilt <= max_tilt_deg."""
        g = self.gains
        grav = self.system.g
        a = a_cmd.copy()
        limited = False
        az_min = (g.min_thrust_g - 1.0) * grav
        if a[2] < az_min:
            a[2], limited = az_min, True
        horizontal = float(np.hypot(a[0], a[1]))
        max_h = np.tan(np.radians(g.max_tilt_deg)) * (a[2] + grav)
        if horizontal > max_h:
            a[0:2] *= max_h / horizontal
            limited = True
        return a, limited

    def settings(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "structure": "position PID + feedforward -> geometric attitude P -> rate P -> mixer",
            "reference_columns": list(REFERENCE_COLUMNS),
            "gains": asdict(self.gains),
            "saturation": "each rotor speed squared clipped to U",
        }
