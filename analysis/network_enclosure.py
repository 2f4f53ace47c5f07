"""Interval enclosures of a learned MLP model's ``f`` and ``∂f/∂z``, computed layer by layer.

:class:`canonid.analysis.enclosure.Enclosure` walks a CasADi SX graph one operation at a time:
general, but the graph of a 3 × 256 network has about 700,000 instructions, so one box takes
minutes. For a canonical model whose regressor is an MLP
(:class:`canonid.kernel.network.CanonicalNet` without GRU layers) the same enclosures follow from
the layers with matrix products (interval bound propagation), in 1–30 ms per box (measured: a 2 × 64
network in 20 dimensions, 3 × 256 in 50):

* pre-activations ``h_k = W_k a_{k−1} + b_k`` and activations ``a_k = σ(h_k)`` as intervals,
  from the box of the normalised ``a_0 = [z̃; ũ]`` (``z̃`` alone without feedthrough);
* slopes ``σ'(h_k)`` as intervals (ReLU's on an interval that reaches 0: ``[0, 1]``, the hull of
  Clarke's generalised derivative, as :mod:`canonid.analysis.enclosure` takes for ``fmax``);
* ``∂raw/∂z̃ ∈ W_L diag(σ'(h_{L−1})) W_{L−1} ⋯ diag(σ'(h_1)) W_{1,z}``, multiplied from the right;
* the cubic branch ``C (W a_0 + b)³`` (:class:`canonid.kernel.network.CanonicalNet`) the same
  way: its cube on ``h = W a_0 + b`` is monotone, ``[lo³, hi³]``, its slope ``3 h²`` holds 0 where
  ``h`` straddles 0, and it adds ``C diag(3 h²) W_z`` to ``∂raw/∂z̃``;
* ``∂f/∂z = Ā + S̄ D_y (C_z + diag(s) ∂raw/∂z̃) D_z⁻¹`` (notation of :mod:`canonid.analysis.certify`).

Soundness. Products of a weight matrix and an interval vector or matrix are enclosed by
:func:`canonid.analysis.interval.point_matmul` (midpoint–radius with a rigorous bound of the float
error). Element-wise steps use the outward-rounded :class:`~canonid.analysis.interval.Interval`
arithmetic, the cube and its slope included. The other ``σ`` and ``σ'`` are evaluated in float64
at the ends of each interval (and at their extrema, when an extremum lies inside) and widened by
``1e-13`` relative plus ``1e-300``, hundreds of times the error of libm's ``tanh``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from canonid.analysis.enclosure import NONFINITE, EnclosureResult
from canonid.analysis.interval import Interval, point_matmul
from canonid.kernel.errors import ShapeError
from canonid.kernel.network import CanonicalNet
from canonid.models.learned import LearnedSystem

__all__ = ["NetworkEnclosure", "network_enclosure"]

_REL = 1e-13
_ABS = 1e-300
#: an extremum of σ or σ' counts as inside an interval this close to it (its location is known
#: to about 1e-15, so this only ever widens)
_NEAR = 1e-6


def _widen(lo: np.ndarray, hi: np.ndarray) -> Interval:
    """Float evaluations of a function's extremes → an interval sure to hold the exact ones."""
    return Interval(lo - _REL * np.abs(lo) - _ABS, hi + _REL * np.abs(hi) + _ABS)


def _silu(x: np.ndarray) -> np.ndarray:
    return 0.5 * x * (1.0 + np.tanh(0.5 * x))


def _silu_slope(x: np.ndarray) -> np.ndarray:
    t = np.tanh(0.5 * x)
    return 0.5 * (1.0 + t) + 0.25 * x * (1.0 - t * t)


def _root(fun: Callable[[np.ndarray], np.ndarray], lo: float, hi: float) -> float:
    """The sign change of ``fun`` in ``[lo, hi]`` by bisection to float precision."""
    f_lo = fun(np.array(lo))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if (fun(np.array(mid)) > 0) == (f_lo > 0):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


