"""A Wiener–Hammerstein chain: a linear filter, a static saturating curve, a second linear filter.
One voltage in, one voltage out, no feedthrough. The shape of the field's electronic
Wiener–Hammerstein benchmarks; the filters, the curve and every number here are chosen here.

Blocks (continuous-time filters, voltages in V, time in s)
---------------------------------------------------------
::

    u ──► G1 ──► w ──► v = s(w) ──► G2 ──► y

Each filter is a third-order low-pass with DC gain 1, a real pole in series with a resonant
pair. Filter ``i`` (``i = 1, 2``) has the real pole ``a_i = 2π f_a`` [rad/s] and the pair
``ω_i = 2π f_n``, damping ratio ``ζ_i``::

    G_i(s) = a_i / (s + a_i) · ω_i² / (s² + 2 ζ_i ω_i s + ω_i²)

written with three states, all in V: ``p`` the real pole's output, ``q`` the filter's output and
``r = q̇ / ω_i`` its scaled rate::

    ṗ = a_i (e − p),   q̇ = ω_i r,   ṙ = ω_i (p − q) − 2 ζ_i ω_i r        (e: the filter's input)

The static curve is an asymmetric soft saturation, a diode-like clamp: slope 1 and curvature 0
at ``w = 0`` on both sides, approaching ``upper`` above and ``−lower`` below::

    s(w) = upper · tanh(w / upper)   (w ≥ 0),      s(w) = lower · tanh(w / lower)   (w < 0)

A level of ``math.inf`` leaves that side linear (``s(w) = w``); ``saturation = (inf, inf)`` is
the linear chain ``G2 G1``.

State, index conventions
------------------------
``x = (p1, q1, r1, p2, q2, r2)``: indices 0–2 are G1's states (``w = q1 = x[1]``), indices 3–5
G2's (``y = q2 = x[4]``). The input is ``u`` [V]; the output ``y = x[4]`` [V] (plus ``w[t]`` in a
dataset).

Discretisation: exact, with the curve's output held
---------------------------------------------------
The chain is defined in discrete time by a sample-and-hold between the blocks: ``u[t]`` is held
over the sample ``[t dt, (t + 1) dt)``, and so is ``v[t] = s(q1[t])``, the curve's value at the
sample's start. Each filter then steps by its exact zero-order-hold map ``(A_d, B_d) =
(exp(A dt), ∫₀^dt exp(A τ) dτ B)`` (one matrix exponential of the augmented matrix, at
construction)::

    (p1, q1, r1)[t+1] = A1d (p1, q1, r1)[t] + B1d u[t]
    (p2, q2, r2)[t+1] = A2d (p2, q2, r2)[t] + B2d s(q1[t])
    y[t] = q2[t]

Closed forms: the discrete poles are ``exp(λ dt)`` of the continuous ones, ``−a_i`` and
``−ζ_i ω_i ± j ω_i √(1 − ζ_i²)``, whatever the curve (the Jacobian of ``f`` is block triangular
with blocks ``A1d`` and ``A2d``); under a constant ``u`` the chain settles at ``q1 = u`` and
``y = s(u)`` (both filters have DC gain 1, and the hold preserves it), ``y = u`` for the linear
chain.

Parameters
----------
``dt = 1e-4 s`` (10 kHz). G1: real pole at 1 kHz, pair at 600 Hz with ζ = 0.25; G2: real pole at
400 Hz, pair at 1.5 kHz with ζ = 0.15 (the slowest decay, G1's pair, has the time constant
``1 / (ζ ω) = 1.06 ms``, 10.6 samples: the chain's memory is some 50 samples). The curve clamps at
``upper = 1.0 V`` and ``lower = 0.4 V``. Under the scenario's multisine (RMS 0.5 V up to 2 kHz)
``w`` swings over about ±1.7 V and lies below −0.4 V on 17 % of the samples: the clamp flattens
the deep negative half-waves and the positive side compresses its peaks. The output then differs
from the linear chain's (same input) by 44 % of its RMS of 0.24 V.

``W = [−0.015, 0.015] V``, about 3.6 % of the output's RMS in noise RMS: the noise of the small
record (scenario ``wiener-hammerstein-small``); the long records of the scenario
``wiener-hammerstein`` have a fifth of it (0.003 V, 0.7 %).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["WienerHammerstein"]

_FILTER = tuple[float, float, float]


def _filter(value: _FILTER, name: str, dt: float) -> _FILTER:
    """``(f_a, f_n, ζ)`` checked: frequencies finite and > 0, below Nyquist; 0 < ζ < 1."""
    values = tuple(float(v) for v in value)
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise SetError(
            f"wiener-hammerstein: {name} must be (real pole Hz, pair Hz, pair damping), three "
            f"finite numbers, got {value}"
        )
    pole, pair, zeta = values
    nyquist = 0.5 / dt
    if not (0 < pole < nyquist and 0 < pair < nyquist):
        raise SetError(
            f"wiener-hammerstein: {name} frequencies must lie in (0, {nyquist:g}) Hz (below "
            f"Nyquist), got {pole:g} and {pair:g}"
        )
    if not (0 < zeta < 1):
        raise SetError(f"wiener-hammerstein: {name} damping must lie in (0, 1), got {zeta:g}")
    return values


def filter_matrices(spec: _FILTER) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time ``(A, B, C)`` of one filter, states ``(p, q, r)`` (module docstring)."""
    a, w, zeta = 2 * math.pi * spec[0], 2 * math.pi * spec[1], spec[2]
    A = np.array([[-a, 0.0, 0.0], [0.0, 0.0, w], [w, -w, -2 * zeta * w]])
    B = np.array([[a], [0.0], [0.0]])
    C = np.array([[0.0, 1.0, 0.0]])
    return A, B, C


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(exp(A dt), ∫₀^dt exp(A τ) dτ B)``: the exact map of ``ẋ = A x + B e`` over ``dt`` with
    ``e`` held (the exponential of the augmented matrix ``[[A, B], [0, 0]] dt``)."""
    from scipy.linalg import expm  # only when a chain is built

    n, m = B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = A, B
    E = expm(augmented * dt)
    return E[:n, :n], E[:n, n:]


class WienerHammerstein(System):
    """Filter, saturating curve, filter: ``u`` [V] in, ``y`` [V] out (module docstring:
    equations, index conventions, discretisation, closed forms, parameters).

    Args:
        g1, g2: each filter's ``(f_a, f_n, ζ)``: real pole [Hz], resonant pair [Hz] (both below
            Nyquist) and the pair's damping ratio in (0, 1).
        saturation: ``(lower, upper)`` [V], the curve's limits below and above (> 0; ``math.inf``
            leaves that side linear).
        dt: sampling time, s.
        u_max: U = [−u_max, u_max] V.
        x_max: half-width of X in every state, V.
        noise: half-width of W, V (the default record's noise is a tenth of it: its scenario).
    """

    description = (
        "Wiener-Hammerstein chain: 3rd-order filter, asymmetric soft saturation (diode-like "
        "clamp), 3rd-order filter; voltage in, voltage out, exact ZOH at 10 kHz"
    )

    def __init__(
        self,
        *,
        g1: _FILTER = (1000.0, 600.0, 0.25),
        g2: _FILTER = (400.0, 1500.0, 0.15),
        saturation: tuple[float, float] = (0.4, 1.0),
        dt: float = 1e-4,
        u_max: float = 3.0,
        x_max: float = 4.0,
        noise: float = 0.015,
    ) -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise SetError(f"wiener-hammerstein: dt must be a finite number > 0, got {dt}")
        self.g1, self.g2 = _filter(g1, "g1", dt), _filter(g2, "g2", dt)
        levels = tuple(float(v) for v in saturation)
        if len(levels) != 2 or not all(v > 0 for v in levels):  # nan fails v > 0
            raise SetError(
                f"wiener-hammerstein: saturation must be (lower, upper), two numbers > 0 "
                f"(inf: linear on that side), got {saturation}"
            )
        for label, value in (("u_max", u_max), ("x_max", x_max)):
            if not (math.isfinite(value) and value > 0):
                raise SetError(
                    f"wiener-hammerstein: {label} must be a finite number > 0, got {value}"
                )
        if not (math.isfinite(noise) and noise >= 0):
            raise SetError(f"wiener-hammerstein: noise must be a finite number >= 0, got {noise}")
        self.saturation = (levels[0], levels[1])
        self.A1d, self.B1d = zero_order_hold(*filter_matrices(self.g1)[:2], dt)
        self.A2d, self.B2d = zero_order_hold(*filter_matrices(self.g2)[:2], dt)
        super().__init__(
            name="wiener-hammerstein",
            dt=dt,
            state_names=("p1", "q1", "r1", "p2", "q2", "r2"),
            state_units=("V",) * 6,
            input_names=("u",),
            input_units=("V",),
            output_names=("y",),
            output_units=("V",),
            X=Box.symmetric(x_max, 6),
            U=Box([-u_max], [u_max]),
            W=Box([-noise], [noise]),
            discretisation="exact ZOH of both filters, the curve's output held over the sample",
            parameters={
                "g1": self.g1,
                "g2": self.g2,
                "filters": "(real pole Hz, pair Hz, pair damping), DC gain 1",
                "saturation": self.saturation,
            },
        )

    def _curve(self, w: ca.SX) -> ca.SX:
        lower, upper = self.saturation
        above = w if math.isinf(upper) else upper * ca.tanh(w / upper)
        below = w if math.isinf(lower) else lower * ca.tanh(w / lower)
        return ca.if_else(w >= 0, above, below)

    def curve(self, w: np.ndarray | float) -> np.ndarray:
        """The static curve ``s(w)`` of the module docstring, elementwise, in NumPy."""
        lower, upper = self.saturation
        w = np.asarray(w, dtype=np.float64)
        above = w if math.isinf(upper) else upper * np.tanh(w / upper)
        below = w if math.isinf(lower) else lower * np.tanh(w / lower)
        return np.where(w >= 0, above, below)

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        first = ca.mtimes(ca.DM(self.A1d), x[0:3]) + ca.mtimes(ca.DM(self.B1d), u[0])
        v = self._curve(x[1])
        second = ca.mtimes(ca.DM(self.A2d), x[3:6]) + ca.mtimes(ca.DM(self.B2d), v)
        return ca.vertcat(first, second)

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return x[4]

    def poles(self) -> np.ndarray:
        """The six continuous-time poles [rad/s] of the two filters (closed forms)."""
        out = []
        for pole_hz, pair_hz, zeta in (self.g1, self.g2):
            a, w = 2 * math.pi * pole_hz, 2 * math.pi * pair_hz
            damped = w * math.sqrt(1 - zeta**2)
            out += [complex(-a, 0.0), complex(-zeta * w, damped), complex(-zeta * w, -damped)]
        return np.array(out)
