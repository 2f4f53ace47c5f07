"""Cascaded tanks with overflow and a saturating level sensor: a simulated analogue of the
Cascaded Tanks benchmark (Schoukens & Noël, nonlinearbenchmark.org), whose records are not in
the repository. The parameters are chosen here (module docstring, "Parameters"), not fitted to
the real set-up.

Physics (continuous time)
-------------------------
A pump fills the upper tank; it drains through a small hole (Torricelli: outflow ∝ √level) into
the lower tank, which drains the same way. Levels are in volts of the level sensors, as in the
benchmark's records; time in seconds::

    ẋ1 = −k1 √x1 + k4 u − s                     (0 ≤ x1 ≤ top)
    ẋ2 =  k2 √x1 − k3 √x2 + p s
    y  = min(x2, y_max)                          (+ w[t] in a dataset)

``s ≥ 0`` is the overflow: zero while the upper tank is below its rim ``top``; once it is full, the
part of the net inflow ``k4 u − k1 √x1`` that would raise it further spills (``x1`` stays at
``top``), and a fraction ``p`` of the spill falls into the lower tank, the rest is lost. The
sensor of the lower tank reads at most ``y_max``: above it the output is flat.

Closed forms (constant ``u``)
-----------------------------
Below the rim, the equilibrium is ``x1* = (k4 u / k1)²``, ``x2* = (k2 / k3)² x1*``; it holds while
``x1* < top``, i.e. ``u < k1 √top / k4``. Above, ``x1* = top``, the spill rate is
``s* = k4 u − k1 √top`` and ``x2* = ((k2 √top + p s*) / k3)²``. Always ``y* = min(x2*, y_max)``.

Discretisation
--------------
``u`` is held over each sample of ``dt = 4 s`` (the benchmark's sampling time). The step is
``substeps`` classical Runge–Kutta (RK4) steps of ``dt / substeps``. At the rim the spill is a
rate inside the RK4 stages (``s = max(k4 u − k1 √top, 0)`` while ``x1 ≥ top``, integrated beside
the levels), so a full tank stays exactly at ``top``; a substep that reaches the rim from below
overshoots it, and the overshoot spills at the substep's end (``p`` times it into the lower tank;
then both levels are clipped at 0). A full tank leaves the rim only when ``u`` changes, at a
sample's start, so the only event inside a sample is the rim being reached. Against 512 substeps,
the default 16 differ by at most 2.3e-5 V on the records of the ``tanks-overflow`` scenario (seed
0; 4 substeps: 3e-4 V, 32: 6e-6 V), a thousandth of the noise's half-width. Water is conserved
exactly: with equal tank sections (``k2 = k1``) and a closed lower tank (``k3 = 0``) each step
raises ``x1 + x2`` by ``k4 u dt − (1 − p) S``, ``S`` the level spilled during the step
(:attr:`OverflowTanks.spill`).

Parameters
----------
``k = (k1, k2, k3, k4) = (0.1, 0.1, 0.095, 0.05)`` (V^½/s for k1–k3, 1/s for k4), ``top = 10 V``,
``p = 0.5``, ``y_max = 10 V``. Around ``u = 5 V`` both tanks settle with time constants
``2 √x / k`` of about 50 s (12 samples). In steady state the lower level is ``1.108 x1*``
below the rim, so the sensor saturates from ``u = 6.01 V`` on, and the rim is reached from
``u = k1 √top / k4 = 6.32 V`` on. The scenario ``tanks-overflow`` (an offset of 5.3 V and a
multisine of RMS 1.2 V) spills a few times per record and saturates the sensor now and then.

√x has an unbounded slope at 0, so the analysis set starts at ``eps > 0``, as for ``tank``.
"""

from __future__ import annotations

import math

import casadi as ca

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["OverflowTanks"]


