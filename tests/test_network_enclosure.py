"""Layer-wise interval enclosures of a learned MLP model (canonid.analysis.network_enclosure).

Every enclosure must hold the exact values: point Jacobians and values of the model sampled in
a box lie inside the box's enclosure, for every activation and option of the network; the
interval matrix product and sum hold every product and sum of their members (computed exactly
with fractions); and on a point box the enclosure is as tight as float arithmetic allows.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from canonid.analysis.certify import learned_gamma
from canonid.analysis.estimate import Budget
from canonid.analysis.interval import Interval, interval_sum, point_matmul
from canonid.analysis.matrix_bounds import spectral_upper
from canonid.analysis.network_enclosure import (
    NetworkEnclosure,
    activation_enclosure,
    network_enclosure,
)
from canonid.kernel.network import CanonicalNet, Layer
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box

ELL, N_U, N_Y = 3, 1, 2


def _net(activation: str, feedthrough: bool, residual: bool, affine: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    d = ELL * (N_U + N_Y)
    width_in = d + (N_U if feedthrough else 0)
    sizes = [width_in, 9, 7, N_Y]
    layers = [
        Layer(
            rng.normal(0, 0.7, (n_out, n_in)),
            rng.normal(0, 0.3, n_out),
            activation if k < len(sizes) - 2 else "linear",
        )
        for k, (n_in, n_out) in enumerate(itertools.pairwise(sizes))
    ]
    return CanonicalNet(
        window=ELL,
        n_u=N_U,
        n_y=N_Y,
        feedthrough=feedthrough,
        layers=tuple(layers),
        u_mean=np.array([0.3]),
        u_std=np.array([1.7]),
        y_mean=np.array([-1.0, 2.0]),
        y_std=np.array([0.5, 3.0]),
        residual_scale=np.array([0.2, 0.4]) if residual else None,
        affine=(rng.normal(0, 0.5, (N_Y, width_in)), rng.normal(0, 0.5, N_Y)) if affine else None,
    )


def _system(net: CanonicalNet) -> LearnedSystem:
    d = net.state_dim
    return LearnedSystem(
        net,
        dt=1.0,
        input_names=("u",),
        output_names=("y1", "y2"),
        X=Box(-2.0 * np.ones(d), 2.0 * np.ones(d)),
        U=Box([-1.5], [1.5]),
        W=Box([0.0, 0.0], [0.0, 0.0]),
    )


CASES = list(
    itertools.product(("relu", "silu", "tanh"), (True, False), (True, False), (True, False))
)


@pytest.mark.parametrize(("activation", "feedthrough", "residual", "affine"), CASES)
def test_sampled_values_and_jacobians_lie_in_the_box_enclosures(
    activation, feedthrough, residual, affine, rng
):
    system = _system(_net(activation, feedthrough, residual, affine))
    assert_boxes_enclose(system, [1e-6, 1e-3, 0.05, 0.3, 1.0, 3.0], rng)


def assert_boxes_enclose(system: LearnedSystem, scales: list[float], rng) -> np.ndarray:
    """Boxes of half-widths about ``scales`` around random centres in [−2, 2]: the values and
    Jacobians sampled in each (corners too) lie in its enclosure; returns the centres."""
    enclosure = network_enclosure(system)
    assert isinstance(enclosure, NetworkEnclosure)
    d, n_u = system.n_x, system.n_u
    centres = rng.uniform(-2, 2, size=(len(scales), d + n_u))
    widths = np.array(scales)[:, None] * rng.uniform(0.2, 1.0, size=(len(scales), d + n_u))
    lo, hi = centres - widths, centres + widths
    res = enclosure([Interval(lo[:, :d], hi[:, :d]), Interval(lo[:, d:], hi[:, d:])])
    assert not res.jac_flags.any()
    jac, val = res.jacobians[0], res.values[0]
    for b in range(len(lo)):
        pts = rng.uniform(lo[b], hi[b], size=(200, d + n_u))
        pts[:2] = lo[b], hi[b]  # the corners count too
        lin = system.linearise(pts[:, :d], pts[:, d:])
        assert np.all(lin.f_x >= jac.lo[b]) and np.all(lin.f_x <= jac.hi[b])
        assert np.all(lin.f >= val.lo[b]) and np.all(lin.f <= val.hi[b])
    return centres


@pytest.mark.parametrize("activation", ["relu", "silu", "tanh"])
def test_a_point_box_is_enclosed_to_float_precision(activation, rng):
    system = _system(_net(activation, True, True, True))
    d = system.n_x
    x, u = rng.uniform(-2, 2, size=(4, d)), rng.uniform(-1.5, 1.5, size=(4, N_U))
    res = network_enclosure(system)([Interval.point(x), Interval.point(u)])
    jac = res.jacobians[0]
    exact = system.linearise(x, u).f_x
    assert np.all(jac.lo <= exact) and np.all(exact <= jac.hi)
    if activation != "relu":  # ReLU at a kink aside, the width is rounding only
        assert np.max(jac.hi - jac.lo) <= 1e-9 * (1 + np.max(np.abs(exact)))


@pytest.mark.parametrize("activation", ["relu", "silu", "tanh", "linear"])
def test_activation_enclosures_hold_every_value_and_slope(activation, rng):
    lo = rng.uniform(-6, 6, size=400)
    hi = lo + rng.exponential(1.5, size=400)
    lo[:3], hi[:3] = -2.4, 2.4  # around SiLU's slope extrema and its minimum
    value, slope = activation_enclosure(activation, Interval(lo, hi))
    x = rng.uniform(lo, hi, size=(300, 400))
    x[0], x[1] = lo, hi
    h = 1e-6
    if activation == "relu":
        f = np.maximum(x, 0.0)
        df = (x > 0).astype(float)
    elif activation == "tanh":
        f, df = np.tanh(x), 1 - np.tanh(x) ** 2
    elif activation == "silu":
        f = x / (1 + np.exp(-x))
        df = (((x + h) / (1 + np.exp(-(x + h)))) - ((x - h) / (1 + np.exp(-(x - h))))) / (2 * h)
    else:
        f, df = x, np.ones_like(x)
    assert np.all(f >= value.lo) and np.all(f <= value.hi)
    slack = 1e-8 if activation == "silu" else 0.0  # the finite difference's own error
    assert np.all(df >= slope.lo - slack) and np.all(df <= slope.hi + slack)
    if activation == "silu":  # the extrema are inside [-2.4, 2.4]: min −0.0998, max 1.0998
        assert slope.lo[0] == pytest.approx(-0.0998, abs=1e-4)
        assert slope.hi[0] == pytest.approx(1.0998, abs=1e-4)


def _exact(v: float) -> Fraction:
    return Fraction(float(v))


@pytest.mark.parametrize("shape", [(3,), (3, 4)])
def test_point_matmul_holds_the_exact_products_of_members(shape, rng):
    w = rng.normal(size=(5, 7)) * 10.0 ** rng.integers(-8, 8, size=(5, 7))
    w[0, :] = [1e16, 1.0, -1e16, 1e-8, 3.0, -3.0, 0.5]  # cancellation
    centre = rng.normal(size=(shape[0], 7, *shape[1:]))
    rad = rng.uniform(0, 1e-3, size=centre.shape)
    box = Interval(centre - rad, centre + rad)
    out = point_matmul(w, box)
    # vectors as one-column matrices, so both shapes are checked by the same loop
    lo, hi = (out.lo, out.hi) if len(shape) == 2 else (out.lo[..., None], out.hi[..., None])
    for x in (box.lo, box.hi, rng.uniform(box.lo, box.hi)):
        cols = x if x.ndim == 3 else x[..., None]
        for b, i, j in itertools.product(range(shape[0]), range(5), range(cols.shape[2])):
            exact = sum(_exact(w[i, k]) * _exact(cols[b, k, j]) for k in range(7))
            assert _exact(lo[b, i, j]) <= exact <= _exact(hi[b, i, j])


def test_interval_sum_holds_the_exact_sums(rng):
    x = rng.normal(size=(4, 50)) * 10.0 ** rng.integers(-10, 10, size=(4, 50))
    x[0, :3] = [1e17, 1.0, -1e17]
    s = interval_sum(Interval(x, x), axis=1)
    for b in range(4):
        exact = sum(_exact(v) for v in x[b])
        assert _exact(s.lo[b]) <= exact <= _exact(s.hi[b])


def test_the_norm_of_a_wide_matrix_is_certified_close_to_its_value(rng):
    # the vectorised interval Cholesky certifies a 256 × 256 matrix's norm to ~1e-9 (relative)
    w = rng.normal(size=(1, 256, 256))
    bound = spectral_upper(Interval.point(w))[0]
    exact = np.linalg.norm(w[0], 2)
    assert exact <= bound <= exact * (1 + 1e-8)


def test_learned_gamma_of_an_mlp_uses_the_layers_and_brackets_the_samples(rng):
    system = _system(_net("silu", True, True, False))
    gamma = learned_gamma(system, budget=Budget(boxes=64, samples=128, starts=1))
    assert "network's layers" in gamma.bracket.upper.method
    pts = rng.uniform(-2, 2, size=(300, system.n_x + N_U))
    pts[:, system.n_x :] *= 0.75
    sampled = np.linalg.norm(
        system.linearise(pts[:, : system.n_x], pts[:, system.n_x :]).f_x, 2, axis=(1, 2)
    )
    assert sampled.max() <= gamma.bracket.upper.value
    assert sampled.max() <= gamma.layer_norms.value
    assert gamma.bracket.lower.value <= gamma.bracket.upper.value
