"""Interval arithmetic, CasADi enclosures and verified matrix bounds: soundness against exact
arithmetic (fractions) and against sampled points, exactness where promised."""

from __future__ import annotations

import warnings
from fractions import Fraction

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.analysis.enclosure import (
    DISCONTINUITY,
    DIV_ZERO,
    SLOPE,
    Enclosure,
    RangeEnclosure,
    describe_flags,
)
from canonid.analysis.interval import Interval, norm_lower, norm_upper
from canonid.analysis.maps import Horizon
from canonid.analysis.matrix_bounds import smin_lower, spectral_upper
from canonid.kernel.errors import SetError
from canonid.models.registry import get_system

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


def _iv(a: float, b: float) -> Interval:
    lo, hi = min(a, b), max(a, b)
    return Interval(np.array([lo]), np.array([hi]))


def _encloses(result: Interval, exact: list[Fraction]) -> bool:
    """``result`` holds every exact value (an infinite end holds everything on its side)."""
    lo, hi = float(result.lo[0]), float(result.hi[0])
    low_ok = lo == -np.inf or (np.isfinite(lo) and Fraction(lo) <= min(exact))
    high_ok = hi == np.inf or (np.isfinite(hi) and Fraction(hi) >= max(exact))
    return low_ok and high_ok


@settings(max_examples=200, deadline=None)
@given(finite, finite, finite, finite)
def test_field_operations_enclose_the_exact_result(a, b, c, d):
    x, y = _iv(a, b), _iv(c, d)
    corners = [(Fraction(p), Fraction(q)) for p in (x.lo[0], x.hi[0]) for q in (y.lo[0], y.hi[0])]
    assert _encloses(x + y, [p + q for p, q in corners])
    assert _encloses(x - y, [p - q for p, q in corners])
    assert _encloses(x * y, [p * q for p, q in corners])
    if not (y.lo[0] <= 0 <= y.hi[0]):
        assert _encloses(x / y, [p / r for p, r in corners])


@settings(max_examples=100, deadline=None)
@given(st.floats(min_value=0, max_value=1e6), st.floats(min_value=0, max_value=1e6))
def test_sqrt_and_square_enclose(a, b):
    x = _iv(a, b)
    s = x.sqrt()
    assert Fraction(s.lo[0]) ** 2 <= Fraction(x.lo[0])
    assert Fraction(s.hi[0]) ** 2 >= Fraction(x.hi[0])
    sq = _iv(-a, b).sq()
    assert sq.lo[0] == 0.0  # the interval holds 0, so does its square
    assert Fraction(sq.hi[0]) >= max(Fraction(a) ** 2, Fraction(b) ** 2)


@settings(max_examples=100, deadline=None)
@given(
    st.floats(min_value=-50, max_value=50),
    st.floats(min_value=-50, max_value=50),
    st.integers(min_value=0, max_value=6),
)
def test_integer_powers_enclose(a, b, p):
    x = _iv(a, b)
    ends = [Fraction(x.lo[0]), Fraction(x.hi[0])]
    exact = [e**p for e in ends] + ([Fraction(0)] if ends[0] <= 0 <= ends[1] and p else [])
    assert _encloses(x.power(p), exact)


def test_exact_zeros_stay_exact():
    unit = Interval.from_bounds(0.0, 1.0)
    assert (unit * Interval.point(3.0)).lo == 0.0
    assert (unit + Interval.point(0.0)).lo == 0.0
    assert unit.sqrt().lo == 0.0
    assert (Interval.point(0.0) / Interval.point(3.0)).lo == 0.0


def test_division_by_an_interval_holding_zero_is_unbounded():
    q = Interval.point(1.0) / Interval.from_bounds(-1.0, 2.0)
    assert q.lo == -np.inf and q.hi == np.inf and not q.finite


def test_norm_bounds_bracket_the_norm(rng):
    v = np.abs(rng.normal(size=(50, 4)))
    exact = np.linalg.norm(v, axis=1)
    assert np.all(norm_lower(v) <= exact) and np.all(norm_upper(v) >= exact)


# ------------------------------------------------------------------------- enclosures of CasADi


def _random_boxes(rng, lo, hi, count, scale=0.3):
    centre = rng.uniform(lo, hi, size=(count, lo.size))
    half = rng.uniform(0, scale, size=(count, lo.size)) * (hi - lo)
    return np.maximum(centre - half, lo), np.minimum(centre + half, hi)


