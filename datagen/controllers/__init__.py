"""Controllers that close the loop around a true system during data generation.

Each controller is one module behind :class:`canonid.datagen.controllers.base.Controller`.
"""

from canonid.datagen.controllers.base import Controller, ControlStep

__all__ = ["ControlStep", "Controller"]