class OverflowTanks(System):
    """Two cascaded tanks, the upper one spilling at its rim, the lower one's level read by a
    sensor that saturates; input the pump voltage (module docstring: equations, closed forms,
    discretisation, parameters).

    Args:
        k: ``(k1, k2, k3, k4)``: outflow of the upper tank, its inflow into the lower one, the
            lower tank's outflow (V^½/s) and the pump's gain (1/s); k3 may be 0 (a closed lower
            tank).
        top: level of the upper tank's rim, V.
        spill_fraction: share ``p`` of the overflow that falls into the lower tank, in [0, 1].
        y_max: the lower level sensor's upper limit, V.
        dt: sampling time, s (the input is held over it).
        substeps: RK4 steps per sample.
        u_max: U = [0, u_max] V.
        eps: lower edge of X in both levels (> 0: γ_f is infinite at 0).
        x2_max: upper edge of X in the lower level, V.
        noise: half-width of the measurement-noise box W, V.
    """

    description = (
        "Cascaded tanks with overflow of the upper tank and a saturating level sensor, "
        "pump voltage in, lower level out, RK4 at Ts = 4 s"
    )
    simulated_stand_in_for = "the Cascaded Tanks benchmark (an analogue, parameters not fitted)"

    def __init__(
        self,
        *,
        k: tuple[float, float, float, float] = (0.1, 0.1, 0.095, 0.05),
        top: float = 10.0,
        spill_fraction: float = 0.5,
        y_max: float = 10.0,
        dt: float = 4.0,
        substeps: int = 16,
        u_max: float = 10.0,
        eps: float = 0.05,
        x2_max: float = 20.0,
        noise: float = 0.02,
    ) -> None:
        values = tuple(float(c) for c in k)
        if len(values) != 4 or not all(math.isfinite(c) for c in values):
            raise SetError(f"tanks-overflow: k must be four finite coefficients, got {k}")
        if not (values[0] > 0 and values[1] >= 0 and values[2] >= 0 and values[3] > 0):
            raise SetError(f"tanks-overflow: k must have k1 > 0, k2 >= 0, k3 >= 0, k4 > 0, got {k}")
        if not (0.0 <= spill_fraction <= 1.0):
            raise SetError(
                f"tanks-overflow: spill_fraction must be in [0, 1], got {spill_fraction}"
            )
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise SetError(f"tanks-overflow: substeps must be an integer >= 1, got {substeps!r}")
        for label, value in (("top", top), ("y_max", y_max), ("u_max", u_max), ("eps", eps)):
            if not (math.isfinite(value) and value > 0):
                raise SetError(f"tanks-overflow: {label} must be a finite number > 0, got {value}")
        if not (eps < top and eps < x2_max):
            raise SetError(
                f"tanks-overflow: eps = {eps} must lie below top = {top} and x2_max = {x2_max}"
            )
        if not (noise >= 0):
            raise SetError(f"tanks-overflow: noise half-width must be >= 0, got {noise}")
        self.k = values
        self.top, self.spill_fraction, self.y_max = float(top), float(spill_fraction), float(y_max)
        self.substeps = substeps
        super().__init__(
            name="tanks-overflow",
            dt=dt,
            state_names=("x1", "x2"),
            state_units=("V", "V"),
            input_names=("u",),
            input_units=("V",),
            output_names=("y",),
            output_units=("V",),
            X=Box([eps, eps], [top, x2_max]),
            U=Box([0.0], [u_max]),
            W=Box([-noise], [noise]),
            discretisation=f"RK4, {substeps} steps per sample, overflow after each, input held",
            parameters={
                "k": self.k,
                "top": self.top,
                "spill_fraction": self.spill_fraction,
                "y_max": self.y_max,
                "substeps": substeps,
                "eps": eps,
            },
        )
        x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
        _, spilled = self._step_expr(x, u)
        self.spill = ca.Function("spill", [x, u], [spilled], ["x", "u"], ["spilled"])

    def _rates(self, x: ca.SX, u: ca.SX) -> tuple[ca.SX, ca.SX]:
        """``(ẋ, s)``: at the rim, the net inflow that would raise the upper level spills."""
        k1, k2, k3, k4 = self.k
        s1 = ca.sqrt(ca.fmax(x[0], 0))
        s2 = ca.sqrt(ca.fmax(x[1], 0))
        net = k4 * u[0] - k1 * s1
        spill = ca.if_else(x[0] >= self.top, ca.fmax(net, 0), 0)
        return ca.vertcat(net - spill, k2 * s1 - k3 * s2 + self.spill_fraction * spill), spill

    def _ode_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return self._rates(x, u)[0]

    def _step_expr(self, x: ca.SX, u: ca.SX) -> tuple[ca.SX, ca.SX]:
        """``x[t+1]`` and the level spilled over the rim during the sample.

        At the rim the spill is a rate inside the RK4 stages (integrated beside the levels), so
        a full tank stays exactly at ``top``; a substep that reaches the rim from below
        overshoots it, and the overshoot spills at the substep's end. A full tank leaves the rim
        only when ``u`` changes, at a sample's start."""
        h = self.dt / self.substeps
        spilled = ca.SX(0)
        for _ in range(self.substeps):
            a, sa = self._rates(x, u)
            b, sb = self._rates(x + 0.5 * h * a, u)
            c, sc = self._rates(x + 0.5 * h * b, u)
            d, sd = self._rates(x + h * c, u)
            x = x + h / 6.0 * (a + 2.0 * b + 2.0 * c + d)
            over = ca.fmax(x[0] - self.top, 0)
            spilled = spilled + h / 6.0 * (sa + 2.0 * sb + 2.0 * sc + sd) + over
            # fmin, not x1 − over: a full tank lands on top exactly, so x1 >= top holds next
            x = ca.fmax(ca.vertcat(ca.fmin(x[0], self.top), x[1] + self.spill_fraction * over), 0)
        return x, spilled

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return self._step_expr(x, u)[0]

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return ca.fmin(x[1], self.y_max)

    def equilibrium(self, u: float) -> tuple[float, float]:
        """The steady levels ``(x1*, x2*)`` under a constant pump voltage ``u`` (closed forms of
        the module docstring)."""
        k1, k2, k3, k4 = self.k
        if k3 <= 0:
            raise SetError("tanks-overflow: a closed lower tank (k3 = 0) has no equilibrium")
        x1 = (k4 * u / k1) ** 2
        if x1 < self.top:
            return x1, (k2 / k3) ** 2 * x1
        spill = k4 * u - k1 * math.sqrt(self.top)
        return self.top, ((k2 * math.sqrt(self.top) + self.spill_fraction * spill) / k3) ** 2