@pytest.mark.parametrize("name", ["tank", "drone2d"])
@pytest.mark.parametrize("which", ["f", "O_3"])
@pytest.mark.parametrize("refine", [False, True])
def test_enclosure_contains_sampled_values_and_jacobians(name, which, refine, rng):
    system = get_system(name)
    fun = system.f if which == "f" else Horizon(system, 3).O
    n, m = fun.nnz_in(0), fun.nnz_in(1)
    ulo, uhi = np.tile(system.U.lo, m // system.n_u), np.tile(system.U.hi, m // system.n_u)
    xlo, xhi = _random_boxes(rng, system.X.lo, system.X.hi, 40)
    blo, bhi = _random_boxes(rng, ulo, uhi, 40)
    res = Enclosure(fun, wrt=0, refine=refine)([Interval(xlo, xhi), Interval(blo, bhi)])
    x, u = ca.SX.sym("x", n), ca.SX.sym("u", m)
    point = ca.Function("p", [x, u], [fun(x, u), ca.jacobian(fun(x, u), x)])
    checked = 0
    for b in np.flatnonzero(res.jac_flags == 0):
        for _ in range(20):
            value, jac = point(rng.uniform(xlo[b], xhi[b]), rng.uniform(blo[b], bhi[b]))
            value, jac = np.asarray(value).ravel(), np.asarray(jac)
            assert np.all(value >= res.values[0].lo[b]) and np.all(value <= res.values[0].hi[b])
            assert np.all(jac >= res.jacobians[0].lo[b]) and np.all(jac <= res.jacobians[0].hi[b])
            checked += 1
    assert checked >= 400


def test_refinement_is_never_wider(rng):
    tank = get_system("tank")
    fun = Horizon(tank, 3).O
    xlo, xhi = _random_boxes(rng, tank.X.lo, tank.X.hi, 60, scale=0.05)
    ubox = [Interval(np.full((60, 3), 1.0), np.full((60, 3), 3.0))]
    plain = Enclosure(fun)([Interval(xlo, xhi), *ubox]).values[0]
    refined = Enclosure(fun, refine=True)([Interval(xlo, xhi), *ubox]).values[0]
    assert np.all(refined.lo >= plain.lo) and np.all(refined.hi <= plain.hi)
    assert np.any(refined.hi - refined.lo < plain.hi - plain.lo)


_X = ca.SX.sym("x")
_U = ca.SX.sym("u")
ELEMENTARY = {
    "sin": ca.sin(_X * _U),
    "cos": ca.cos(_X + _U),
    "tan": ca.tan(_X / 4),
    "atan": ca.atan(_X * _U),
    "tanh": ca.tanh(_X - _U),
    "sinh": ca.sinh(_X),
    "cosh": ca.cosh(_X * _U),
    "exp": ca.exp(_X / _U),
    "log": ca.log(_X + _U),
    "constpow": _X**2.5,
    "pow": ca.power(_X, _U),
    "cube": _X**3 - _U,
    "sqrt": ca.sqrt(_X * _U),
    "inv": 1 / (_X + _U),
    "fabs": ca.fabs(_X - 2 * _U),
    "fmin": ca.fmin(_X, 2 * _U),
    "fmax": ca.fmax(_X * _X, _U),
    "twice": 2 * _X + _U,
    "logic": ca.if_else(ca.logic_or(ca.logic_and(_X > 1, ca.logic_not(_U > 2)), _X == _U), _X, _U),
}


@pytest.mark.parametrize("name", sorted(ELEMENTARY))
def test_elementary_operations_are_enclosed(name, rng):
    fun = ca.Function(name, [_X, _U], [ELEMENTARY[name]])
    lo = rng.uniform(0.2, 2.0, size=(30, 2))
    hi = lo + rng.uniform(0.0, 1.0, size=(30, 2))
    res = Enclosure(fun, wrt=0)([Interval(lo[:, :1], hi[:, :1]), Interval(lo[:, 1:], hi[:, 1:])])
    dfun = ca.Function("d", [_X, _U], [ELEMENTARY[name], ca.jacobian(ELEMENTARY[name], _X)])
    for b in range(30):
        for _ in range(30):
            x, u = rng.uniform(lo[b, 0], hi[b, 0]), rng.uniform(lo[b, 1], hi[b, 1])
            value, slope = (float(v) for v in dfun(x, u))
            assert res.values[0].lo[b, 0] <= value <= res.values[0].hi[b, 0]
            if res.jac_flags[b] == 0:
                assert res.jacobians[0].lo[b, 0, 0] <= slope <= res.jacobians[0].hi[b, 0, 0]


def test_fmax_kink_gives_the_hull_of_the_one_sided_slopes():
    x = ca.SX.sym("x")
    u = ca.SX.sym("u")
    res = Enclosure(ca.Function("relu", [x, u], [ca.fmax(x, 0)]), wrt=0)(
        [Interval.from_bounds([[-1.0]], [[2.0]]), Interval.point([[0.0]])]
    )
    assert res.jac_flags[0] == 0
    assert res.jacobians[0].lo[0, 0, 0] == 0.0 and res.jacobians[0].hi[0, 0, 0] == 1.0
    assert res.values[0].lo[0, 0] == 0.0 and res.values[0].hi[0, 0] == 2.0


def test_flags_say_why_a_jacobian_is_unbounded():
    x = ca.SX.sym("x")
    u = ca.SX.sym("u")
    cases = {
        SLOPE: ca.sqrt(x),
        DIV_ZERO: 1 / x,
        DISCONTINUITY: ca.if_else(x > 0.5, x, 2 * x),
    }
    for bit, expr in cases.items():
        res = Enclosure(ca.Function("g", [x, u], [expr]), wrt=0)(
            [Interval.from_bounds([[0.0]], [[1.0]]), Interval.point([[0.0]])]
        )
        assert res.jac_flags[0] & bit, describe_flags(int(res.jac_flags[0]))
    assert "√" in describe_flags(SLOPE)


def test_unsupported_operation_is_refused_by_name():
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    with pytest.raises(SetError, match="OP_ERF"):
        Enclosure(ca.Function("g", [x, u], [ca.erf(x)]))


def test_range_enclosure_is_sound_and_tighter(rng):
    tank = get_system("tank")
    lo, hi = _random_boxes(rng, np.array([0.05, 0.05, 1.0]), np.array([5.0, 5.0, 3.0]), 50)
    enc, flags, points = RangeEnclosure(tank.f)(lo, hi)
    natural = Enclosure(tank.f)([Interval(lo[:, :2], hi[:, :2]), Interval(lo[:, 2:], hi[:, 2:])])
    assert np.all(flags == 0)
    assert np.all(enc.lo >= natural.values[0].lo) and np.all(enc.hi <= natural.values[0].hi)
    for b in range(50):
        samples = rng.uniform(lo[b], hi[b], size=(50, 3))
        values = tank.f_batch(samples[:, :2], samples[:, 2:])
        assert np.all(values >= enc.lo[b]) and np.all(values <= enc.hi[b])
        assert np.all((points[b] >= lo[b]) & (points[b] <= hi[b]))


# ------------------------------------------------------------------------- verified matrix bounds


@pytest.mark.parametrize("shape", [(2, 2), (3, 2), (4, 3), (6, 6), (9, 6)])
def test_singular_value_bounds_hold_for_every_member(shape, rng):
    centre = rng.normal(size=(20, *shape))
    radius = np.abs(rng.normal(size=(20, *shape))) * 0.05
    matrices = Interval(centre - radius, centre + radius)
    upper, lower = spectral_upper(matrices), smin_lower(matrices)
    for _ in range(200):
        member = centre + radius * rng.uniform(-1, 1, size=centre.shape)
        sv = np.linalg.svd(member, compute_uv=False)
        assert np.all(sv[:, 0] <= upper)
        assert np.all(sv[:, -1] >= lower)


@pytest.mark.parametrize("shape", [(2, 2), (3, 2), (5, 3), (2, 3)])
def test_point_matrices_are_exact_to_1e8(shape, rng):
    a = rng.normal(size=(30, *shape))
    sv = np.linalg.svd(a, compute_uv=False)
    upper = spectral_upper(Interval.point(a))
    assert np.all(upper >= sv[:, 0]) and np.allclose(upper, sv[:, 0], rtol=1e-8, atol=0)
    lower = smin_lower(Interval.point(a))
    if shape[0] < shape[1]:
        assert np.all(lower == 0.0)  # a wide matrix has n − m zero singular values
    else:
        assert np.all(lower <= sv[:, -1]) and np.allclose(lower, sv[:, -1], rtol=1e-8, atol=0)


def test_rank_deficient_matrix_has_zero_lower_bound():
    a = np.array([[[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]]])
    assert smin_lower(Interval.point(a))[0] == 0.0


def test_norm_bounds_of_matrices_too_large_for_float64_are_trivial_not_nan():
    """Entries near 1e200 overflow the Gram matrix: the bounds must be the trivial ones
    (an upper bound ∞, a lower bound 0), never NaN, which a branch-and-bound would drop."""
    big = np.full((3, 4, 4), 1e200)
    big[1] = np.eye(4) * 1e200
    j = Interval(big * 0.5, big)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no "invalid value" noise either
        upper, lower = spectral_upper(j), smin_lower(j)
    assert np.all(upper == np.inf) and np.all(lower == 0.0)
