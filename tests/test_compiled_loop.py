"""The compiled closed loop flies exactly the step loop's flight (same bytes), and hands failed
flights back to the step loop."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.datagen.compiled_loop import CHUNK, CompiledLoop, loop_functions
from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.datagen.controllers.nmpc import NMPC
from canonid.datagen.references import drone2d_reference
from canonid.datagen.scenarios import DRONE2D_INPUT_WEIGHTS, DRONE2D_STATE_WEIGHTS
from canonid.datagen.simulate import ClosedLoop, Excitation, simulate_closed_loop
from canonid.models.drone2d import Drone2D
from canonid.models.registry import get_system

HORIZON = 10  # short: compiling the solver is the slow part of these tests


def _same_flight(a: ClosedLoop, b: ClosedLoop) -> None:
    for name in ("x", "u", "y_clean", "y", "reference"):
        left, right = getattr(a, name), getattr(b, name)
        # np.save records the memory order: it must match for the files to match
        assert left.flags.c_contiguous == right.flags.c_contiguous, name
        assert left.shape == right.shape and left.tobytes() == right.tobytes(), name
    assert a.summary() == b.summary()


def _fly(system, controller, reference, seed, *, step_by_step=False, **kwargs):
    return simulate_closed_loop(
        system,
        controller,
        reference,
        x0=reference[0],
        rng=np.random.default_rng(seed),
        step_by_step=step_by_step,
        **kwargs,
    )


def _no_steps(monkeypatch, controller_type):
    """Make a per-step controller call fail the test: the compiled loop must fly alone."""

    def called(self, t, x):
        raise AssertionError(f"step {t} went through the step loop")

    monkeypatch.setattr(controller_type, "__call__", called)


# ---------------------------------------------------------------------------- the NMPC
@pytest.fixture(scope="module")
def drone():
    return Drone2D()


def _nmpc(drone, cache, **kwargs):
    h = drone.hover_speed
    weights = {"state_weights": DRONE2D_STATE_WEIGHTS, "input_weights": DRONE2D_INPUT_WEIGHTS}
    return NMPC(drone, u_eq=(h, h), horizon=HORIZON, cache_dir=cache, **weights, **kwargs)


@pytest.fixture(scope="module", params=["fatrop-c", "fatrop", "ipopt"])
def nmpc(request, drone, tmp_path_factory):
    controller = _nmpc(drone, tmp_path_factory.mktemp("cache"), solver=request.param)
    assert controller.solver_used == request.param
    return controller


@pytest.mark.parametrize("clip", [True, False])
def test_nmpc_flight_equals_the_step_loop_flight(drone, nmpc, clip, monkeypatch):
    # 2 whole chunks and 30 single steps; loose steps (the first one at t = 0, without a
    # previous input) and excitation exercise every branch of the step
    reference = drone2d_reference(np.random.default_rng(4), T=2 * CHUNK + 30, dt=drone.dt)
    excitation = Excitation(std=1.0, loose_probability=0.3, loose_std=10.0)
    options = {"excitation": excitation, "clip_input": clip}
    old = _fly(drone, nmpc, reference, 24, step_by_step=True, **options)
    assert old.failures == 0 and old.loose_steps > 1
    _no_steps(monkeypatch, NMPC)
    new = _fly(drone, nmpc, reference, 24, **options)
    _same_flight(new, old)


def test_failed_solves_send_the_flight_back_to_the_step_loop(drone, tmp_path):
    # 12 iterations are too few for some solves (12 of 60 fail with CasADi 3.8.2)
    failing = _nmpc(drone, tmp_path, solver="fatrop", max_iter=12)
    reference = drone2d_reference(np.random.default_rng(1), T=CHUNK + 10, dt=drone.dt)
    options = {"excitation": Excitation(std=1.0), "clip_input": True}
    new = _fly(drone, failing, reference, 3, **options)
    assert new.failures > 0
    assert set(new.failure_reasons) == {"fatrop failed"}
    _same_flight(new, _fly(drone, failing, reference, 3, step_by_step=True, **options))


def test_flights_of_another_system_go_step_by_step(nmpc, monkeypatch):
    other = Drone2D()  # equal, but not the system the loop was built for
    reference = drone2d_reference(np.random.default_rng(2), T=8, dt=other.dt)
    calls = []
    real = NMPC.__call__

    def counted(self, t, x):
        calls.append(t)
        return real(self, t, x)

    monkeypatch.setattr(NMPC, "__call__", counted)
    _fly(other, nmpc, reference, 0)
    assert calls == list(range(8))


# ---------------------------------------------------------------------------- any policy
class _Proportional(Controller):
    """u = k (r − x[1]) on the tank's lower level, ``ok`` False above ``ceiling``; a step
    counter as memory; ``calls`` counts the per-step calls. Written twice, per step in NumPy
    and as a CasADi policy, with the same floating-point operations."""

    name = "proportional"

    def __init__(self, system, k, ceiling, chunk):
        self.system, self.k, self.ceiling = system, k, ceiling
        memory, x, window = ca.MX.sym("m"), ca.MX.sym("x", 2), ca.MX.sym("r")
        policy = ca.Function(
            "p", [memory, x, window], [self.k * (window - x[1]), memory + 1, x[1] <= ceiling]
        )
        step, chunked = loop_functions(system, policy, name="proportional", chunk=chunk)
        self.loop = CompiledLoop(system, step, chunked, 1, lambda ref, x0: np.zeros(1))
        self.calls = 0

    def reset(self, reference, x0):
        self.reference = reference

    def __call__(self, t, x):
        self.calls += 1
        u = self.k * (self.reference[t, 0] - x[1])
        return ControlStep(u=np.array([u]), ok=bool(x[1] <= self.ceiling))

    def settings(self):
        return {"type": self.name}

    def compiled_loop(self):
        return self.loop


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    T=st.integers(2, 23),
    chunk=st.integers(1, 6),
    loose=st.floats(0.0, 1.0),
    clip=st.booleans(),
    ceiling=st.sampled_from([np.inf, 1.0]),
)
def test_any_policy_flies_like_its_step_loop(seed, T, chunk, loose, clip, ceiling):
    tank = get_system("tank")
    controller = _Proportional(tank, k=3.0, ceiling=ceiling, chunk=chunk)
    reference = np.random.default_rng(seed).uniform(0.0, 3.0, size=(T, 1))
    kwargs = {
        "x0": np.array([0.5, 0.5]),
        "excitation": Excitation(std=0.5, loose_probability=loose, loose_std=1.0),
        "clip_input": clip,
    }
    new = simulate_closed_loop(
        tank, controller, reference, rng=np.random.default_rng(seed), **kwargs
    )
    new_calls, controller.calls = controller.calls, 0
    old = simulate_closed_loop(
        tank, controller, reference, rng=np.random.default_rng(seed), step_by_step=True, **kwargs
    )
    _same_flight(new, old)
    # the compiled loop flew alone unless a step was not ok; then the step loop flew it all
    assert new_calls == (T if old.failures else 0)
