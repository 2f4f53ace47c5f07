"""The chain of three masses: closed forms of its linear part (modes, damping, RK4's eigenvalues),
energy of the unforced chain, accelerations as outputs, the documented mode table."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.cli import main
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import SetError, ShapeError
from canonid.models import MassChain, get_system

positive = st.floats(0.2, 5.0)
triples = st.tuples(positive, positive, positive)


def _matrices(mass, stiffness, damping):
    """M, K, C of wall–m1–m2–m3 with joints (k_i, c_i), written here from the chain's topology."""

    def chain(k):
        k1, k2, k3 = k
        return np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])

    return np.diag(mass), chain(stiffness), chain(damping)


def _state_matrix(mass, stiffness, damping):
    M, K, C = _matrices(mass, stiffness, damping)
    Minv = np.linalg.inv(M)
    return np.block([[np.zeros((3, 3)), np.eye(3)], [-Minv @ K, -Minv @ C]])


def _ode_jacobian(system, x):
    xs, us = ca.SX.sym("x", 6), ca.SX.sym("u", 1)
    jac = ca.Function("j", [xs, us], [ca.jacobian(system.ode(xs, us), xs)])
    return np.asarray(jac(x, [0.0]))


def _rk4_factor(z):
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def _energy(system, x):
    """Kinetic + spring energy, the cubic joint's included (its potential is cubic·q1⁴/4)."""
    M, K, _ = _matrices(system.mass, system.stiffness, system.damping)
    q, v = x[..., :3], x[..., 3:]
    return (
        0.5 * np.einsum("...i,ij,...j", v, M, v)
        + 0.5 * np.einsum("...i,ij,...j", q, K, q)
        + 0.25 * system.cubic * q[..., 0] ** 4
    )


def _sorted(values):
    return np.sort_complex(np.round(values, 10))


# ---------------------------------------------------------------- the registry's entry


def test_registered_with_names_and_units():
    system = get_system("masses")
    assert isinstance(system, MassChain)
    assert (system.n_x, system.n_u, system.n_y, system.dt) == (6, 1, 3, 0.02)
    assert system.output_names == ("a1", "a2", "a3")
    assert system.output_units == ("m/s^2",) * 3
    assert system.input_units == ("N",)


# ---------------------------------------------------------------- modes in closed form


@settings(max_examples=25, deadline=None)
@given(triples, triples, st.tuples(st.floats(0, 2), st.floats(0, 2), st.floats(0, 2)))
def test_linear_chain_eigenvalues_are_those_of_the_mass_spring_damper_matrices(m, k, c):
    system = MassChain(mass=m, stiffness=k, damping=c, cubic=0.0)
    expected = np.linalg.eigvals(_state_matrix(m, k, c))
    found = np.linalg.eigvals(_ode_jacobian(system, np.zeros(6)))
    np.testing.assert_allclose(_sorted(found), _sorted(expected), atol=1e-8)
    # undamped: ±i ω_j with ω_j² the eigenvalues of M⁻¹K
    M, K, _ = _matrices(m, k, c)
    omega2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    undamped = MassChain(mass=m, stiffness=k, damping=(0.0, 0.0, 0.0), cubic=0.0)
    jac = np.linalg.eigvals(_ode_jacobian(undamped, np.zeros(6)))
    np.testing.assert_allclose(np.abs(jac.real), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.sort(jac.imag[jac.imag > 0] ** 2), omega2, rtol=1e-9)


@settings(max_examples=25, deadline=None)
@given(triples, triples, st.tuples(st.floats(0, 2), st.floats(0, 2), st.floats(0, 2)))
def test_discrete_eigenvalues_are_rk4_of_the_continuous_ones(m, k, c):
    system = MassChain(mass=m, stiffness=k, damping=c, cubic=0.0, rate_hz=50.0)
    lam = np.linalg.eigvals(_state_matrix(m, k, c))
    f_x = system.linearise(np.zeros((1, 6)), np.zeros((1, 1))).f_x[0]
    np.testing.assert_allclose(
        _sorted(np.linalg.eigvals(f_x)), _sorted(_rk4_factor(lam * system.dt)), atol=1e-8
    )


