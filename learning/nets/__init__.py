"""The identification networks, one module each, behind :class:`SequenceModel`; one registry.

========================  =================================================================
name                      model
========================  =================================================================
``mlp``                   Ours (MLP): canonical state, MLP regressor Ĥ
``gru``                   Ours (GRU): canonical state, GRU regressor reading z pair by pair
``classic-gru``           Classic GRU: recurrent state, warm-up on the burn-in window
``masti``                 Masti et al.: encoder → latent dynamics → output, with auto-encoder
========================  =================================================================
"""

from __future__ import annotations

from typing import Any

from canonid.kernel.errors import CanonidError
from canonid.learning.nets.arx import ARX
from canonid.learning.nets.base import CanonicalModel, SequenceModel
from canonid.learning.nets.classic_gru import ClassicGRU
from canonid.learning.nets.masti import Masti
from canonid.learning.nets.ours_gru import OursGRU
from canonid.learning.nets.ours_mlp import OursMLP
from canonid.learning.nets.reduced import ReducedNet
from canonid.learning.nets.registry import (
    ALL_NETS,
    NETS,
    NotReducibleError,
    UnknownModelError,
    check_reducible,
    model_names,
)

__all__ = [
    "ALL_NETS",
    "ARX",
    "NETS",
    "CanonicalModel",
    "ClassicGRU",
    "Masti",
    "NotReducibleError",
    "OursGRU",
    "OursMLP",
    "ReducedNet",
    "SequenceModel",
    "UnknownModelError",
    "build_net",
    "check_reducible",
    "model_names",
]


def build_net(name: str, **config: Any) -> SequenceModel:
    """Build network ``name`` (one of :data:`ALL_NETS`) from its constructor arguments (as
    :meth:`SequenceModel.config`)."""
    try:
        cls = ALL_NETS[name]
    except KeyError:
        raise UnknownModelError(
            f"unknown model {name!r}; expected one of {model_names()}"
        ) from None
    try:
        return cls(**config)
    except CanonidError:
        raise  # already names what is wrong (a bad window, say)
    except (TypeError, ValueError) as exc:
        raise UnknownModelError(f"model {name!r}: bad configuration {config}: {exc}") from None
