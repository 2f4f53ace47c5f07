"""Ours (MLP): the canonical model with an MLP regressor ``Ĥ(z_t, u_t)`` (paper §III, appendix)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from canonid.kernel.errors import ShapeError
from canonid.learning.nets.base import CanonicalModel, mlp
from canonid.learning.nets.mlp_bptt import bptt_rollout, uses_bptt

__all__ = ["OursMLP"]


class OursMLP(CanonicalModel):
    """``Ĥ`` = MLP on ``[z_t; u_t]`` (``z_t`` alone without feedthrough), plus an optional cubic
    branch ``C (W x + b)³`` on the same input ``x`` (elementwise cube).

    The cubic branch is a low-rank polynomial path: a sum of cubes of ``cubic`` linear forms of
    the regression vector, the kind of term polynomial state-space models add. Unlike the MLP's
    SiLU units, which grow linearly beyond the training range, it keeps a cubic growth there,
    which extrapolates a hardening spring; ``C`` starts at zero, so training starts from the MLP.

    Args:
        hidden: hidden layer widths; the paper uses 3 × 256 on the simulated systems and
            2 × 2048 on the quadrotor.
        activation: the hidden layers' nonlinearity, ``"relu"`` (the paper's), ``"tanh"`` or
            ``"silu"``.
        cubic: units of the cubic branch (0: none).
        groups: ``K`` independent networks side by side (the mean of ``K`` trained ones:
            :func:`canonid.learning.members.average_members`): every hidden width is ``K``
            members' units, the hidden layers after the first are block-diagonal and are applied
            block by block (``K`` products of one member's size, not one ``K²`` times as large); the
            weights are stored dense, so saving, analysis and export read a plain MLP.
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual``, ``linear`` (see
            :class:`canonid.learning.nets.base.SequenceModel` and
            :class:`canonid.learning.nets.base.CanonicalModel`).
    """

    name = "mlp"
    label = "Ours (MLP)"
    hidden_option = "hidden"
    #: training rollouts (gradients of the weights recorded) run the hand-written
    #: back-propagation of :mod:`canonid.learning.nets.mlp_bptt`; ``False``: autograd records
    #: :meth:`CanonicalModel.rollout` step by step (benchmarks/bench_training.py compares both)
    bptt: bool = True

    def __init__(
        self,
        *,
        hidden: Sequence[int] = (256, 256, 256),
        activation: str = "relu",
        cubic: int = 0,
        groups: int = 1,
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.hidden = tuple(int(h) for h in hidden)
        self.activation = activation
        if int(cubic) != cubic or cubic < 0:
            raise ShapeError(f"cubic must be a number of units ≥ 0, got {cubic!r}")
        self.cubic = int(cubic)
        if int(groups) != groups or groups < 1 or any(h % int(groups) for h in self.hidden):
            raise ShapeError(
                f"groups must be a number ≥ 1 that divides every hidden width {list(self.hidden)},"
                f" got {groups!r}"
            )
        self.groups = int(groups)
        # each block-diagonal layer's blocks, (K, out, in), kept while its weight is unchanged
        self._blocks: dict[int, tuple[tuple[int, int], torch.Tensor]] = {}
        width = self._head_width(self.state_dim)
        self.net = mlp(width, self.hidden, self.n_y, activation=activation)
        # built after the MLP, so that a network without it draws the same initial weights
        self.cubic_in = nn.Linear(width, self.cubic) if self.cubic else None
        self.cubic_out = nn.Linear(self.cubic, self.n_y, bias=False) if self.cubic else None
        if self.cubic_out is not None:
            nn.init.zeros_(self.cubic_out.weight)

    def options(self) -> dict[str, Any]:
        extra = {"cubic": self.cubic} if self.cubic else {}  # saved models without it load
        if self.groups > 1:
            extra["groups"] = self.groups
        return {"hidden": list(self.hidden), "activation": self.activation, **extra}

    def output_layer(self) -> nn.Linear:
        last = self.net[-1]
        assert isinstance(last, nn.Linear)
        return last

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        if self.groups == 1 and uses_bptt(self, u_past, y_past, u_future):
            self._check_rollout_args(u_past, y_past, u_future)
            return bptt_rollout(self, u_past, y_past, u_future)
        return super().rollout(u_past, y_past, u_future)

    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        x = self._head_input(z, u)
        out = self.net(x) if self.groups == 1 else self._grouped(x)
        if self.cubic_in is None or self.cubic_out is None:
            return out
        return out + self.cubic_out(self.cubic_in(x) ** 3)

    def _grouped(self, x: torch.Tensor) -> torch.Tensor:
        """``self.net(x)`` with each layer after the first applied block by block (``groups``):
        the same numbers up to rounding, since the weights off the blocks are zero."""
        layers = list(self.net)
        k = self.groups
        for i in range(0, len(layers) - 1, 2):
            linear, activation = layers[i], layers[i + 1]
            assert isinstance(linear, nn.Linear)
            if i == 0:  # the first layer reads the shared input: one product
                x = linear(x)
            else:  # (K, rows, in) @ (K, in, out) + bias, one batched product
                blocks = self._layer_blocks(i, linear)
                _, width_out, width_in = blocks.shape
                parts = x.reshape(-1, k, width_in).transpose(0, 1)
                bias = linear.bias.view(k, 1, width_out)
                out = torch.baddbmm(bias, parts, blocks.transpose(1, 2))
                x = out.transpose(0, 1).reshape(*x.shape[:-1], k * width_out)
            x = activation(x)
        return layers[-1](x)

    def _layer_blocks(self, index: int, linear: nn.Linear) -> torch.Tensor:
        """The ``(K, out, in)`` diagonal blocks of ``linear``'s weight; while no gradient is
        recorded, cut once per version of the weight (a simulation's steps reuse them)."""
        k, weight = self.groups, linear.weight
        out, inp = weight.shape[0] // k, weight.shape[1] // k
        blocks = weight.view(k, out, k, inp).diagonal(dim1=0, dim2=2).permute(2, 0, 1)  # a view
        if torch.is_grad_enabled():
            return blocks
        key = (weight._version, weight.data_ptr())
        cached = self._blocks.get(index)
        if cached is None or cached[0] != key:
            cached = self._blocks[index] = (key, blocks.contiguous())
        return cached[1]
