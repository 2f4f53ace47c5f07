"""The kernel under every layer: errors, atomic file I/O, argument validators, lazy exports, the
one trajectory and dataset type, the canonical state's shift and a trained network as numpy
arrays.

It needs numpy only — no CasADi, torch or scipy — so each layer above (``canonid.models``,
``canonid.datagen``, ``canonid.learning``, ``canonid.analysis`` and the application layer in
``canonid``) can use it without pulling in another's dependencies. ``tests/test_layout.py``
enforces that.
"""

from __future__ import annotations

from canonid.kernel.lazy import lazy_exports

_EXPORTS = {
    "CanonidError": "canonid.kernel.errors",
    "CheckpointError": "canonid.kernel.errors",
    "DataError": "canonid.kernel.errors",
    "OptionError": "canonid.kernel.errors",
    "Dataset": "canonid.kernel.dataset",
    "Trajectory": "canonid.kernel.dataset",
    "as_trajectories": "canonid.kernel.dataset",
    "OutputError": "canonid.kernel.errors",
    "SetError": "canonid.kernel.errors",
    "ShapeError": "canonid.kernel.errors",
    "UnknownSplitError": "canonid.kernel.errors",
    "UnknownSystemError": "canonid.kernel.errors",
    "lazy_exports": "canonid.kernel.lazy",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
