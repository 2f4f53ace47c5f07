"""Datasets: references, controllers, closed-loop simulation, storage and loaders.

See :mod:`datagen.dataset` for the time-alignment convention shared by every layer.
"""

from datagen.dataset import Dataset, Trajectory

__all__ = ["Dataset", "Trajectory"]
