"""The one registry of true systems. Tests and the CLI are parametrised over it.

A later system joins by one line in ``_FACTORIES``; ``get_system(name, **params)`` passes the
parameters to the system's constructor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from canonid.kernel.errors import UnknownSystemError
from canonid.models.base import System
from canonid.models.drone2d import Drone2D
from canonid.models.linear import LINEAR_EXAMPLES
from canonid.models.quadrotor import Quadrotor
from canonid.models.tank import Tank

__all__ = ["get_system", "register_system", "system_names"]

_FACTORIES: dict[str, Callable[..., System]] = {
    "tank": Tank,
    "drone2d": Drone2D,
    "quadrotor": Quadrotor,
    **LINEAR_EXAMPLES,
}


def register_system(name: str, factory: Callable[..., System]) -> None:
    """Add a system to the registry (raises if the name is taken)."""
    if name in _FACTORIES:
        raise ValueError(f"system {name!r} is already registered")
    _FACTORIES[name] = factory


def system_names() -> list[str]:
    """Names of the registered systems, in registration order."""
    return list(_FACTORIES)


def get_system(name: str, **params: Any) -> System:
    """Build the registered system ``name`` with optional constructor parameters."""
    try:
        factory = _FACTORIES[name]
    except KeyError:
        raise UnknownSystemError(
            f"unknown system {name!r}; expected one of: {', '.join(system_names())}"
        ) from None
    return factory(**params)
