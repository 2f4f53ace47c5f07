"""The simulated quadrotor (Blackbird stand-in) and its cascaded controller.

Closed forms: hover, a pure yaw torque, free fall, tilted thrust, rotor drag; invariants: unit
quaternion over long runs, RK4's fifth-order local error, the IMU against finite differences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from canonid.datagen.controllers.quadrotor_cascade import CascadeGains, QuadrotorCascade
from canonid.datagen.quadrotor_reference import quadrotor_reference
from canonid.kernel.errors import SetError, ShapeError
from canonid.models import Quadrotor, get_system


@pytest.fixture(scope="module")
def quad() -> Quadrotor:
    sys_ = get_system("quadrotor")
    assert isinstance(sys_, Quadrotor)
    return sys_


def _yaw_quaternion(psi: float) -> np.ndarray:
    return np.array([math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)])


def _state(p=(0, 0, 0), v=(0, 0, 0), q=(1, 0, 0, 0), w=(0, 0, 0)) -> np.ndarray:
    return np.concatenate([p, v, q, w]).astype(np.float64)


def _random_unit_states(rng: np.random.Generator, n: int, rate: float = 3.0) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.hstack(
        [
            rng.uniform(-2, 2, (n, 3)),
            rng.uniform(-3, 3, (n, 3)),
            q,
            rng.uniform(-rate, rate, (n, 3)),
        ]
    )


# ---------------------------------------------------------------- identity and parameters


def test_named_as_simulated_stand_in(quad):
    assert quad.simulated_stand_in_for == "Blackbird UAV dataset (real flights)"
    assert "SIMULATED" in quad.description
    d = quad.describe()
    assert d["parameters"]["simulated"] is True
    assert (quad.n_x, quad.n_u, quad.n_y, quad.dt) == (13, 4, 6, 0.02)


def test_hover_speed_closed_form(quad):
    # kT = 2.27e-8 N/rpm² · (60/2π)² ; Ω_h = √(m g / 4 kT)
    kT = 2.27e-8 * (60 / (2 * math.pi)) ** 2
    assert quad.kT == pytest.approx(kT, rel=1e-15)
    assert quad.hover_speed == pytest.approx(math.sqrt(0.915 * 9.81 / (4 * kT)), rel=1e-14)
    assert quad.hover_speed == pytest.approx(1041.19, abs=0.01)


def test_bad_parameters_are_refused():
    with pytest.raises(SetError, match="cannot lift"):
        Quadrotor(omega_max=500.0)
    with pytest.raises(SetError, match="J must be"):
        Quadrotor(J=(1e-3, 0.0, 1e-3))
    with pytest.raises(SetError, match="m must be"):
        Quadrotor(m=-1.0)
    with pytest.raises(SetError, match="noise must be two half-widths"):
        Quadrotor(noise=(0.1,))  # type: ignore[arg-type]


# ---------------------------------------------------------------- closed forms


@pytest.mark.parametrize("psi", [0.0, 0.7, -2.5, math.pi])
def test_hover_thrust_balances_gravity(quad, psi):
    """Level, at rest, all rotors at Ω_h: the state is a fixed point and the IMU reads +g, 0."""
    x = _state(p=(0.3, -1.0, 2.0), q=_yaw_quaternion(psi))
    u = [quad.hover_speed] * 4
    np.testing.assert_allclose(quad.step(x, u), x, atol=1e-12)
    np.testing.assert_allclose(quad.output(x, u), [0, 0, quad.g, 0, 0, 0], atol=1e-12)


def test_pure_yaw_torque_spins_about_z_only(quad):
    """Ω1² = Ω3² = Ω_h² + δ, Ω2² = Ω4² = Ω_h² − δ: no roll/pitch torque, thrust still m g, so
    ωz = α t with α = 4 k_D δ / Jz, yaw ψ = α t² / 2, and nothing else moves."""
    h2, delta = quad.hover_speed**2, 2.0e4
    u = np.sqrt([h2 + delta, h2 - delta, h2 + delta, h2 - delta])
    steps = 100
    sim = quad.simulate(quad.hover_state(), np.tile(u, (steps, 1)))
    t = np.arange(steps + 1) * quad.dt
    x = np.vstack([sim.x, sim.x_final])
    alpha = 4 * quad.kD * delta / quad.J[2]
    np.testing.assert_allclose(x[:, 10:12], 0.0, atol=1e-12)  # ωx, ωy: rounding only
    np.testing.assert_allclose(x[:, 12], alpha * t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(x[:, 0:6], 0.0, atol=1e-12)  # position and velocity
    psi = 0.5 * alpha * t**2
    expected_q = np.array([_yaw_quaternion(p) for p in psi])
    np.testing.assert_allclose(x[:, 6:10], expected_q, atol=1e-9)
    # IMU: specific force +g along body z, gyro reads (0, 0, ωz)
    np.testing.assert_allclose(sim.y[:, 0:3], np.tile([0, 0, quad.g], (steps, 1)), atol=1e-12)
    np.testing.assert_allclose(sim.y[:, 3:6], x[:-1, 10:13], atol=0)


def test_free_fall_reads_zero_and_tilted_thrust_reads_thrust_over_mass(quad):
    x = _state(q=(math.cos(0.2), math.sin(0.2), 0.0, 0.0))  # rolled by 0.4 rad, at rest
    np.testing.assert_allclose(quad.output(x, [0, 0, 0, 0]), 0.0, atol=1e-15)
    u = np.full(4, 900.0)
    thrust = 4 * quad.kT * 900.0**2
    np.testing.assert_allclose(quad.output(x, u)[:3], [0, 0, thrust / quad.m], rtol=1e-14)


def test_rotor_drag_appears_on_the_accelerometer_in_body_axes(quad):
    """Yawed by +90°: world +x is body −y, so a world velocity vx = 1 m/s reads +dy on acc_y."""
    _, dy, dz = quad.drag
    x = _state(v=(1.0, 0.0, -2.0), q=_yaw_quaternion(math.pi / 2))
    acc = quad.output(x, [0, 0, 0, 0])[:3]
    np.testing.assert_allclose(acc, [0.0, dy * 1.0, dz * 2.0], atol=1e-14)


def test_single_rotor_torque_matches_the_x_layout(quad):
    """Rotor 1 sits at (+a, +a): extra thrust ΔT there gives τ = (a ΔT, −a ΔT, k_D ΔΩ²)."""
    h = quad.hover_speed
    bump = 50.0
    d_sq = (h + bump) ** 2 - h**2
    xdot = np.asarray(quad.ode(quad.hover_state(), [h + bump, h, h, h])).ravel()
    a = quad.arm_length / math.sqrt(2)
    tau = np.array([a * quad.kT * d_sq, -a * quad.kT * d_sq, quad.kD * d_sq])
    np.testing.assert_allclose(xdot[10:13], tau / np.asarray(quad.J), rtol=1e-12)
    np.testing.assert_allclose(xdot[5], quad.kT * d_sq / quad.m, rtol=1e-9)


# ---------------------------------------------------------------- invariants


def test_quaternion_stays_unit_norm_over_a_long_simulation(quad):
    """20 000 steps (400 s) of tumbling under oscillating differential thrust: ‖q‖ = 1 to
    rounding at every step, while plain RK4 (no renormalisation) drifts measurably."""
    steps = 20_000
    t = np.arange(steps) * quad.dt
    h2 = quad.hover_speed**2
    d = 3.0e4
    u_sq = np.column_stack(
        [
            h2 + d * np.sin(1.3 * t),
            h2 + d * np.sin(0.7 * t + 1.0),
            h2 - d * np.sin(1.3 * t),
            h2 - d * np.sin(0.7 * t + 1.0),
        ]
    )
    sim = quad.simulate(quad.hover_state(), np.sqrt(u_sq))
    norms = np.linalg.norm(sim.x[:, 6:10], axis=1)
    assert np.max(np.abs(sim.x[:, 10:13])) > 2.0  # it really rotates
    assert np.max(np.abs(norms - 1.0)) < 1e-13

    # the same run with plain RK4 drifts: the renormalisation is what keeps the norm
    ode = quad.ode
    x = quad.hover_state()
    dt = quad.dt
    for k in range(2000):
        uk = np.sqrt(u_sq[k])
        k1 = np.asarray(ode(x, uk)).ravel()
        k2 = np.asarray(ode(x + dt / 2 * k1, uk)).ravel()
        k3 = np.asarray(ode(x + dt / 2 * k2, uk)).ravel()
        k4 = np.asarray(ode(x + dt * k3, uk)).ravel()
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert abs(np.linalg.norm(x[6:10]) - 1.0) > 1e-11


def test_rk4_local_error_is_fifth_order(rng):
    """One step against a tight adaptive solution: halving dt divides the error by ≈ 2⁵."""
    errors = []
    x0 = _random_unit_states(rng, 1, rate=6.0)[0]
    u = rng.uniform(700, 1400, 4)
    for rate_hz in (50.0, 100.0):
        sys_ = Quadrotor(rate_hz=rate_hz)
        ode = sys_.ode
        ref = solve_ivp(
            lambda _t, x, ode=ode: np.asarray(ode(x, u)).ravel(),
            (0.0, sys_.dt),
            x0,
            method="DOP853",
            rtol=1e-13,
            atol=1e-13,
        ).y[:, -1]
        errors.append(np.linalg.norm(sys_.step(x0, u) - ref))
    ratio = errors[0] / errors[1]
    assert 20.0 < ratio < 45.0, (errors, ratio)


def test_accelerometer_is_specific_force_from_finite_differences(rng):
    """Rᵀ (Δv/Δt − g_W) on a 10 kHz simulation matches the accelerometer channel of h."""
    sys_ = Quadrotor(rate_hz=10_000.0)
    for x0 in _random_unit_states(rng, 5):
        u = rng.uniform(600, 1500, 4)
        x1 = sys_.step(x0, u)
        x2 = sys_.step(x1, u)
        v_dot = (x2[3:6] - x0[3:6]) / (2 * sys_.dt)  # central difference at x1
        w, qx, qy, qz = x1[6:10]
        R = np.array(
            [
                [1 - 2 * (qy**2 + qz**2), 2 * (qx * qy - w * qz), 2 * (qx * qz + w * qy)],
                [2 * (qx * qy + w * qz), 1 - 2 * (qx**2 + qz**2), 2 * (qy * qz - w * qx)],
                [2 * (qx * qz - w * qy), 2 * (qy * qz + w * qx), 1 - 2 * (qx**2 + qy**2)],
            ]
        )
        expected = R.T @ (v_dot - np.array([0.0, 0.0, -sys_.g]))
        np.testing.assert_allclose(sys_.output(x1, u)[:3], expected, atol=1e-5)


# ---------------------------------------------------------------- the cascaded controller


def _closed_loop(quad, ctrl, reference, x0):
    ctrl.reset(reference, x0)
    x = np.asarray(x0, dtype=np.float64)
    xs, us, infos = [], [], []
    for t in range(len(reference)):
        step = ctrl(t, x)
        xs.append(x)
        us.append(step.u)
        infos.append(step.info)
        x = quad.step(x, step.u)
    return np.array(xs), np.array(us), infos


def test_controller_at_hover_commands_hover_speed(quad):
    ctrl = QuadrotorCascade(quad)
    ref = np.tile([0.5, -0.5, 1.0, 0, 0, 0, 0.3], (5, 1))
    x = _state(p=(0.5, -0.5, 1.0), q=_yaw_quaternion(0.3))
    ctrl.reset(ref, x)
    step = ctrl(0, x)
    np.testing.assert_allclose(step.u, quad.hover_speed, rtol=1e-10)
    np.testing.assert_allclose(quad.output(x, step.u), [0, 0, quad.g, 0, 0, 0], atol=1e-8)


def test_controller_tracks_a_slow_reference_with_small_error(quad):
    """A 1 m circle at 0.5 rad/s with a slow climb and yaw sweep, from 1 m away in yaw: after
    2 s the position error stays below 10 % of the radius and the yaw error below 0.05 rad."""
    T = 1000
    t = np.arange(T) * quad.dt
    ref = np.column_stack(
        [
            np.cos(0.5 * t),
            np.sin(0.5 * t),
            0.5 * np.sin(0.3 * t),
            -0.5 * np.sin(0.5 * t),
            0.5 * np.cos(0.5 * t),
            0.15 * np.cos(0.3 * t),
            0.8 * np.sin(0.2 * t),
        ]
    )
    xs, _, infos = _closed_loop(quad, QuadrotorCascade(quad), ref, quad.hover_state((1, 0, 0)))
    err = np.linalg.norm(xs[100:, 0:3] - ref[100:, 0:3], axis=1)
    assert err.max() < 0.1
    yaw = 2 * np.arctan2(xs[100:, 9], xs[100:, 6])  # no roll/pitch part to speak of here
    yaw_err = np.angle(np.exp(1j * (yaw - ref[100:, 6])))
    assert np.max(np.abs(yaw_err)) < 0.05
    assert not any(i["saturated"] for i in infos)


def test_controller_saturates_to_U_on_an_aggressive_step(quad):
    ref = np.tile([10.0, -10.0, 20.0, 0, 0, 0, 3.0], (150, 1))  # far beyond what U allows
    xs, us, infos = _closed_loop(quad, QuadrotorCascade(quad), ref, quad.hover_state())
    assert quad.U.contains(us)
    assert any(i["saturated"] for i in infos) and any(i["tilt_limited"] for i in infos)
    # the tilt limit holds: body z stays within max_tilt (+ transient margin) of vertical
    qw, qx, qy = xs[:, 6], xs[:, 7], xs[:, 8]
    cos_tilt = 1 - 2 * (qx**2 + qy**2)
    assert np.degrees(np.arccos(np.clip(cos_tilt, -1, 1))).max() < 60.0
    assert np.all(np.isfinite(xs)) and np.all(np.abs(qw) <= 1.0)


def test_controller_errors_name_the_problem(quad):
    ctrl = QuadrotorCascade(quad)
    with pytest.raises(ShapeError, match=r"quadrotor reference must have shape \(T, 7\)"):
        ctrl.reset(np.zeros((10, 3)), quad.hover_state())
    with pytest.raises(ShapeError, match="outside the reference"):
        ctrl(0, quad.hover_state())
    with pytest.raises(ShapeError, match=r"flies a canonid\.models\.quadrotor\.Quadrotor"):
        QuadrotorCascade(get_system("drone2d"))  # type: ignore[arg-type]
    settings = QuadrotorCascade(quad, gains=CascadeGains(max_tilt_deg=20.0)).settings()
    assert settings["gains"]["max_tilt_deg"] == 20.0
    assert settings["reference_columns"] == ["px", "py", "pz", "vx", "vy", "vz", "yaw"]


# ---------------------------------------------------------------- random 3-D references


def test_reference_is_a_seeded_smooth_spline_with_its_derivative():
    ref = quadrotor_reference(np.random.default_rng(7), steps=500, dt=0.02)
    assert ref.shape == (500, 7)
    np.testing.assert_array_equal(ref, quadrotor_reference(np.random.default_rng(7), steps=500))
    assert not np.array_equal(ref, quadrotor_reference(np.random.default_rng(8), steps=500))
    # velocity columns are the derivative of the position columns (central differences, O(dt²))
    fd = (ref[2:, 0:3] - ref[:-2, 0:3]) / (2 * 0.02)
    np.testing.assert_allclose(fd, ref[1:-1, 3:6], atol=1e-2)
    assert np.max(np.abs(np.diff(ref[:, 6]))) < 0.2  # unwrapped yaw: no ±2π jumps
    assert np.max(np.abs(ref[:, 0:3])) <= 4.0 and np.max(np.abs(ref[:, 3:6])) <= 6.0


def test_reference_limits_and_arguments_are_enforced():
    with pytest.raises(ShapeError, match="no spline within"):
        quadrotor_reference(np.random.default_rng(0), speed_limit=1e-3, max_draws=3)
    with pytest.raises(ShapeError, match="waypoints"):
        quadrotor_reference(np.random.default_rng(0), waypoints=(1, 3))
    with pytest.raises(ShapeError, match="box must be"):
        quadrotor_reference(np.random.default_rng(0), box=((0, 1), (0, 1)))
