"""Datasets: references, controllers, closed-loop simulation, storage and loaders.

See :mod:`canonid.datagen.dataset` for the time-alignment convention shared by every layer.
"""

from canonid.datagen.dataset import Dataset, Trajectory
from canonid.datagen.generate import GenerationConfig, GenerationResult, generate_dataset
from canonid.datagen.scenarios import get_scenario, scenario_names

__all__ = [
    "Dataset",
    "GenerationConfig",
    "GenerationResult",
    "Trajectory",
    "generate_dataset",
    "get_scenario",
    "scenario_names",
]
