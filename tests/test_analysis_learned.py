"""Learned models against the bound, through plain numpy callables: the exact canonical map of
a linear system stays within the noise-induced level, a biased one does not; the state probe."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from canonid.analysis.bound import BoundConstants
from canonid.analysis.estimate import Estimate
from canonid.analysis.learned import residual_check, state_probe, window_rows
from canonid.analysis.linear import alpha_exact, canonical_regressor, gamma_exact
from canonid.kernel.errors import DataError, ShapeError
from canonid.models.linear import linear_example


@dataclass
class Trajectory:
    """Duck-typed like datagen's Trajectory: u, y, y_clean, x."""

    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray | None
    x: np.ndarray | None


def _trajectories(system, count, steps, rng, noise=True):
    out = []
    for _ in range(count):
        u = rng.uniform(system.U.lo, system.U.hi, size=(steps, system.n_u))
        sim = system.simulate(rng.uniform(0.5 * system.X.lo, 0.5 * system.X.hi), u)
        w = rng.uniform(system.W.lo, system.W.hi, size=sim.y.shape) if noise else 0 * sim.y
        out.append(Trajectory(u=u, y=sim.y + w, y_clean=sim.y, x=sim.x))
    return out


def _constants(system, window):
    def est(q, v, k):
        return Estimate(q, v, k, {}, "exact: closed form", window=window)

    return BoundConstants(
        window,
        est("gamma_f", gamma_exact(system.A), "upper"),
        est("alpha", alpha_exact(system.A, system.C, window), "lower"),
        est("gamma_h", float(np.linalg.norm(system.C, 2)), "upper"),
    )


@pytest.mark.parametrize("name", ["linear", "linear-mimo"])
@pytest.mark.parametrize("window", [2, 3])
def test_exact_canonical_map_stays_within_the_noise_level(name, window, rng):
    system = linear_example(name)
    test = _trajectories(system, 4, 80, rng)
    constants = _constants(system, window)
    check = residual_check(canonical_regressor(system, window), test, constants)
    assert check.rows == 4 * (80 - window) and check.excluded == 0
    assert check.within == check.rows and check.max_ratio <= 1.0
    # the residual is not trivially small: it is the noise, propagated
    assert check.residual["q50"] > 0.1 * system.W.radius


def test_a_biased_regressor_exceeds_the_level(rng):
    system = linear_example("linear")
    exact = canonical_regressor(system, 2)
    check = residual_check(
        lambda z, u: exact(z, u) + 0.5, _trajectories(system, 2, 60, rng), _constants(system, 2)
    )
    assert check.within < check.rows and check.max_ratio > 1.0


def test_rows_follow_the_time_convention(rng):
    system = linear_example("linear")
    traj = _trajectories(system, 1, 10, rng)
    rows = window_rows(traj, 3)
    # row k is t = 3 + k: z holds samples t−3 … t−1, the target is y_t, x_start is x_{t−3}
    assert rows.count == 7
    assert np.allclose(rows.z[0], np.column_stack([traj[0].u[:3], traj[0].y[:3]]).ravel())
    assert np.allclose(rows.y_now[0], traj[0].y[3]) and np.allclose(rows.x_start[0], traj[0].x[0])
    w = traj[0].y - traj[0].y_clean
    assert rows.w_window[0] == pytest.approx(np.linalg.norm(w[:3]))


def test_probe_from_z_recovers_the_state_on_noise_free_data(rng):
    system = linear_example("linear-mimo")
    train = _trajectories(system, 4, 60, rng, noise=False)
    test = _trajectories(system, 2, 60, rng, noise=False)
    result = state_probe(train, test, window=3, kind="affine")
    assert result.features == "z" and result.rmse < 1e-6


def test_probe_from_reduced_states_with_the_bound(rng):
    system = linear_example("linear")
    window = 2
    train = _trajectories(system, 3, 50, rng)
    test = _trajectories(system, 2, 50, rng)
    # the "reduced state" here is the true state itself: the probe must be exact
    reduced_train = [t.x[window:] for t in train]
    reduced_test = [t.x[window:] for t in test]
    result = state_probe(
        train,
        test,
        window=window,
        constants=_constants(system, window),
        reduced_train=reduced_train,
        reduced_test=reduced_test,
        kind="quadratic",
    )
    assert result.features == "reduced" and result.rmse < 1e-6
    assert result.bound_rows == result.test_rows and result.within == result.bound_rows


def test_bad_inputs_are_refused(rng):
    system = linear_example("linear")
    trajs = _trajectories(system, 1, 20, rng)
    constants = _constants(system, 2)
    with pytest.raises(ShapeError, match="regressor returned shape"):
        residual_check(lambda z, u: np.zeros((len(z), 3)), trajs, constants)
    no_clean = [Trajectory(u=trajs[0].u, y=trajs[0].y, y_clean=None, x=trajs[0].x)]
    with pytest.raises(DataError, match="y_clean"):
        residual_check(canonical_regressor(system, 2), no_clean, constants)
    no_state = [Trajectory(u=trajs[0].u, y=trajs[0].y, y_clean=trajs[0].y_clean, x=None)]
    with pytest.raises(DataError, match="true states"):
        state_probe(no_state, no_state, window=2)
    with pytest.raises(ShapeError, match="reduced states"):
        state_probe(
            trajs,
            trajs,
            window=2,
            reduced_train=[np.zeros((3, 2))],
            reduced_test=[np.zeros((3, 2))],
        )
    with pytest.raises(ShapeError, match="window"):
        window_rows(trajs, 0)
