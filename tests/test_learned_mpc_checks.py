"""The model checks of benchmarks/learned_mpc.py on a learned model that is the true system.

The canonical model ŷ_t = a y_{t−1} + b u_{t−1} (ℓ = 1, one linear layer) is exactly
x⁺ = a x + b u, y = x: its open-loop predictions along any loop are the true outputs and its
response to an input step is the true one, b Σ a^i per unit step. A shift of the window by one
sample in the checks would show here as non-zero errors.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from canonid.kernel.network import CanonicalNet, Layer
from canonid.models.learned import LearnedSystem
from canonid.models.linear import LinearSystem
from canonid.models.sets import Box

A, B = 0.9, 0.5


@pytest.fixture
def bench(monkeypatch):
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    return importlib.import_module("learned_mpc")


def _model(a: float = A) -> LearnedSystem:
    net = CanonicalNet(
        window=1,
        n_u=1,
        n_y=1,
        feedthrough=False,
        layers=(Layer(np.array([[B, a]]), np.zeros(1), "linear"),),  # z = (u_{t−1}, y_{t−1})
        u_mean=np.zeros(1),
        u_std=np.ones(1),
        y_mean=np.zeros(1),
        y_std=np.ones(1),
    )
    box = Box([-10.0, -10.0], [10.0, 10.0])
    return LearnedSystem(
        net,
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
        X=box,
        U=Box([-1.0], [1.0]),
        W=Box([0.0], [0.0]),
    )


def _flight(true: LinearSystem, rng, T: int = 60) -> SimpleNamespace:
    u = rng.uniform(-1, 1, size=(T, 1))
    x = np.zeros((T, 1))
    x[0] = 0.3
    for t in range(T - 1):
        x[t + 1] = true.step(x[t], u[t])
    return SimpleNamespace(u=u, x=x, y=x.copy(), T=T)


def test_an_exact_model_predicts_the_loop_without_error(bench, rng):
    true = LinearSystem([[A]], [[B]], [[1.0]])
    flight = _flight(true, rng)
    steps = flight.T - 1  # the loop runs from sample ℓ = 1
    errors = bench.open_loop_errors(_model(), flight.u, flight.y, flight.y[1:], steps)
    assert errors is not None
    first, last = errors
    assert first.shape == last.shape == (steps - bench.HORIZON + 1, 1)
    np.testing.assert_allclose(first, 0.0, atol=1e-12)
    np.testing.assert_allclose(last, 0.0, atol=1e-12)
    _, wrong = bench.open_loop_errors(_model(0.8), flight.u, flight.y, flight.y[1:], steps)
    assert np.max(np.abs(wrong)) > 1e-3
    assert bench.open_loop_errors(_model(), flight.u, flight.y, flight.y[1:], 5) is None


def test_an_exact_model_answers_an_input_step_as_the_true_system(bench, rng):
    true = LinearSystem([[A]], [[B]], [[1.0]])
    case = bench.Case("linear", true, [0.0], [1.0], [1.0], [0], "", False, {"+1": [1.0]})
    flights = [_flight(true, rng) for _ in range(2)]
    true_change, learned_change = bench.input_response(_model(), case, flights, [1.0])
    assert true_change.shape == learned_change.shape == (10, 1)
    expected = B * sum(A**i for i in range(bench.HORIZON - 1))  # y after N samples, no feedthrough
    np.testing.assert_allclose(true_change, expected, rtol=1e-12)
    np.testing.assert_allclose(learned_change, expected, rtol=1e-12)


def test_an_exact_model_answers_a_step_from_rest_as_the_true_system(bench):
    true = LinearSystem([[A]], [[B]], [[1.0]])
    case = bench.Case(
        "linear", true, [0.0], [1.0], [1.0], [0], "", False, {"+1": [1.0]}, {"+1": [0]}, [0.0]
    )
    true_change, learned_change = bench.rest_response(_model(), case, [1.0])
    expected = B * sum(A**i for i in range(bench.HORIZON - 1))
    np.testing.assert_allclose(true_change, [expected], rtol=1e-12)
    np.testing.assert_allclose(learned_change, [expected], rtol=1e-12)
    assert bench.judge(true_change, learned_change, [0]) == {"ratios": [1.0], "ok": True}
    _, slower = bench.rest_response(_model(0.8), case, [1.0])
    assert not bench.judge(true_change, slower, [0])["ok"]  # a = 0.8: 0.57 of the change
    assert bench.judge(true_change, -learned_change, [0])["ratios"] == [-1.0]  # the wrong sign


def test_rows_name_the_design_and_the_rollout_length_that_differ_from_the_defaults(bench):
    design = {"kind": "multisine", "rms": 5.0}
    meta = {"scenario": {"name": "drone2d-id", "design": design}, "generation": {"design": design}}
    run = SimpleNamespace(dataset=SimpleNamespace(metadata=meta))
    assert bench.dataset_label(run) == "drone2d-id"
    meta["generation"]["design"] = {"kind": "multisine", "rms": 15.0}
    assert bench.dataset_label(run) == "drone2d-id, multisine RMS 15.0"
    paper = {"scenario": {"name": "drone2d"}, "generation": {"system": "drone2d"}}
    assert (
        bench.dataset_label(SimpleNamespace(dataset=SimpleNamespace(metadata=paper))) == "drone2d"
    )
    quick = bench.PROFILES["quick"]["train"]["horizon"]
    recipe = {"model": "mlp", "profile": "quick", "train_options": {"horizon": quick}}
    assert bench.model_label(recipe) == "mlp"
    recipe["train_options"]["horizon"] = 10
    assert bench.model_label(recipe) == "mlp, horizon 10"
    assert bench.model_label({**recipe, "model": "arx"}) == "arx"
