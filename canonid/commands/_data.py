"""Options and loading shared by the commands that read identification data (train, evaluate)."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from canonid.datagen.loaders import is_dataset
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError
from canonid.runfolder import (
    DATA_FLAGS,
    RUN_FILE,
    check_compatible,
    load,
    pick_split,
    recipe_of,
    run_data,
)

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

_FLAGS = DATA_FLAGS


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


def scoring_data(
    run_dir: Path,
    data: str | Path | None,
    given: Mapping[str, Any],
    *,
    split: str | None,
    model: Mapping[str, Any],
) -> tuple[Dataset, str, str | None]:
    """The data that score the run in ``run_dir``: ``(dataset, data path, split or None for the
    default)``.

    Without ``data``, the run's own data split as training split them (default: ``test``, else
    ``val``). With ``data``, that file read with the run's recorded loader options overridden by
    those ``given`` (a canonid dataset takes none), checked against the ``model``'s ``info``.
    """
    recipe = recipe_of(run_dir)
    if data is None:
        if recipe is None:
            raise DataError(
                f"{run_dir / RUN_FILE} not found: the run names no data; give --data FILE"
            )
        if any(value is not None for value in given.values()):
            raise DataError(
                f"{', '.join(_FLAGS[k] for k, v in given.items() if v is not None)} apply to "
                "--data FILE; the run's own data are read with the options it recorded"
            )
        dataset, default_split = run_data(recipe)
        return dataset, recipe.data, split or default_split
    options = dict(given)
    if not is_dataset(data):
        recorded = recipe.data_options if recipe is not None else {}
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
