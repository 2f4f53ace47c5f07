"""A run folder: its file names, the data its recipe names, its history and its evaluation.

``canonid train``, ``canonid reduce``, ``canonid evaluate``, the reductions of the compression
study and the Table-1 jobs of ``canonid reproduce`` all write the same folder:

* ``run.json`` (:data:`RUN_FILE`) — the recipe: ``data``, ``data_options``, ``val``,
  ``val_fraction``, the model and its options;
* the model (``config.json``, ``weights.pt``, ``normalisation.json``) and ``checkpoint.pt``;
* ``history.csv`` and ``training_curve.png`` (:func:`write_history`);
* ``metrics.json`` (:data:`METRICS_FILE`) and ``rollouts.png`` (:func:`evaluate_run`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from datagen.dataset import Dataset, Trajectory
from datagen.loaders import is_dataset, load_data, split_train_val
from learning import Model, evaluate
from learning.plots import plot_rollouts, plot_training_curve
from models.errors import DataError
from models.io import atomic_write_json, atomic_write_text

__all__ = [
    "DATA_FLAGS",
    "HISTORY_FILE",
    "METRICS_FILE",
    "RUN_FILE",
    "check_compatible",
    "evaluate_run",
    "load",
    "load_splits",
    "pick_split",
    "run_data",
    "write_history",
]

RUN_FILE = "run.json"
#: the loader options a run records, by the command-line flag that sets each
DATA_FLAGS = {
    "inputs": "--inputs",
    "outputs": "--outputs",
    "experiment_column": "--experiment-column",
    "dt": "--dt",
}
METRICS_FILE = "metrics.json"
HISTORY_FILE = "history.csv"


def load_splits(
    recipe: dict[str, Any],
) -> tuple[Dataset, list[Trajectory], list[Trajectory], str, str]:
    """The data of ``recipe``: ``(dataset, train, val, scoring split name, data path)``, split as
    :func:`run_data` splits them."""
    dataset, scoring = run_data(recipe)
    train, val = list(dataset.split("train")), list(dataset.split("val"))
    return dataset, train, val, scoring, str(recipe["data"])


def load(path: str | Path, options: Mapping[str, Any]) -> Dataset:
    """Read ``path`` with the loader ``options``; a canonid dataset carries its own names and
    sampling time, so options given with one are refused rather than silently ignored."""
    given = [DATA_FLAGS[key] for key, value in options.items() if value is not None]
    if given and is_dataset(path):
        raise DataError(
            f"{path} is a canonid dataset, which carries its own signal names and sampling "
            f"time: {', '.join(given)} apply to CSV and .npz data only"
        )
    return load_data(path, **options)


def check_compatible(
    dataset: Dataset,
    reference: Dataset | Mapping[str, Any],
    *,
    where: str,
    whose: str = "the run's",
) -> None:
    """Refuse data whose sampling time or signals differ from ``reference`` (a dataset, or a
    model's ``info`` with ``dt``, ``input_names`` and ``output_names``)."""
    if isinstance(reference, Dataset):
        ref: Mapping[str, Any] = {
            "dt": reference.dt,
            "input_names": list(reference.input_names),
            "output_names": list(reference.output_names),
        }
    else:
        ref = reference
    dt = ref.get("dt")
    if isinstance(dt, (int, float)) and not math.isclose(dataset.dt, dt, rel_tol=1e-9):
        raise DataError(f"{where}: sampling time dt = {dataset.dt:g} s, {whose} is {dt:g} s")
    for key, kind in (("input_names", "input"), ("output_names", "output")):
        names = ref.get(key)
        have = list(getattr(dataset, key))
        if isinstance(names, list) and len(names) != len(have):
            raise DataError(f"{where}: {len(have)} {kind}(s) {have}, {whose} are {names}")


def run_data(recipe: Mapping[str, Any]) -> tuple[Dataset, str]:
    """The data of a training run split as training used them, and the split that scores it.

    The splits are ``train``, ``val`` (from the ``--val`` file, else DATA's own ``val`` split,
    else cut off DATA's ``train`` split by ``val_fraction``) and DATA's ``test`` split if any;
    the score uses ``test`` when there is one, else ``val``.
    """
    data_path, options = str(recipe["data"]), dict(recipe.get("data_options") or {})
    dataset = load(data_path, options)
    if "train" not in dataset.splits:
        raise DataError(
            f"{data_path}: no 'train' split to train on; it has {sorted(dataset.splits)}"
        )
    if recipe.get("val") is not None:
        val_path = str(recipe["val"])
        val_set = load(val_path, options)
        check_compatible(val_set, dataset, where=val_path, whose=f"{data_path}'s")
        if "val" in val_set.splits:
            val = val_set.split("val")
        elif len(val_set.splits) == 1:
            val = val_set.split(next(iter(val_set.splits)))
        else:
            raise DataError(
                f"{val_path}: validation data need a 'val' split or a single split; it has "
                f"{sorted(val_set.splits)}"
            )
        dataset = dataclasses.replace(
            dataset,
            splits={**dataset.splits, "val": val},
            metadata={**dataset.metadata, "validation_split": f"the file {val_path}"},
        )
    elif "val" not in dataset.splits:
        dataset = split_train_val(dataset, val_fraction=recipe.get("val_fraction", 0.2))
    return dataset, "test" if "test" in dataset.splits else "val"


def pick_split(dataset: Dataset, name: str | None, *, where: str) -> tuple[str, list[Trajectory]]:
    """Split ``name``; by default ``test`` if present, else the only split there is."""
    if name is None:
        if "test" in dataset.splits:
            name = "test"
        elif len(dataset.splits) == 1:
            name = next(iter(dataset.splits))
        else:
            raise DataError(
                f"{where}: no 'test' split; choose one of {sorted(dataset.splits)} with --split"
            )
    if name not in dataset.splits:
        raise DataError(f"{where}: no split {name!r}; it has {sorted(dataset.splits)}")
    return name, list(dataset.split(name))


def write_history(run_dir: Path, history: list[dict[str, Any]]) -> None:
    """``history.csv`` (one row per epoch, a column per key any row has) and its figure."""
    keys: list[str] = []
    for row in history:
        keys += [k for k in row if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: ("" if row.get(k) is None else row[k]) for k in keys})
    atomic_write_text(run_dir / HISTORY_FILE, buf.getvalue())
    plot_training_curve(history, run_dir / "training_curve.png")


def evaluate_run(
    run_dir: Path,
    model: Model,
    dataset: Dataset,
    *,
    data_path: str,
    split: str | None,
    horizon: int,
    stride: int,
    n_init: int | None,
) -> dict[str, Any]:
    """Score ``model`` on ``dataset``; write metrics.json and rollouts.png to ``run_dir``."""
    name, trajs = pick_split(dataset, split, where=data_path)
    ell, longest = model.window, max(tr.T for tr in trajs)
    if n_init is None and "n_init" in dataset.metadata:
        n_init = max(int(dataset.metadata["n_init"]), ell)
    elif n_init is None:
        n_init = max(ell, min(50, longest - 1))
    ev = evaluate(
        model,
        trajs,
        horizon=horizon,
        stride=stride,
        n_init=n_init,
        output_names=dataset.output_names,
    )
    metrics = {
        "schema": 1,
        **ev.to_json(),
        "data": {"path": data_path, "split": name, "n_trajectories": len(trajs)},
    }
    atomic_write_json(run_dir / METRICS_FILE, metrics)
    plot_rollouts(
        model,
        trajs,
        run_dir / "rollouts.png",
        n_init=ev.n_init,
        output_names=dataset.output_names,
        dt=dataset.dt,
    )
    return metrics