def test_default_modes_match_the_closed_form_and_the_documented_table():
    system = get_system("masses")
    M, K, _ = _matrices(system.mass, system.stiffness, system.damping)
    omega = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    # fixed-free chain of 3 equal masses and springs: ω_j = 2 √(k/m) sin((2j−1)π/14)
    np.testing.assert_allclose(omega, 20 * np.sin(np.array([1, 3, 5]) * np.pi / 14), rtol=1e-12)
    # C = (c/k) K: modal damping ζ_j = (c/k) ω_j / 2, the real part of λ_j is −ζ_j ω_j
    zeta = 0.007 * omega / 2
    lam = np.linalg.eigvals(_state_matrix(system.mass, system.stiffness, system.damping))
    lam = lam[lam.imag > 0]
    np.testing.assert_allclose(np.sort(-lam.real), np.sort(zeta * omega), rtol=1e-9)
    # the module docstring's table, as printed
    np.testing.assert_allclose(omega, [4.4504, 12.4698, 18.0194], atol=5e-5)
    np.testing.assert_allclose(omega / (2 * np.pi), [0.7083, 1.9846, 2.8679], atol=5e-5)
    np.testing.assert_allclose(zeta, [0.01558, 0.04364, 0.06307], atol=5e-6)
    np.testing.assert_allclose(2 * np.pi / omega / system.dt, [70.6, 25.2, 17.4], atol=0.05)
    tau = 1 / (zeta[0] * omega[0])
    assert tau == pytest.approx(14.43, abs=0.005) and tau / system.dt == pytest.approx(721, abs=1)
    # well resolved and long: ≥ 10 samples per fastest period, ≥ 100 samples per slowest decay
    assert 2 * np.pi / omega[-1] / system.dt >= 10 and tau / system.dt >= 100


def test_cubic_joint_stiffens_the_wall_spring_by_three_cubic_q1_squared():
    system = get_system("masses")
    q1 = 0.1
    x = np.array([q1, 0, 0, 0, 0, 0.0])
    stiffer = (system.stiffness[0] + 3 * system.cubic * q1**2, *system.stiffness[1:])
    expected = _state_matrix(system.mass, stiffer, system.damping)
    np.testing.assert_allclose(_ode_jacobian(system, x), expected, rtol=1e-12, atol=1e-12)
    assert 3 * system.cubic * q1**2 / system.stiffness[0] == pytest.approx(0.3)


# ---------------------------------------------------------------- energy, unforced


def _mode_shape(system, j):
    M, K, _ = _matrices(system.mass, system.stiffness, system.damping)
    values, vectors = np.linalg.eig(np.linalg.solve(M, K))
    order = np.argsort(values.real)
    return np.sqrt(values.real[order[j]]), vectors.real[:, order[j]]


@pytest.mark.parametrize("mode", [0, 1, 2])
def test_undamped_linear_mode_loses_energy_exactly_as_rk4_predicts(mode):
    """RK4 on ż = A z, A normal with eigenvalues ±iω, scales a mode's energy by |R(iω dt)|² per
    step: slightly below 1, the scheme's own dissipation."""
    system = MassChain(damping=(0.0, 0.0, 0.0), cubic=0.0)
    omega, shape = _mode_shape(system, mode)
    x0 = np.concatenate([0.1 * shape / np.abs(shape).max(), np.zeros(3)])
    steps = 2000
    sim = system.simulate(x0, np.zeros((steps, 1)))
    ratio = _energy(system, sim.x_final) / _energy(system, x0)
    per_step = abs(_rk4_factor(1j * omega * system.dt)) ** 2
    assert per_step < 1
    assert ratio == pytest.approx(per_step**steps, rel=1e-9)


def test_undamped_chain_with_the_cubic_joint_keeps_its_energy():
    """The cubic joint is conservative: with RK4's own dissipation made negligible (1 kHz, about
    (ω dt)⁶ / 72 = 4e-13 per step on the fastest mode) the energy, quartic term included, stays
    put over several periods of the slowest mode."""
    x0 = np.array([0.3, -0.2, 0.4, 0.5, 0.0, -1.0])
    system = MassChain(damping=(0.0, 0.0, 0.0), rate_hz=1000.0)
    assert 0.25 * system.cubic * x0[0] ** 4 > 0.01 * _energy(system, x0)
    sim = system.simulate(x0, np.zeros((5000, 1)))
    energy = _energy(system, np.vstack([sim.x, sim.x_final]))
    np.testing.assert_allclose(energy, energy[0], rtol=1e-8)


def test_damped_slowest_mode_decays_at_twice_zeta_omega():
    """From the slowest mode's shape at rest, energy ∝ exp(−2 ζ1 ω1 t), up to a wobble of order
    ζ1 within each period."""
    system = MassChain(cubic=0.0)
    omega, shape = _mode_shape(system, 0)
    zeta = system.damping[0] / system.stiffness[0] * omega / 2
    x0 = np.concatenate([0.1 * shape / np.abs(shape).max(), np.zeros(3)])
    steps = 721  # one time constant
    sim = system.simulate(x0, np.zeros((steps, 1)))
    ratio = _energy(system, sim.x_final) / _energy(system, x0)
    assert ratio == pytest.approx(math.exp(-2 * zeta * omega * steps * system.dt), rel=0.05)


