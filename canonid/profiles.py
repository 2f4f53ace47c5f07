"""Experiment profiles: the one place where the budgets of every stage are written down, as data.

A profile maps a stage name (``"train"``, ``"reduce"``, ``"reproduce"``) to the options of that
stage. ``quick`` fits in minutes on a 2-core CPU and goes through the same code path as ``paper``,
which uses the paper's numbers (10,000 regressor epochs, Adam at 1e-4) and is meant for a GPU or a
cluster; ``tiny`` exists for the tests (the same code path in seconds). How each ``quick`` value
was chosen, with the commands and figures, is in the docs ("Identification", "Model reduction").

``train`` holds :class:`canonid.learning.training.TrainOptions`. An epoch is ``windows_per_epoch``
sub-windows drawn over all training trajectories, so a budget means the same number of optimiser
steps however the data are cut.

``reduce`` holds the auto-encoder's :class:`~canonid.learning.training.TrainOptions` and the
:class:`canonid.learning.reduction.ReductionOptions` (sizes of E and D, the share of epochs with Ĥ
frozen, loss weights, ``linear_skip``) in one mapping.

:func:`load_profile` gives a profile typed (:class:`Profile`: :class:`~canonid.learning.training.
TrainOptions`, :class:`ReduceStage`, :class:`ReproduceStage`), validated when it is built: a
misspelt key at any level is an error naming it.

``reproduce`` (read by :mod:`canonid.reproduce`) says what ``canonid reproduce`` runs: the default
systems, windows, models and number of seeds of Table 1 (jobs start in the listed order, the
longest first); per system the dataset (``data``: seed, flights per split, samples per flight);
``train``: overrides of the ``train`` stage for every Table-1 job (``per_system`` and
``per_model``: further overrides for one system or model); ``networks``: per system and model,
constructor options over the paper's network (:data:`canonid.learning.presets.PAPER_NET_OPTIONS`);
``evaluation``: the paper metric's rollout length and start stride; ``analysis``: per system,
the windows, sets, Monte-Carlo trials and the budget of every certified search (systems not
listed are not analysed); ``defaults``: the models and windows that also get a column trained
with canonid's default network options (:data:`canonid.learning.presets.DEFAULT_NET_OPTIONS`)
and the profile's ``train`` stage without the overrides above (what ``canonid train --profile
P`` runs), beside the paper's columns; ``compression``: which trained runs the compression study
reduces, at which rates and seeds (``epochs`` overrides the ``reduce`` stage's); ``rollouts``:
the window of the per-system rollout figure.

:func:`profile_values` writes an option's value in every profile for ``--help``, so that the
command line shows the defaults that this table holds.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from canonid.kernel.catalog import help_value
from canonid.kernel.errors import OptionError

if TYPE_CHECKING:  # torch: the option types load when a profile is typed, not for --help
    from canonid.learning.reduction import ReductionOptions
    from canonid.learning.training import TrainOptions

__all__ = [
    "DEFAULT_PROFILE",
    "PROFILES",
    "Profile",
    "ReduceStage",
    "ReproduceStage",
    "load_profile",
    "profile",
    "profile_names",
    "profile_values",
    "reduce_options",
    "stage_train_options",
    "train_options",
]

#: the profile every command and ``canonid.fit`` use when none is named
DEFAULT_PROFILE = "quick"

PROFILES: dict[str, dict[str, dict[str, Any]]] = {
    "quick": {
        "reproduce": {
            "systems": ["tank"],
            "windows": [10, 5],
            "models": ["gru", "mlp", "classic-gru", "masti", "arx"],
            "seeds": 1,
            "data": {
                "tank": {"seed": 0, "counts": {"train": 60, "val": 20, "test": 20}},
                "drone2d": {"seed": 0, "counts": {"train": 60, "val": 10, "test": 10}},
                "quadrotor": {"seed": 0, "counts": {"train": 40, "val": 10, "test": 10}},
            },
            "train": {
                "epochs": 150,
                "horizon": 50,
                # Table 1's budget as measured for the paper comparison (docs: Reproducing)
                "batch_size": 16,
                "grad_clip": None,  # None switches the train stage's clipping off
                "weight_decay": 0.0,  # nor was there weight decay in it
                "windows_per_epoch": 240,
                "val_windows": 1000,
                "val_measure": "rollout",  # the paper's models validate on rollouts, as it did
                "per_model": {"gru": {"epochs": 30}, "mlp": {"epochs": 300}},
            },
            "evaluation": {"horizon": 100, "stride": 5},
            "analysis": {
                "tank": {
                    "windows": [1, 2, 3, 4, 5],
                    "X": [[0.05, 0.05], [5.0, 5.0]],
                    "U": [[1.0], [3.0]],
                    "trials": 200,
                    "budget_seconds": 5.0,
                    "boxes": 20_000,
                },
                "drone2d": {
                    "windows": [1, 2, 3, 4, 5],
                    "trials": 100,
                    "budget_seconds": 5.0,
                    "boxes": 20_000,
                },
                # 13 states: sampled bounds and the Monte-Carlo check; few boxes keep it to minutes
                "quadrotor": {
                    "windows": [1, 2, 3, 4, 5],
                    "trials": 100,
                    "budget_seconds": 5.0,
                    "boxes": 2_000,
                },
            },
            "compression": {
                "models": ["mlp"],
                "windows": [10],
                "rates": [0.3, 0.6, 0.9],
                "seeds": [0],
                "epochs": 60,
            },
            "rollouts": {"window": 10},
            # what `canonid train --model mlp` gets, beside the paper's model; one window keeps
            # the demo within its 10 minutes (docs: Reproducing the paper)
            "defaults": {"models": ["mlp"], "windows": [10]},
        },
        # chosen on validation over three systems (docs: Identification, "Defaults and …")
        "train": {
            "epochs": 600,
            "batch_size": 32,
            "lr": 3e-3,
            "lr_final": 1e-5,
            # bounds the rare large gradients of open-loop rollouts (docs: Identification)
            "grad_clip": 1.0,
            # a small Adam weight decay, the same on every record
            "weight_decay": 1e-5,
            "horizon": 50,
            "curriculum_epochs": 50,
            "windows_per_epoch": 480,
            "alpha_first": 10.0,
            "patience": 200,
            "val_every": 5,
            "val_stride": 5,
            "val_horizon": 100,
            "val_windows": 250,
            # validation scores the free-run simulation of each record, as the field does
            "val_measure": "simulation",
            "checkpoint_every": 25,
        },
        # chosen on validation (docs: Model reduction)
        "reduce": {
            "epochs": 150,
            "batch_size": 16,
            "lr": 3e-4,
            "lr_final": 1e-5,
            "horizon": 50,
            "curriculum_epochs": 50,
            "windows_per_epoch": 240,
            "alpha_first": 1.0,
            "patience": None,
            "val_every": 5,
            "val_stride": 5,
            "val_horizon": 100,
            "checkpoint_every": 25,
            "encoder_hidden": [128, 128],
            "decoder_hidden": [128, 128],
            "freeze_fraction": 0.75,
            "reconstruction_weight": 1.0,
            "consistency_weight": 1.0,
            "output_weight": 1.0,
            "linear_skip": True,
        },
    },
    "paper": {
        "reproduce": {
            "systems": ["tank", "drone2d", "quadrotor"],
            "windows": [30, 25, 20, 15, 10, 5],
            "models": ["gru", "mlp", "classic-gru", "masti"],
            "seeds": 3,
            "data": {
                "tank": {"seed": 0, "counts": {"train": 60, "val": 20, "test": 20}},
                "drone2d": {"seed": 0, "counts": {"train": 500, "val": 20, "test": 20}},
                "quadrotor": {"seed": 0, "counts": {"train": 146, "val": 20, "test": 10}},
            },
            # the authors' epoch: one sub-window per training flight
            "train": {
                "per_system": {
                    "tank": {"windows_per_epoch": 60},
                    "drone2d": {"windows_per_epoch": 500},
                    "quadrotor": {"windows_per_epoch": 146},
                }
            },
            "networks": {"quadrotor": {"mlp": {"hidden": [2048, 2048]}}},
            "evaluation": {"horizon": 100, "stride": 1},
            "analysis": {
                "tank": {
                    "windows": list(range(1, 11)),
                    "X": [[0.05, 0.05], [5.0, 5.0]],
                    "U": [[1.0], [3.0]],
                    "trials": 1000,
                    "budget_seconds": 600.0,
                    "boxes": 200_000,
                },
                "drone2d": {
                    "windows": list(range(1, 11)),
                    "trials": 1000,
                    "budget_seconds": 600.0,
                    "boxes": 200_000,
                },
                "quadrotor": {
                    "windows": list(range(1, 11)),
                    "trials": 1000,
                    "budget_seconds": 600.0,
                    "boxes": 200_000,
                },
            },
            "compression": {
                "models": ["mlp"],
                "windows": [5, 10, 15, 20, 25, 30],
                "rates": [0.15, 0.30, 0.45, 0.60, 0.75, 0.90],
                "seeds": [0, 1, 2],
            },
            "rollouts": {"window": 10},
            # no "defaults" column: under this train stage it would be canonid's network at the
            # paper's budget, not what canonid does by default (the quick profile shows that)
        },
        "train": {
            "epochs": 10_000,
            "batch_size": 32,
            "lr": 1e-4,
            "lr_final": None,
            "horizon": 100,
            "curriculum_epochs": 1_000,
            "windows_per_epoch": 64,
            "alpha_first": 10.0,
            "patience": 1_000,
            "val_every": 10,
            "val_stride": 1,
            "val_horizon": 100,
            "checkpoint_every": 100,
        },
        "reduce": {
            "epochs": 3_000,
            "batch_size": 32,
            "lr": 1e-4,
            "lr_final": None,
            "horizon": 100,
            "curriculum_epochs": 2_250,
            "windows_per_epoch": 64,
            "alpha_first": 1.0,
            "patience": None,
            "val_every": 10,
            "val_stride": 1,
            "val_horizon": 100,
            "checkpoint_every": 100,
            "encoder_hidden": [512, 512],
            "decoder_hidden": [512, 512],
            "freeze_fraction": 0.75,
            "reconstruction_weight": 1.0,
            "consistency_weight": 1.0,
            "output_weight": 1.0,
            "linear_skip": False,
        },
    },
    "tiny": {
        "reproduce": {
            "systems": ["tank"],
            "windows": [5],
            "models": ["mlp", "classic-gru"],
            "seeds": 1,
            "data": {
                "tank": {"seed": 0, "counts": {"train": 4, "val": 2, "test": 2}, "T": 140},
                "quadrotor": {"seed": 0, "counts": {"train": 2, "val": 1, "test": 1}, "T": 400},
            },
            "train": {},
            "evaluation": {"horizon": 100, "stride": 5},
            "analysis": {
                "tank": {
                    "windows": [5],
                    "X": [[0.05, 0.05], [5.0, 5.0]],
                    "U": [[1.0], [3.0]],
                    "trials": 5,
                    "budget_seconds": 1.0,
                    "boxes": 3_000,  # the tank's hull needs ≤ 2,405 boxes a step to be tight
                },
                "quadrotor": {"windows": [2], "trials": 5, "budget_seconds": 1.0, "boxes": 100},
            },
            "compression": {"models": ["mlp"], "windows": [5], "rates": [0.5], "seeds": [0]},
            "rollouts": {"window": 5},
            "defaults": {"models": ["mlp"], "windows": [5]},
        },
        "train": {
            "epochs": 3,
            "batch_size": 8,
            "lr": 1e-3,
            "lr_final": None,
            "horizon": 10,
            "curriculum_epochs": 0,
            "windows_per_epoch": 8,
            "alpha_first": 10.0,
            "patience": None,
            "val_every": 1,
            "val_stride": 10,
            "val_horizon": 20,
            "checkpoint_every": 1,
        },
        "reduce": {
            "epochs": 2,
            "batch_size": 8,
            "lr": 1e-3,
            "lr_final": None,
            "horizon": 10,
            "curriculum_epochs": 0,
            "windows_per_epoch": 8,
            "alpha_first": 1.0,
            "patience": None,
            "val_every": 1,
            "val_stride": 10,
            "val_horizon": 20,
            "checkpoint_every": 1,
            "encoder_hidden": [16],
            "decoder_hidden": [16],
            "freeze_fraction": 0.5,
            "reconstruction_weight": 1.0,
            "consistency_weight": 1.0,
            "output_weight": 1.0,
            "linear_skip": False,
        },
    },
}


def _refuse_unknown(data: Mapping[str, Any], known: set[str] | frozenset[str], where: str) -> None:
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise OptionError(f"{where}: unknown key(s) {unknown}; known: {sorted(known)}")


@functools.cache
def _train_keys() -> frozenset[str]:
    """The fields of :class:`TrainOptions`: the keys a ``train`` mapping may hold."""
    from canonid.learning.training import TrainOptions

    return frozenset(f.name for f in dataclasses.fields(TrainOptions))


@dataclass(frozen=True)
class ReduceStage:
    """The ``reduce`` stage: the auto-encoder's training options and the reduction's."""

    train: TrainOptions
    reduction: ReductionOptions

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str) -> ReduceStage:
        """Split one mapping into the two option sets; an unknown key is refused by name."""
        from canonid.learning.reduction import ReductionOptions
        from canonid.learning.training import TrainOptions

        reduction_keys = {f.name for f in dataclasses.fields(ReductionOptions)}
        _refuse_unknown(data, _train_keys() | reduction_keys, where)
        return cls(
            TrainOptions.from_dict({k: v for k, v in data.items() if k in _train_keys()}),
            ReductionOptions.from_dict({k: v for k, v in data.items() if k not in _train_keys()}),
        )


@dataclass(frozen=True)
class ReproduceStage:
    """The ``reproduce`` stage (see the module docstring for each field); built from the
    profile's mapping, every level of which refuses a key it does not know, by name."""

    systems: tuple[str, ...]
    windows: tuple[int, ...]
    models: tuple[str, ...]
    seeds: int
    data: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    train: Mapping[str, Any] = field(default_factory=dict)
    networks: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    evaluation: Mapping[str, Any] = field(default_factory=dict)
    analysis: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    compression: Mapping[str, Any] = field(default_factory=dict)
    rollouts: Mapping[str, Any] = field(default_factory=dict)
    defaults: Mapping[str, Any] = field(default_factory=dict)

    #: the keys of the nested mappings that have a fixed set of them
    EVALUATION_KEYS = frozenset({"horizon", "stride"})
    COMPRESSION_KEYS = frozenset({"models", "windows", "rates", "seeds", "epochs"})
    ROLLOUTS_KEYS = frozenset({"window"})
    DEFAULTS_KEYS = frozenset({"models", "windows"})

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str) -> ReproduceStage:
        known = {f.name for f in dataclasses.fields(cls)}
        _refuse_unknown(data, known, where)
        missing = sorted(k for k in ("systems", "windows", "models", "seeds") if k not in data)
        if missing:
            raise OptionError(f"{where}: missing key(s) {missing}")
        for key, keys in (
            ("evaluation", cls.EVALUATION_KEYS),
            ("compression", cls.COMPRESSION_KEYS),
            ("rollouts", cls.ROLLOUTS_KEYS),
            ("defaults", cls.DEFAULTS_KEYS),
        ):
            _refuse_unknown(data.get(key, {}), keys, f"{where}.{key}")
        train = dict(data.get("train", {}))
        _refuse_unknown(train, _train_keys() | {"per_model", "per_system"}, f"{where}.train")
        for group in ("per_model", "per_system"):
            for name, overrides in train.get(group, {}).items():
                _refuse_unknown(overrides, _train_keys(), f"{where}.train.{group}.{name}")
        body = copy.deepcopy(dict(data))
        for key in ("systems", "windows", "models"):
            body[key] = tuple(body[key])
        return cls(**body)


