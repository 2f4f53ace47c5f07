"""The NMPC's output-reference option (track="output"): closed forms on linear systems."""

from __future__ import annotations

import numpy as np
import pytest

from canonid.datagen.controllers.nmpc import NMPC
from canonid.kernel.errors import ShapeError
from canonid.models.linear import LinearSystem

A = np.array([[0.8, 0.2], [-0.2, 0.8]])
B = np.array([[0.5], [1.0]])


def _run(nmpc: NMPC, system: LinearSystem, reference: np.ndarray, steps: int) -> np.ndarray:
    x = np.zeros(system.n_x)
    nmpc.reset(reference, x)
    ys = []
    for t in range(steps):
        step = nmpc(t, x)
        assert step.ok
        ys.append(system.output(x, step.u))
        x = system.step(x, step.u)
    return np.array(ys)


def test_an_output_reference_is_reached_with_the_steady_state_input():
    """y = x1: with u_eq the input that holds y = r, the optimum's steady state is y = r."""
    system = LinearSystem(A, B, [[1.0, 0.0]])
    r = 0.4
    dc_gain = (system.C @ np.linalg.solve(np.eye(2) - A, B)).item()
    nmpc = NMPC(
        system,
        u_eq=[r / dc_gain],
        horizon=15,
        track="output",
        output_weights=[10.0],
        input_weights=[0.1],
        terminal="none",
        solver="fatrop",
        tol=1e-8,
    )
    y = _run(nmpc, system, np.full((60, 1), r), 60)
    assert abs(y[-1, 0] - r) < 1e-5 and abs(y[0, 0]) < 1e-12


def test_output_tracking_with_h_the_identity_is_state_tracking():
    """C = I: ‖h(x) − r‖²_Q is ‖x − r‖²_Q, so both options plan the same inputs."""
    system = LinearSystem(A, B, np.eye(2))
    common = {"u_eq": [0.0], "horizon": 8, "input_weights": [0.5], "terminal": "none"}
    common.update(solver="fatrop", tol=1e-9)
    by_state = NMPC(system, state_weights=[3.0, 1.0], **common)
    by_output = NMPC(system, track="output", output_weights=[3.0, 1.0], **common)
    ref = np.column_stack([np.linspace(0, 0.5, 30), np.linspace(0, -0.3, 30)])
    np.testing.assert_allclose(
        _run(by_output, system, ref, 20), _run(by_state, system, ref, 20), rtol=0, atol=1e-6
    )
    assert by_output.settings()["track"] == "output"
    assert by_output.settings()["output_weights"] == [3.0, 1.0]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"track": "output", "state_weights": [1.0, 1.0]}, "needs output_weights"),
        ({"track": "output", "output_weights": [1.0], "terminal": "lqr"}, "terminal='none'"),
        ({"track": "outputs", "output_weights": [1.0]}, "track must be 'state' or 'output'"),
        ({"track": "output", "output_weights": [1.0, 2.0]}, "output_weights must have shape"),
    ],
)
def test_bad_output_options_are_refused(kwargs, message):
    system = LinearSystem(A, B, [[1.0, 0.0]])
    options = {"u_eq": [0.0], "input_weights": [1.0], "terminal": "none", "solver": "fatrop"}
    with pytest.raises(ShapeError, match=message):
        NMPC(system, **{**options, **kwargs})


def test_auto_does_not_compile_a_large_prediction_model(monkeypatch):
    """Above COMPILE_LIMIT SX instructions "auto" keeps the plugin (no gcc run at all)."""
    import canonid.datagen.controllers.nmpc as nmpc_module

    def no_compiler(*args, **kwargs):
        raise AssertionError("compile_functions was called")

    monkeypatch.setattr(nmpc_module, "compile_functions", no_compiler)
    monkeypatch.setattr(nmpc_module, "COMPILE_LIMIT", 1)
    system = LinearSystem(A, B, [[1.0, 0.0]])
    options = {"u_eq": [0.0], "input_weights": [1.0], "terminal": "none", "solver": "auto"}
    nmpc = NMPC(system, track="output", output_weights=[1.0], **options)
    assert nmpc.solver_used == "fatrop"
