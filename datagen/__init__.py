"""Datasets: references, controllers, closed-loop simulation, storage and loaders.

See :mod:`datagen.dataset` for the time-alignment convention shared by every layer.
"""

from datagen.dataset import Dataset, Trajectory
from datagen.generate import GenerationConfig, GenerationResult, generate_dataset
from datagen.scenarios import get_scenario, scenario_names

__all__ = [
    "Dataset",
    "GenerationConfig",
    "GenerationResult",
    "Trajectory",
    "generate_dataset",
    "get_scenario",
    "scenario_names",
]
