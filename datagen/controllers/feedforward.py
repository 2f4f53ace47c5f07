"""Open loop: the command is the reference itself (no feedback), for experiments on systems that
are stable on their own.

With ``r[t]`` the reference's row ``t`` (one column per input)::

    u[t] = r[t]

so an open-loop flight is driven by its reference plus the scenario's input design, which
:mod:`canonid.datagen.simulate` adds to the command (the mass chain's ``masses-id``: a zero
reference and a multisine).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix

__all__ = ["Feedforward"]


class Feedforward(Controller):
    """Applies the reference's row ``t`` as the command of sample ``t``.

    Args:
        n_u: the number of inputs, which the reference's columns must match.
    """

    name = "feedforward"

    def __init__(self, n_u: int) -> None:
        if n_u < 1:
            raise ShapeError(f"feedforward: n_u must be >= 1, got {n_u}")
        self.n_u = int(n_u)
        self._reference: np.ndarray | None = None

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        self._reference = as_matrix(reference, self.n_u, "feedforward reference")

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        if self._reference is None:
            raise ShapeError("feedforward called before reset(reference, x0)")
        return ControlStep(u=self._reference[t].copy())

    def settings(self) -> dict[str, Any]:
        return {"type": self.name, "n_u": self.n_u, "law": "u[t] = reference[t] (open loop)"}
