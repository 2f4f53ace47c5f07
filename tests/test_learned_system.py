"""A trained canonical model as a CasADi system (canonid.models.learned) against the torch model.

The SX graph is built from the exported weights (canonid.learning.NumpyModel.network()); it must
give the torch model's numbers in float64 on random points and along a 100-step open-loop rollout,
for every option of Ours (MLP) and Ours (GRU) and for their reduced models.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from canonid.kernel.errors import ShapeError
from canonid.kernel.network import CanonicalNet, Layer
from canonid.learning.data import Normalisation
from canonid.learning.export import NotExportableError
from canonid.learning.model import Model
from canonid.learning.nets import NETS, ReducedNet, build_net
from canonid.models.base import System
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box

N_U, N_Y, ELL = 2, 1, 3
TOL = 1e-9


def _norm() -> Normalisation:
    return Normalisation(
        u_mean=np.array([0.1, -0.2]),
        u_std=np.array([1.5, 0.7]),
        y_mean=np.array([2.0]),
        y_std=np.array([3.0]),
        dy_std=np.array([0.5]),
    )


def _random_model(name: str, seed: int, **config) -> Model:
    """Network ``name`` in float64 with random weights (biases too) and a non-trivial residual
    scale."""
    torch.manual_seed(seed)
    net = build_net(name, window=ELL, n_u=N_U, n_y=N_Y, **config).double()
    with torch.no_grad():
        for p in net.parameters():
            p.normal_(0.0, 0.6)
        net.residual_scale.fill_(0.3)
    return Model(net, _norm())


def mlp_model(*, activation="relu", feedthrough=True, residual=False, hidden=(8, 8), seed=0):
    """Ours (MLP), random weights."""
    return _random_model(
        "mlp",
        seed,
        feedthrough=feedthrough,
        residual=residual,
        hidden=list(hidden),
        activation=activation,
    )


def gru_model(*, feedthrough=True, residual=False, seed=0):
    """Ours (GRU), two GRU layers of 6 and a head of 5, random weights."""
    return _random_model(
        "gru",
        seed,
        feedthrough=feedthrough,
        residual=residual,
        hidden_size=6,
        num_layers=2,
        head_hidden=[5],
    )


def reduced_model(*, residual=False, linear_skip=False, seed=0, regressor="mlp"):
    full = (mlp_model if regressor == "mlp" else gru_model)(residual=residual, seed=seed)
    net = ReducedNet.around(
        full.net, latent_dim=4, encoder_hidden=(6,), decoder_hidden=(6,), linear_skip=linear_skip
    ).double()
    with torch.no_grad():
        for p in net.encoder.parameters():
            p.normal_(0.0, 0.5)
        for p in net.decoder.parameters():
            p.normal_(0.0, 0.5)
    return Model(net, full.norm)


def as_system(model: Model) -> LearnedSystem:
    dim = model.export().network()
    n_x = dim.latent_dim if hasattr(dim, "latent_dim") else ELL * (N_U + N_Y)
    return LearnedSystem(
        dim,
        dt=0.5,
        input_names=("a", "b"),
        output_names=("y",),
        X=Box(-np.ones(n_x), np.ones(n_x)),
        U=Box(-np.ones(N_U), np.ones(N_U)),
        W=Box([0.0], [0.0]),
    )


MLP_CASES = list(itertools.product(("relu", "silu", "tanh"), (True, False), (True, False)))
REDUCED_CASES = list(itertools.product((True, False), (True, False), ("mlp", "gru")))


def _check_against_torch(model: Model, system: LearnedSystem, rng) -> None:
    exported = model.export()
    z = rng.normal(0.0, 2.0, size=(64, ELL * (N_U + N_Y)))
    u = rng.normal(0.0, 2.0, size=(64, N_U))
    x = system.state_of_window(z)
    np.testing.assert_allclose(system.h_batch(x, u), exported.H(z, u), rtol=0, atol=TOL)
    # a 100-step open-loop rollout from a measured burn-in window
    steps = 100
    u_seq = rng.uniform(-1.0, 1.0, size=(ELL + steps, N_U))
    y_burn = rng.uniform(-1.0, 1.0, size=(ELL, N_Y))
    expected = exported.simulate(u_seq, y_burn)
    z0 = np.concatenate([u_seq[:ELL], y_burn], axis=1).ravel()
    sim = system.simulate(system.state_of_window(z0), u_seq[ELL:])
    assert sim.y.shape == expected.shape == (steps, N_Y)
    np.testing.assert_allclose(sim.y, expected, rtol=0, atol=TOL * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize(("activation", "feedthrough", "residual"), MLP_CASES)
def test_mlp_system_equals_the_torch_model(activation, feedthrough, residual, rng):
    model = mlp_model(activation=activation, feedthrough=feedthrough, residual=residual)
    system = as_system(model)
    _check_against_torch(model, system, rng)
    # the canonical state is the measured window itself and f is the exact shift plus Ĥ
    z = rng.normal(size=ELL * (N_U + N_Y))
    u = rng.normal(size=N_U)
    np.testing.assert_array_equal(system.state_of_window(z), z)
    z_next = system.step(z, u)
    np.testing.assert_array_equal(z_next[: -(N_U + N_Y)], z[N_U + N_Y :])
    np.testing.assert_array_equal(z_next[-(N_U + N_Y) : -N_Y], u)
    np.testing.assert_array_equal(z_next[-N_Y:], system.output(z, u))


@pytest.mark.parametrize(
    ("feedthrough", "residual"), list(itertools.product((True, False), repeat=2))
)
def test_gru_system_equals_the_torch_model(feedthrough, residual, rng):
    model = gru_model(feedthrough=feedthrough, residual=residual)
    system = as_system(model)
    assert system.parameters["regressor"] == "GRU" and system.parameters["gru_hidden"] == [6, 6]
    _check_against_torch(model, system, rng)


@pytest.mark.parametrize(("residual", "linear_skip", "regressor"), REDUCED_CASES)
def test_reduced_system_equals_the_torch_model(residual, linear_skip, regressor, rng):
    model = reduced_model(residual=residual, linear_skip=linear_skip, regressor=regressor)
    system = as_system(model)
    assert system.n_x == 4 and system.state_names[0] == "xbar0"
    _check_against_torch(model, system, rng)
    exported = model.export()
    x = rng.normal(size=(16, 4))
    u = rng.normal(size=(16, N_U))
    np.testing.assert_allclose(system.f_batch(x, u), exported.step(x, u), rtol=0, atol=TOL)
    z = rng.normal(size=(16, ELL * (N_U + N_Y)))
    np.testing.assert_allclose(system.state_of_window(z), exported.encode(z), rtol=0, atol=TOL)


def test_names_units_and_dt_come_from_the_arguments():
    system = LearnedSystem(
        mlp_model().export().network(),
        dt=0.25,
        input_names=("pump", "valve"),
        output_names=("level",),
        input_units=("V", "-"),
        output_units=("m",),
        X=Box(-np.ones(9), np.ones(9)),
        U=Box(-np.ones(2), np.ones(2)),
        W=Box([0.0], [0.0]),
    )
    assert system.dt == 0.25 and (system.n_x, system.n_u, system.n_y) == (9, 2, 1)
    assert system.state_names[:3] == ("pump[t-3]", "valve[t-3]", "level[t-3]")
    assert system.state_names[-1] == "level[t-1]"
    assert system.state_units[:3] == ("V", "-", "m")


def _affine_net(hidden: tuple[int, ...], *, residual: bool, rng) -> CanonicalNet:
    dims = (ELL * (N_U + N_Y) + N_U, *hidden, N_Y)
    layers = [
        Layer(rng.normal(size=(o, i)), rng.normal(size=o), "tanh" if k < len(hidden) else "linear")
        for k, (i, o) in enumerate(itertools.pairwise(dims))
    ]
    return CanonicalNet(
        window=ELL,
        n_u=N_U,
        n_y=N_Y,
        feedthrough=True,
        layers=tuple(layers),
        u_mean=np.array([0.1, -0.2]),
        u_std=np.array([1.5, 0.7]),
        y_mean=np.array([2.0]),
        y_std=np.array([3.0]),
        residual_scale=np.array([0.3]) if residual else None,
        affine=(rng.normal(size=(N_Y, dims[0])), rng.normal(size=N_Y)),
    )


def _unit_system(net: CanonicalNet) -> LearnedSystem:
    return LearnedSystem(
        net,
        dt=1.0,
        input_names=("a", "b"),
        output_names=("y",),
        X=Box(-np.ones(9), np.ones(9)),
        U=Box(-np.ones(2), np.ones(2)),
        W=Box([0.0], [0.0]),
    )


@pytest.mark.parametrize("residual", [False, True])
@pytest.mark.parametrize("hidden", [(), (5,)])
def test_the_affine_path_is_added_in_normalised_units(hidden, residual, rng):
    """Ĥ = y_mean + y_std ⊙ (ỹ_prev + s ⊙ (MLP(a) + L a + c)) by hand, for a hand-built net."""
    net = _affine_net(hidden, residual=residual, rng=rng)
    system = _unit_system(net)
    z = rng.normal(size=(20, 9))
    u = rng.normal(size=(20, 2))
    a = np.hstack([(z - net.z_mean) / net.z_std, (u - net.u_mean) / net.u_std])
    v = a
    for layer in net.layers:
        v = v @ layer.weight.T + layer.bias
        v = np.tanh(v) if layer.activation == "tanh" else v
    L, c = net.affine
    raw = v + a @ L.T + c
    y_tilde = a[:, 8:9] + 0.3 * raw if residual else raw
    np.testing.assert_allclose(system.h_batch(z, u), 2.0 + 3.0 * y_tilde, rtol=1e-12, atol=1e-12)


def test_from_data_takes_the_hulls_of_the_training_windows(rng):
    model = mlp_model()

    class Traj:
        def __init__(self, T):
            self.u = rng.uniform(-1, 1, size=(T, N_U))
            self.y_clean = rng.uniform(0, 2, size=(T, N_Y))
            self.y = self.y_clean + rng.uniform(-0.1, 0.1, size=(T, N_Y))

    trajs = [Traj(30), Traj(40)]
    system = LearnedSystem.from_data(
        model.export().network(), trajs, dt=1.0, input_names=("a", "b"), output_names=("y",)
    )
    u_all = np.concatenate([t.u for t in trajs])
    y_all = np.concatenate([t.y for t in trajs])
    np.testing.assert_array_equal(system.U.lo, u_all.min(axis=0))
    pair_lo = np.concatenate([u_all.min(axis=0), y_all.min(axis=0)])
    assert np.all(system.X.lo >= np.tile(pair_lo, ELL))
    assert system.W.contains(np.concatenate([t.y - t.y_clean for t in trajs]))
    assert 0.09 < system.W.hi[0] <= 0.1
    reduced = reduced_model()
    rsys = LearnedSystem.from_data(
        reduced.export().network(), trajs, dt=1.0, input_names=("a", "b"), output_names=("y",)
    )
    from canonid.kernel.canonical import cut_windows

    windows = np.concatenate([cut_windows(t.u, t.y, ELL) for t in trajs])
    assert rsys.X.contains(reduced.export().encode(windows), atol=1e-12)


@pytest.mark.parametrize(
    ("feedthrough", "residual"), list(itertools.product((True, False), repeat=2))
)
def test_arx_system_equals_the_torch_model(feedthrough, residual, rng):
    model = _random_model("arx", 3, feedthrough=feedthrough, residual=residual)
    _check_against_torch(model, as_system(model), rng)


@pytest.mark.parametrize("name", [n for n in NETS if n not in ("mlp", "gru", "arx")])
def test_only_canonical_models_export(name):
    net = build_net(name, window=ELL, n_u=N_U, n_y=N_Y)
    with pytest.raises(NotExportableError, match=f"only canonical models export.*'{name}'"):
        Model(net, _norm()).export().network()


def test_a_description_that_does_not_chain_is_refused(rng):
    with pytest.raises(ShapeError, match="layer 1 reads 4 values, expected 5"):
        CanonicalNet(
            window=ELL,
            n_u=N_U,
            n_y=N_Y,
            feedthrough=True,
            layers=(Layer(np.ones((5, 11)), np.ones(5), "relu"), Layer(np.ones((1, 4)), [0.0])),
            u_mean=np.zeros(2),
            u_std=np.ones(2),
            y_mean=np.zeros(1),
            y_std=np.ones(1),
        )
    with pytest.raises(ShapeError, match="activation must be one of"):
        Layer(np.ones((1, 1)), [0.0], "gelu")


@pytest.mark.parametrize("feedthrough", [True, False])
def test_the_affine_path_of_a_gru_regressor_reads_the_window_not_the_gru_state(feedthrough, rng):
    """raw = head([h_ℓ; ũ]) + L x + c with x = [z̃; ũ] (or z̃): adding (L, c) to a description
    adds y_std ⊙ s ⊙ (L x + c) to Ĥ."""
    import dataclasses

    plain = gru_model(feedthrough=feedthrough, residual=True).export().network()
    L = rng.normal(size=(N_Y, plain.regression_dim))
    c = rng.normal(size=N_Y)
    with_affine = dataclasses.replace(plain, affine=(L, c))
    z, u = rng.normal(size=(10, 9)), rng.normal(size=(10, 2))
    x = (z - plain.z_mean) / plain.z_std
    if feedthrough:
        x = np.hstack([x, (u - plain.u_mean) / plain.u_std])
    box = {"X": Box(-np.ones(9), np.ones(9)), "U": Box(-np.ones(2), np.ones(2)), "W": Box([0], [0])}
    names = {"input_names": ("a", "b"), "output_names": ("y",)}
    base = LearnedSystem(plain, dt=1.0, **names, **box).h_batch(z, u)
    added = LearnedSystem(with_affine, dt=1.0, **names, **box).h_batch(z, u)
    np.testing.assert_allclose(added - base, 3.0 * 0.3 * (x @ L.T + c), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("activation", ["relu", "tanh", "silu"])
@pytest.mark.parametrize("feedthrough", [False, True])
@pytest.mark.parametrize("residual", [False, True])
def test_the_numpy_linearisation_equals_casadis(activation, feedthrough, residual, rng):
    """``LearnedSystem.linearise`` (numpy, for the MLP) == ``System.linearise`` (CasADi AD)."""
    system = as_system(mlp_model(activation=activation, feedthrough=feedthrough, residual=residual))
    x = rng.normal(size=(7, system.n_x))
    u = rng.normal(size=(7, system.n_u))
    fast, reference = system.linearise(x, u), System.linearise(system, x, u)
    for key in ("f", "h", "f_x", "f_u", "h_x", "h_u"):
        np.testing.assert_allclose(getattr(fast, key), getattr(reference, key), atol=1e-9)


def test_the_numpy_linearisation_includes_the_affine_path(rng):
    net = _affine_net((5,), residual=True, rng=rng)
    system = _unit_system(net)
    x, u = rng.normal(size=(4, system.n_x)), rng.normal(size=(4, system.n_u))
    fast, reference = system.linearise(x, u), System.linearise(system, x, u)
    np.testing.assert_allclose(fast.f_x, reference.f_x, atol=1e-9)
    np.testing.assert_allclose(fast.h_u, reference.h_u, atol=1e-9)
