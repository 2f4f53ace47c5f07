"""The planar-drone NMPC: hover, tracking, fallback on failure, compiled = plugin, no compiler."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

import canonid.datagen.controllers._compiled as compiled
from canonid.datagen.controllers._buffered import BufferedFunction
from canonid.datagen.controllers.nmpc import NMPC
from canonid.datagen.references import drone2d_reference
from canonid.datagen.scenarios import DRONE2D_INPUT_WEIGHTS, DRONE2D_STATE_WEIGHTS
from canonid.datagen.simulate import Excitation, simulate_closed_loop
from canonid.kernel.errors import ShapeError
from canonid.models.drone2d import Drone2D

HORIZON = 10  # short: compiling the solver is the slow part of these tests


@pytest.fixture(scope="module")
def drone():
    return Drone2D()


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("nmpc-cache")


def _nmpc(drone, cache, **kwargs):
    h = drone.hover_speed
    options = {
        "u_eq": (h, h),
        "horizon": HORIZON,
        "state_weights": DRONE2D_STATE_WEIGHTS,
        "input_weights": DRONE2D_INPUT_WEIGHTS,
        "cache_dir": cache,
        **kwargs,
    }
    return NMPC(drone, **options)


@pytest.fixture(scope="module")
def plugin(drone, cache):
    return _nmpc(drone, cache, solver="fatrop")


def test_keeps_the_drone_at_hover(drone, plugin):
    loop = simulate_closed_loop(
        drone, plugin, np.zeros((90, 6)), x0=np.zeros(6), rng=np.random.default_rng(0)
    )
    assert loop.failures == 0
    assert np.abs(loop.x).max() < 1e-6
    np.testing.assert_allclose(loop.u, drone.hover_speed, rtol=1e-6)


def test_tracks_a_slow_reference_with_small_error(drone, plugin):
    """A 20 s spline through 5 waypoints, stretched to 40 s, with σ = 1 rad/s excitation."""
    ref = drone2d_reference(np.random.default_rng(3), T=1200, dt=drone.dt, n_waypoints=(5, 5))
    loop = simulate_closed_loop(
        drone,
        plugin,
        ref,
        x0=ref[0],
        rng=np.random.default_rng(1),
        excitation=Excitation(std=1.0),
        clip_input=True,
    )
    assert loop.failures == 0
    position_error = np.linalg.norm(loop.x[:, :2] - ref[:, :2], axis=1)
    assert np.sqrt(np.mean(position_error**2)) < 0.01  # m, on a path spanning metres
    assert position_error.max() < 0.03
    assert np.abs(loop.x[:, 2]).max() < 0.2  # rad
    assert drone.U.contains(loop.u)


def test_failed_solve_falls_back_on_the_shifted_plan(drone, cache, monkeypatch):
    ctrl = _nmpc(drone, cache, solver="fatrop")
    ref = drone2d_reference(np.random.default_rng(0), T=50, dt=drone.dt)
    ctrl.reset(ref, ref[0])
    first = ctrl(0, ref[0])
    assert first.ok
    plan = ctrl._plan.copy()
    monkeypatch.setattr(ctrl, "_solve_once", lambda params: ("forced failure", None))
    second, third = ctrl(1, ref[1]), ctrl(2, ref[2])
    assert not second.ok and second.info["status"] == "forced failure"
    np.testing.assert_array_equal(second.u, plan[1])
    np.testing.assert_array_equal(third.u, plan[2])
    ctrl.reset(ref, ref[0])  # no plan yet: the equilibrium input
    np.testing.assert_array_equal(ctrl(0, ref[0]).u, [drone.hover_speed] * 2)


def test_solver_that_cannot_converge_reports_failures_without_printing(drone, cache, capfd):
    ctrl = _nmpc(drone, cache, solver="fatrop", max_iter=1)
    ref = drone2d_reference(np.random.default_rng(0), T=5, dt=drone.dt)
    capfd.readouterr()
    loop = simulate_closed_loop(drone, ctrl, ref, x0=ref[0], rng=np.random.default_rng(0))
    assert loop.failures == 5 and all("fatrop failed" in k for k in loop.failure_reasons)
    # the compiled loop failed, then every step of the step loop: CasADi's input dumps (about
    # ten lines per failed call) are caught, nothing reaches the terminal
    assert capfd.readouterr() == ("", "")


def test_compiled_solver_equals_the_plugin_and_is_cached(drone, cache, plugin, capfd):
    ctrl = _nmpc(drone, cache, solver="fatrop-c")
    assert ctrl.solver_used == "fatrop-c"
    libraries = sorted(cache.glob("*.so"))
    assert len(libraries) == 1
    built = libraries[0].stat().st_mtime_ns
    again = _nmpc(drone, cache, solver="auto")  # same problem: the cached library is reused
    assert again.solver_used == "fatrop-c" and libraries[0].stat().st_mtime_ns == built
    ref = drone2d_reference(np.random.default_rng(5), T=150, dt=drone.dt)
    runs = [
        simulate_closed_loop(
            drone, c, ref, x0=ref[0], rng=np.random.default_rng(2), excitation=Excitation(1.0)
        )
        for c in (ctrl, plugin)
    ]
    np.testing.assert_array_equal(runs[0].x, runs[1].x)  # the same algorithm, bit for bit
    failing = _nmpc(drone, cache, solver="fatrop-c", max_iter=1)
    capfd.readouterr()
    step = (failing.reset(ref, ref[0]), failing(0, ref[0]))[1]
    assert not step.ok and step.info["status"] == "fatrop-c failed"
    assert capfd.readouterr().err == ""  # the compiled solver's failure is silent too


def test_without_a_compiler_auto_uses_the_plugin(drone, tmp_path, monkeypatch):
    monkeypatch.setattr(compiled.shutil, "which", lambda name: None)
    assert _nmpc(drone, tmp_path, solver="auto").solver_used == "fatrop"
    assert not list(tmp_path.iterdir())
    with pytest.raises(ShapeError, match="needs a working C compiler"):
        _nmpc(drone, tmp_path, solver="fatrop-c")


def test_settings_and_bad_arguments(drone, plugin):
    settings = json.loads(json.dumps(plugin.settings()))
    assert settings["horizon"] == HORIZON and settings["solver"] == "fatrop"
    P = np.array(settings["terminal_weight"])
    assert np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)
    with pytest.raises(ShapeError, match="horizon"):
        _nmpc(drone, None, horizon=0)
    with pytest.raises(ShapeError, match="solver"):
        _nmpc(drone, None, solver="snopt")
    with pytest.raises(ShapeError, match="state_weights"):
        _nmpc(drone, None, state_weights=(1.0, 1.0))
    with pytest.raises(ShapeError, match="before reset"):
        _nmpc(drone, None, solver="fatrop")(0, np.zeros(6))


def _replace(library, data: bytes) -> None:
    """New bytes under the library's name (a new file: this process still maps the old one)."""
    tmp = library.with_suffix(".new")
    tmp.write_bytes(data)
    tmp.replace(library)


