"""Ours (MLP) with a cubic branch downstream of training: the plain description, its numpy and
CasADi forms against torch, the interval enclosures, the global-bound path, saving and
``canonid export``."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
import torch
from test_learned_system import N_U, N_Y, _random_model, as_system
from test_network_enclosure import assert_boxes_enclose

from canonid.analysis.certify import layer_norm_bound, learned_gamma
from canonid.analysis.estimate import Budget
from canonid.analysis.interval import Interval
from canonid.analysis.network_enclosure import activation_enclosure, network_enclosure
from canonid.kernel.errors import ShapeError
from canonid.kernel.network import ACTIVATIONS, CanonicalNet, Layer
from canonid.learning.model import Model
from canonid.learning.nets import ReducedNet, build_net
from canonid.models.base import System
from canonid.models.learned import model_function

UNITS = 3
OPTIONS = list(itertools.product((True, False), (True, False), ("off", "skip")))


def cubic_model(*, feedthrough=True, residual=False, linear="off", seed=0, units=UNITS) -> Model:
    """Ours (MLP) with ``units`` cubic units, random weights: ``C`` non-zero, the branch scaled
    down so that short rollouts stay bounded."""
    model = _random_model(
        "mlp",
        seed,
        feedthrough=feedthrough,
        residual=residual,
        linear=linear,
        hidden=[8, 8],
        cubic=units,
    )
    net = model.net
    if units:
        with torch.no_grad():
            net.cubic_in.weight.mul_(0.5)
            net.cubic_out.weight.mul_(0.02)
    return model


def _numpy_h(net: CanonicalNet, z: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``Ĥ`` from the plain description, written out in numpy (kernel.network's equations)."""
    zn, un = (z - net.z_mean) / net.z_std, (u - net.u_mean) / net.u_std
    x = np.hstack([zn, un]) if net.feedthrough else zn
    v = x
    for layer in net.layers:
        pre = v @ layer.weight.T + layer.bias
        v = np.maximum(pre, 0.0) if layer.activation == "relu" else pre
    raw = v
    if net.affine is not None:
        raw = raw + x @ net.affine[0].T + net.affine[1]
    assert net.cubic is not None
    first, second = net.cubic
    raw = raw + (x @ first.weight.T + first.bias) ** 3 @ second.weight.T + second.bias
    yn = raw if net.residual_scale is None else zn[:, -net.n_y :] + net.residual_scale * raw
    return yn * net.y_std + net.y_mean


@pytest.mark.parametrize(("feedthrough", "residual", "linear"), OPTIONS)
def test_the_plain_description_holds_the_branch_and_gives_torchs_numbers(
    feedthrough, residual, linear, rng
):
    model = cubic_model(feedthrough=feedthrough, residual=residual, linear=linear)
    exported = model.export()
    net = exported.network()
    assert isinstance(net, CanonicalNet) and net.cubic is not None
    first, second = net.cubic
    torch_net = model.net
    assert first.activation == "cube" and second.activation == "linear"
    np.testing.assert_array_equal(first.weight, torch_net.cubic_in.weight.detach().numpy())
    np.testing.assert_array_equal(first.bias, torch_net.cubic_in.bias.detach().numpy())
    np.testing.assert_array_equal(second.weight, torch_net.cubic_out.weight.detach().numpy())
    assert np.any(second.weight != 0) and not np.any(second.bias)
    z = rng.normal(0.0, 2.0, size=(64, net.state_dim))
    u = rng.normal(0.0, 2.0, size=(64, N_U))
    expected = exported.H(z, u)  # the torch forward in float64
    np.testing.assert_allclose(_numpy_h(net, z, u), expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("feedthrough", "residual", "linear"), OPTIONS)