@dataclass(frozen=True)
class Profile:
    """A profile, typed and validated: its ``train`` stage, ``reduce`` stage and, if it has
    one, its ``reproduce`` stage."""

    name: str
    train: TrainOptions
    reduce: ReduceStage
    reproduce: ReproduceStage | None

    @classmethod
    def from_dict(cls, name: str, data: Mapping[str, Any]) -> Profile:
        from canonid.learning.training import TrainOptions

        where = f"profile {name!r}"
        _refuse_unknown(data, {"train", "reduce", "reproduce"}, where)
        try:
            train = TrainOptions.from_dict(data["train"])
            reduce = ReduceStage.from_dict(data["reduce"], where=f"{where}, reduce")
        except KeyError as exc:
            raise OptionError(f"{where}: missing stage {exc}") from None
        except OptionError as exc:
            raise OptionError(f"{where}: {exc}") from None
        stage = data.get("reproduce")
        reproduce = (
            None if stage is None else ReproduceStage.from_dict(stage, where=f"{where}, reproduce")
        )
        return cls(name, train, reduce, reproduce)


def profile_names() -> list[str]:
    return list(PROFILES)


def profile_values(stage: str, key: str) -> str:
    """``default from --profile: quick 600, paper 10000, tiny 3``: the value of ``key`` in the
    ``stage`` of every profile, as ``--help`` shows it (:func:`canonid.kernel.catalog.help_value`;
    profiles separated by ``;`` where a value is a list). Every profile must set ``key``: the
    default of a key left to the option classes would need torch to be read."""
    values = [(name, stages[stage][key]) for name, stages in PROFILES.items()]
    between = "; " if any(isinstance(v, (list, tuple)) for _, v in values) else ", "
    return "default from --profile: " + between.join(f"{n} {help_value(v)}" for n, v in values)