@pytest.mark.parametrize(
    "damage",
    [
        lambda lib: _replace(lib, lib.read_bytes()[:4096]),  # truncated: SIGBUS when loaded
        lambda lib: _replace(lib, b"\x7fELF" + bytes(200)),  # garbage
        lambda lib: compiled._checksum_file(lib).unlink(),  # no checksum beside it
    ],
    ids=["truncated", "garbage", "no-checksum"],
)
def test_a_damaged_cached_library_is_rebuilt_not_loaded(damage, tmp_path, caplog):
    import casadi as ca

    x = ca.SX.sym("x")
    square = ca.Function("square", [x], [x**2 + 1])
    first = compiled.compile_functions([square], name="sq", cache_dir=tmp_path)
    assert first is not None and float(first[0](3.0)) == 10.0
    (library,) = tmp_path.glob("sq-*.so")
    intact = library.read_bytes()
    assert compiled._checksum_file(library).read_text().strip() == compiled.sha256_file(library)
    damage(library)
    again = compiled.compile_functions([square], name="sq", cache_dir=tmp_path)
    assert again is not None and float(again[0](4.0)) == 17.0
    assert "does not match its checksum: rebuilding it" in caplog.text
    assert compiled.sha256_file(library) == compiled._checksum_file(library).read_text().strip()
    assert len(library.read_bytes()) == len(intact)


def test_buffered_calls_give_the_plain_call_bits(drone, plugin):
    """The step's solver through numpy buffers (what NMPC.__call__ uses) and through a plain
    CasADi call: the same plan, bit for bit; matrices as inputs are refused."""
    ref = drone2d_reference(np.random.default_rng(4), T=40, dt=drone.dt)
    plugin.reset(ref, ref[0])
    params = np.concatenate([ref[0], plugin._windows[: (HORIZON + 1) * 6]])
    plain = np.asarray(plugin._solve(plugin._guess, params), dtype=np.float64).ravel()
    buffered = BufferedFunction(plugin._solve)
    np.testing.assert_array_equal(buffered(plugin._guess, params), plain)
    np.testing.assert_array_equal(buffered(plugin._guess, params), plain)  # bound arrays reused
    x = ca.SX.sym("x", 2, 2)
    with pytest.raises(ValueError, match="not a dense column vector"):
        BufferedFunction(ca.Function("matrix", [x], [x]))
