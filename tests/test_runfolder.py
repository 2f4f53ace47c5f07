"""The typed run folder: the recipe's JSON, and the same recipe and seed giving the same run
folder and the same Table 1 (tiny profile, real training)."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import pytest
import torch
from learning_helpers import siso_dataset_file

from canonid.datagen.loaders import data_checksum
from canonid.kernel.errors import CheckpointError
from canonid.learning.presets import net_options
from canonid.profiles import train_options
from canonid.reproduce import table1_rows
from canonid.reproduce_jobs import TrainJob
from canonid.runfolder import (
    RUN_FILE,
    ReductionRecipe,
    RunEvaluation,
    RunRecipe,
    read_recipe,
    recipe_of,
    train_run,
)


@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("data"), T=80)


def _recipe(data: Path, **changes) -> RunRecipe:
    recipe = RunRecipe(
        data=str(data),
        model="mlp",
        window=3,
        net_options=net_options("mlp", {"hidden": [16, 16], "cubic": 0}),
        profile="tiny",
        train_options=train_options("tiny", seed=0, device="cpu").to_dict(),
        command=("canonid", "test"),
    )
    return dataclasses.replace(recipe, **changes)


def test_the_recipe_round_trips_and_names_an_unknown_key(tmp_path):
    recipe = _recipe(tmp_path / "d.npz")
    body = json.loads(json.dumps(recipe.to_dict()))
    assert body["format"] == "canonid-run" and body["version"] == 1
    assert RunRecipe.from_dict(body, where="run.json") == recipe
    old = {k: v for k, v in body.items() if k != "version"}  # written before the version field
    assert RunRecipe.from_dict(old, where="run.json") == recipe
    given = dataclasses.replace(recipe, given_options=("horizon", "epochs"))
    assert RunRecipe.from_dict(json.loads(json.dumps(given.to_dict())), where="run.json") == given
    # a recipe of a canonid before the options given were recorded: none given
    older = {k: v for k, v in given.to_dict().items() if k != "given_options"}
    assert RunRecipe.from_dict(older, where="run.json").given_options == ()
    with pytest.raises(CheckpointError, match=r"given_options.*a list of option names"):
        RunRecipe.from_dict({**body, "given_options": "horizon"}, where="run.json")
    # --members is recorded only where given, so a recipe without it reads (and writes) as before
    assert "members" not in body and RunRecipe.from_dict(body, where="run.json").members is None
    counted = dataclasses.replace(recipe, members=1)
    written = json.loads(json.dumps(counted.to_dict()))
    assert written["members"] == 1 and RunRecipe.from_dict(written, where="run.json") == counted
    for bad in (0, "3", True):
        with pytest.raises(CheckpointError, match=r"'members' must be an integer >= 1"):
            RunRecipe.from_dict({**body, "members": bad}, where="run.json")
    with pytest.raises(CheckpointError, match=r"unknown run recipe key\(s\) \['windw'\]"):
        RunRecipe.from_dict({**body, "windw": 3}, where="run.json")
    with pytest.raises(CheckpointError, match="version 2"):
        RunRecipe.from_dict({**body, "version": 2}, where="run.json")
    with pytest.raises(CheckpointError, match="reduction run"):
        RunRecipe.from_dict({**body, "kind": "reduction"}, where="run.json")


def test_one_reader_gives_the_typed_recipe_of_either_kind_or_one_line(tmp_path):
    reduction = ReductionRecipe(
        data="d.npz",
        regressor="mlp",
        window=3,
        latent_dim=2,
        source_run="/runs/mlp",
        compression=0.5,
        seed=0,
        train_options={"epochs": 2},
        reduction_options={"linear_skip": True},
        command=("canonid", "reduce"),
    )
    body = json.loads(json.dumps(reduction.to_dict()))
    assert body["kind"] == "reduction" and body["model"] == "reduced" and body["version"] == 1
    reduction.write(tmp_path / "r")
    assert read_recipe(tmp_path / "r") == reduction
    _recipe(tmp_path / "d.npz").write(tmp_path / "t")
    assert read_recipe(tmp_path / "t") == _recipe(tmp_path / "d.npz")
    assert recipe_of(tmp_path) is None  # no run.json: a model saved without a run
    old = {k: v for k, v in body.items() if k != "version"}  # written before the version field
    assert ReductionRecipe.from_dict(old, where="run.json") == reduction
    path = tmp_path / "r" / RUN_FILE
    for change, needle in (
        ({"version": 2}, "version 2"),
        ({"latent": 2}, r"unknown run recipe key\(s\) \['latent'\]"),
        ({"kind": "sweep"}, "unknown run kind 'sweep'"),
        ({"model": "mlp"}, "model 'mlp'"),
    ):
        path.write_text(json.dumps({**body, **change}))
        with pytest.raises(CheckpointError, match=needle) as caught:
            read_recipe(tmp_path / "r")
        assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def _contents(run: Path) -> dict[str, object]:
    """Every file of a run folder that the recipe and seed determine: JSON bodies, the history
    without its wall-clock column, and the weights as tensors."""
    out: dict[str, object] = {
        name: json.loads((run / name).read_text())
        for name in (RUN_FILE, "config.json", "normalisation.json", "metrics.json")
    }
    with (run / "history.csv").open() as f:
        out["history"] = [
            {k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)
        ]
    out["weights"] = {
        k: v.tolist() for k, v in torch.load(run / "weights.pt", weights_only=True).items()
    }
    return out


def test_the_same_recipe_gives_the_same_run_folder(dataset_path, tmp_path):
    recipe = _recipe(dataset_path)
    first = train_run(recipe, tmp_path / "a")
    second = train_run(recipe, tmp_path / "b")
    assert isinstance(first.evaluation, RunEvaluation)
    assert first.evaluation.split == "val" and first.evaluation.rollout_mse_clean is not None
    assert first.evaluation.rollout_mse == second.evaluation.rollout_mse
    # the recipe as written: its data by absolute path and checksum
    assert RunRecipe.read(tmp_path / "a") == recipe.pinned() == first.recipe
    assert Path(first.recipe.data).is_absolute()
    assert first.recipe.data_sha256 == data_checksum(dataset_path)
    assert _contents(tmp_path / "a") == _contents(tmp_path / "b")
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert metrics == first.evaluation.to_json() | {"data": metrics["data"]}


def test_the_same_table1_jobs_give_the_same_table1(dataset_path, tmp_path):
    def jobs(out: Path) -> list[TrainJob]:
        return [
            TrainJob(
                system="damped",
                model=model,
                window=3,
                seed=0,
                data=str(dataset_path),
                data_sha256="-",
                folder=str(out / f"{model}-l3-s0"),
                profile="tiny",
                train_options=train_options("tiny", seed=0, device="cpu").to_dict(),
                evaluation={"horizon": 20, "stride": 5},
                net_options=net_options(model, {}, paper=True),
            )
            for model in ("mlp", "arx")
        ]

    tables = [table1_rows([job.run() for job in jobs(tmp_path / name)]) for name in "ab"]
    assert tables[0] == tables[1] and len(tables[0]) == 2
    assert all(cell.mean_clean is not None for cell in tables[0])
