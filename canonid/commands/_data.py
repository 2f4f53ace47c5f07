"""Options and loading shared by the commands that read identification data (train, evaluate)."""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from datagen.dataset import Dataset, Trajectory
from datagen.loaders import is_dataset, load_data, split_train_val
from models.errors import DataError
from models.io import read_json

__all__ = [
    "USER_DATA_SPLIT",
    "add_data_options",
    "check_compatible",
    "data_options",
    "load",
    "pick_split",
    "run_data",
    "scoring_data",
    "user_data_as_test",
]

#: the split name under which ``evaluate --data`` scores the records of a CSV or .npz file
USER_DATA_SPLIT = "all"

_FLAGS = {
    "inputs": "--inputs",
    "outputs": "--outputs",
    "experiment_column": "--experiment-column",
    "dt": "--dt",
}


def _columns(text: str) -> list[str]:
    cols = [c.strip() for c in text.split(",") if c.strip()]
    if not cols:
        raise argparse.ArgumentTypeError("expected COL[,COL...]")
    return cols


def add_data_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("CSV data (a .csv file, or a folder of them: one experiment each)")
    g.add_argument("--inputs", type=_columns, metavar="COL,...", help="input columns")
    g.add_argument("--outputs", type=_columns, metavar="COL,...", help="output columns")
    g.add_argument(
        "--experiment-column", metavar="COL", help="column whose value names the experiment"
    )
    g.add_argument("--dt", type=float, metavar="SECONDS", help="sampling time (CSV, .npz)")


def data_options(args: argparse.Namespace) -> dict[str, Any]:
    """The loader options given on the command line (JSON-ready, for the run's recipe)."""
    return {key: getattr(args, key) for key in _FLAGS}


def load(path: str | Path, options: Mapping[str, Any]) -> Dataset:
    """Read ``path`` with the loader ``options``; a canonid dataset carries its own names and
    sampling time, so options given with one are refused rather than silently ignored."""
    given = [_FLAGS[key] for key, value in options.items() if value is not None]
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


def scoring_data(
    recipe_path: Path,
    data: str | Path | None,
    given: Mapping[str, Any],
    *,
    split: str | None,
    model: Mapping[str, Any],
) -> tuple[Dataset, str, str | None]:
    """The data that score a run: ``(dataset, data path, split or None for the default)``.

    Without ``data``, the run's own data split as training split them (default: ``test``, else
    ``val``). With ``data``, that file read with the run's recorded loader options overridden by
    those ``given`` (a canonid dataset takes none), checked against the ``model``'s ``info``.
    """
    recipe = read_json(recipe_path, what="run recipe") if recipe_path.is_file() else {}
    if not isinstance(recipe, dict):
        raise DataError(f"{recipe_path} is not a canonid run recipe (expected a JSON object)")
    if data is None:
        if "data" not in recipe:
            raise DataError(f"{recipe_path}: no field 'data'; give --data FILE")
        if any(value is not None for value in given.values()):
            raise DataError(
                f"{', '.join(_FLAGS[k] for k, v in given.items() if v is not None)} apply to "
                "--data FILE; the run's own data are read with the options it recorded"
            )
        dataset, default_split = run_data(recipe)
        return dataset, str(recipe["data"]), split or default_split
    options = dict(given)
    if not is_dataset(data):
        recorded = recipe.get("data_options") or {}
        options = {k: recorded.get(k) if given.get(k) is None else given[k] for k in _FLAGS}
    dataset = user_data_as_test(load(data, options))
    check_compatible(dataset, model, where=str(data))
    return dataset, str(data), split


def user_data_as_test(dataset: Dataset) -> Dataset:
    """A CSV or .npz file read for scoring: its records are test data, not a ``train`` split,
    so they are named :data:`USER_DATA_SPLIT` (a canonid dataset keeps its splits)."""
    if dataset.metadata.get("source") not in ("csv", "npz") or set(dataset.splits) != {"train"}:
        return dataset
    return dataclasses.replace(dataset, splits={USER_DATA_SPLIT: dataset.split("train")})


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
