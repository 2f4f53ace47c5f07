"""Ours (MLP): the canonical model with an MLP regressor ``Ĥ(z_t, u_t)`` (paper §III, appendix)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from canonid.learning.nets.base import CanonicalModel, mlp

__all__ = ["OursMLP"]


class OursMLP(CanonicalModel):
    """``Ĥ`` = MLP on ``[z_t; u_t]`` (``z_t`` alone without feedthrough).

    Args:
        hidden: hidden layer widths; the paper uses 3 × 256 on the simulated systems and
            2 × 2048 on the quadrotor.
        activation: the hidden layers' nonlinearity, ``"relu"`` (the paper's), ``"tanh"`` or
            ``"silu"``.
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual``, ``linear`` (see
            :class:`canonid.learning.nets.base.SequenceModel` and
            :class:`canonid.learning.nets.base.CanonicalModel`).
    """

    name = "mlp"
    label = "Ours (MLP)"
    hidden_option = "hidden"

    def __init__(
        self,
        *,
        hidden: Sequence[int] = (256, 256, 256),
        activation: str = "relu",
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.hidden = tuple(int(h) for h in hidden)
        self.activation = activation
        self.net = mlp(
            self._head_width(self.state_dim), self.hidden, self.n_y, activation=activation
        )

    def options(self) -> dict[str, Any]:
        return {"hidden": list(self.hidden), "activation": self.activation}

    def output_layer(self) -> nn.Linear:
        last = self.net[-1]
        assert isinstance(last, nn.Linear)
        return last

    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return self.net(self._head_input(z, u))
