"""The true systems: CasADi definitions of f, h, their sets X, U, W, and one registry.

This package is the root of canonid's dependency graph (``canonid → {datagen, learning,
analysis} → models``); it needs only numpy and CasADi.
"""

from models.base import SimResult, System
from models.drone2d import Drone2D
from models.errors import (
    CanonidError,
    CheckpointError,
    DataError,
    NotImplementedYetError,
    SetError,
    ShapeError,
    UnknownSystemError,
)
from models.linear import LinearSystem, linear_example
from models.quadrotor import Quadrotor
from models.registry import get_system, register_system, system_names
from models.sets import Box
from models.tank import Tank

__all__ = [
    "Box",
    "CanonidError",
    "CheckpointError",
    "DataError",
    "Drone2D",
    "LinearSystem",
    "NotImplementedYetError",
    "Quadrotor",
    "SetError",
    "ShapeError",
    "SimResult",
    "System",
    "Tank",
    "UnknownSystemError",
    "get_system",
    "linear_example",
    "register_system",
    "system_names",
]
