"""The NMPC's Gauss-Newton SQP option (hessian="gauss-newton") against the exact-Hessian NLP."""

from __future__ import annotations

import numpy as np
import pytest

from canonid.datagen.controllers.nmpc import NMPC
from canonid.kernel.errors import ShapeError
from canonid.kernel.network import CanonicalNet, Layer
from canonid.models.base import System
from canonid.models.learned import LearnedSystem
from canonid.models.linear import LinearSystem
from canonid.models.sets import Box
from canonid.models.tank import Tank

A = np.array([[0.8, 0.2], [-0.2, 0.8]])
B = np.array([[0.5], [1.0]])
AUTO = {"hessian": "gauss-newton", "solver": "auto"}
GAUSS_NEWTON = {"hessian": "gauss-newton", "sqp_tol": 1e-8, "sqp_max_iter": 50}


def _loop(nmpc: NMPC, system: System, reference: np.ndarray, x0, steps: int):
    x = np.asarray(x0, dtype=np.float64)
    nmpc.reset(reference, x)
    us, statuses = [], []
    for t in range(steps):
        step = nmpc(t, x)
        assert step.ok, step.info
        us.append(step.u)
        statuses.append(step.info["status"])
        x = system.step(x, step.u)
    return np.array(us), statuses


def test_on_a_linear_system_one_quadratic_programme_is_the_exact_plan():
    """Linear f and h: the linearisation is exact, so the first QP is the NLP and the second
    confirms it (the condensed programme is solved exactly by DAQP)."""
    system = LinearSystem(A, B, [[1.0, 0.0]])
    common = {"u_eq": [0.0], "horizon": 10, "input_weights": [0.1], "terminal": "none"}
    common.update(solver="fatrop", tol=1e-9, track="output", output_weights=[5.0])
    exact = NMPC(system, **common)
    gauss_newton = NMPC(system, **{**common, "solver": "auto"}, hessian="gauss-newton")
    ref = np.column_stack([np.linspace(0.0, 0.6, 30)])
    u_exact, _ = _loop(exact, system, ref, [0.0, 0.0], 15)
    u_gn, statuses = _loop(gauss_newton, system, ref, [0.0, 0.0], 15)
    np.testing.assert_allclose(u_gn, u_exact, rtol=0, atol=1e-6)
    assert all(s == "ok (SQP, 2 QPs)" for s in statuses)
    assert gauss_newton.compiled_loop() is None
    assert gauss_newton.settings()["hessian"] == "gauss-newton"


@pytest.mark.parametrize("track", ["state", "output"])
def test_on_the_tank_both_hessians_plan_the_same_inputs(track):
    """A fixed point of the SQP is a KKT point of the NLP: the same inputs up to the tolerances."""
    tank = Tank()
    u_eq = [tank.equilibrium_input(2.0)]
    common = {"u_eq": u_eq, "horizon": 8, "input_weights": [1e-2], "terminal": "none"}
    common.update(solver="fatrop", tol=1e-8)
    if track == "state":
        common.update(state_weights=[1.0, 0.1])
        ref = np.tile([2.5, 2.5], (20, 1))
    else:
        common.update(track="output", output_weights=[1.0])
        ref = np.full((20, 1), 2.5)
    x0 = [2.0, 2.0]
    u_exact, _ = _loop(NMPC(tank, **common), tank, ref, x0, 12)
    gn = NMPC(tank, **{**common, "solver": "auto"}, **GAUSS_NEWTON)
    u_gn, statuses = _loop(gn, tank, ref, x0, 12)
    np.testing.assert_allclose(u_gn, u_exact, rtol=0, atol=1e-5)
    assert not any("limit" in s for s in statuses)


def test_a_learned_model_runs_with_its_numpy_linearisation(rng):
    """2 inputs, 1 output, ℓ = 3, SiLU, residual, an affine path; the SQP reads the numpy
    Jacobians of ``LearnedSystem.linearise``."""
    layers = (Layer(0.3 * rng.normal(size=(6, 9)), 0.1 * rng.normal(size=6), "silu"),)
    layers += (Layer(0.3 * rng.normal(size=(1, 6)), np.zeros(1)),)
    net = CanonicalNet(
        window=3,
        n_u=2,
        n_y=1,
        feedthrough=False,
        layers=layers,
        u_mean=np.zeros(2),
        u_std=np.ones(2),
        y_mean=np.zeros(1),
        y_std=np.ones(1),
        residual_scale=np.array([0.5]),
        affine=(0.1 * rng.normal(size=(1, 9)), np.zeros(1)),
    )
    d = net.state_dim
    system = LearnedSystem(
        net,
        dt=0.1,
        input_names=[f"u{i}" for i in range(net.n_u)],
        output_names=[f"y{i}" for i in range(net.n_y)],
        X=Box(-np.ones(d), np.ones(d)),
        U=Box(-np.ones(net.n_u), np.ones(net.n_u)),
        W=Box(np.zeros(net.n_y), np.zeros(net.n_y)),
    )
    common = {"u_eq": np.zeros(net.n_u), "horizon": 5, "input_weights": np.ones(net.n_u)}
    common.update(solver="fatrop", tol=1e-8, terminal="none", track="output")
    common.update(output_weights=np.ones(net.n_y))
    ref = np.full((10, net.n_y), 0.1)
    u_exact, _ = _loop(NMPC(system, **common), system, ref, np.zeros(d), 4)
    gn = NMPC(system, **{**common, "solver": "auto"}, **GAUSS_NEWTON)
    u_gn, _ = _loop(gn, system, ref, np.zeros(d), 4)
    np.testing.assert_allclose(u_gn, u_exact, rtol=0, atol=1e-5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"hessian": "bfgs"}, "hessian must be one of"),
        ({"hessian": "gauss-newton"}, "leave solver='auto'"),
        ({**AUTO, "sqp_max_iter": 0}, "sqp_max_iter must be an integer"),
        ({**AUTO, "sqp_tol": 0.0}, "sqp_tol > 0"),
    ],
)
def test_bad_gauss_newton_options_are_refused(kwargs, message):
    system = LinearSystem(A, B, [[1.0, 0.0]])
    options = {"u_eq": [0.0], "input_weights": [1.0], "terminal": "none", "solver": "fatrop"}
    options.update(track="output", output_weights=[1.0])
    with pytest.raises(ShapeError, match=message):
        NMPC(system, **{**options, **kwargs})
