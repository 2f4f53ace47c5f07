"""The development suite's generated systems: the Wiener–Hammerstein chain (and its small, noisy
record), the lightly damped vibrating structure, the Bouc–Wen oscillator and the drive with dry
friction. Closed forms of their linear parts, the invariants of their nonlinearities, and
``canonid generate`` end to end (same seed, same bytes)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.cli import main
from canonid.datagen.controllers.feedforward import Feedforward
from canonid.datagen.generate import dataset_excitation
from canonid.datagen.scenarios import get_scenario
from canonid.datagen.simulate import Excitation, simulate_closed_loop
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import SetError, ShapeError
from canonid.models import BoucWen, FrictionDrive, Vibration, WienerHammerstein, get_system
from canonid.models.registry import system_names

#: the suite's records: scenario → (system, samples per record for the end-to-end test, splits)
SUITE = {
    "wiener-hammerstein": ("wiener-hammerstein", 2000, {"train": 1, "val": 1, "test": 1}),
    "wiener-hammerstein-small": ("wiener-hammerstein", 1000, {"train": 1, "val": 1, "test": 1}),
    "vibration": ("vibration", 2000, {"train": 1, "val": 1, "test": 1}),
    "bouc-wen": ("bouc-wen", 2000, {"train": 1, "val": 1, "test": 1}),
    "friction-drive": ("friction-drive", 2000, {"train": 1, "val": 1, "test": 1}),
}
SYSTEMS = sorted({system for system, _, _ in SUITE.values()})


def _rk4_factor(z):
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def _sorted(values):
    return np.sort_complex(np.round(np.asarray(values, dtype=complex), 9))


def _ode_jacobian(system, x, u):
    xs, us = ca.SX.sym("x", system.n_x), ca.SX.sym("u", system.n_u)
    jac = ca.Function("j", [xs, us], [ca.jacobian(system.ode(xs, us), xs)])
    return np.asarray(jac(x, u))


def _f_jacobian(system, x, u):
    return system.linearise(np.atleast_2d(x), np.atleast_2d(u)).f_x[0]


def _constant(system, u, steps):
    """Simulate ``steps`` samples of the constant input ``u`` from rest; the last state."""
    return system.simulate(np.zeros(system.n_x), np.full((steps, system.n_u), u)).x_final


# ---------------------------------------------------------------- the registry and the scenarios


@pytest.mark.parametrize("scenario", sorted(SUITE))
def test_registered_with_a_scenario_units_and_parameters(scenario):
    name = SUITE[scenario][0]
    assert name in system_names()
    system = get_system(name)
    assert get_scenario(scenario).system == name and system.name == name
    for units in (system.state_units, system.input_units, system.output_units):
        assert all(isinstance(u, str) and u for u in units)
    described = system.describe()
    assert described["parameters"] and described["discretisation"]
    assert system.description and system.W.dim == system.n_y


@pytest.mark.parametrize("name", SYSTEMS)
def test_the_compiled_open_loop_flies_the_same_bytes_as_the_step_loop(name):
    system = get_system(name)
    rng = np.random.default_rng(5)
    T = 257  # not a multiple of the chunk: whole chunks and single steps
    reference = rng.uniform(system.U.lo, system.U.hi, size=(T, system.n_u)) * 0.3
    kwargs = {
        "x0": np.zeros(system.n_x),
        "excitation": Excitation(std=float(system.U.hi[0]) * 0.05),
        "clip_input": True,
    }
    compiled = Feedforward(system.n_u, system=system, chunk=50)
    assert compiled.compiled_loop() is not None
    fast = simulate_closed_loop(system, compiled, reference, rng=np.random.default_rng(1), **kwargs)
    slow = simulate_closed_loop(
        system, compiled, reference, rng=np.random.default_rng(1), step_by_step=True, **kwargs
    )
    for field in ("x", "u", "y", "y_clean"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field))


def test_the_feedforward_checks_its_system_and_chunk():
    with pytest.raises(ShapeError, match="has 1 inputs"):
        Feedforward(2, system=get_system("bouc-wen"))
    with pytest.raises(ShapeError, match="chunk must be an integer >= 1"):
        Feedforward(1, system=get_system("bouc-wen"), chunk=0)
    assert Feedforward(1).compiled_loop() is None


def _generate(folder, scenario, seed, capsys=None):
    _, steps, _ = SUITE[scenario]
    argv = ["generate", scenario, "--out", str(folder), "--seed", str(seed), "--no-progress"]
    if scenario != "wiener-hammerstein-small":  # its default is already small
        argv += ["--steps", str(steps)]
    return main(argv)


@pytest.mark.parametrize("scenario", sorted(SUITE))
def test_canonid_generate_end_to_end_same_seed_same_bytes(scenario, tmp_path, capsys):
    name, steps, _ = SUITE[scenario]
    assert _generate(tmp_path / "a", scenario, 3) == 0
    assert "dataset written to" in capsys.readouterr().out
    assert _generate(tmp_path / "b", scenario, 3) == 0
    for file in ("dataset.npz", "dataset.json"):
        assert (tmp_path / "a" / file).read_bytes() == (tmp_path / "b" / file).read_bytes()
    assert _generate(tmp_path / "c", scenario, 4) == 0
    other = (tmp_path / "c" / "dataset.npz").read_bytes()
    assert other != (tmp_path / "a" / "dataset.npz").read_bytes()

    ds = Dataset.load(tmp_path / "a")
    system, sc = get_system(name), get_scenario(scenario)
    meta = ds.metadata
    assert meta["controller"]["type"] == "feedforward" and meta["system"]["name"] == name
    assert meta["units"]["outputs"] == dict(zip(system.output_names, system.output_units))
    assert ds.dt == system.dt and ds.output_names == system.output_names
    half = np.full(system.n_y, sc.noise) if sc.noise is not None else system.W.hi
    assert meta["noise"]["box"]["upper"] == pytest.approx(list(half))
    for split in ("train", "val", "test"):
        excitation = dataset_excitation(ds, split)
        for tr, exc in zip(ds.split(split), excitation):
            if tr.info.get("samples", [0])[0] == 0:  # not a validation tail: from rest
                np.testing.assert_array_equal(tr.x[0], np.zeros(system.n_x))
            # open loop: the applied input is the regenerated excitation, inside U
            np.testing.assert_allclose(tr.u, system.U.clip(exc.total), rtol=0, atol=0)
            assert np.all(system.U.contains_rows(tr.u)) and np.all(system.X.contains_rows(tr.x))
            np.testing.assert_allclose(tr.y_clean, system.h_batch(tr.x, tr.u), rtol=1e-12)
            assert np.all(np.abs(tr.y - tr.y_clean) <= half)
    if scenario == "wiener-hammerstein-small":
        assert ds.counts() == {"train": 1, "val": 1, "test": 1}
        assert [tr.T for s in ("train", "val", "test") for tr in ds.split(s)] == [800, 200, 1000]
    else:
        assert ds.counts() == SUITE[scenario][2]
        assert all(tr.T == steps for s in ("train", "val", "test") for tr in ds.split(s))


def test_the_small_record_is_noisy_the_long_ones_are_not(tmp_path):
    assert _generate(tmp_path / "small", "wiener-hammerstein-small", 0) == 0
    assert _generate(tmp_path / "long", "wiener-hammerstein", 0) == 0
    ratios = {}
    for kind in ("small", "long"):
        tr = Dataset.load(tmp_path / kind).split("train")[0]
        ratios[kind] = np.std(tr.y - tr.y_clean) / np.std(tr.y_clean)
    assert 0.02 <= ratios["small"] <= 0.06 and ratios["long"] <= 0.01
    # the scenario's noise is recorded in the configuration, and --noise still overrides it
    generation = Dataset.load(tmp_path / "long").metadata["generation"]
    assert generation["noise"] == 0.003
    argv = ["generate", "wiener-hammerstein", "--out", str(tmp_path / "loud"), "--steps", "2000"]
    assert main([*argv, "--noise", "0.01", "--no-progress"]) == 0
    assert Dataset.load(tmp_path / "loud").metadata["noise"]["box"]["upper"] == [0.01]


@pytest.mark.parametrize(
    ("name", "kwargs", "message"),
    [
        ("wiener-hammerstein", {"g1": (1000.0, 6000.0, 0.25)}, "below Nyquist"),
        ("wiener-hammerstein", {"g2": (400.0, 1500.0, 1.0)}, "damping must lie in"),
        ("wiener-hammerstein", {"saturation": (0.0, 1.0)}, "saturation must be"),
        ("wiener-hammerstein", {"noise": -1.0}, "noise must be"),
        ("vibration", {"damping_ratio": (0.01, 0.02, 1.0)}, "damping_ratio must be"),
        ("vibration", {"mass": (1.0, 0.0, 1.0)}, "mass must be"),
        ("vibration", {"rate_hz": 50.0}, "below Nyquist"),
        ("vibration", {"substeps": 0}, "substeps must be"),
        ("bouc-wen", {"nu": 0.5}, "nu must be"),
        ("bouc-wen", {"beta": 100.0, "gamma": 500.0}, "keep the hysteretic force bounded"),
        ("bouc-wen", {"mass": math.nan}, "mass must be"),
        ("friction-drive", {"static": 0.5}, "must be at least the Coulomb"),
        ("friction-drive", {"smoothing": 0.001}, "use substeps >= 151"),
        ("friction-drive", {"inertia": 0.0}, "inertia must be"),
    ],
)
def test_bad_parameters_are_named(name, kwargs, message):
    with pytest.raises(SetError, match=f"{name}: .*{message}"):
        get_system(name, **kwargs)


# ---------------------------------------------------------------- Wiener–Hammerstein


def test_wiener_hammerstein_poles_are_the_exponentials_of_the_filters_whatever_the_curve(rng):
    system = WienerHammerstein()
    expected = _sorted(np.exp(system.poles() * system.dt))
    for x in (np.zeros(6), rng.uniform(-2, 2, 6)):
        f_x = _f_jacobian(system, x, [0.3])
        np.testing.assert_allclose(_sorted(np.linalg.eigvals(f_x)), expected, atol=1e-9)


def test_wiener_hammerstein_filters_are_the_zero_order_hold_of_their_transfer_functions():
    from scipy.signal import cont2discrete

    from canonid.models.wiener_hammerstein import filter_matrices

    system = WienerHammerstein()
    for spec, (Ad, Bd) in (
        (system.g1, (system.A1d, system.B1d)),
        (system.g2, (system.A2d, system.B2d)),
    ):
        A, B, C = filter_matrices(spec)
        a, w, zeta = 2 * math.pi * spec[0], 2 * math.pi * spec[1], spec[2]
        # the realisation has the documented transfer function: DC gain 1, these poles
        assert (C @ np.linalg.solve(-A, B)).item() == pytest.approx(1.0, rel=1e-12)
        poles = np.roots(np.polymul([1, a], [1, 2 * zeta * w, w**2]))
        np.testing.assert_allclose(_sorted(np.linalg.eigvals(A)), _sorted(poles), rtol=1e-9)
        ref_A, ref_B, *_ = cont2discrete((A, B, C, np.zeros((1, 1))), system.dt, method="zoh")
        np.testing.assert_allclose(Ad, ref_A, atol=1e-13)
        np.testing.assert_allclose(Bd, ref_B, atol=1e-13)


@pytest.mark.parametrize("u", [-0.8, -0.2, 0.0, 0.5, 1.5])
def test_wiener_hammerstein_settles_at_the_curve_of_its_input_and_the_linear_chain_at_it(u):
    for saturation in ((0.4, 1.0), (math.inf, math.inf)):
        system = WienerHammerstein(saturation=saturation)
        x = _constant(system, u, 1500)  # memory ≈ 50 samples
        assert x[1] == pytest.approx(u, abs=1e-12)  # w: G1 has DC gain 1
        expected = float(system.curve(u))
        assert system.output(x, [u])[0] == pytest.approx(expected, abs=1e-12)
    lower, upper = 0.4, 1.0
    assert float(WienerHammerstein().curve(u)) == pytest.approx(
        upper * math.tanh(u / upper) if u >= 0 else lower * math.tanh(u / lower), rel=1e-15
    )
    assert float(WienerHammerstein(saturation=(math.inf, math.inf)).curve(u)) == u


@settings(max_examples=40, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50))
def test_the_curve_is_a_monotone_clamp_with_slope_one_at_zero(a, b):
    system = WienerHammerstein()
    lo, hi = sorted((a, b))
    s_lo, s_hi = system.curve(lo), system.curve(hi)
    assert s_lo <= s_hi and -0.4 <= s_lo and s_hi <= 1.0
    # A clamp never amplifies; c·tanh(w/c) rounds up to one ulp above |w| where w is tiny.
    assert abs(system.curve(lo)) <= abs(lo) * (1 + 4 * np.finfo(float).eps)
    w = ca.SX.sym("w")
    slope = ca.Function("s", [w], [ca.jacobian(system._curve(w), w)])
    assert float(slope(1e-9)) == pytest.approx(1.0) and float(slope(-1e-9)) == pytest.approx(1.0)
    np.testing.assert_allclose(
        float(ca.Function("c", [w], [system._curve(w)])(lo)), system.curve(lo), rtol=1e-15
    )


# ---------------------------------------------------------------- the vibrating structure


def test_vibration_modes_match_the_closed_form_and_the_documented_table():
    system = Vibration(cubic=0.0)
    j = np.array([1, 3, 5])
    np.testing.assert_allclose(system.omega, 200 * np.sin(j * np.pi / 14), rtol=1e-12)
    lam = np.linalg.eigvals(_ode_jacobian(system, np.zeros(6), [0.0]))
    np.testing.assert_allclose(_sorted(lam), _sorted(system.poles()), atol=1e-8)
    upper = lam[lam.imag > 0]
    zeta = np.sort(-upper.real / np.abs(upper))
    np.testing.assert_allclose(zeta, [0.01, 0.015, 0.02], rtol=1e-9)
    # the module docstring's table, as printed
    np.testing.assert_allclose(system.omega, [44.504, 124.698, 180.194], atol=5e-4)
    np.testing.assert_allclose(system.omega / (2 * np.pi), [7.083, 19.846, 28.679], atol=5e-4)
    np.testing.assert_allclose(2 * np.pi / system.omega / system.dt, [28.2, 10.1, 7.0], atol=0.05)
    tau = 1 / (0.01 * system.omega[0])
    assert tau == pytest.approx(2.25, abs=0.005) and tau / system.dt == pytest.approx(449, abs=1)


@settings(max_examples=20, deadline=None)
@given(
    st.tuples(*[st.floats(0.5, 2.0)] * 3),
    st.tuples(*[st.floats(5e3, 2e4)] * 3),
    st.tuples(*[st.floats(0.0, 0.05)] * 3),
)
def test_every_mode_has_its_damping_ratio_and_rk4_gives_the_discrete_eigenvalues(m, k, zeta):
    system = Vibration(mass=m, stiffness=k, damping_ratio=zeta, cubic=0.0, rate_hz=400.0)
    lam = np.linalg.eigvals(_ode_jacobian(system, np.zeros(6), [0.0]))
    upper = lam[lam.imag > 0]
    order = np.argsort(np.abs(upper))
    np.testing.assert_allclose(-upper[order].real / np.abs(upper[order]), zeta, atol=1e-9)
    # ω_j: the eigenvalues of M⁻¹K, computed here from the chain's topology
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    omega = np.sqrt(np.sort(np.linalg.eigvals(np.diag(1 / np.asarray(m)) @ K).real))
    np.testing.assert_allclose(np.abs(upper[order]), omega, rtol=1e-9)
    h = system.dt / system.substeps
    f_x = _f_jacobian(system, np.zeros(6), [0.0])
    np.testing.assert_allclose(
        _sorted(np.linalg.eigvals(f_x)), _sorted(_rk4_factor(lam * h) ** system.substeps), atol=1e-8
    )


@pytest.mark.parametrize("d3", [0.0, 0.003, -0.007])
def test_the_cubic_joint_stiffens_k3_by_three_cubic_d3_squared(d3):
    system = get_system("vibration")
    x = np.array([0.0, 0.001, 0.001 + d3, 0.0, 0.0, 0.0])
    jac = _ode_jacobian(system, x, [0.0])
    # ∂a3/∂q3 = −(k3 + 3 cubic d3²) / m3
    tangent = system.stiffness[2] + 3 * system.cubic * d3**2
    assert -jac[5, 2] * system.mass[2] == pytest.approx(tangent, rel=1e-12)
    if abs(d3) > 0.007 - 1e-12:  # the docstring: 30 % near 7.1 mm
        assert 0.28 < 3 * system.cubic * d3**2 / system.stiffness[2] < 0.32


def test_vibration_outputs_are_the_accelerations_and_the_force_acts_on_mass_one(rng):
    system = get_system("vibration")
    x, force = rng.normal(scale=1e-3, size=6), 7.0
    np.testing.assert_allclose(
        system.output(x, [force]), np.asarray(system.ode(x, [force])).ravel()[3:], rtol=1e-14
    )
    # feedthrough: a unit force at rest accelerates mass 1 alone, by 1 / m1
    np.testing.assert_allclose(system.output(np.zeros(6), [1.0]), [1.0, 0.0, 0.0], atol=1e-15)


# ---------------------------------------------------------------- Bouc–Wen


def test_bouc_wen_with_a_linear_element_is_the_oscillator_of_stiffness_k_plus_alpha():
    system = BoucWen(beta=0.0, gamma=0.0)
    lam = np.linalg.eigvals(_ode_jacobian(system, np.zeros(3), [0.0]))
    np.testing.assert_allclose(_sorted(lam), _sorted(system.linear_poles()), atol=1e-9)
    omega = np.abs(system.linear_poles()[1])
    assert omega == pytest.approx(math.sqrt((2e4 + 1.5e4) / 1.0), rel=1e-12)  # 29.8 Hz
    assert omega / (2 * math.pi) == pytest.approx(29.8, abs=0.05)
    h = system.dt / system.substeps
    f_x = _f_jacobian(system, np.zeros(3), [0.0])
    np.testing.assert_allclose(
        _sorted(np.linalg.eigvals(f_x)), _sorted(_rk4_factor(lam * h) ** system.substeps), atol=1e-9
    )
    # and z − α y stays what it was: the linear element is a spring
    sim = system.simulate([0.0, 0.0, 0.0], np.full((200, 1), 3.0))
    np.testing.assert_allclose(sim.x[:, 2], system.alpha * sim.x[:, 0], atol=1e-9)


def _sine_response(system, amplitude, hz):
    """The last period of the response to a sine, closed, after 8 s (transients decay by e^-19)."""
    samples = round(1 / (hz * system.dt))
    periods = math.ceil(8 * hz)
    t = np.arange(periods * samples) * system.dt
    u = amplitude * np.sin(2 * np.pi * hz * t)[:, None]
    sim = system.simulate(np.zeros(3), u)
    return sim.x[-samples - 1 :], u[-samples - 1 :, 0]  # the last period, closed


@pytest.mark.parametrize(("amplitude", "hz"), [(10.0, 5.0), (25.0, 12.5), (40.0, 2.0)])
def test_bouc_wen_loops_dissipate_and_the_work_balances(amplitude, hz):
    system = get_system("bouc-wen")
    x, u = _sine_response(system, amplitude, hz)
    y, v, z = x[:, 0], x[:, 1], x[:, 2]
    assert abs(y[-1] - y[0]) < 1e-3 * np.ptp(y)  # periodic: the loop closes
    dy = np.diff(y)
    area = np.sum(0.5 * (z[1:] + z[:-1]) * dy)  # ∮ z dy
    assert area > 0.01 * np.ptp(z) * np.ptp(y)
    work = np.sum(u[:-1] * dy)  # the force is held over each sample: exact
    damper = system.damping * np.sum(0.5 * (v[1:] + v[:-1]) * dy)
    assert work == pytest.approx(damper + area, rel=0.02)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31), st.floats(5.0, 60.0))
def test_the_hysteretic_force_stays_below_its_bound(seed, scale):
    system = get_system("bouc-wen")
    u = np.clip(np.random.default_rng(seed).normal(scale=scale, size=(400, 1)), -60, 60)
    z = system.simulate(np.zeros(3), u).x[:, 2]
    assert system.z_max == pytest.approx(7.5)
    assert np.max(np.abs(z)) <= system.z_max * (1 + 1e-6)


def test_bouc_wen_four_substeps_agree_with_sixty_four_on_a_scenario_record():
    design = get_scenario("bouc-wen").design
    coarse, fine = get_system("bouc-wen"), BoucWen(substeps=64)
    u = design.signal(np.random.default_rng(0), 2000, coarse.dt, 1)
    a = coarse.simulate(np.zeros(3), u).y[:, 0]
    b = fine.simulate(np.zeros(3), u).y[:, 0]
    assert np.max(np.abs(a - b)) < 1e-3 * np.std(b)


# ---------------------------------------------------------------- the drive with dry friction


@settings(max_examples=60, deadline=None)
@given(st.floats(-50, 50))
def test_friction_opposes_the_motion_and_never_exceeds_the_breakaway_torque(omega):
    system = get_system("friction-drive")
    f = float(system.friction(omega))
    assert omega * f >= 0 and abs(f) <= system.static
    assert float(system.friction(-omega)) == -f
    w = ca.SX.sym("w")
    assert float(ca.Function("F", [w], [system._friction(w)])(omega)) == pytest.approx(
        f, rel=1e-14, abs=1e-300
    )


def test_without_dry_friction_the_drive_is_first_order_with_pole_minus_b_over_j():
    system = FrictionDrive(coulomb=0.0, static=0.0)
    h = system.dt / system.substeps
    f_x = _f_jacobian(system, [0.0], [0.0])
    assert f_x[0, 0] == pytest.approx(_rk4_factor(-0.3 / 0.1 * h) ** system.substeps, rel=1e-13)
    x = _constant(system, 1.2, 2000)  # 20 s, 60 time constants
    assert x[0] == pytest.approx(1.2 / 0.3, rel=1e-12)


def test_the_drive_slides_at_the_coulomb_speed_and_sticks_below_the_coulomb_torque():
    system = get_system("friction-drive")
    # far above T_s: (τ − T_c) / b, the Stribeck and tanh terms negligible at 13 rad/s
    assert _constant(system, 5.0, 2000)[0] == pytest.approx((5.0 - 1.0) / 0.3, rel=1e-12)
    assert _constant(system, -5.0, 2000)[0] == pytest.approx(-(5.0 - 1.0) / 0.3, rel=1e-12)
    # below T_c it creeps at less than ε atanh(|τ| / T_c)
    for tau in (0.5, -0.9):
        omega = _constant(system, tau, 2000)[0]
        assert np.sign(omega) == np.sign(tau)
        assert abs(omega) < system.smoothing * math.atanh(abs(tau) / system.coulomb)
