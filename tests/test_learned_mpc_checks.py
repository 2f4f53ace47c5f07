"""The model checks of benchmarks/studies/learned_mpc/learned_mpc.py on a learned model that is
the true system.

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
    monkeypatch.syspath_prepend(
        str(Path(__file__).resolve().parents[1] / "benchmarks" / "studies" / "learned_mpc")
    )
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


def test_the_response_by_size_is_the_closed_form_at_every_sample_and_scale(bench, rng):
    true = LinearSystem([[A]], [[B]], [[1.0]])
    case = bench.Case("linear", true, [0.0], [1.0], [1.0], [0], "", False, {"+1": [1.0]})
    flights = [_flight(true, rng) for _ in range(2)]
    true_paths, learned_paths = bench.response_paths(_model(), case, flights, [1.0])
    assert true_paths.shape == (10, bench.HORIZON, 1)
    # y_k changes by B Σ_{i<k−1} a^i after k samples (no feedthrough: nothing at the first)
    expected = [B * sum(A**i for i in range(k - 1)) for k in range(1, bench.HORIZON + 1)]
    np.testing.assert_allclose(true_paths[..., 0], np.tile(expected, (10, 1)), atol=1e-12)
    np.testing.assert_allclose(learned_paths, true_paths, atol=1e-12)
    rows = bench.response_by_size(_model(0.8), case, flights, [1.0], [0])
    assert [(r["scale"], r["samples"]) for r in rows] == [
        (s, k) for s in bench.STEP_SCALES for k in (bench.HORIZON // 2, bench.HORIZON)
    ]
    for row in rows:  # linear: the true change scales with the step, the ratio does not
        k = row["samples"]
        assert row["true"][0] == pytest.approx(row["scale"] * expected[k - 1], rel=1e-12)
        slower = B * sum(0.8**i for i in range(k - 1))
        assert row["ratios"][0] == pytest.approx(slower / expected[k - 1], rel=1e-9)


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


class _Planner:
    """A stand-in for the NMPC: a fixed input sequence, whatever it is fed."""

    def __init__(self, inputs: np.ndarray) -> None:
        self.inputs = inputs
        self.fed: list[np.ndarray] = []  # every state it was fed, the reset's first

    def reset(self, reference, state) -> None:
        self.fed.append(np.array(state))

    def __call__(self, k: int, state):
        self.fed.append(np.array(state))
        return SimpleNamespace(u=self.inputs[k], ok=True, info={})


def _loop(bench, rng, seed: int, steps: int = 12):
    true = LinearSystem([[A]], [[B]], [[1.0]])
    case = bench.Case("linear", true, [0.0], [1.0], [1.0], [0], "", False, {})
    flight = _flight(true, rng)
    flight.reference = np.zeros((flight.T, 1))
    planner = _Planner(rng.uniform(-1, 1, size=(steps, 1)))
    noise = Box([-0.1], [0.1])
    loop = bench.closed_loop(
        planner, case, flight, 1, steps, learned=True, noise=noise, rng=np.random.default_rng(seed)
    )
    return true, case, flight, planner, loop


def test_the_loop_records_the_windows_it_feeds_the_states_and_the_noise_it_draws(bench, rng):
    _, _, flight, planner, loop = _loop(bench, rng, seed=3)
    steps = len(loop.u)
    np.testing.assert_array_equal(loop.z, np.array(planner.fed[1:]))  # what the planner was fed
    # ℓ = 1: z_k = (u, y_meas) of the sample before step k (the recorded one for k = 0)
    np.testing.assert_array_equal(loop.z[0], [flight.u[0, 0], flight.y[0, 0]])
    np.testing.assert_array_equal(loop.z[1:, 0], loop.u[:-1, 0])
    np.testing.assert_array_equal(loop.z[1:, 1], loop.y_meas[1:-1, 0])
    drawn = np.random.default_rng(3).uniform(-0.1, 0.1, size=(steps, 1))
    np.testing.assert_array_equal(loop.noise, drawn)
    np.testing.assert_allclose(loop.y_meas[1:] - loop.y, drawn, atol=1e-15)
    assert loop.x[0] == flight.x[1]
    np.testing.assert_allclose(loop.x[1:], A * loop.x[:-1] + B * loop.u[:-1], atol=1e-15)
    np.testing.assert_allclose(loop.y, loop.x, atol=1e-15)  # y = x, no feedthrough


def test_the_visited_hull_is_the_box_of_the_windows_and_inputs_of_all_loops(bench, rng):
    loops = [_loop(bench, rng, seed)[-1] for seed in (0, 1)]
    z_box, u_box = bench.visited_hull(loops)
    z = np.vstack([loop.z for loop in loops])
    u = np.vstack([loop.u for loop in loops])
    assert z_box.lower == tuple(z.min(axis=0)) and z_box.upper == tuple(z.max(axis=0))
    assert u_box.lower == tuple(u.min(axis=0)) and u_box.upper == tuple(u.max(axis=0))
    single = bench.visited_hull(loops[:1])[0]
    assert all(a >= b for a, b in zip(single.lower, z_box.lower))  # one loop: a smaller box


def test_the_theory_beside_the_loop_gives_the_closed_forms(bench, rng):
    """ℓ = 1: the learned model's f(z, u) = (u, a y + b u_prev) has γ_f = √(a² + b²) (its
    sampled and certified bounds bracket it); the true x⁺ = a x + b u, y = x has γ_f = a and
    α_1 = 1, so the bound of each window is 2 a |w| exactly."""
    loops, case = [], None
    for seed in (0, 1):
        _, case, _, _, loop = _loop(bench, rng, seed)
        loops.append(loop)
    args = SimpleNamespace(gamma_seconds=2.0, theory_seconds=2.0)
    theory = bench.loop_theory(case, _model(), _model(), loops, args)
    exact = float(np.hypot(A, B))
    for where in ("loops", "training hull"):
        g = theory["gamma_learned"][where]
        assert g["lower"]["value"] <= exact * (1 + 1e-9)
        assert g["lower"]["value"] >= exact * 0.999  # linear: any sample attains it
        assert g["branch_and_bound"]["value"] >= exact * (1 - 1e-9)
    bound = theory["bound"]
    # the premise x_j ∈ X = [−1, 1]: the windows from states outside do not count
    inside = np.concatenate([np.abs(loop.x[:, 0]) <= 1.0 for loop in loops])
    noise = np.concatenate([np.abs(loop.noise[:, 0]) for loop in loops])[inside]
    assert 0 < inside.sum() < inside.size
    assert theory["true"]["alpha"]["lower"]["value"] == pytest.approx(1.0)
    gamma = theory["true"]["gamma_f"]["upper"]["value"]
    assert gamma == pytest.approx(A, rel=0.05) and gamma >= A
    assert bound["windows"] == inside.size and bound["windows_applied"] == noise.size
    assert bound["bound_max"] == pytest.approx(2 * gamma * noise.max(), rel=1e-12)
    assert bound["noise_norm_median"] == pytest.approx(float(np.median(noise)), rel=1e-12)
    # the model is the true system: from the measured window its one-step error is a |w_{k−1}|
    # (0 at k = 0, whose window is the recorded, noise-free sample)
    errors = np.concatenate([np.r_[0.0, A * np.abs(loop.noise[:-1, 0])] for loop in loops])
    assert theory["one_step_error"]["steps"] == noise.size
    assert theory["one_step_error"]["max"] == pytest.approx(errors[inside].max(), rel=1e-12)
    lines = "\n".join(bench.theory_lines("linear", {"window": 1, "theory": theory}))
    assert "infinite" not in lines and f"{bound['bound_max']:.4g}" in lines
    # where a constant makes the bound infinite the text says which, and prints no bound
    infinite = {**bound, "infinite": "α_1 has the lower bound 0 (trivial)", "factor": None}
    infinite.update(bound_median=None, bound_max=None)
    res = {"window": 1, "theory": {**theory, "bound": infinite}}
    lines = "\n".join(bench.theory_lines("linear", res))
    assert "The bound is infinite: α_1 has the lower bound 0 (trivial)" in lines
    assert "Factor" not in lines and f"{bound['bound_max']:.4g}" not in lines
