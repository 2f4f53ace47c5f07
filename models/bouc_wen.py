"""A hysteretic oscillator of Bouc–Wen type: a mass on a spring and a damper, in parallel with a
hysteretic element whose force ``z`` has a memory of its own. Force in, displacement out. The
shape of the field's Bouc–Wen benchmark; the numbers here are chosen here.

Mechanics (continuous time)
---------------------------
``y`` is the displacement from rest [m], ``v = ẏ`` the velocity [m/s], ``z`` the hysteretic
force [N], ``u`` the applied force [N]::

    m v̇ = u − k y − c v − z
    ż   = α v − β |v| |z|^(ν−1) z − γ v |z|^ν

``α`` [N/m] is the element's stiffness while ``z`` is small; ``β`` and ``γ`` [1/m for ν = 1,
N^(1−ν)/m in general] shape the loop, ``ν ≥ 1`` its sharpness. For ``ν = 1`` the force is written
``ż = α v − β |v| z − γ v |z|`` (Lipschitz everywhere).

State, index conventions
------------------------
``x = (y, v, z)``: index 0 the displacement [m], 1 the velocity [m/s], 2 the hysteretic force [N].
Input ``u`` [N]; output ``y = x[0]`` [m] (no feedthrough).

Closed forms
------------
* With ``β = γ = 0`` the element is a linear spring: ``z − α y`` stays constant and the oscillator
  is linear with stiffness ``k + α``, natural frequency ``√((k + α) / m)`` and damping ratio
  ``c / (2 √((k + α) m))``; its continuous poles are ``0`` (the constant) and
  ``−c / (2m) ± j √((k + α)/m − (c / 2m)²)``.
* For ``β + γ > 0`` and ``β ≥ |γ|`` the force stays bounded: a loop never carries ``|z|`` past
  ``z_max = (α / (β + γ))^(1/ν)`` once it is below it (``ż`` and ``v`` have opposite signs beyond).
* The element dissipates: over a closed cycle of a periodic response the loop's area ``∮ z dy``
  is positive, and the work of the force balances it and the damper, ``∮ u dy = c ∮ v² dt +
  ∮ z dy``.

Discretisation
--------------
``substeps`` classical Runge–Kutta (RK4) steps of ``h = dt / substeps`` per sample, ``u`` held.
``|v|`` has a kink at ``v = 0`` (each reversal of the motion), where RK4 drops to first order
locally; the default ``h = 0.5 ms`` is about a tenth of the fastest linear time scale
(``1 / √((k + α)/m) = 5.3 ms``) and keeps a record of the scenario within 1e-3 of its RMS of a
simulation with 16 times more substeps (tested).

Parameters
----------
``m = 1 kg``, ``k = 2e4 N/m``, ``c = 5 N·s/m``, ``α = 1.5e4 N/m``, ``β = 1500 /m``, ``γ = 500 /m``,
``ν = 1``, ``dt = 2 ms`` (500 Hz), 4 substeps. Small motions see the stiffness ``k + α = 3.5e4
N/m`` (29.8 Hz, damping ratio 1.3 %), large ones ``k = 2e4 N/m`` (22.5 Hz) once ``z`` saturates at
``z_max = α / (β + γ) = 7.5 N``, that is beyond ``|y| ≈ z_max / α = 0.5 mm``. The scenario's
multisine (RMS 10 N) moves the mass by 0.64 mm RMS and keeps ``|z|`` within a tenth of ``z_max``
on 18 % of the samples: most cycles open a loop.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["BoucWen"]


class BoucWen(System):
    """Mass, spring, damper and a Bouc–Wen hysteretic element; force in, displacement out
    (module docstring: equations, index conventions, closed forms, discretisation, parameters).

    Args:
        mass: ``m``, kg.
        stiffness: ``k`` of the linear spring, N/m.
        damping: ``c`` of the viscous damper, N·s/m.
        alpha: ``α``, the hysteretic element's initial stiffness, N/m.
        beta, gamma: the loop's shape (units in the module docstring); ``β + γ > 0`` and
            ``β ≥ |γ|`` keep ``z`` bounded, ``β = γ = 0`` makes the element linear.
        nu: ``ν ≥ 1``, the loop's sharpness.
        rate_hz: sampling rate, Hz.
        substeps: RK4 steps per sample.
        force_max: U = [−force_max, force_max] N.
        position_box, velocity_box, force_box: half-widths of X for ``y`` [m], ``v`` [m/s] and
            ``z`` [N].
        noise: half-width of W, m.
    """

    description = (
        "Bouc-Wen hysteretic oscillator: mass, spring, damper and hysteretic force, "
        "force in, displacement out, RK4 (4 substeps) at 500 Hz"
    )

    def __init__(
        self,
        *,
        mass: float = 1.0,
        stiffness: float = 2.0e4,
        damping: float = 5.0,
        alpha: float = 1.5e4,
        beta: float = 1500.0,
        gamma: float = 500.0,
        nu: float = 1.0,
        rate_hz: float = 500.0,
        substeps: int = 4,
        force_max: float = 60.0,
        position_box: float = 0.01,
        velocity_box: float = 1.0,
        force_box: float = 20.0,
        noise: float = 1.0e-5,
    ) -> None:
        for label, value, least in (
            ("mass", mass, "> 0"),
            ("stiffness", stiffness, ">= 0"),
            ("damping", damping, ">= 0"),
            ("alpha", alpha, ">= 0"),
            ("beta", beta, "any"),
            ("gamma", gamma, "any"),
            ("rate_hz", rate_hz, "> 0"),
            ("force_max", force_max, "> 0"),
            ("position_box", position_box, "> 0"),
            ("velocity_box", velocity_box, "> 0"),
            ("force_box", force_box, "> 0"),
            ("noise", noise, ">= 0"),
        ):
            ok = math.isfinite(value) and (
                least == "any" or (value >= 0 if least == ">= 0" else value > 0)
            )
            if not ok:
                what = "a finite number" + ("" if least == "any" else f" {least}")
                raise SetError(f"bouc-wen: {label} must be {what}, got {value}")
        if not (math.isfinite(nu) and nu >= 1):
            raise SetError(f"bouc-wen: nu must be a finite number >= 1, got {nu}")
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise SetError(f"bouc-wen: substeps must be an integer >= 1, got {substeps!r}")
        if (beta != 0 or gamma != 0) and not (beta + gamma > 0 and beta >= abs(gamma)):
            raise SetError(
                f"bouc-wen: beta + gamma > 0 and beta >= |gamma| keep the hysteretic force "
                f"bounded (or beta = gamma = 0: a linear element), got beta = {beta}, "
                f"gamma = {gamma}"
            )
        if stiffness + alpha <= 0:
            raise SetError("bouc-wen: stiffness + alpha must be > 0 (the small-motion stiffness)")
        self.mass, self.stiffness, self.damping = float(mass), float(stiffness), float(damping)
        self.alpha, self.beta, self.gamma, self.nu = (
            float(alpha),
            float(beta),
            float(gamma),
            float(nu),
        )
        self.substeps = substeps
        p, v, z = position_box, velocity_box, force_box
        super().__init__(
            name="bouc-wen",
            dt=1.0 / rate_hz,
            state_names=("y", "v", "z"),
            state_units=("m", "m/s", "N"),
            input_names=("u",),
            input_units=("N",),
            output_names=("y",),
            output_units=("m",),
            X=Box([-p, -v, -z], [p, v, z]),
            U=Box([-force_max], [force_max]),
            W=Box([-noise], [noise]),
            discretisation=f"RK4, {substeps} steps per sample, input held",
            parameters={
                "mass": self.mass,
                "stiffness": self.stiffness,
                "damping": self.damping,
                "alpha": self.alpha,
                "beta": self.beta,
                "gamma": self.gamma,
                "nu": self.nu,
                "substeps": substeps,
            },
        )

    @property
    def z_max(self) -> float:
        """``(α / (β + γ))^(1/ν)``, the bound of the hysteretic force (``inf`` when linear)."""
        if self.beta + self.gamma <= 0:
            return math.inf
        return float((self.alpha / (self.beta + self.gamma)) ** (1.0 / self.nu))

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        y, v, z = x[0], x[1], x[2]
        if self.nu == 1.0:
            zdot = self.alpha * v - self.beta * ca.fabs(v) * z - self.gamma * v * ca.fabs(z)
        else:
            size = ca.fabs(z)
            zdot = (
                self.alpha * v
                - self.beta * ca.fabs(v) * size ** (self.nu - 1.0) * z
                - self.gamma * v * size**self.nu
            )
        vdot = (u[0] - self.stiffness * y - self.damping * v - z) / self.mass
        return ca.vertcat(v, vdot, zdot)

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

    def linear_poles(self) -> np.ndarray:
        """The continuous poles of the oscillator with a linear element (``β = γ = 0``): ``0`` and
        the pair of the module docstring's closed form."""
        m, c, k = self.mass, self.damping, self.stiffness + self.alpha
        sigma = c / (2 * m)
        damped = np.sqrt(complex(k / m - sigma**2))
        return np.array([0.0, -sigma + 1j * damped, -sigma - 1j * damped])
