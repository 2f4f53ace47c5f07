"""Classic GRU: a recurrent baseline whose state is the GRU hidden vector (paper §V-B)."""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import nn

from canonid.learning.canonical import state_to_pairs
from canonid.learning.nets.base import SequenceModel, mlp

__all__ = ["ClassicGRU"]


class ClassicGRU(SequenceModel):
    """``h_{t+1} = GRU([u_t; y_t], h_t)``, ``y_t = head(h_t)`` (``head([h_t; u_t])`` with
    feedthrough), ``h`` starting at zero.

    Warm-up: the GRU reads the ℓ measured pairs of the burn-in, giving ``h`` at the first
    predicted sample; afterwards it is fed its own predictions ``[u_t; ŷ_t]``. Its one-step map
    :meth:`one_step` is the warm-up on a measured window followed by the head.

    Args:
        hidden_size: ``n_h``; default ``⌈ℓ (n_u + n_y) / 2⌉``, so that the two layers' hidden
            vectors together match ``dim z`` (paper appendix).
        num_layers: 2 (paper).
        head_hidden: width of the head's single hidden layer; default ``n_h`` (paper).
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual`` (see
            :class:`canonid.learning.nets.base.SequenceModel`).
    """

    name = "classic-gru"
    label = "Classic GRU"

    def __init__(
        self,
        *,
        hidden_size: int | None = None,
        num_layers: int = 2,
        head_hidden: int | None = None,
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.hidden_size = int(hidden_size or math.ceil(self.state_dim / 2))
        self.num_layers = int(num_layers)
        self.head_hidden = int(head_hidden or self.hidden_size)
        self.gru = nn.GRU(self.pair_dim, self.hidden_size, self.num_layers, batch_first=True)
        self.head = mlp(self._head_width(self.hidden_size), (self.head_hidden,), self.n_y)

    def options(self) -> dict[str, Any]:
        return {
            "hidden_size": self.hidden_size,
            "num_layers": self.num_layers,
            "head_hidden": self.head_hidden,
        }

    def one_step(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        _, h = self.gru(state_to_pairs(z, self.n_u, self.n_y))
        return self._output(self.head(self._head_input(h[-1], u)), z[:, -self.n_y :])

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        self._check_rollout_args(u_past, y_past, u_future)
        _, h = self.gru(torch.cat([u_past, y_past], dim=-1))  # warm-up from h = 0
        y_prev = y_past[:, -1]
        outputs = []
        for k in range(u_future.shape[1]):
            u_k = u_future[:, k]
            y_k = self._output(self.head(self._head_input(h[-1], u_k)), y_prev)
            outputs.append(y_k)
            _, h = self.gru(torch.cat([u_k, y_k], dim=-1)[:, None, :], h)
            y_prev = y_k
        return torch.stack(outputs, dim=1)
