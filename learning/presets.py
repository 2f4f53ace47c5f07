"""Named network options: what a new run gets by default, and the paper's configuration.

``DEFAULT_NET_OPTIONS`` are the best options we know per model, chosen on validation over several
systems (docs, "Identification": the table and the commands behind it); a model not listed keeps
its constructor's defaults. ``PAPER_NET_OPTIONS`` are the authors' published code's
configuration, which produced the paper's numbers (the paper's text writes ``Ĥ(z_t, u_t)``, its
code predicts the increment of ``y`` from ``z_t`` alone); ``canonid reproduce`` trains it.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

__all__ = ["DEFAULT_NET_OPTIONS", "PAPER_NET_OPTIONS", "net_options"]

DEFAULT_NET_OPTIONS: dict[str, dict[str, Any]] = {
    "mlp": {"residual": True, "feedthrough": False, "activation": "silu", "linear": "skip"},
    "arx": {"residual": False, "feedthrough": False},
}

PAPER_NET_OPTIONS: dict[str, dict[str, Any]] = {
    "mlp": {
        "hidden": [256, 256, 256],
        "activation": "relu",
        "residual": True,
        "feedthrough": False,
        "linear": "off",
    },
}


def net_options(
    model: str, overrides: Mapping[str, Any] | None = None, *, paper: bool = False
) -> dict[str, Any]:
    """The constructor options of ``model``: the defaults (or the paper's, ``paper=True``)
    updated with ``overrides``."""
    base = (PAPER_NET_OPTIONS if paper else DEFAULT_NET_OPTIONS).get(model, {})
    return {**copy.deepcopy(base), **dict(overrides or {})}
