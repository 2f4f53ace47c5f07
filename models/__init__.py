"""The true systems: CasADi definitions of f, h, their sets X, U, W, and one registry.

The layer above the kernel (``canonid → {datagen, learning, analysis} → models → kernel``); it
needs numpy and CasADi. The names below are imported lazily (PEP 562), so importing the package
costs nothing until a system is built.
"""

from __future__ import annotations

from canonid.kernel.lazy import lazy_exports

_EXPORTS = {
    "SimResult": "canonid.models.base",
    "System": "canonid.models.base",
    "BoucWen": "canonid.models.bouc_wen",
    "Drone2D": "canonid.models.drone2d",
    "FrictionDrive": "canonid.models.friction_drive",
    "LearnedSystem": "canonid.models.learned",
    "LinearSystem": "canonid.models.linear",
    "linear_example": "canonid.models.linear",
    "MassChain": "canonid.models.masses",
    "OverflowTanks": "canonid.models.overflow_tanks",
    "get_system": "canonid.models.registry",
    "register_system": "canonid.models.registry",
    "system_names": "canonid.models.registry",
    "Box": "canonid.models.sets",
    "Tank": "canonid.models.tank",
    "Quadrotor": "canonid.models.quadrotor",
    "Vibration": "canonid.models.vibration",
    "WienerHammerstein": "canonid.models.wiener_hammerstein",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
