"""ARX: the linear canonical model ``ŷ_t = L·[z_t; u_t] + c``, fitted by least squares."""

from __future__ import annotations

from typing import Any

import torch

from canonid.learning.nets.base import CanonicalModel

__all__ = ["ARX"]


class ARX(CanonicalModel):
    """The affine path of :class:`~canonid.learning.nets.base.CanonicalModel` alone: an ARX model of
    orders ``n_a = n_b = ℓ`` (``b_0`` too with feedthrough) on the canonical state.

    :func:`canonid.learning.training.fit` sets ``L, c`` by least squares on the one-step regression
    of the training data and takes no gradient step (``iterative = False``); simulated in open loop
    it is the linear baseline of the identification tables.

    Args:
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual`` (see
            :class:`canonid.learning.nets.base.SequenceModel`); ``linear`` is always ``"arx"``.
    """

    name = "arx"
    label = "ARX (linear)"
    iterative = False
    no_widths = "it is linear, with no hidden layers (its size is the window ℓ alone)"

    def __init__(self, **common: Any) -> None:
        common.pop("linear", None)
        super().__init__(linear="arx", **common)

    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return z.new_zeros(z.shape[0], self.n_y)
