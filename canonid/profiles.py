"""Experiment profiles: the one place where the budgets of every stage are written down, as data.

A profile maps a stage name (``"train"``; later ``"reduce"``, ``"reproduce"``) to the options of
that stage. ``quick`` fits in minutes on a 2-core CPU and goes through the same code path as
``paper``, which uses the paper's numbers (10,000 regressor epochs, Adam at 1e-4) and is meant for
a GPU or a cluster. Later issues add their stages here.

How ``quick`` ``train`` was chosen (tank, ℓ = 10; commands and figures in the README): the
rollout length, learning-rate schedule, batch and curriculum were tuned for the best validation
error in a few CPU minutes; validation runs every 5 epochs on every 5th start time to keep its
cost below the training's.
"""

from __future__ import annotations

import copy
from typing import Any

from learning.training import OptionError, TrainOptions

__all__ = ["PROFILES", "profile", "profile_names", "train_options"]

PROFILES: dict[str, dict[str, dict[str, Any]]] = {
    "quick": {
        "train": {
            "epochs": 600,
            "batch_size": 16,
            "lr": 3e-3,
            "lr_final": 1e-5,
            "horizon": 50,
            "curriculum_epochs": 50,
            "windows_per_trajectory": 4,
            "alpha_first": 10.0,
            "patience": None,
            "val_every": 5,
            "val_stride": 5,
            "val_horizon": 100,
            "checkpoint_every": 25,
        },
    },
    "paper": {
        "train": {
            "epochs": 10_000,
            "batch_size": 32,
            "lr": 1e-4,
            "lr_final": None,
            "horizon": 100,
            "curriculum_epochs": 1_000,
            "windows_per_trajectory": 1,
            "alpha_first": 10.0,
            "patience": 1_000,
            "val_every": 10,
            "val_stride": 1,
            "val_horizon": 100,
            "checkpoint_every": 100,
        },
    },
}


def profile_names() -> list[str]:
    return list(PROFILES)


def profile(name: str) -> dict[str, dict[str, Any]]:
    """A copy of profile ``name`` (stage → options)."""
    try:
        return copy.deepcopy(PROFILES[name])
    except KeyError:
        raise OptionError(f"unknown profile {name!r}; expected one of {profile_names()}") from None


def train_options(name: str, **overrides: Any) -> TrainOptions:
    """The ``train`` stage of profile ``name`` as :class:`TrainOptions`, with ``overrides``
    (``None`` values are ignored, so CLI defaults pass through)."""
    opts = profile(name)["train"]
    opts.update({k: v for k, v in overrides.items() if v is not None})
    return TrainOptions.from_dict(opts)
