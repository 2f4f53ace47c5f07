"""Datasets: references, controllers, closed-loop simulation, storage and loaders.

The trajectory and dataset types, and the time-alignment convention shared by every layer, are
the kernel's (:mod:`canonid.kernel.dataset`). The names below are imported lazily (PEP 562):
generation needs CasADi and the NMPC controller, reading data does not.
"""

from __future__ import annotations

from canonid.kernel.lazy import lazy_exports

_EXPORTS = {
    "GenerationConfig": "canonid.datagen.generate",
    "GenerationResult": "canonid.datagen.generate",
    "generate_dataset": "canonid.datagen.generate",
    "get_scenario": "canonid.datagen.scenarios",
    "scenario_names": "canonid.datagen.scenarios",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