def test_the_casadi_system_and_its_numpy_linearisation_give_torchs_numbers(
    feedthrough, residual, linear, rng
):
    model = cubic_model(feedthrough=feedthrough, residual=residual, linear=linear)
    exported, system = model.export(), as_system(model)
    assert system.parameters["cubic"] == UNITS
    assert "with a cubic branch" in system.discretisation
    z = rng.normal(0.0, 2.0, size=(64, system.n_x))
    u = rng.normal(0.0, 2.0, size=(64, N_U))
    np.testing.assert_allclose(system.h_batch(z, u), exported.H(z, u), rtol=1e-12, atol=1e-12)
    # a short open-loop rollout from a measured burn-in window
    ell, steps = exported.window, 15
    u_seq = rng.uniform(-1.0, 1.0, size=(ell + steps, N_U))
    y_burn = rng.uniform(-1.0, 1.0, size=(ell, N_Y))
    expected = exported.simulate(u_seq, y_burn)
    z0 = np.concatenate([u_seq[:ell], y_burn], axis=1).ravel()
    sim = system.simulate(system.state_of_window(z0), u_seq[ell:])
    np.testing.assert_allclose(sim.y, expected, rtol=1e-11, atol=1e-11)
    # the numpy linearisation (the MLP's fast path) against CasADi's AD on the SX graph
    fast, reference = system.linearise(z[:7], u[:7]), System.linearise(system, z[:7], u[:7])
    for key in ("f", "h", "f_x", "f_u", "h_x", "h_u"):
        np.testing.assert_allclose(
            getattr(fast, key), getattr(reference, key), rtol=1e-11, atol=1e-10
        )


