"""Several trainings of one Ours (MLP) recipe, averaged into one canonical model.

:func:`average_members` takes ``K`` trained Ours (MLP) models that differ only in their weights
(the same window, options and normalisation: trainings of one recipe from other seeds) and
returns one :class:`~canonid.learning.model.Model` whose regressor is the mean of theirs,
``Ĥ = (Ĥ_1 + … + Ĥ_K) / K``. The result is itself an Ours (MLP): its hidden layers hold the
members' units side by side (the first layer's rows stacked, the later layers block-diagonal),
its output layer and affine path are the members' averaged, and its cubic branch holds their
units side by side, scaled by ``1/K``. So it rolls out, simulates, saves, loads, analyses and
exports as any trained network, and its state is the canonical state of the paper: the
average is taken at every step, on the model's own past predictions, not over separately
simulated outputs. The network knows its ``K`` groups (``OursMLP(groups=K)``) and applies each
block-diagonal layer block by block, so a step costs about what the ``K`` members' steps cost
together; the weights are stored dense, zeros off the blocks, so analysis and export read a
plain MLP (the numpy analysis multiplies the zeros; CasADi's symbolic export drops them).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import ShapeError
from canonid.learning.data import WindowBank
from canonid.learning.model import Model
from canonid.learning.nets import OursMLP, build_net
from canonid.learning.training import (
    TrainOptions,
    _fit_validation_horizon,
    _validation_starts,
    validation_loss,
)

__all__ = ["average_members", "validation_losses"]


def _linears(net: OursMLP) -> list[nn.Linear]:
    return [m for m in net.net if isinstance(m, nn.Linear)]


def _cubic(net: Any) -> tuple[nn.Linear, nn.Linear]:
    assert isinstance(net.cubic_in, nn.Linear) and isinstance(net.cubic_out, nn.Linear)
    return net.cubic_in, net.cubic_out


def _affine(net: Any) -> nn.Linear:
    assert isinstance(net.affine, nn.Linear)
    return net.affine


def _check(members: Sequence[Model]) -> OursMLP:
    """The first member's network, once every member is an Ours (MLP) of its configuration
    and normalisation; else a :class:`ShapeError` naming the first difference."""
    if len(members) < 1:
        raise ShapeError("average_members: give at least one model")
    first = members[0]
    if not isinstance(first.net, OursMLP):
        raise ShapeError(f"average_members averages Ours (MLP) models; member 1 is {first.name}")
    config, norm = first.net.config(), first.norm.to_dict()
    for i, member in enumerate(members[1:], start=2):
        if not isinstance(member.net, OursMLP):
            raise ShapeError(
                f"average_members averages Ours (MLP) models; member {i} is {member.name}"
            )
        other = member.net.config()
        for key in sorted({*config, *other}):
            if config.get(key) != other.get(key):
                raise ShapeError(
                    f"member {i} differs from member 1 in {key}: {other.get(key)!r} against "
                    f"{config.get(key)!r} (members are trainings of one recipe)"
                )
        if member.norm.to_dict() != norm:
            raise ShapeError(
                f"member {i} was normalised with other statistics than member 1 (members are "
                "trained on the same data)"
            )
        if not torch.equal(member.net.residual_scale, first.net.residual_scale):
            raise ShapeError(f"member {i} has another residual scale than member 1")
    return first.net


def average_members(members: Sequence[Model]) -> Model:
    """One Ours (MLP) whose ``Ĥ`` is the mean of the ``members``' (see the module docstring).

    The result's :attr:`Model.info` is the first member's. One member gives an equal copy of
    it.
    """
    first = _check(members)
    k = len(members)
    nets = [m.net for m in members]
    config = first.config()
    config["hidden"] = [k * h for h in first.hidden]
    config["groups"] = k * first.groups  # members that are means themselves keep their blocks
    if first.cubic:
        config["cubic"] = k * first.cubic
    out = build_net("mlp", **config).to(dtype=next(first.parameters()).dtype)
    assert isinstance(out, OursMLP)
    layers = [_linears(n) for n in nets]  # type: ignore[arg-type]  # checked by _check
    with torch.no_grad():
        for i, layer in enumerate(_linears(out)):
            parts = [member[i] for member in layers]
            if i == 0:  # every member reads the same head input: rows side by side
                layer.weight.copy_(torch.cat([p.weight for p in parts]))
                layer.bias.copy_(torch.cat([p.bias for p in parts]))
            elif i < len(layers[0]) - 1:  # each member's units read only that member's
                layer.weight.copy_(torch.block_diag(*(p.weight for p in parts)))
                layer.bias.copy_(torch.cat([p.bias for p in parts]))
            else:  # the output: the mean of the members' outputs
                layer.weight.copy_(torch.cat([p.weight for p in parts], dim=1) / k)
                layer.bias.copy_(torch.stack([p.bias for p in parts]).mean(dim=0))
        if out.cubic_in is not None and out.cubic_out is not None:
            cubic = [_cubic(n) for n in nets]
            out.cubic_in.weight.copy_(torch.cat([w.weight for w, _ in cubic]))
            out.cubic_in.bias.copy_(torch.cat([w.bias for w, _ in cubic]))
            out.cubic_out.weight.copy_(torch.cat([c.weight for _, c in cubic], dim=1) / k)
        if out.affine is not None:
            affine = [_affine(n) for n in nets]
            out.affine.weight.copy_(torch.stack([a.weight for a in affine]).mean(dim=0))
            out.affine.bias.copy_(torch.stack([a.bias for a in affine]).mean(dim=0))
        out.residual_scale.copy_(first.residual_scale)
    out.eval()
    return Model(out, members[0].norm, info=dict(members[0].info))


def validation_losses(
    models: Sequence[Model], val: Sequence[Trajectory] | Sequence[Any], options: TrainOptions
) -> list[float]:
    """Each model's validation loss as :func:`~canonid.learning.training.fit` scores an epoch
    under ``options`` (normalised rollout MSE), all on the same windows: those of the first
    model's window and normalisation, drawn as ``options`` draws them. Models of one recipe
    (the members and their average) are compared by one computation, so that no difference in
    how their losses were summed can decide between them."""
    first = models[0]
    val = as_trajectories(val, what="validation data")
    opts = _fit_validation_horizon(options, first.window, max(tr.T for tr in val))
    bank = WindowBank(val, first.norm)
    starts = _validation_starts(bank, first.window + opts.rollout_horizon, opts)
    return [validation_loss(m.net, bank, starts, opts.rollout_horizon) for m in models]
