"""Controllers that close the loop around a true system during data generation.

Each controller is one module behind :class:`datagen.controllers.base.Controller`.
"""

from datagen.controllers.base import Controller, ControlStep

__all__ = ["ControlStep", "Controller"]