#: SiLU's minimum (where σ' = 0) and the two extrema of its slope (where σ'' = 0)
_SILU_ARGMIN = _root(_silu_slope, -2.0, -1.0)
_SILU_MIN = float(_silu(np.array(_SILU_ARGMIN))) - 1e-12
_SLOPE_ARG = _root(lambda x: 2.0 + x * np.tanh(-0.5 * x), 2.0, 3.0)  # 2 + x(1 − 2σ(x)) = 0
_SLOPE_MAX = float(_silu_slope(np.array(_SLOPE_ARG))) + 1e-12
_SLOPE_MIN = float(_silu_slope(np.array(-_SLOPE_ARG))) - 1e-12


def _inside(point: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return (lo - _NEAR <= point) & (point <= hi + _NEAR)


def activation_enclosure(name: str, h: Interval) -> tuple[Interval, Interval]:
    """``σ(h)`` and ``σ'(h)`` enclosed for an interval ``h`` of pre-activations."""
    lo, hi = h.lo, h.hi
    if name == "linear":
        return h, Interval.point(np.ones_like(lo))
    if name == "relu":
        slope = Interval((lo > 0).astype(np.float64), (hi >= 0).astype(np.float64))
        return Interval(np.maximum(lo, 0.0), np.maximum(hi, 0.0)), slope
    if name == "tanh":
        d_lo, d_hi = 1.0 - np.tanh(lo) ** 2, 1.0 - np.tanh(hi) ** 2
        top = np.where((lo <= 0) & (hi >= 0), 1.0, np.maximum(d_lo, d_hi))
        slope = _widen(np.minimum(d_lo, d_hi), top)
        return _widen(np.tanh(lo), np.tanh(hi)), Interval(
            np.maximum(slope.lo, 0.0), np.minimum(slope.hi, 1.0)
        )
    if name == "silu":
        v_lo, v_hi = _silu(lo), _silu(hi)
        bottom = np.where(_inside(_SILU_ARGMIN, lo, hi), _SILU_MIN, np.minimum(v_lo, v_hi))
        d_lo, d_hi = _silu_slope(lo), _silu_slope(hi)
        s_bottom = np.where(_inside(-_SLOPE_ARG, lo, hi), _SLOPE_MIN, np.minimum(d_lo, d_hi))
        s_top = np.where(_inside(_SLOPE_ARG, lo, hi), _SLOPE_MAX, np.maximum(d_lo, d_hi))
        return _widen(bottom, np.maximum(v_lo, v_hi)), _widen(s_bottom, s_top)
    if name == "cube":  # increasing; its slope 3h² is 0 at h = 0 (Interval.sq keeps that)
        return h.power(3), h.sq().scale(3.0)
    raise ShapeError(f"no interval enclosure for the activation {name!r}")


class NetworkEnclosure:
    """The enclosure of ``f`` and ``∂f/∂z`` of an MLP canonical model, as
    :class:`canonid.analysis.enclosure.Enclosure` gives them (``enclosure([X box, U box])``)."""

    #: how an upper bound found with it is described
    method = (
        "certified: interval Jacobian branch-and-bound on the network's layers (interval bound "
        "propagation, outward rounding)"
    )

    def __init__(self, net: CanonicalNet) -> None:
        if not isinstance(net, CanonicalNet) or net.recurrent:
            raise ShapeError("the layer-wise enclosure needs a canonical model with an MLP")
        self.net = net
        d, p = net.state_dim, net.n_u + net.n_y
        self.n_in = (d, net.n_u)
        shift = np.zeros((d, d))
        shift[: d - p, p:] = np.eye(d - p)
        self.shift = shift
        self.linear_z = net.linear_part()[:, :d]

    def _normalised(self, x: Interval, mean: np.ndarray, std: np.ndarray) -> Interval:
        return (x - Interval.point(mean)) / Interval.point(std)

    def __call__(self, inputs: Sequence[Interval]) -> EnclosureResult:
        net = self.net
        z, u = inputs
        batch, d, n_y = z.shape[0], net.state_dim, net.n_y
        if z.shape != (batch, d) or u.shape != (batch, net.n_u):
            raise ShapeError(
                f"network enclosure: expected boxes of shape ({batch}, {d}) and "
                f"({batch}, {net.n_u}), got {z.shape} and {u.shape}"
            )
        zn = self._normalised(z, net.z_mean, net.z_std)
        un = self._normalised(u, net.u_mean, net.u_std)
        a0 = (
            Interval(np.hstack([zn.lo, un.lo]), np.hstack([zn.hi, un.hi]))
            if net.feedthrough
            else zn
        )
        a, slopes = a0, []
        for layer in net.layers:
            h = point_matmul(layer.weight, a) + Interval.point(layer.bias)
            a, slope = activation_enclosure(layer.activation, h)
            slopes.append(slope)
        raw = a
        first = net.layers[0].weight[:, :d]
        if len(net.layers) == 1:
            jac = Interval.point(np.broadcast_to(first, (batch, *first.shape)).copy())
        else:
            jac = self._scale_rows(slopes[0], Interval.point(first[None]))
            for layer, slope in zip(net.layers[1:-1], slopes[1:-1]):
                jac = self._scale_rows(slope, point_matmul(layer.weight, jac))
            jac = point_matmul(net.layers[-1].weight, jac)  # ∂raw/∂z̃ from the network, (B, n_y, d)
        if net.cubic is not None:  # C (W a0 + b)³ and its C diag(3 h²) W_z
            inner, outer = net.cubic
            h = point_matmul(inner.weight, a0) + Interval.point(inner.bias)
            cube, slope = activation_enclosure(inner.activation, h)
            raw = raw + point_matmul(outer.weight, cube) + Interval.point(outer.bias)
            w_z = Interval.point(inner.weight[None, :, :d])
            jac = jac + point_matmul(outer.weight, self._scale_rows(slope, w_z))
        scale = Interval.point(net.output_scale[None, :, None])
        if net.affine is not None:
            raw = raw + point_matmul(net.affine[0], a0) + Interval.point(net.affine[1])
        jac_y = Interval.point(self.linear_z[None]) + scale * jac  # ∂ỹ/∂z̃
        yn = raw * Interval.point(net.output_scale)
        if net.residual_scale is not None:
            yn = zn[:, d - n_y :] + yn
        y = yn * Interval.point(net.y_std) + Interval.point(net.y_mean)
        jac_h = jac_y * Interval.point(net.y_std[None, :, None]) / Interval.point(net.z_std)
        lo = np.broadcast_to(self.shift, (batch, d, d)).copy()
        hi = lo.copy()
        lo[:, d - n_y :, :], hi[:, d - n_y :, :] = jac_h.lo, jac_h.hi
        p = net.n_u + n_y
        values = Interval(
            np.hstack([z.lo[:, p:], u.lo, y.lo]), np.hstack([z.hi[:, p:], u.hi, y.hi])
        )
        jacobian = Interval(lo, hi)
        bad_value = ~np.all(values.finite, axis=1)
        bad_jac = bad_value | ~np.all(jacobian.finite, axis=(1, 2))
        return EnclosureResult(
            values=[values],
            jacobians=[jacobian],
            value_flags=np.where(bad_value, NONFINITE, 0),
            jac_flags=np.where(bad_jac, NONFINITE, 0),
        )

    @staticmethod
    def _scale_rows(slope: Interval, m: Interval) -> Interval:
        """``diag(slope) · m`` per box: ``slope`` ``(B, n)``, ``m`` ``(B or 1, n, d)``."""
        return Interval(slope.lo[:, :, None], slope.hi[:, :, None]) * m


def network_enclosure(system: LearnedSystem) -> NetworkEnclosure | None:
    """The layer-wise enclosure of ``system`` when its regressor is an MLP and its state the
    window ``z`` (not a reduced model, not an ensemble), else ``None`` (the SX graph's enclosure
    applies)."""
    net = system.network
    if isinstance(net, CanonicalNet) and not net.recurrent and len(system.members) == 1:
        return NetworkEnclosure(net)
    return None
