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
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.hidden = tuple(int(h) for h in hidden)
        self.activation = activation
        if int(cubic) != cubic or cubic < 0:
            raise ShapeError(f"cubic must be a number of units ≥ 0, got {cubic!r}")
        self.cubic = int(cubic)
        width = self._head_width(self.state_dim)
        self.net = mlp(width, self.hidden, self.n_y, activation=activation)
        # built after the MLP, so that a network without it draws the same initial weights
        self.cubic_in = nn.Linear(width, self.cubic) if self.cubic else None
        self.cubic_out = nn.Linear(self.cubic, self.n_y, bias=False) if self.cubic else None
        if self.cubic_out is not None:
            nn.init.zeros_(self.cubic_out.weight)

    def options(self) -> dict[str, Any]:
        extra = {"cubic": self.cubic} if self.cubic else {}  # saved models without it load
        return {"hidden": list(self.hidden), "activation": self.activation, **extra}

    def output_layer(self) -> nn.Linear:
        last = self.net[-1]
        assert isinstance(last, nn.Linear)
        return last

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        if uses_bptt(self, u_past, y_past, u_future):
            self._check_rollout_args(u_past, y_past, u_future)
            return bptt_rollout(self, u_past, y_past, u_future)
        return super().rollout(u_past, y_past, u_future)

    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        x = self._head_input(z, u)
        if self.cubic_in is None or self.cubic_out is None:
            return self.net(x)
        return self.net(x) + self.cubic_out(self.cubic_in(x) ** 3)
