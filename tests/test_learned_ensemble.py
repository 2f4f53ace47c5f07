"""An ensemble as one learned system (canonid.models.learned, "Ensembles"): Ĥ is the mean of
its members', each with its own normalisation, over the same window state; the fast numpy
linearisation, the certified layer-norm bound and `canonid export RUN RUN` follow it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from canonid.analysis.certify import layer_norm_bound
from canonid.analysis.network_enclosure import network_enclosure
from canonid.kernel.errors import ShapeError
from canonid.learning.data import Normalisation
from canonid.learning.model import Model
from canonid.learning.nets import build_net
from canonid.models.base import System
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box

N_U, N_Y, ELL = 2, 2, 3
N_X = ELL * (N_U + N_Y)


def _net(seed: int, *, window: int = ELL, residual: bool = True, scale: float = 1.0):
    """Ours (MLP) with random float64 weights and a normalisation of its own."""
    torch.manual_seed(seed)
    net = build_net(
        "mlp",
        window=window,
        n_u=N_U,
        n_y=N_Y,
        hidden=[6, 5],
        activation="silu",
        feedthrough=seed % 2 == 0,
        residual=residual,
    ).double()
    with torch.no_grad():
        for p in net.parameters():
            p.normal_(0.0, 0.5)
        net.residual_scale.fill_(0.4)
    norm = Normalisation(
        u_mean=np.array([0.1, -0.2]) * scale,
        u_std=np.array([1.5, 0.7]) * scale,
        y_mean=np.array([2.0, -1.0]) * scale,
        y_std=np.array([3.0, 0.5]) * scale,
        dy_std=np.array([0.5, 0.2]),
    )
    return Model(net, norm).export().network()


def _system(net, members=()) -> LearnedSystem:
    return LearnedSystem(
        net,
        dt=0.1,
        input_names=("a", "b"),
        output_names=("y1", "y2"),
        X=Box(-2 * np.ones(N_X), 2 * np.ones(N_X)),
        U=Box(-np.ones(N_U), np.ones(N_U)),
        W=Box(np.zeros(N_Y), np.zeros(N_Y)),
        members=members,
    )


@pytest.fixture(scope="module")
def nets():
    return [_net(0), _net(1, scale=2.0), _net(2, residual=False)]


def test_the_mean_of_the_members_outputs_and_the_shift_of_it(nets, rng):
    z, u = rng.uniform(-2, 2, size=(30, N_X)), rng.uniform(-1, 1, size=(30, N_U))
    alone = [_system(net).h_batch(z, u) for net in nets]
    ensemble = _system(nets[0], nets[1:])
    mean = np.mean(alone, axis=0)
    np.testing.assert_allclose(ensemble.h_batch(z, u), mean, rtol=0, atol=1e-12)
    x_next = ensemble.f_batch(z, u)
    np.testing.assert_allclose(x_next, np.hstack([z[:, N_U + N_Y :], u, mean]), atol=1e-12)
    assert ensemble.parameters["members"] == 3 and "mean of 3" in ensemble.discretisation
    # one member alone is the model itself, described as before
    single = _system(nets[0])
    assert single.members == (nets[0],) and "members" not in single.parameters
    np.testing.assert_array_equal(single.h_batch(z, u), alone[0])


def test_the_numpy_linearisation_is_the_mean_and_agrees_with_casadi(nets, rng):
    z, u = rng.uniform(-2, 2, size=(7, N_X)), rng.uniform(-1, 1, size=(7, N_U))
    ensemble = _system(nets[0], nets[1:])
    fast = ensemble.linearise(z, u)
    exact = System.linearise(ensemble, z, u)  # CasADi's Jacobians of the SX graph
    for key in ("f", "h", "f_x", "f_u", "h_x", "h_u"):
        np.testing.assert_allclose(getattr(fast, key), getattr(exact, key), atol=1e-10)


def test_certified_layer_norm_bound_covers_the_sampled_slopes(nets, rng):
    ensemble = _system(nets[0], nets[1:])
    bound = layer_norm_bound(ensemble)
    assert bound.kind == "upper" and np.isfinite(bound.value)
    alone = [layer_norm_bound(_system(net)).details["regressor_z"] for net in nets]
    assert bound.details["members_regressor_z"] == alone
    assert bound.details["regressor_z"] >= np.mean(alone)
    z, u = rng.uniform(-2, 2, size=(400, N_X)), rng.uniform(-1, 1, size=(400, N_U))
    slopes = np.linalg.norm(ensemble.linearise(z, u).f_x, ord=2, axis=(1, 2))
    assert slopes.max() <= bound.value
    # the layer-wise interval enclosure reads one network: the SX graph's applies instead
    assert network_enclosure(ensemble) is None and network_enclosure(_system(nets[0])) is not None


def test_members_of_another_window_or_kind_are_refused(nets):
    with pytest.raises(ShapeError, match=r"member 2 has \(ℓ, n_u, n_y\) = \(4, 2, 2\)"):
        _system(nets[0], [_net(3, window=4)])
    with pytest.raises(ShapeError, match="member 2 is a str"):
        _system(nets[0], ["not a network"])
