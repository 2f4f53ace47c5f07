"""Ours (MLP)'s cubic branch: ``Ĥ`` = MLP + ``C (W x + b)³``, ``C`` started at zero."""

from __future__ import annotations

import pytest
import torch

from canonid.kernel.errors import ShapeError
from canonid.learning.nets import build_net

SHAPE = {"window": 3, "n_u": 1, "n_y": 2, "hidden": [8, 8], "linear": "skip"}


def test_a_cubic_branch_starts_as_the_plain_network_with_the_same_weights() -> None:
    torch.manual_seed(0)
    plain = build_net("mlp", **SHAPE)
    torch.manual_seed(0)
    cubic = build_net("mlp", cubic=4, **SHAPE)
    for key, value in plain.state_dict().items():
        assert torch.equal(cubic.state_dict()[key], value)
    z, u = torch.randn(5, plain.state_dim), torch.randn(5, 1)
    assert torch.equal(plain.one_step(z, u), cubic.one_step(z, u))


def test_the_cubic_branch_adds_a_sum_of_cubes_of_linear_forms() -> None:
    torch.manual_seed(1)
    net = build_net("mlp", cubic=3, feedthrough=True, **SHAPE)
    assert net.cubic_in is not None and net.cubic_out is not None
    with torch.no_grad():
        net.cubic_out.weight.normal_()
    z, u = torch.randn(4, net.state_dim), torch.randn(4, 1)
    x = torch.cat([z, u], dim=1)
    expected = net.net(x) + (x @ net.cubic_in.weight.T + net.cubic_in.bias) ** 3 @ (
        net.cubic_out.weight.T
    )
    assert torch.allclose(net.regress(z, u), expected)
    # a cubic: doubling the branch's pre-activations multiplies its output by 8
    with torch.no_grad():
        net.cubic_in.bias.zero_()
        pre = net.cubic_out(net.cubic_in(x) ** 3)
        assert torch.allclose(net.cubic_out(net.cubic_in(2 * x) ** 3), 8 * pre, rtol=1e-5)


def test_the_cubic_option_round_trips_and_is_absent_from_plain_configs() -> None:
    net = build_net("mlp", cubic=5, **SHAPE)
    assert net.config()["cubic"] == 5
    assert "cubic" not in build_net("mlp", **SHAPE).config()
    rebuilt = build_net("mlp", **{k: v for k, v in net.config().items()})
    rebuilt.load_state_dict(net.state_dict())


@pytest.mark.parametrize("units", [-1, 2.5])
def test_a_bad_number_of_cubic_units_is_refused(units: float) -> None:
    with pytest.raises(ShapeError, match="cubic"):
        build_net("mlp", cubic=units, **SHAPE)


def test_stacked_candidates_refuse_a_cubic_branch() -> None:
    from canonid.kernel.errors import OptionError
    from canonid.learning.batched import Candidate, fit_batched
    from tests.learning_helpers import damped_split

    train, val = damped_split()
    with pytest.raises(OptionError, match="cubic"):
        fit_batched(train, val, [Candidate.of()], window=2, net_options={"cubic": 2})
