"""What the identification models are called and the options they are built with, as plain data.

The command line shows these names and defaults in ``--help`` without importing torch; the
networks of :mod:`canonid.learning.nets` are built from them (``tests/test_layout.py`` checks
that the names agree with the registry and the activations the networks know).

``DEFAULT_NET_OPTIONS`` are the best options we know per model, chosen on validation over several
systems (docs, "Identification": the table and the commands behind it); a model not listed keeps
its constructor's defaults. ``PAPER_NET_OPTIONS`` are the authors' published code's
configuration, which produced the paper's numbers (the paper's text writes ``Ĥ(z_t, u_t)``, its
code predicts the increment of ``y`` from ``z_t`` alone); ``canonid reproduce`` trains it.
``DEFAULT_MODEL``, ``DEFAULT_VAL_FRACTION``, ``EVAL_HORIZON`` and ``COMPRESSION_RATES`` are the
defaults that the application applies where an option is not given, and that ``--help`` shows
(:func:`help_value`).
``INFO_*`` name the fields of a trained model's ``info`` that the application writes
(:mod:`canonid.coverage`) and the model's loader checks (:func:`canonid.learning.model.check_info`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

__all__ = [
    "ACTIVATION_NAMES",
    "COMPRESSION_RATES",
    "DEFAULT_MODEL",
    "DEFAULT_NET_OPTIONS",
    "DEFAULT_VAL_FRACTION",
    "DEVICE_NAMES",
    "EVAL_HORIZON",
    "INFO_TRAINING_RANGE",
    "INFO_UNVALIDATED",
    "LINEAR_PATHS",
    "MODEL_LABELS",
    "MODEL_NAMES",
    "PAPER_NET_OPTIONS",
    "help_value",
    "model_label",
    "net_options",
    "preset_word",
]

#: the registered identification models, in table order (:func:`canonid.learning.model_names`)
MODEL_NAMES = ("mlp", "gru", "classic-gru", "masti", "arx")

#: the model a run trains when none is named
DEFAULT_MODEL = "mlp"

#: the share of the training data held out for validation when the data have no val split
DEFAULT_VAL_FRACTION = 0.2

#: the evaluation's rollout length: the paper metric's 100-step open-loop rollouts
EVAL_HORIZON = 100

#: the compression study's rates, the paper's: 15 %, 30 %, …, 90 %
COMPRESSION_RATES = (0.15, 0.30, 0.45, 0.60, 0.75, 0.90)

#: each model's name in tables and figures (the paper's column names; ARX is ours)
MODEL_LABELS = {
    "classic-gru": "Classic GRU",
    "masti": "Masti et al.",
    "gru": "Ours (GRU)",
    "mlp": "Ours (MLP)",
    "arx": "ARX (linear)",
}


def model_label(model: str) -> str:
    """The table name of ``model`` (its registry name when it has none)."""
    return MODEL_LABELS.get(model, model)


#: hidden-layer nonlinearities of the MLPs, by name (:data:`canonid.learning.nets.base.ACTIVATIONS`)
ACTIVATION_NAMES = ("relu", "silu", "tanh")

#: a canonical model's affine path: none; a linear skip started at zero and trained with the
#: network, like the linear bypass of deepSI's residual networks; or started at the
#: least-squares ARX fit with the nonlinear part's output layer at zero
LINEAR_PATHS = ("off", "skip", "arx")

#: the torch devices a training option may name (``cuda:N`` picks one GPU); ``auto``: CUDA when
#: present and the job is large enough to run faster there
DEVICE_NAMES = ("auto", "cpu", "cuda")

#: a trained model's ``info``: each signal's span over the training part, and where the training
#: part leaves the validation part's spans
INFO_TRAINING_RANGE = "training_range"
INFO_UNVALIDATED = "training_outside_validation"

DEFAULT_NET_OPTIONS: dict[str, dict[str, Any]] = {
    "mlp": {
        "residual": True,
        "feedthrough": "auto",
        "activation": "silu",
        "linear": "skip",
        "cubic": "auto",
    },
    "arx": {"residual": False, "feedthrough": False},
}

PAPER_NET_OPTIONS: dict[str, dict[str, Any]] = {
    "mlp": {
        "hidden": [256, 256, 256],
        "activation": "relu",
        "residual": True,
        "feedthrough": False,
        "linear": "off",
        "cubic": 0,  # the paper's model has no cubic branch (and runs no test for one)
    },
}


def net_options(
    model: str, overrides: Mapping[str, Any] | None = None, *, paper: bool = False
) -> dict[str, Any]:
    """The constructor options of ``model``: the defaults (or the paper's, ``paper=True``)
    updated with ``overrides``."""
    base = (PAPER_NET_OPTIONS if paper else DEFAULT_NET_OPTIONS).get(model, {})
    return {**copy.deepcopy(base), **dict(overrides or {})}


def help_value(value: Any) -> str:
    """A default as ``--help`` shows it: ``on`` / ``off`` for a boolean, ``none`` for ``None``,
    a number as one would type it (``600``, ``0.2``, ``3e-3``), a list comma-separated."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if value is None:
        return "none"
    if isinstance(value, (list, tuple)):
        return ",".join(help_value(v) for v in value)
    if isinstance(value, float) and value != 0 and abs(value) < 1e-2:
        mantissa, exponent = f"{value:e}".split("e")
        return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def preset_word(model: str, option: str) -> str:
    """The default of ``model``'s option ``option`` as ``--help`` says it (:func:`help_value`:
    ``on`` / ``off`` for a boolean, else the value, ``auto``, ``silu``), read from
    :data:`DEFAULT_NET_OPTIONS`."""
    return help_value(DEFAULT_NET_OPTIONS[model][option])
