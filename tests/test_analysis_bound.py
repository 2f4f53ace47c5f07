"""Proposition 2 checked by Monte-Carlo: zero violations with certified constants, on the tank
and on a linear system; a wrong constant is caught; solver failures are counted apart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from canonid.analysis import bound as bound_module
from canonid.analysis.argmin import ArgminResult
from canonid.analysis.bound import BoundConstants, check_bound
from canonid.analysis.estimate import Budget, Estimate
from canonid.analysis.linear import alpha_exact, gamma_exact
from canonid.analysis.lipschitz import lipschitz_bracket
from canonid.analysis.observability import alpha_bracket
from canonid.analysis.reach import reachable_hulls
from canonid.kernel.errors import SetError, ShapeError
from canonid.models.linear import linear_example
from canonid.models.registry import get_system
from canonid.models.sets import Box

X = Box([0.05, 0.05], [5.0, 5.0])
U = Box([1.0], [3.0])
BUDGET = Budget(boxes=20000, samples=512, starts=2)


def _constant(quantity: str, value: float, kind: str, window: int) -> Estimate:
    return Estimate(quantity, value, kind, {}, "exact: closed form", window=window)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def tank_constants():
    tank = get_system("tank")
    hulls = reachable_hulls(tank, 2, X=X, U=U)
    out = {}
    previous = []
    for ell in (1, 2, 3):
        gamma = lipschitz_bracket(tank.f, hulls[ell - 1], U, window=ell, budget=BUDGET)
        # the pairs search runs for ℓ = 2 (4-D); ℓ = 3 takes α_3 ≥ α_2
        alpha = alpha_bracket(
            tank, ell, X=X, U=U, previous=previous, budget=BUDGET, max_pair_dims=4
        )
        previous.append(alpha.lower)
        out[ell] = (gamma, alpha)
    return tank, out


@pytest.mark.parametrize("window", [2, 3])
def test_tank_has_no_violation_with_certified_constants(tank_constants, window):
    tank, constants = tank_constants
    gamma, alpha = constants[window]
    certified = BoundConstants(window, gamma.upper, alpha.lower)
    estimated = BoundConstants(window, gamma.lower, alpha.upper)
    assert certified.certified and not estimated.certified
    for noise in ("uniform", "vertices"):
        check = check_bound(
            tank,
            certified,
            trials=300,
            X=X,
            U=U,
            noise=noise,
            starts=4,
            seed=window,
            estimated=estimated,
        )
        assert check.violations == 0
        assert check.max_ratio is not None and check.max_ratio <= 1.0
        assert check.max_error > 0 and check.worst_case_bound > 0
        # trials that the proof covers are nearly all of them
        assert check.solver_failures < check.trials // 10


def test_window_one_of_the_tank_has_an_infinite_bound(tank_constants):
    tank, constants = tank_constants
    gamma, alpha = constants[1]
    certified = BoundConstants(1, gamma.upper, alpha.lower)
    assert alpha.lower.value == 0.0 and math.isinf(certified.factor)
    check = check_bound(tank, certified, trials=50, X=X, U=U, starts=2)
    assert check.violations == 0 and check.max_ratio is None and check.worst_case_bound is None


@pytest.mark.parametrize("name", ["linear", "linear-mimo"])
@pytest.mark.parametrize("window", [2, 4])
def test_linear_system_has_no_violation_with_exact_constants(name, window):
    system = linear_example(name)
    alpha = alpha_exact(system.A, system.C, window)
    constants = BoundConstants(
        window,
        _constant("gamma_f", gamma_exact(system.A), "upper", window),
        _constant("alpha", alpha, "lower", window),
    )
    check = check_bound(system, constants, trials=400, seed=1, starts=3)
    assert check.violations == 0 and check.solver_failures == 0
    assert 0 < check.max_ratio <= 1.0


def test_a_too_large_alpha_is_caught_as_violations():
    """The check can fail: claim α 100 times too large and the bound is broken."""
    system = linear_example("linear")
    window = 2
    wrong = BoundConstants(
        window,
        _constant("gamma_f", gamma_exact(system.A), "upper", window),
        _constant("alpha", 100 * alpha_exact(system.A, system.C, window), "lower", window),
    )
    check = check_bound(system, wrong, trials=200, seed=2, starts=3)
    assert check.violations > 0 and check.max_ratio > 1.0


def test_solver_failures_are_counted_apart(monkeypatch):
    system = linear_example("linear")
    window = 2
    constants = BoundConstants(
        window,
        _constant("gamma_f", gamma_exact(system.A), "upper", window),
        _constant("alpha", alpha_exact(system.A, system.C, window), "lower", window),
    )

    def bad_solver(horizon, ybar, ubar, box, *, starts, rng):
        # a far corner of X: objective worse than at the true state
        x = np.tile(box.hi, (ybar.shape[0], 1))
        return ArgminResult(x=x, objective=np.full(ybar.shape[0], 1e9), iterations=0, starts=1)

    monkeypatch.setattr(bound_module, "output_error_argmin", bad_solver)
    check = check_bound(system, constants, trials=40, seed=3)
    assert check.solver_failures == 40 and check.violations == 0


def test_same_seed_gives_the_same_check():
    system = linear_example("linear")
    constants = BoundConstants(
        2,
        _constant("gamma_f", gamma_exact(system.A), "upper", 2),
        _constant("alpha", alpha_exact(system.A, system.C, 2), "lower", 2),
    )
    a = check_bound(system, constants, trials=50, seed=7, starts=2)
    b = check_bound(system, constants, trials=50, seed=7, starts=2)
    da, db = a.to_dict(), b.to_dict()
    da.pop("seconds"), db.pop("seconds")
    assert np.array_equal(a.errors, b.errors) and da == db


def test_bad_inputs_are_refused():
    system = linear_example("linear")
    good = _constant("alpha", 0.1, "lower", 2)
    gamma = _constant("gamma_f", 1.0, "upper", 2)
    with pytest.raises(ShapeError, match="window"):
        BoundConstants(0, gamma, good)
    with pytest.raises(SetError, match="gamma_f and alpha"):
        BoundConstants(2, good, gamma)
    constants = BoundConstants(2, gamma, good)
    with pytest.raises(ShapeError, match="trials"):
        check_bound(system, constants, trials=0)
    with pytest.raises(SetError, match="outside X"):
        check_bound(system, constants, trials=5, states=np.full((3, 2), 5.0))
