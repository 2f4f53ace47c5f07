"""The one registry of true systems. Tests and the CLI are parametrised over it.

A later system joins by one line in ``_FACTORIES``; ``get_system(name, **params)`` passes the
parameters to the system's constructor.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

from canonid.kernel.errors import UnknownSystemError
from canonid.models.base import System
from canonid.models.bouc_wen import BoucWen
from canonid.models.drone2d import Drone2D
from canonid.models.friction_drive import FrictionDrive
from canonid.models.linear import LINEAR_EXAMPLES
from canonid.models.masses import MassChain
from canonid.models.overflow_tanks import OverflowTanks
from canonid.models.quadrotor import Quadrotor
from canonid.models.tank import Tank
from canonid.models.vibration import Vibration
from canonid.models.wiener_hammerstein import WienerHammerstein

__all__ = ["get_system", "register_system", "signal_units", "system_names"]

_FACTORIES: dict[str, Callable[..., System]] = {
    "tank": Tank,
    "drone2d": Drone2D,
    "quadrotor": Quadrotor,
    "masses": MassChain,
    "tanks-overflow": OverflowTanks,
    "wiener-hammerstein": WienerHammerstein,
    "vibration": Vibration,
    "bouc-wen": BoucWen,
    "friction-drive": FrictionDrive,
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


def signal_units(
    metadata: Mapping[str, Any], names: Sequence[str], kind: Literal["inputs", "outputs"]
) -> list[str | None]:
    """The unit of each signal in ``names`` (``None`` where unknown): from a dataset's
    ``metadata["units"]`` (``{kind: {name: unit}}`` as ``canonid generate`` writes it, or a flat
    ``{name: unit}``), else from the registered system the metadata name (``metadata["system"]``,
    a name or a description with a ``"name"``) when its signals are these ``names``."""
    units = metadata.get("units")
    if isinstance(units, Mapping):
        by_kind = units.get(kind)
        table: Mapping[str, Any] = by_kind if isinstance(by_kind, Mapping) else units
        found = [table.get(n) for n in names]
        if any(isinstance(u, str) for u in found):
            return [u if isinstance(u, str) else None for u in found]
    system = metadata.get("system")
    name = system.get("name") if isinstance(system, Mapping) else system
    if not isinstance(name, str) or name not in _FACTORIES:
        return [None] * len(names)
    known = get_system(name)
    signals = dict(
        zip(known.output_names, known.output_units)
        if kind == "outputs"
        else zip(known.input_names, known.input_units)
    )
    return [signals.get(n) for n in names]
