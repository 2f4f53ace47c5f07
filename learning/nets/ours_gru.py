"""Ours (GRU): the canonical model whose regressor reads ``z_t`` pair by pair with a GRU."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from canonid.learning.canonical import state_to_pairs
from canonid.learning.nets.base import CanonicalModel, mlp

__all__ = ["OursGRU"]


class OursGRU(CanonicalModel):
    """``Ĥ(z_t, u_t) = head([h_ℓ; u_t])`` where a GRU reads the ℓ pairs ``[u_i; y_i]`` of ``z_t``
    (oldest first) from a zero hidden state, and ``h_ℓ`` is its last top-layer hidden state.

    The shift of ``z`` is the canonical one, so the GRU state is rebuilt from the window at every
    step (paper eq. for Ours (GRU): ``h_{t−ℓ} = 0``).

    Args:
        hidden_size, num_layers: the GRU (paper: 128, 3).
        head_hidden: hidden widths of the MLP head (one layer of 128 by default).
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual``, ``linear`` (see
            :class:`canonid.learning.nets.base.SequenceModel` and
            :class:`canonid.learning.nets.base.CanonicalModel`).
    """

    name = "gru"
    label = "Ours (GRU)"
    hidden_option = "head_hidden"

    def __init__(
        self,
        *,
        hidden_size: int = 128,
        num_layers: int = 3,
        head_hidden: Sequence[int] = (128,),
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.hidden_size, self.num_layers = int(hidden_size), int(num_layers)
        self.head_hidden = tuple(int(h) for h in head_hidden)
        self.gru = nn.GRU(self.pair_dim, self.hidden_size, self.num_layers, batch_first=True)
        self.head = mlp(self._head_width(self.hidden_size), self.head_hidden, self.n_y)

    def options(self) -> dict[str, Any]:
        return {
            "hidden_size": self.hidden_size,
            "num_layers": self.num_layers,
            "head_hidden": list(self.head_hidden),
        }

    def output_layer(self) -> nn.Linear:
        last = self.head[-1]
        assert isinstance(last, nn.Linear)
        return last

    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        _, h = self.gru(state_to_pairs(z, self.n_u, self.n_y))  # zero initial state
        return self.head(self._head_input(h[-1], u))