def load_profile(name: str) -> Profile:
    """Profile ``name``, typed and validated (a misspelt key is an error naming it)."""
    if name not in PROFILES:
        raise OptionError(f"unknown profile {name!r}; expected one of {profile_names()}")
    return Profile.from_dict(name, PROFILES[name])


def profile(name: str) -> dict[str, dict[str, Any]]:
    """A copy of profile ``name`` (stage → options), validated by :func:`load_profile`."""
    load_profile(name)
    return copy.deepcopy(PROFILES[name])


def train_options(name: str, **overrides: Any) -> TrainOptions:
    """The ``train`` stage of profile ``name`` as :class:`TrainOptions`, with ``overrides``
    (``None`` values are ignored, so CLI defaults pass through)."""
    return stage_train_options(name, {k: v for k, v in overrides.items() if v is not None})


def stage_train_options(name: str, overrides: Mapping[str, Any]) -> TrainOptions:
    """The ``train`` stage of profile ``name`` with ``overrides`` applied as given: unlike
    :func:`train_options`, where ``None`` means "not given", ``None`` here switches an option
    off (a reproduce stage's ``grad_clip: None``, a study's column without clipping)."""
    from canonid.learning.training import TrainOptions

    opts = profile(name)["train"]
    opts.update(overrides)
    return TrainOptions.from_dict(opts)


def reduce_options(name: str, **overrides: Any) -> tuple[TrainOptions, ReductionOptions]:
    """The ``reduce`` stage of profile ``name``, split into the auto-encoder's
    :class:`TrainOptions` and :class:`ReductionOptions`, with ``overrides`` (``None`` values
    are ignored) applied to either; an unknown key raises :class:`OptionError`."""
    from canonid.learning.reduction import ReductionOptions
    from canonid.learning.training import TrainOptions

    opts = profile(name)["reduce"]
    opts.update({k: v for k, v in overrides.items() if v is not None})
    train_keys = _train_keys()
    return (
        TrainOptions.from_dict({k: v for k, v in opts.items() if k in train_keys}),
        ReductionOptions.from_dict({k: v for k, v in opts.items() if k not in train_keys}),
    )
