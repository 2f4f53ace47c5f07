"""Discrete PID on one state component (the cascaded tanks' data generator).

With ``e[t] = r[t] − x[t][i]`` (``r`` = column 0 of the reference, ``i`` = ``state_index``)::

    u[t] = kp · e[t] + ki · (e[0] + … + e[t]) + kd · (e[t] − e[t−1]),   e[−1] = 0

The integral is the plain running sum of the errors including the current one (no ``dt``), the
derivative a first difference whose first value is ``e[0]``, and the command is not saturated:
this is the authors' loop, gains (4, 0.6, 4) for the tank.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix

__all__ = ["PID"]


class PID(Controller):
    """Single-input PID tracking ``reference[:, 0]`` with state component ``state_index``.

    Args:
        kp, ki, kd: gains (the tank's are 4, 0.6, 4).
        state_index: which component of the true state is controlled (the tank's lower level
            ``x2`` is component 1).
    """

    name = "pid"

    def __init__(
        self, *, kp: float = 4.0, ki: float = 0.6, kd: float = 4.0, state_index: int = 1
    ) -> None:
        for label, gain in (("kp", kp), ("ki", ki), ("kd", kd)):
            if not np.isfinite(gain):
                raise ShapeError(f"PID gain {label} must be finite, got {gain}")
        if state_index < 0:
            raise ShapeError(f"PID state_index must be >= 0, got {state_index}")
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.state_index = int(state_index)
        self._reference: np.ndarray | None = None
        self._integral = 0.0
        self._previous_error = 0.0

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        ref = np.asarray(reference, dtype=np.float64)
        self._reference = as_matrix(ref, ref.shape[1] if ref.ndim == 2 else 1, "PID reference")
        if self.state_index >= np.asarray(x0).size:
            raise ShapeError(
                f"PID state_index {self.state_index} is out of range for a state of size "
                f"{np.asarray(x0).size}"
            )
        self._integral = 0.0
        self._previous_error = 0.0

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        if self._reference is None:
            raise ShapeError("PID called before reset(reference, x0)")
        error = float(self._reference[t, 0] - x[self.state_index])
        self._integral += error
        derivative = error - self._previous_error
        self._previous_error = error
        u = self.kp * error + self.ki * self._integral + self.kd * derivative
        return ControlStep(u=np.array([u]))

    def settings(self) -> dict[str, Any]:
        return {
            "type": self.name,
            "kp": self.kp,
            "ki": self.ki,
            "kd": self.kd,
            "state_index": self.state_index,
            "integral": "running sum of errors including the current one",
            "derivative": "e[t] - e[t-1], e[-1] = 0",
            "saturation": None,
        }
