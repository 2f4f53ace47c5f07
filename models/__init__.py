"""The true systems: CasADi definitions of f, h, their sets X, U, W, and one registry.

This package is the root of canonid's dependency graph (``canonid → {datagen, learning,
analysis} → models``); it needs only numpy and CasADi. The names below are imported lazily
(PEP 562), so that ``learning`` can use the CasADi-free modules (``models.errors``,
``models.canonical``, ``models.io``, ``models._validate``) without importing CasADi.
"""

from __future__ import annotations

from models.lazy import lazy_exports

_EXPORTS = {
    "SimResult": "models.base",
    "System": "models.base",
    "Drone2D": "models.drone2d",
    "CanonidError": "models.errors",
    "CheckpointError": "models.errors",
    "DataError": "models.errors",
    "SetError": "models.errors",
    "ShapeError": "models.errors",
    "UnknownSystemError": "models.errors",
    "LearnedSystem": "models.learned",
    "LinearSystem": "models.linear",
    "linear_example": "models.linear",
    "get_system": "models.registry",
    "register_system": "models.registry",
    "system_names": "models.registry",
    "Box": "models.sets",
    "Tank": "models.tank",
    "Quadrotor": "models.quadrotor",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
