"""γ_f of a learned model (canonid.analysis.certify) against closed forms and sampled values."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import torch
from test_learned_system import as_system, gru_model, mlp_model, reduced_model

from canonid.analysis.certify import layer_norm_bound, learned_gamma
from canonid.analysis.estimate import Budget
from canonid.kernel.canonical import shift_matrices

BUDGET = Budget(boxes=16, samples=256, starts=2)


def _torch_jacobian_z(model, z: np.ndarray, u: np.ndarray) -> np.ndarray:
    """∂Ĥ/∂z (physical units) of the torch model at one point, by autograd."""
    norm, net = model.norm, model.net
    zt = torch.tensor(z, requires_grad=True)
    z_mean = torch.tensor(np.tile(np.concatenate([norm.u_mean, norm.y_mean]), 3))
    z_std = torch.tensor(np.tile(np.concatenate([norm.u_std, norm.y_std]), 3))
    un = torch.tensor(norm.norm_u(u))[None]
    y = net.one_step(((zt - z_mean) / z_std)[None], un)[0] * torch.tensor(norm.y_std)
    rows = [torch.autograd.grad(y[i], zt, retain_graph=True)[0].numpy() for i in range(len(y))]
    return np.array(rows)


@pytest.mark.parametrize("residual", [False, True])
def test_a_linear_model_gives_the_norm_of_its_shift_matrix_exactly(residual, rng):
    """No hidden layer: f(z, u) = (Ā + S̄ L_z) z + …, so γ_f = ‖Ā + S̄ L_z‖₂ on any set."""
    model = mlp_model(hidden=(), residual=residual)
    system = as_system(model)
    L_z = _torch_jacobian_z(model, rng.normal(size=9), rng.normal(size=2))
    A, _, S = shift_matrices(3, 2, 1)
    exact = np.linalg.norm(A + S @ L_z, 2)
    gamma = learned_gamma(system, budget=BUDGET)
    assert gamma.bracket.lower.value == pytest.approx(exact, rel=1e-9)
    assert gamma.bracket.upper.value == pytest.approx(exact, rel=1e-9)
    assert gamma.bracket.upper.value >= gamma.bracket.lower.value
    assert gamma.layer_norms.value >= exact * (1 - 1e-12)
    assert gamma.layer_norms.method.startswith("certified, loose")


@pytest.mark.parametrize("activation", ["relu", "silu", "tanh"])
@pytest.mark.parametrize("feedthrough", [True, False])
def test_certified_bounds_are_above_every_sampled_jacobian(activation, feedthrough, rng):
    model = mlp_model(activation=activation, feedthrough=feedthrough, residual=True)
    system = as_system(model)
    gamma = learned_gamma(system, budget=BUDGET)
    A, _, S = shift_matrices(3, 2, 1)
    z = system.X.sample(rng, 200)
    u = system.U.sample(rng, 200)
    sampled = [np.linalg.norm(A + S @ _torch_jacobian_z(model, zi, ui), 2) for zi, ui in zip(z, u)]
    assert max(sampled) <= gamma.bracket.upper.value * (1 + 1e-12)
    assert max(sampled) <= gamma.layer_norms.value * (1 + 1e-12)
    assert gamma.bracket.lower.value >= max(sampled) * (1 - 1e-9)  # the search finds them too
    assert gamma.upper.value == min(gamma.bracket.upper.value, gamma.layer_norms.value)


def test_the_reduced_model_bound_is_above_its_sampled_jacobians(rng):
    model = reduced_model(linear_skip=True)
    system = as_system(model)
    bound = layer_norm_bound(system)
    xs, us = ca.SX.sym("x", system.n_x), ca.SX.sym("u", system.n_u)
    jac = ca.Function("jacobian_f", [xs, us], [ca.jacobian(system.f(xs, us), xs)])
    x = system.X.sample(rng, 100)
    u = system.U.sample(rng, 100)
    sampled = [np.linalg.norm(np.asarray(jac(xi, ui)), 2) for xi, ui in zip(x, u)]
    assert 0 < max(sampled) <= bound.value
    gamma = learned_gamma(system, budget=BUDGET)
    assert gamma.bracket.lower.value <= gamma.bracket.upper.value


def test_a_gru_regressor_is_certified_by_branch_and_bound_only(rng):
    model = gru_model(residual=True)
    system = as_system(model)
    gamma = learned_gamma(system, budget=BUDGET)
    assert gamma.layer_norms.value == np.inf and gamma.layer_norms.method.startswith("trivial")
    assert np.isfinite(gamma.bracket.upper.value) and gamma.upper is gamma.bracket.upper
    A, _, S = shift_matrices(3, 2, 1)
    z, u = system.X.sample(rng, 50), system.U.sample(rng, 50)
    sampled = [np.linalg.norm(A + S @ _torch_jacobian_z(model, zi, ui), 2) for zi, ui in zip(z, u)]
    assert max(sampled) <= gamma.bracket.upper.value


@pytest.mark.parametrize("name", ["tanh", "exp", "atan", "sinh"])
def test_increasing_functions_are_enclosed_by_the_images_of_the_ends(name, rng):
    """A wide interval's image is [g(lo), g(hi)] (one arb ball over it would be far looser:
    the SiLU layers' interval bounds depend on it), and it contains every sampled value."""
    from canonid.analysis.enclosure import Enclosure
    from canonid.analysis.interval import Interval

    x = ca.SX.sym("x")
    g = getattr(ca, name)
    enclosure = Enclosure(ca.Function("g", [x], [g(x)]), wrt=0)
    lo, hi = np.array([[-10.0], [-1.0], [2.0]]), np.array([[10.0], [1.0], [30.0]])
    res = enclosure([Interval(lo, hi)])
    value, slope = res.values[0], res.jacobians[0]
    exact_lo, exact_hi = (
        np.asarray(getattr(np, name.replace("atan", "arctan"))(v)) for v in (lo, hi)
    )
    np.testing.assert_allclose(value.lo, exact_lo, rtol=1e-12)
    np.testing.assert_allclose(value.hi, exact_hi, rtol=1e-12)
    assert np.all(value.lo <= exact_lo) and np.all(value.hi >= exact_hi)
    for row in range(3):
        points = rng.uniform(lo[row, 0], hi[row, 0], size=200)
        derivative = np.asarray(ca.Function("d", [x], [ca.jacobian(g(x), x)]).map(200)(points))
        assert np.all(slope.lo[row].min() <= derivative + 1e-12)
        assert np.all(derivative <= slope.hi[row].max() + 1e-12)
