"""The true systems: hand-computed values, invariants, batched evaluation, bad input."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.kernel.errors import SetError, ShapeError, UnknownSystemError
from canonid.models import Box, Drone2D, LinearSystem, Tank, get_system, system_names

# ---------------------------------------------------------------- the registry, parametrised


def test_registry_lists_the_three_kinds():
    names = system_names()
    assert {"tank", "drone2d", "linear"} <= set(names)


def test_dimensions_and_sets_are_consistent(system):
    assert system.f.size_in(0) == (system.n_x, 1)
    assert system.f.size_in(1) == (system.n_u, 1)
    assert system.f.size_out(0) == (system.n_x, 1)
    assert system.h.size_out(0) == (system.n_y, 1)
    assert (system.X.dim, system.U.dim, system.W.dim) == (system.n_x, system.n_u, system.n_y)
    for box in (system.X, system.U, system.W):
        assert np.all(box.lo <= box.hi)
    assert len(system.state_units) == system.n_x
    assert len(system.input_units) == system.n_u
    assert len(system.output_units) == system.n_y
    assert system.dt > 0
    d = system.describe()
    assert d["n_x"] == system.n_x and d["name"] == system.name


def test_batched_simulation_equals_loop_of_single_steps(system, rng):
    n, steps = 4, 7
    x0 = system.X.sample(rng, n)
    u = rng.uniform(system.U.lo, system.U.hi, size=(n, steps, system.n_u))
    batch = system.simulate_batch(x0, u)
    for i in range(n):
        x = x0[i]
        for t in range(steps):
            np.testing.assert_allclose(batch.x[i, t], x, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(
                batch.y[i, t], system.output(x, u[i, t]), rtol=1e-12, atol=1e-12
            )
            x = system.step(x, u[i, t])
        np.testing.assert_allclose(batch.x_final[i], x, rtol=1e-12, atol=1e-12)
    single = system.simulate(x0[0], u[0])
    np.testing.assert_array_equal(single.y, batch.y[0])


def test_f_batch_equals_step(system, rng):
    x = system.X.sample(rng, 5)
    u = system.U.sample(rng, 5)
    out = system.f_batch(x, u)
    for i in range(5):
        np.testing.assert_allclose(out[i], system.step(x[i], u[i]), rtol=1e-13)
    hy = system.h_batch(x, u)
    for i in range(5):
        np.testing.assert_allclose(hy[i], system.output(x[i], u[i]), rtol=1e-13)


@pytest.mark.parametrize("bad", ["state", "input"])
def test_wrong_length_is_refused_with_a_named_error(system, bad):
    x = np.zeros(system.n_x + (1 if bad == "state" else 0))
    u = np.zeros(system.n_u + (1 if bad == "input" else 0))
    with pytest.raises(ShapeError, match=rf"{system.name}: {bad}"):
        system.step(x, u)


def test_nan_is_refused(system):
    x = system.X.center.copy()
    x[0] = np.nan
    with pytest.raises(ShapeError, match="non-finite"):
        system.step(x, system.U.center)
    with pytest.raises(ShapeError, match="inputs u"):
        system.simulate(system.X.center, np.full((3, system.n_u), np.inf))


def test_unknown_system_names_the_choices():
    with pytest.raises(UnknownSystemError, match=r"unknown system 'pendulum'.*tank"):
        get_system("pendulum")


# ---------------------------------------------------------------- tank


@pytest.mark.parametrize(
    ("x", "u", "expected"),
    [
        # x1 = x1 − 0.5√x1 + 0.4u ; x2 = x2 + 0.2√x1 − 0.3√x2
        ((1.0, 1.0), 2.0, (1.0 - 0.5 + 0.8, 1.0 + 0.2 - 0.3)),
        ((4.0, 0.25), 0.0, (4.0 - 1.0, 0.25 + 0.4 - 0.15)),
        ((0.0, 0.0), 1.5, (0.6, 0.0)),
        # clipping at 0: a negative pump command empties the upper tank
        ((1.0, 0.04), -5.0, (0.0, 0.04 + 0.2 - 0.06)),
        # the lower tank drains below zero without clipping: 0.01 + 0 − 0.03 → 0
        ((0.0, 0.01), 0.0, (0.0, 0.0)),
    ],
)
def test_tank_step_matches_hand_computation(x, u, expected):
    tank = Tank()
    np.testing.assert_allclose(tank.step(x, [u]), expected, rtol=1e-14, atol=1e-15)
    assert tank.output(x, [u])[0] == x[1]


def test_tank_equilibrium_input_holds_the_level():
    tank = Tank()
    level = 2.5
    u = tank.equilibrium_input(level)
    # upper level at equilibrium: k1 √x1 = k2 u
    x1 = (0.4 * u / 0.5) ** 2
    np.testing.assert_allclose(tank.step([x1, level], [u]), [x1, level], rtol=1e-12)


def test_tank_refuses_an_analysis_set_touching_zero():
    with pytest.raises(SetError, match="eps must be > 0"):
        Tank(eps=0.0)


# ---------------------------------------------------------------- planar drone


def test_drone_hover_keeps_the_state_still():
    drone = Drone2D()
    omega = math.sqrt(drone.m * drone.g / (2 * drone.kT))
    assert omega == pytest.approx(110.7, abs=0.05)
    x = np.array([0.3, -1.2, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(drone.step(x, [omega, omega]), x, atol=1e-12)


def test_drone_positive_differential_gives_positive_angular_acceleration():
    drone = Drone2D()
    x = np.zeros(6)
    xdot = np.asarray(drone.ode(x, [100.0, 120.0])).ravel()
    expected = drone.kT * drone.L / drone.J * (120.0**2 - 100.0**2)
    assert xdot[5] == pytest.approx(expected, rel=1e-12)
    assert xdot[5] > 0


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(-2, 2), min_size=6, max_size=6),
    st.lists(st.floats(0, 250), min_size=2, max_size=2),
)
def test_drone_step_is_one_explicit_euler_step(x, u):
    drone = Drone2D()
    x = np.asarray(x)
    expected = x + drone.dt * np.asarray(drone.ode(x, u)).ravel()
    np.testing.assert_allclose(drone.step(x, u), expected, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(drone.output(x, u), x[:3])


def test_drone_open_loop_is_unstable():
    drone = Drone2D()
    omega = drone.hover_speed
    # Jacobian at hover: a tilt makes horizontal acceleration grow -> the pair (θ, vx) is
    # a double integrator chain; the linearisation has eigenvalues on or outside the unit circle
    x = ca.SX.sym("x", 6)
    jac = ca.Function("j", [x], [ca.jacobian(drone.f(x, [omega, omega]), x)])
    eig = np.linalg.eigvals(np.asarray(jac(np.zeros(6))))
    assert np.max(np.abs(eig)) >= 1.0 - 1e-12


# ---------------------------------------------------------------- linear


def test_linear_round_trip_against_the_matrices(rng):
    A = np.array([[0.5, 0.1], [0.0, 0.8]])
    B = np.array([[1.0], [0.5]])
    C = np.array([[1.0, -1.0]])
    D = np.array([[0.2]])
    sys_ = LinearSystem(A, B, C, D, dt=0.1)
    u = rng.normal(size=(20, 1))
    sim = sys_.simulate([1.0, -1.0], u)
    x = np.array([1.0, -1.0])
    for t in range(20):
        np.testing.assert_allclose(sim.x[t], x, atol=1e-14)
        np.testing.assert_allclose(sim.y[t], C @ x + D @ u[t], atol=1e-14)
        x = A @ x + B @ u[t]
    np.testing.assert_allclose(sim.x_final, x, atol=1e-14)


def test_linear_shape_mismatch_names_the_matrix():
    with pytest.raises(ShapeError, match=r"C must have shape \(1, 2\)"):
        LinearSystem(np.eye(2), np.ones((2, 1)), np.ones((1, 3)))


def test_box_validation():
    with pytest.raises(SetError, match="lower > upper"):
        Box([0.0, 1.0], [1.0, 0.5])
    with pytest.raises(SetError, match="finite"):
        Box([0.0], [np.inf])
    b = Box([0, -1], [2, 1])
    assert b.contains([1, 0]) and not b.contains([3, 0])
    assert b.radius == pytest.approx(math.sqrt(5))
