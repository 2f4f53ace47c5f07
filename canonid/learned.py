"""A run folder's trained model as a CasADi system, with its sets from the run's training data.

``learned_system(RUN)`` reads the model of ``RUN`` (``canonid.learning.Model.load``), exports its
weights (``NumpyModel.network()``: Ours (MLP), Ours (GRU) and their reduced models) and builds a
:class:`canonid.models.learned.LearnedSystem` with

* ``dt``, input and output names from the data the run was trained on (``RUN/run.json``), units
  from the dataset's metadata where it has them;
* X and U the hulls of the training split's windows and inputs (the same training trajectories
  ``canonid train`` used, validation split included when it was cut from the data);
* W the dataset's noise box (``metadata["noise"]["box"]``) when it records one, else the hull of
  the training noise ``y − y_clean``, else ``{0}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from canonid.datagen.loaders import is_dataset
from canonid.kernel.errors import DataError
from canonid.learning import Model
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box
from canonid.runfolder import RUN_FILE, load, load_splits, recipe_of

__all__ = ["LearnedRun", "learned_system"]


@dataclass(frozen=True)
class LearnedRun:
    """A trained model of a run folder, its system and the data it came from."""

    run: Path
    model: Model
    system: LearnedSystem
    dataset: Any
    train: list[Any]


def _noise_box(dataset: Any, n_y: int) -> Box | None:
    box = dataset.metadata.get("noise", {}).get("box") if dataset.metadata else None
    if not isinstance(box, dict) or len(box.get("lower", ())) != n_y:
        return None
    return Box(box["lower"], box["upper"])


def learned_system(run_dir: Path, *, data: Path | None = None) -> LearnedRun:
    """The model of ``run_dir`` as a system (see the module docstring).

    ``data`` replaces the training data named in ``run_dir/run.json`` (its ``train`` split, or
    all of it when it has no such split).

    Raises:
        NotExportableError: the run's model is not a canonical model (or a reduced one).
        DataError: the run has no recipe naming its data and ``data`` is not given.
    """

    model = Model.load(run_dir)
    net = model.export().network()  # refuses the non-canonical models first
    recipe = recipe_of(run_dir)
    if data is None:
        if recipe is None:
            raise DataError(f"{run_dir / RUN_FILE} not found: the run names no data; give them")
        dataset, train, *_ = load_splits(recipe)  # the training split as `train` cut it
    else:
        recorded = recipe.data_options if recipe is not None else {}
        dataset = load(data, {} if is_dataset(data) else dict(recorded))
        splits = dataset.splits
        train = (
            list(splits["train"]) if "train" in splits else [t for s in splits.values() for t in s]
        )
    units = dataset.metadata.get("units", {}) if dataset.metadata else {}
    system = LearnedSystem.from_data(
        net,
        train,
        dt=float(model.info.get("dt", dataset.dt)),
        input_names=dataset.input_names,
        output_names=dataset.output_names,
        input_units=[units.get("inputs", {}).get(n, "-") for n in dataset.input_names],
        output_units=[units.get("outputs", {}).get(n, "-") for n in dataset.output_names],
        W=_noise_box(dataset, model.n_y),
        name=f"learned:{run_dir.name}",
    )
    return LearnedRun(run=run_dir, model=model, system=system, dataset=dataset, train=train)
