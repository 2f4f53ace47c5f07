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
import itertools
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

from canonid.kernel.errors import OptionError

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
    "MAX_LR",
    "MAX_NETWORK_ENV",
    "MAX_NETWORK_GB",
    "MAX_WINDOWS_PER_EPOCH",
    "MODEL_LABELS",
    "MODEL_NAMES",
    "PAPER_NET_OPTIONS",
    "check_network_memory",
    "help_value",
    "model_label",
    "net_options",
    "parse_list",
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


#: the largest learning rate (``--lr``) a run may start from: Adam's steps scale with it, and
#: far above 1 the weights leave float32's range in a few steps
MAX_LR = 10.0
#: the most sub-windows an epoch may draw (``--windows-per-epoch``): their start times are held
#: in memory, 8 bytes each (10⁷: 80 MB)
MAX_WINDOWS_PER_EPOCH = 10_000_000

#: the default ceiling, in GB (10⁹ bytes), of the memory a network to be trained may need
#: (:func:`check_network_memory`); the environment variable :data:`MAX_NETWORK_ENV` overrides it
MAX_NETWORK_GB = 4.0
MAX_NETWORK_ENV = "CANONID_MAX_NETWORK_GB"


def network_bytes(widths: Sequence[int], cubic: int, n_in: int, n_out: int) -> int:
    """The memory a network needs to train: its parameters (the dense layers
    ``n_in → widths… → n_out`` and a cubic branch of ``cubic`` units, ``n_in → cubic → n_out``),
    as float32 weights and Adam's two moments, 12 bytes each."""
    sizes = [n_in, *widths, n_out]
    layers = sum((a + 1) * b for a, b in itertools.pairwise(sizes))
    return 12 * (layers + cubic * (n_in + 1 + n_out))


def check_network_memory(
    widths: Sequence[int], cubic: int, n_in: int, n_out: int, *, given: str
) -> None:
    """Refuse, before anything is allocated, a network whose :func:`network_bytes` passes the
    ceiling (:data:`MAX_NETWORK_GB`, or the environment's :data:`MAX_NETWORK_ENV`); ``given``:
    the options that asked for it, which the message names."""
    text = os.environ.get(MAX_NETWORK_ENV)
    try:
        ceiling = MAX_NETWORK_GB if text is None else float(text)
    except ValueError:
        ceiling = float("nan")
    if not 0 < ceiling < float("inf"):
        raise OptionError(f"{MAX_NETWORK_ENV}: expected a number of GB > 0, got {text!r}")
    need = network_bytes(widths, cubic, n_in, n_out)
    if need > ceiling * 1e9:
        raise OptionError(
            f"{given}: the network would need at least {need / 1e9:.3g} GB to train (its "
            f"parameters as float32 weights and Adam's two moments), above the ceiling of "
            f"{ceiling:g} GB; give smaller sizes, or raise the ceiling with {MAX_NETWORK_ENV}=GB"
        )


_Item = TypeVar("_Item")


def parse_list(text: str, item: Callable[[str], _Item], what: str) -> list[_Item]:
    """The one list syntax of the command line: items separated by commas, ``"2,5,10"`` →
    ``[2, 5, 10]``; where ``item`` is ``int``, also ranges ``A-B`` (both ends in), ``"1-3,8"``
    → ``[1, 2, 3, 8]``. ``what``: how one item is written, for the :class:`OptionError`."""
    words = [word.strip() for word in text.split(",")]
    ranges = item is int
    expected = f"expected {what}[,{what}...]{' or a range A-B' if ranges else ''}, got {text!r}"
    values: list[Any] = []
    try:
        for word in words:
            lo, dash, hi = word.partition("-") if ranges else (word, "", "")
            if dash and lo:  # A-B (a leading minus is a sign, not a range)
                first, last = int(lo), int(hi)
                if first > last:  # a range that runs backwards
                    raise ValueError(word)
                values += range(first, last + 1)
            else:
                values.append(item(word))
    except (ValueError, TypeError):
        raise OptionError(expected) from None
    if not values or "" in words:
        raise OptionError(expected)
    return values
