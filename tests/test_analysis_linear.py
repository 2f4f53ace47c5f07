"""Linear systems are the oracle: α_ℓ = σ_min(O_ℓ), γ_f = ‖A‖₂ in closed form.

Every estimator must bracket the closed form (lower ≤ exact ≤ upper) and the exact paths must
hit it to 1e-8 (relative).
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from canonid.analysis.estimate import Budget
from canonid.analysis.linear import (
    alpha_exact,
    canonical_regressor,
    gamma_exact,
    observability_matrix,
    toeplitz_matrix,
)
from canonid.analysis.lipschitz import lipschitz_bracket
from canonid.analysis.maps import Horizon, batched
from canonid.analysis.observability import _pairs_branch_and_bound, alpha_bracket
from canonid.kernel.canonical import cut_windows
from canonid.kernel.errors import ShapeError
from canonid.models.linear import LinearSystem, linear_example

SMALL = Budget(boxes=200, samples=256, starts=2)


@st.composite
def linear_systems(draw):
    n = draw(st.integers(1, 4))
    m = draw(st.integers(1, 2))
    p = draw(st.integers(1, 2))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n)) * draw(st.sampled_from([0.3, 0.6, 1.0]))
    B = rng.normal(size=(n, m))
    C = rng.normal(size=(p, n))
    D = rng.normal(size=(p, m)) if draw(st.booleans()) else None
    return LinearSystem(A, B, C, D)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(linear_systems(), st.integers(1, 6))
def test_observability_matrix_is_the_jacobian_of_O(system, window):
    obs = observability_matrix(system.A, system.C, window)
    assert obs.shape == (window * system.n_y, system.n_x)
    if window == system.n_x:
        assert np.allclose(obs, control.obsv(system.A, system.C), atol=1e-12)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(3, system.n_x))
    ubar = rng.normal(size=(3, window * system.n_u))
    hz = Horizon(system, window)
    (o,) = batched(hz.O, x, ubar)
    expected = x @ obs.T + ubar @ toeplitz_matrix(system, window).T
    assert np.allclose(o, expected, rtol=1e-10, atol=1e-10)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(linear_systems(), st.integers(1, 5))
def test_alpha_bracket_holds_the_closed_form(system, window):
    exact = alpha_exact(system.A, system.C, window)
    bracket = alpha_bracket(system, window, budget=SMALL)
    scale = max(exact, 1e-12)
    assert bracket.lower.value <= exact + 1e-12 * scale
    assert bracket.upper.value >= exact - 1e-10 * max(1.0, exact)
    if window * system.n_y < system.n_x:
        assert exact == 0.0 and bracket.lower.value == 0.0
    elif exact > 1e-6:
        # ∂O/∂x is constant: the certified lower bound is exact up to the slack its interval
        # Cholesky of OᵀO − μ²I needs, which grows with the Gram matrix's rounding, n·ε·κ²
        # (the ladder of slacks steps by 1000×); σ_min sampling is exact
        obs = observability_matrix(system.A, system.C, window)
        kappa = np.linalg.norm(obs, 2) / exact
        rel = max(1e-8, 1e3 * obs.shape[1] * np.finfo(float).eps * kappa**2)
        assert bracket.lower.details["exact"]
        assert bracket.lower.value == pytest.approx(exact, rel=rel)
        assert bracket.upper.value == pytest.approx(exact, rel=1e-8)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(linear_systems())
def test_gamma_bracket_holds_the_closed_form(system):
    exact = gamma_exact(system.A)
    bracket = lipschitz_bracket(system.f, system.X, system.U, budget=SMALL)
    assert bracket.lower.value <= exact * (1 + 1e-12) + 1e-300
    assert bracket.upper.value >= exact
    assert bracket.lower.value == pytest.approx(exact, rel=1e-8)
    assert bracket.upper.value == pytest.approx(exact, rel=1e-8)


def test_gamma_h_is_the_norm_of_C():
    system = linear_example("linear-mimo")
    bracket = lipschitz_bracket(system.h, system.X, system.U, quantity="gamma_h", budget=SMALL)
    assert bracket.upper.value == pytest.approx(np.linalg.norm(system.C, 2), rel=1e-8)


@pytest.mark.parametrize("window", [2, 3])
def test_pairs_search_is_exact_on_a_linear_system(window):
    """The mean-value bound of a constant Jacobian is σ_min itself: the search closes at once."""
    system = linear_example("linear-mimo")
    exact = alpha_exact(system.A, system.C, window)
    est = _pairs_branch_and_bound(
        system,
        window,
        system.X,
        system.U,
        tol=1e-9,
        budget=SMALL,
        upper=exact * 1.5,
        batch=16,
        progress=None,
    )
    assert est.value <= exact
    assert est.value == pytest.approx(exact, rel=1e-8)


def test_alpha_is_zero_when_rank_deficient():
    # x2 never reaches the output: (A, C) unobservable at every horizon
    system = LinearSystem([[0.9, 0.0], [0.0, 0.5]], [[1.0], [1.0]], [[1.0, 0.0]])
    for window in (1, 2, 4):
        assert alpha_exact(system.A, system.C, window) == pytest.approx(0.0, abs=1e-15)
        bracket = alpha_bracket(system, window, budget=SMALL)
        assert bracket.lower.value == 0.0
        assert bracket.upper.value == pytest.approx(0.0, abs=1e-12)


def test_long_windows_are_not_capped_at_n():
    system = linear_example("linear")
    obs = observability_matrix(system.A, system.C, 7)
    assert obs.shape == (7, 2)
    assert alpha_exact(system.A, system.C, 7) > alpha_exact(system.A, system.C, 2)


def test_canonical_regressor_reproduces_noise_free_outputs(rng):
    system = linear_example("linear-mimo")
    window = 3
    u = rng.uniform(-1, 1, size=(60, system.n_u))
    sim = system.simulate(rng.uniform(-1, 1, size=system.n_x), u)
    z = cut_windows(u, sim.y, window)[:-1]
    pred = canonical_regressor(system, window)(z, u[window:])
    assert np.allclose(pred, sim.y[window:], atol=1e-10)


def test_bad_window_is_refused():
    system = linear_example("linear")
    with pytest.raises(ShapeError, match="window"):
        observability_matrix(system.A, system.C, 0)
    with pytest.raises(ShapeError, match="window"):
        alpha_bracket(system, 0)
