"""Proposition 2's bound along recorded trajectories (:func:`canonid.analysis.bound.bound_along`).

A linear system is the oracle: α_ℓ = σ_min(𝒪_ℓ), γ_f = ‖A‖₂, so the bound of each window is
``2 ‖A‖^ℓ / σ_min(𝒪_ℓ) · ‖w̄‖`` exactly, and the least-squares state estimate along a simulated
noisy trajectory stays below it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from canonid.analysis.bound import BoundConstants, bound_along
from canonid.analysis.estimate import Estimate
from canonid.analysis.linear import alpha_exact, gamma_exact, observability_matrix, toeplitz_matrix
from canonid.kernel.errors import ShapeError
from canonid.models.linear import linear_example
from canonid.models.sets import Box


def _constant(quantity: str, value: float, kind: str, window: int, **details) -> Estimate:
    return Estimate(quantity, value, kind, {}, "exact: closed form", window=window, details=details)  # type: ignore[arg-type]


def _constants(system, window: int) -> BoundConstants:
    return BoundConstants(
        window,
        _constant("gamma_f", gamma_exact(system.A), "upper", window),
        _constant("alpha", alpha_exact(system.A, system.C, window), "lower", window),
    )


def _simulate(system, rng, T: int):
    """A noisy trajectory from inside X: states, inputs, noise (y = C x + D u + w)."""
    x = np.zeros((T + 1, system.n_x))
    x[0] = 0.5 * system.X.center
    u = rng.uniform(system.U.lo, system.U.hi, size=(T, system.n_u))
    for t in range(T):
        x[t + 1] = system.A @ x[t] + system.B @ u[t]
    w = rng.uniform(system.W.lo, system.W.hi, size=(T, system.n_y))
    return x, u, w


@pytest.mark.parametrize("name", ["linear", "linear-mimo"])
@pytest.mark.parametrize("window", [2, 4])
def test_the_bound_of_a_linear_system_is_the_closed_form_and_holds(name, window, rng):
    system = linear_example(name)
    constants = _constants(system, window)
    x, u, w = _simulate(system, rng, 30)
    along = bound_along(
        constants, [w], states=[x], inputs=[u], X=Box.symmetric(1e3, system.n_x), U=system.U
    )
    assert along.applies.all() and along.noise_norms.size == 30 - window + 1
    gamma, alpha = gamma_exact(system.A), alpha_exact(system.A, system.C, window)
    expected = [2 * gamma**window / alpha * np.linalg.norm(w[j : j + window]) for j in along.start]
    np.testing.assert_allclose(along.bounds, expected, rtol=1e-12)
    summary = along.summary()
    assert summary["bound_max"] == pytest.approx(max(expected), rel=1e-12)
    assert summary["bound_median"] == pytest.approx(float(np.median(expected)), rel=1e-12)
    assert summary["infinite"] is None and summary["certified"]
    # the least-squares estimate of x_j from the window, propagated ℓ steps, against x_{j+ℓ}
    obs, toep = observability_matrix(system.A, system.C, window), toeplitz_matrix(system, window)
    A_ell = np.linalg.matrix_power(system.A, window)
    for j, bound in zip(along.start, along.bounds):
        ybar = obs @ x[j] + toep @ u[j : j + window].ravel() + w[j : j + window].ravel()
        x_hat = np.linalg.lstsq(obs, ybar - toep @ u[j : j + window].ravel(), rcond=None)[0]
        assert np.linalg.norm(A_ell @ (x_hat - x[j])) <= bound


def test_a_zero_alpha_or_an_infinite_gamma_makes_the_bound_infinite_and_says_which(rng):
    system = linear_example("linear")
    w = rng.uniform(-0.01, 0.01, size=(8, system.n_y))
    no_alpha = BoundConstants(
        2,
        _constant("gamma_f", gamma_exact(system.A), "upper", 2),
        _constant("alpha", 0.0, "lower", 2),
    )
    along = bound_along(no_alpha, [w])
    assert np.all(np.isinf(along.bounds))
    summary = along.summary()
    assert summary["bound_max"] is None and summary["bound_median"] is None
    assert summary["factor"] is None and "α_2" in summary["infinite"]
    assert "do not separate the states" in summary["infinite"]  # an exact 0: structure
    searched = BoundConstants(
        2, no_alpha.gamma_f, Estimate("alpha", 0.0, "lower", {}, "trivial (budget)", window=2)
    )
    assert "no positive bound was certified" in (searched.why_infinite() or "")
    no_gamma = BoundConstants(
        2,
        _constant("gamma_f", math.inf, "upper", 2, why="H_1 has no finite certified box"),
        _constant("alpha", 1.0, "lower", 2),
    )
    reason = bound_along(no_gamma, [w]).infinite
    assert reason is not None and "γ_f" in reason and "H_1" in reason
    # zero noise in a window: the bound is 0 even with an infinite factor
    assert bound_along(no_alpha, [np.zeros((3, system.n_y))]).bounds.tolist() == [0.0, 0.0]


def test_windows_stack_the_samples_they_name_and_the_premises_are_checked():
    ell, T = 3, 9
    w = np.zeros((T, 2))
    w[4] = [3.0, 4.0]  # norm 5, inside the windows that start at 2, 3 and 4
    constants = BoundConstants(
        ell, _constant("gamma_f", 1.0, "upper", ell), _constant("alpha", 0.5, "lower", ell)
    )
    x = np.zeros((T, 1))
    x[1] = 2.0  # outside X = [−1, 1]: the window that starts at 1 does not apply
    u = np.zeros((T, 1))
    u[7] = 5.0  # outside U: the windows that hold sample 7 (starts 5, 6) do not apply
    X, U = Box([-1.0], [1.0]), Box([-1.0], [1.0])
    second = np.ones((2, 2))  # a trajectory shorter than the window: no window
    along = bound_along(constants, [w, second], states=[x, x[:2]], inputs=[u, u[:2]], X=X, U=U)
    assert along.start.tolist() == list(range(T - ell + 1))
    assert along.trajectory.tolist() == [0] * (T - ell + 1)
    assert along.noise_norms.tolist() == [0, 0, 5, 5, 5, 0, 0]
    assert along.bounds.tolist() == [0, 0, 20, 20, 20, 0, 0]  # 2 · 1³ / 0.5 · 5
    assert along.applies.tolist() == [True, False, True, True, True, False, False]
    assert along.summary()["windows_applied"] == 4
    with pytest.raises(ShapeError):
        bound_along(constants, [w], states=[x])  # states without X
    with pytest.raises(ShapeError):
        bound_along(constants, [w], states=[x[:4]], X=X)  # fewer states than noise samples


def test_box_rows_are_inside_exactly_when_every_coordinate_is_including_the_faces():
    box = Box([0.0, -1.0], [1.0, 1.0])
    rows = np.array([[0.5, 0.0], [0.0, -1.0], [1.0, 1.0], [1.0001, 0.0], [0.5, -1.5]])
    assert box.contains_rows(rows).tolist() == [True, True, True, False, False]
    assert box.contains_rows(rows[:3]).all() == box.contains(rows[:3])