# ---------------------------------------------------------------- outputs and the step


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3),
    st.lists(st.floats(-3, 3), min_size=3, max_size=3),
    st.floats(-10, 10),
)
def test_outputs_are_the_accelerations(q, v, force):
    system = get_system("masses")
    x, u = np.array(q + v), [force]
    xdot = np.asarray(system.ode(x, u)).ravel()
    np.testing.assert_array_equal(system.output(x, u), xdot[3:])
    np.testing.assert_array_equal(xdot[:3], v)
    # the force moves only the free mass: feedthrough 1/m3 into a3, none into a1, a2
    shift = system.output(x, [force + 1.0]) - system.output(x, u)
    np.testing.assert_allclose(shift, [0.0, 0.0, 1.0 / system.mass[2]], atol=1e-9)


def test_step_is_one_rk4_step_of_the_ode(rng):
    system = get_system("masses")

    def ode(x, u):
        return np.asarray(system.ode(x, u)).ravel()

    h = system.dt
    for _ in range(5):
        x, u = system.X.sample(rng, 1)[0], system.U.sample(rng, 1)[0]
        k1 = ode(x, u)
        k2 = ode(x + h / 2 * k1, u)
        k3 = ode(x + h / 2 * k2, u)
        k4 = ode(x + h * k3, u)
        expected = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        np.testing.assert_allclose(system.step(x, u), expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mass": (1.0, 0.0, 1.0)}, "mass must be three finite numbers > 0"),
        ({"stiffness": (1.0, 1.0)}, "stiffness must be three finite numbers > 0"),
        ({"damping": (0.1, -0.1, 0.1)}, "damping must be three finite numbers >= 0"),
        ({"cubic": -1.0}, "cubic must be a finite number >= 0"),
        ({"force_max": math.inf}, "force_max must be a finite number > 0"),
    ],
)
def test_bad_parameters_are_named(kwargs, message):
    with pytest.raises(SetError, match=f"masses: {message}"):
        MassChain(**kwargs)


# ---------------------------------------------------------------- its identification data


def test_feedforward_applies_the_reference_as_the_command():
    from canonid.datagen.controllers.feedforward import Feedforward

    ctrl = Feedforward(2)
    reference = np.arange(10.0).reshape(5, 2)
    ctrl.reset(reference, np.zeros(6))
    for t in range(5):
        np.testing.assert_array_equal(ctrl(t, np.ones(6)).u, reference[t])
    with pytest.raises(ShapeError, match="feedforward reference"):
        ctrl.reset(np.zeros((5, 3)), np.zeros(6))


def _generate(folder, seed):
    argv = ["generate", "masses-id", "--out", str(folder), "--seed", str(seed), "--steps", "1000"]
    return main([*argv, "--n-train", "2", "--n-val", "1", "--n-test", "1", "--no-progress"])


def test_generate_masses_id_open_loop_multisine_same_seed_same_bytes(tmp_path, capsys):
    assert _generate(tmp_path / "a", 3) == 0 and _generate(tmp_path / "b", 3) == 0
    assert "informativeness (window 60)" in capsys.readouterr().out
    for name in ("dataset.npz", "dataset.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert _generate(tmp_path / "c", 4) == 0
    assert (tmp_path / "a" / "dataset.npz").read_bytes() != (
        tmp_path / "c" / "dataset.npz"
    ).read_bytes()

    ds = Dataset.load(tmp_path / "a")
    system = get_system("masses")
    assert ds.counts() == {"train": 2, "val": 1, "test": 1}
    assert ds.output_names == ("a1", "a2", "a3") and ds.dt == system.dt
    meta = ds.metadata
    assert meta["controller"]["type"] == "feedforward" and meta["scenario"]["name"] == "masses-id"
    assert meta["units"]["outputs"] == {"a1": "m/s^2", "a2": "m/s^2", "a3": "m/s^2"}
    for tr in ds.split("train"):
        assert tr.T == 1000 and np.all(tr.reference == 0.0)
        np.testing.assert_array_equal(tr.x[0], np.zeros(6))  # from rest
        # open loop: the applied force is the multisine alone, RMS 4 N, inside U
        assert np.sqrt(np.mean(tr.u**2)) == pytest.approx(4.0, rel=1e-9)
        assert np.all(np.abs(tr.u) <= system.U.hi)
        # the outputs are the accelerations of the recorded states, plus noise inside W
        np.testing.assert_allclose(tr.y_clean, system.h_batch(tr.x, tr.u), rtol=1e-12)
        assert np.all(np.abs(tr.y - tr.y_clean) <= 0.05)
        assert np.all(np.abs(tr.x) <= system.X.hi)
