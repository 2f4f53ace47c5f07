"""The registry of identification networks: name → class, and the checks that read it.

It lives apart from :mod:`canonid.learning.nets` so that :mod:`canonid.learning.nets.reduced` can
look up the canonical model it wraps without importing the package that imports it.
"""

from __future__ import annotations

from canonid.kernel.errors import CanonidError
from canonid.learning.nets.arx import ARX
from canonid.learning.nets.base import CanonicalModel, SequenceModel
from canonid.learning.nets.classic_gru import ClassicGRU
from canonid.learning.nets.masti import Masti
from canonid.learning.nets.ours_gru import OursGRU
from canonid.learning.nets.ours_mlp import OursMLP

__all__ = [
    "ALL_NETS",
    "NETS",
    "NotReducibleError",
    "UnknownModelError",
    "check_reducible",
    "model_names",
]


class UnknownModelError(CanonidError, ValueError):
    """A model name that is not in the registry, or a configuration its class refuses."""


class NotReducibleError(CanonidError, ValueError):
    """The model asked for cannot be reduced (only canonical models can)."""


#: the registry: name → class (tests are parametrised over it)
NETS: dict[str, type[SequenceModel]] = {
    cls.name: cls for cls in (OursMLP, OursGRU, ClassicGRU, Masti, ARX)
}

#: every network a saved model may hold: the identification models, and the reduced model that
# : :mod:`canonid.learning.nets.reduced` adds when it is imported (``canonid.learning.nets`` imports
# it first)
ALL_NETS: dict[str, type[SequenceModel]] = dict(NETS)


def model_names() -> list[str]:
    """Registered model names, in table order."""
    return list(NETS)


def check_reducible(name: str) -> type[CanonicalModel]:
    """The class of registered model ``name`` if it is a canonical model, else
    :class:`NotReducibleError` naming the models that can be reduced."""
    cls = ALL_NETS.get(name)
    if cls is None or not issubclass(cls, CanonicalModel):
        reducible = [
            f"{c.label} ({n!r})" for n, c in ALL_NETS.items() if issubclass(c, CanonicalModel)
        ]
        label = f"{cls.label} ({name!r})" if cls is not None else repr(name)
        raise NotReducibleError(
            f"only canonical models can be reduced ({', '.join(reducible)}); got {label}"
        )
    return cls
