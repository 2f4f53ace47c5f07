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
import io
from pathlib import Path
from typing import Any

from datagen.dataset import Dataset, Trajectory
from datagen.loaders import load_data, split_train_val
from learning import Model, evaluate
from learning.plots import plot_rollouts, plot_training_curve
from models.errors import DataError
from models.io import atomic_write_json, atomic_write_text

__all__ = [
    "HISTORY_FILE",
    "METRICS_FILE",
    "RUN_FILE",
    "evaluate_run",
    "load_splits",
    "pick_split",
    "write_history",
]

RUN_FILE = "run.json"
METRICS_FILE = "metrics.json"
HISTORY_FILE = "history.csv"


def load_splits(
    recipe: dict[str, Any],
) -> tuple[Dataset, list[Trajectory], list[Trajectory], str, str]:
    """The data of ``recipe``: ``(dataset, train, val, test split name, data path)``.

    Validation is the ``val`` split of ``recipe["val"]`` (its ``train`` split if it has no
    ``val``), else the data's own ``val`` split, else a ``val_fraction`` share of its training
    trajectories. The test split is ``test`` if the data has one, else ``val``.
    """
    data_path, options = recipe["data"], recipe["data_options"]
    dataset = load_data(data_path, **options)
    if recipe["val"] is not None:
        val_set = load_data(recipe["val"], **options)
        val = list(val_set.split("val") if "val" in val_set.splits else val_set.split("train"))
    elif "val" in dataset.splits:
        val = list(dataset.split("val"))
    else:
        dataset = split_train_val(dataset, val_fraction=recipe["val_fraction"])
        val = list(dataset.split("val"))
    train = list(dataset.split("train"))
    return dataset, train, val, "test" if "test" in dataset.splits else "val", data_path


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
    if n_init is None and "n_init" in dataset.metadata:
        n_init = max(int(dataset.metadata["n_init"]), model.window)
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
