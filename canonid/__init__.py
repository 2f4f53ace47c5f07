"""canonid: learn reduced nonlinear state-space models with the output-error canonical method.

The names a Python user needs, from the library packages (``kernel``, ``models``, ``datagen``,
``learning``, ``analysis``) in one place; the CLI, experiment profiles, sweeps and reports live
in this package's modules. A typical session::

    import canonid

    system = canonid.get_system("tank")                      # a registered true system
    data = canonid.load_data("data/tank")                    # canonid dataset, CSV or .npz
    result = canonid.fit(data.split("train"), data.split("val"), window=2)  # `canonid train`'s
    # defaults: the quick profile; canonid.train_options("quick", epochs=50) shortens it
    scores = canonid.evaluate(result.model, data.split("test"), horizon=100)
    report = canonid.analyze(system, [2])                    # γ_f, α_ℓ, Proposition 2
    checks = report.learned_checks([result.model.export()], data.split("train"),
                                   data.split("test"))      # the model against the theory

Systems and data
    :func:`get_system`, :func:`system_names` (the registry), :class:`Dataset`,
    :class:`Trajectory` (the one trajectory type every function takes; other objects with
    ``.u``, ``.y`` are converted once, ``Trajectory.of(obj)``), :func:`load_data` (a dataset,
    CSV file or folder, or ``.npz``), :class:`GenerationConfig` and :func:`generate_dataset`
    (closed-loop data).
Identification (torch)
    :func:`fit` (by default the options ``canonid train`` uses: :func:`train_options` of the
    ``quick`` profile) with :class:`TrainOptions`, :class:`Model` (``Model.load(run_dir)``,
    ``.export()``), :func:`evaluate`, :func:`reduce_model` with :class:`ReductionOptions`.
Analysis
    :func:`analyze` → :class:`AnalysisReport`; every number is an :class:`Estimate` that says
    whether it is a lower bound, an upper bound or an estimate.

Errors
    Every error canonid raises on purpose is a :class:`CanonidError` (and the closest built-in
    type, e.g. ``ValueError``), whose message names the argument, file or field at fault.

The names load on first use (PEP 562), so ``import canonid`` imports neither numpy, torch nor
CasADi; ``canonid.load_data`` needs numpy only, ``canonid.fit`` imports torch,
``canonid.get_system`` CasADi.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from canonid.kernel.lazy import lazy_exports

#: the package version (pyproject.toml reads it from here)
__version__ = "0.1.0"

_EXPORTS = {
    "CanonidError": "canonid.kernel.errors",
    "get_system": "canonid.models.registry",
    "system_names": "canonid.models.registry",
    "Dataset": "canonid.kernel.dataset",
    "Trajectory": "canonid.kernel.dataset",
    "load_data": "canonid.datagen.loaders",
    "GenerationConfig": "canonid.datagen.generate",
    "generate_dataset": "canonid.datagen.generate",
    "fit": "canonid.api",
    "train_options": "canonid.profiles",
    "TrainOptions": "canonid.learning.training",
    "Model": "canonid.learning.model",
    "evaluate": "canonid.learning.evaluate",
    "reduce_model": "canonid.learning.reduction",
    "ReductionOptions": "canonid.learning.reduction",
    "analyze": "canonid.analysis.report",
    "AnalysisReport": "canonid.analysis.report",
    "Estimate": "canonid.analysis.estimate",
}

__all__ = [
    "AnalysisReport",
    "CanonidError",
    "Dataset",
    "Estimate",
    "GenerationConfig",
    "Model",
    "ReductionOptions",
    "TrainOptions",
    "Trajectory",
    "__version__",
    "analyze",
    "evaluate",
    "fit",
    "generate_dataset",
    "get_system",
    "load_data",
    "reduce_model",
    "system_names",
    "train_options",
]

if TYPE_CHECKING:  # what the lazy names are, for type checkers and editors
    from canonid.analysis.estimate import Estimate
    from canonid.analysis.report import AnalysisReport, analyze
    from canonid.api import fit
    from canonid.datagen.generate import GenerationConfig, generate_dataset
    from canonid.datagen.loaders import load_data
    from canonid.kernel.dataset import Dataset, Trajectory
    from canonid.kernel.errors import CanonidError
    from canonid.learning.evaluate import evaluate
    from canonid.learning.model import Model
    from canonid.learning.reduction import ReductionOptions, reduce_model
    from canonid.learning.training import TrainOptions
    from canonid.models.registry import get_system, system_names
    from canonid.profiles import train_options


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
