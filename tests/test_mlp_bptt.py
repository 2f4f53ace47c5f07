"""Ours (MLP)'s hand-written training rollout (canonid.learning.nets.mlp_bptt) against autograd
through the step-by-step rollout: the same predictions and the same weight gradients (float64),
over every option of the network; and the cases that keep autograd's rollout."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from learning_helpers import damped_split

from canonid.learning import fit
from canonid.learning.nets import OursMLP, build_net
from canonid.learning.nets.base import output_error
from canonid.learning.nets.mlp_bptt import uses_bptt
from canonid.learning.training import TrainOptions


def _net(seed: int = 0, **options) -> OursMLP:
    torch.manual_seed(seed)
    net = build_net("mlp", **options).double()
    assert isinstance(net, OursMLP)
    with torch.no_grad():
        for p in net.parameters():  # zero-started layers (cubic output, skip) get weights too
            p.normal_(0.0, 0.3)
        if net.cubic_out is not None:  # small, as after training: iterated cubes run away
            net.cubic_out.weight.normal_(0.0, 0.05)
        net.residual_scale.uniform_(0.2, 1.5)
    return net


def _both(net: OursMLP, u: torch.Tensor, y: torch.Tensor, ell: int):
    """Predictions and weight gradients of one output-error loss, by autograd through the
    step-by-step rollout and by the hand-written back-propagation."""
    results = []
    for bptt in (False, True):
        net.bptt = bptt
        assert uses_bptt(net, u) is bptt
        pred = net.rollout(u[:, :ell], y[:, :ell], u[:, ell:])
        loss = output_error(pred, y[:, ell:], alpha_first=10.0)
        results.append((pred.detach(), torch.autograd.grad(loss, list(net.parameters()))))
    return results


@settings(max_examples=60, deadline=None)
@given(
    activation=st.sampled_from(["silu", "relu", "tanh"]),
    cubic=st.sampled_from([0, 3]),
    linear=st.sampled_from(["off", "skip", "arx"]),
    feedthrough=st.booleans(),
    residual=st.booleans(),
    hidden=st.lists(st.integers(1, 9), min_size=1, max_size=3),
    window=st.integers(1, 4),
    n_u=st.integers(1, 3),
    n_y=st.integers(1, 3),
    horizon=st.integers(1, 6),
    batch=st.integers(1, 4),
    seed=st.integers(0, 2**16),
)
def test_predictions_and_weight_gradients_equal_autograds(
    activation, cubic, linear, feedthrough, residual, hidden, window, n_u, n_y, horizon, batch, seed
):
    net = _net(
        seed,
        window=window,
        n_u=n_u,
        n_y=n_y,
        feedthrough=feedthrough,
        residual=residual,
        linear=linear,
        hidden=hidden,
        activation=activation,
        cubic=cubic,
    )
    gen = torch.Generator().manual_seed(seed)
    u = torch.randn(batch, window + horizon, n_u, generator=gen, dtype=torch.float64)
    y = torch.randn(batch, window + horizon, n_y, generator=gen, dtype=torch.float64)
    (pred_a, grads_a), (pred_b, grads_b) = _both(net, u, y, window)
    # a rollout that runs away (the cube of a cube …) overflows both ways alike; not a model
    # training would keep
    assume(bool(pred_a.abs().max() < 1e3) and all(bool(g.isfinite().all()) for g in grads_a))
    torch.testing.assert_close(pred_b, pred_a, rtol=1e-12, atol=1e-12)
    names = [name for name, _ in net.named_parameters()]
    for name, ga, gb in zip(names, grads_a, grads_b, strict=True):
        torch.testing.assert_close(gb, ga, rtol=1e-10, atol=1e-12, msg=name)


def test_without_recorded_weight_gradients_the_step_by_step_rollout_runs():
    net = _net(window=2, n_u=1, n_y=1, hidden=[4], cubic=0)
    u = torch.randn(3, 5, 1, dtype=torch.float64)
    y = torch.randn(3, 5, 1, dtype=torch.float64)
    with torch.no_grad():
        assert not uses_bptt(net, u, y)
    net.net[0].weight.requires_grad_(False)  # a frozen layer: autograd's own graph
    assert not uses_bptt(net, u, y)
    net.net[0].weight.requires_grad_(True)
    assert uses_bptt(net, u, y)
    assert not uses_bptt(net, u.requires_grad_(True), y)  # a gradient for the data: autograd's
    # and that path still differentiates in the data
    pred = net.rollout(u[:, :2], y[:, :2], u[:, 2:])
    (grad_u,) = torch.autograd.grad(pred.sum(), [u])
    assert grad_u.shape == u.shape and torch.isfinite(grad_u).all()


def test_no_hidden_layer_keeps_the_step_by_step_rollout():
    net = _net(window=2, n_u=1, n_y=1, hidden=[], cubic=0)
    u = torch.randn(2, 4, 1, dtype=torch.float64)
    assert not uses_bptt(net, u)


def test_float32_training_runs_agree_with_autograds_to_rounding():
    """Five short epochs of ``fit`` both ways: the same early stop and losses that differ by
    rounding only (the products are summed in another order)."""
    train, val = damped_split(4, 2, 60)
    options = TrainOptions(
        epochs=5, batch_size=8, horizon=8, curriculum_epochs=3, windows_per_epoch=24, seed=3
    )
    net_options = {"hidden": [16, 16], "activation": "silu", "linear": "skip", "cubic": 2}
    runs = []
    for bptt in (False, True):
        OursMLP.bptt = bptt
        try:
            runs.append(
                fit(train, val, model="mlp", window=3, options=options, net_options=net_options)
            )
        finally:
            OursMLP.bptt = True
    a, b = runs
    assert (a.best_epoch, a.epochs_run) == (b.best_epoch, b.epochs_run)
    losses_a = [row["train_loss"] for row in a.history[1:]]
    losses_b = [row["train_loss"] for row in b.history[1:]]
    np.testing.assert_allclose(losses_b, losses_a, rtol=1e-4)
    for key, value in a.model.net.state_dict().items():
        torch.testing.assert_close(b.model.net.state_dict()[key], value, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("bptt", [False, True])
def test_the_same_seed_gives_the_same_weights(bptt):
    train, val = damped_split(3, 2, 40)
    options = TrainOptions(epochs=2, batch_size=4, horizon=5, windows_per_epoch=8, seed=1)
    OursMLP.bptt = bptt
    try:
        first, second = (
            fit(train, val, model="mlp", window=2, options=options, net_options={"hidden": [8]})
            for _ in range(2)
        )
    finally:
        OursMLP.bptt = True
    for key, value in first.model.net.state_dict().items():
        assert torch.equal(second.model.net.state_dict()[key], value), key


def test_a_wrapped_regressor_keeps_the_step_by_step_rollout():
    """``net.net`` replaced by a wrapper (as ``torch.compile`` returns): autograd's rollout,
    which calls the wrapper, not the layers it may no longer expose."""

    class Wrapped(torch.nn.Module):
        def __init__(self, inner: torch.nn.Module) -> None:
            super().__init__()
            self.inner = inner

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.inner(x)

    net = _net(window=2, n_u=1, n_y=1, hidden=[4], cubic=0)
    net.net = Wrapped(net.net)
    u = torch.randn(2, 5, 1, dtype=torch.float64)
    y = torch.randn(2, 5, 1, dtype=torch.float64)
    assert not uses_bptt(net, u, y)
    pred = net.rollout(u[:, :2], y[:, :2], u[:, 2:])
    pred.sum().backward()
    assert net.net.inner[0].weight.grad is not None