@pytest.mark.parametrize("residual", [False, True])
def test_a_reduced_model_on_a_cubic_regressor_exports(residual, rng):
    full = cubic_model(residual=residual, linear="skip")
    net = ReducedNet.around(
        full.net, latent_dim=4, encoder_hidden=(6,), decoder_hidden=(6,), linear_skip=True
    ).double()
    with torch.no_grad():
        for p in [*net.encoder.parameters(), *net.decoder.parameters()]:
            p.normal_(0.0, 0.5)
    model = Model(net, full.norm)
    exported, system = model.export(), as_system(model)
    assert exported.network().regressor.cubic is not None
    z = rng.normal(size=(16, exported.window * (N_U + N_Y)))
    u = rng.normal(size=(16, N_U))
    x = system.state_of_window(z)
    np.testing.assert_allclose(x, exported.encode(z), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(system.h_batch(x, u), exported.H(z, u), rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(system.f_batch(x, u), exported.step(x, u), rtol=1e-11, atol=1e-11)
    # the SX graph's interval enclosure (the reduced model's γ_f) takes the cube too
    bound = layer_norm_bound(system)
    assert bound.value == np.inf and "no finite global bound" in bound.method
    gamma = learned_gamma(system, budget=Budget(boxes=8, samples=64, starts=1))
    assert gamma.bracket.lower.value <= gamma.bracket.upper.value


def test_the_cube_is_enclosed_with_its_slope(rng):
    lo = rng.uniform(-4, 4, size=400)
    hi = lo + rng.exponential(1.5, size=400)
    lo[:2], hi[:2] = [-1.0, 0.0], [2.0, 0.0]  # straddling 0, and the point 0
    value, slope = activation_enclosure("cube", Interval(lo, hi))
    x = rng.uniform(lo, hi, size=(300, 400))
    x[0], x[1] = lo, hi
    assert np.all(x**3 >= value.lo) and np.all(x**3 <= value.hi)
    assert np.all(3 * x**2 >= slope.lo) and np.all(3 * x**2 <= slope.hi)
    straddles = (lo < 0) & (hi > 0)
    assert np.all(slope.lo[straddles] == 0.0) and slope.hi[0] >= 12.0
    assert value.lo[1] == value.hi[1] == slope.lo[1] == slope.hi[1] == 0.0
    # outward rounding only: a point interval stays within a few ulps
    pt = rng.uniform(-3, 3, size=50)
    value, slope = activation_enclosure("cube", Interval.point(pt))
    assert np.all(value.hi - value.lo <= 1e-14 * (1 + np.abs(pt) ** 3))


@pytest.mark.parametrize(("feedthrough", "residual", "linear"), OPTIONS)
def test_sampled_values_and_jacobians_lie_in_the_box_enclosures(feedthrough, residual, linear, rng):
    system = as_system(cubic_model(feedthrough=feedthrough, residual=residual, linear=linear))
    centres = assert_boxes_enclose(system, [0.0, 1e-6, 1e-3, 0.05, 0.5, 2.0], rng)
    d, enclosure = system.n_x, network_enclosure(system)
    assert enclosure is not None
    # a point box: as tight as float arithmetic allows
    x, u = centres[:, :d], centres[:, d:]
    point = enclosure([Interval.point(x), Interval.point(u)]).jacobians[0]
    exact = system.linearise(x, u).f_x
    assert np.all(point.lo <= exact) and np.all(exact <= point.hi)
    assert np.max(point.hi - point.lo) <= 1e-9 * (1 + np.max(np.abs(exact)))


def test_a_cubic_branch_has_no_finite_global_bound_but_a_certified_one_on_the_hull(rng):
    system = as_system(cubic_model(residual=True))
    bound = layer_norm_bound(system)
    assert bound.kind == "upper" and bound.value == np.inf
    assert bound.method.startswith("trivial: no finite global bound")
    assert bound.to_dict()["value"] is None
    gamma = learned_gamma(system, budget=Budget(boxes=64, samples=128, starts=1))
    assert "network's layers" in gamma.bracket.upper.method
    assert gamma.bracket.lower.kind == "lower" and gamma.bracket.upper.kind == "upper"
    assert np.isfinite(gamma.bracket.upper.value) and gamma.upper is gamma.bracket.upper
    assert gamma.to_dict()["best_upper"] == gamma.bracket.upper.value
    pts = np.hstack([system.X.sample(rng, 300), system.U.sample(rng, 300)])
    f_x = system.linearise(pts[:, : system.n_x], pts[:, system.n_x :]).f_x
    sampled = np.linalg.norm(f_x, 2, axis=(1, 2)).max()
    assert gamma.bracket.lower.value <= gamma.bracket.upper.value
    assert sampled <= gamma.bracket.upper.value


def test_a_branch_that_reads_no_state_keeps_the_networks_global_bound():
    """``C = 0`` (as training starts) or ``W_z = 0``: the branch adds nothing to ∂f/∂z."""
    model = cubic_model(residual=True)
    plain = as_system(model)
    net = plain.network
    assert isinstance(net, CanonicalNet) and net.cubic is not None
    without = layer_norm_bound(_with(plain, replace(net, cubic=None))).value
    assert np.isfinite(without)
    first, second = net.cubic
    for branch in (
        (first, Layer(np.zeros_like(second.weight), second.bias)),
        (
            Layer(
                np.hstack([0 * first.weight[:, : net.state_dim], first.weight[:, net.state_dim :]]),
                first.bias,
                "cube",
            ),
            second,
        ),
    ):
        changed = replace(net, cubic=branch)
        assert not changed.cubic_reads_state()
        assert layer_norm_bound(_with(plain, changed)).value == without
    assert net.cubic_reads_state()


def _with(system, net):
    from canonid.models.learned import LearnedSystem

    return LearnedSystem(
        net,
        dt=system.dt,
        input_names=system.input_names,
        output_names=system.output_names,
        X=system.X,
        U=system.U,
        W=system.W,
    )


def test_a_cube_inside_the_layers_also_has_no_finite_global_bound():
    net = as_system(cubic_model(units=0)).network
    layers = list(net.layers)
    layers[0] = Layer(layers[0].weight, layers[0].bias, "cube")
    changed = replace(net, layers=tuple(layers))
    bound = layer_norm_bound(_with(as_system(cubic_model(units=0)), changed))
    assert bound.value == np.inf and "activation cube" in bound.method
    assert ACTIVATIONS["cube"] == np.inf


def test_a_malformed_cubic_branch_is_refused():
    net = as_system(cubic_model()).network
    first, second = net.cubic
    bad = {
        "its first layer must cube": (Layer(first.weight, first.bias, "relu"), second),
        "reads": (Layer(first.weight[:, 1:], first.bias, "cube"), second),
        "last layer must be linear": (first, Layer(second.weight, second.bias, "cube")),
        "a pair of layers": (first,),
    }
    for message, branch in bad.items():
        with pytest.raises(ShapeError, match=message):
            replace(net, cubic=branch)


def test_without_cubic_units_the_export_is_the_plain_networks():
    torch.manual_seed(3)
    plain = build_net("mlp", window=3, n_u=N_U, n_y=N_Y, hidden=[8, 8], residual=True)
    torch.manual_seed(3)
    zero = build_net("mlp", window=3, n_u=N_U, n_y=N_Y, hidden=[8, 8], residual=True, cubic=0)
    assert zero.config() == plain.config()
    norm = cubic_model().norm
    a, b = as_system(Model(plain.double(), norm)), as_system(Model(zero.double(), norm))
    assert a.network.cubic is None and "cubic" not in a.parameters
    assert "cubic branch" not in a.discretisation
    assert model_function(a).serialize() == model_function(b).serialize()


@pytest.fixture(scope="module")
def cubic_run(tmp_path_factory):
    """A library run of Ours (MLP) with 2 cubic units (3 epochs on damped data), its data saved
    beside it (the library run records no recipe): ``(run, data, model)``."""
    from learning_helpers import damped_split

    from canonid.kernel.dataset import Dataset, Trajectory
    from canonid.learning.training import TrainOptions, fit

    folder = tmp_path_factory.mktemp("cubic")
    train, val = damped_split()
    opts = TrainOptions(epochs=3, batch_size=8, horizon=5, lr=1e-2, device="cpu")
    info = {"dt": 0.5, "input_names": ["u1"], "output_names": ["y1"]}
    run = folder / "run"
    result = fit(
        train,
        val,
        window=2,
        options=opts,
        net_options={"cubic": 2, "hidden": [8, 8], "residual": True},
        run_dir=run,
        info=info,
    )
    as_record = lambda t: Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)  # noqa: E731
    data = Dataset(
        splits={"train": tuple(map(as_record, train)), "val": tuple(map(as_record, val))},
        dt=0.5,
        input_names=("u1",),
        output_names=("y1",),
    ).save(folder / "data" / "dataset.npz")
    return run, data, result.model


def test_a_trained_cubic_model_saves_loads_and_exports(cubic_run, tmp_path, capsys):
    from canonid.cli import main
    from canonid.models.learned import load_function

    run, data, trained = cubic_run
    assert trained.net.cubic_out is not None and torch.any(trained.net.cubic_out.weight != 0)
    loaded = Model.load(run)
    assert loaded.net.config()["cubic"] == 2
    z = np.random.default_rng(0).normal(size=(20, 4))
    u = np.random.default_rng(1).normal(size=(20, 1))
    np.testing.assert_array_equal(loaded.export().H(z, u), trained.export().H(z, u))
    # `canonid export` of the run on its data (given, as the library run records no recipe)
    target = tmp_path / "cubic.casadi"
    assert main(["export", str(run), "--casadi", str(target), "--data", str(data)]) == 0
    assert "4 states" in capsys.readouterr().out
    fun = load_function(target)
    x_next, y = fun(z[0], u[0])
    expected = loaded.export().H(z[0], u[0])
    np.testing.assert_allclose(np.asarray(y).ravel(), expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(
        np.asarray(x_next).ravel(), np.concatenate([z[0][2:], u[0], expected]), atol=1e-9
    )


def test_analyze_says_why_a_cubic_runs_layer_norm_bound_is_infinite(cubic_run, tmp_path, capsys):
    """``canonid analyze --run``'s γ_f line names the reason the layer-norm bound is ∞, taken from
    the Estimate's details; the certified bound on the hull stays finite."""
    import json

    from canonid.cli import main

    run, data, _ = cubic_run
    out = tmp_path / "analysis"
    argv = ["analyze", "--run", str(run), "--data", str(data), "--budget", "30", "--boxes", "40"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    gamma = json.loads((out / "learned_analysis.json").read_text())["gamma_f"]
    why = gamma["layer_norms"]["details"]["unbounded"]
    assert why == "the slope 3 h² of its cubic branch is unbounded on the whole space"
    assert f"∞ (product of layer norms: {why}); so γ_f ≤ " in printed, printed
    assert "(product of layer norms, loose)" not in printed
    assert gamma["layer_norms"]["value"] is None and np.isfinite(gamma["best_upper"])
