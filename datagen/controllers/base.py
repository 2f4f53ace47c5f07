"""The one interface every data-generation controller implements.

A flight is run as::

    ctrl.reset(reference, x0)
    for t in range(T):
        step = ctrl(t, x[t])          # state feedback on the true state x[t]
        u[t] = step.u                 # (excitation noise is added by the simulator, not here)

``reference`` has one row per sample (``(T, n_r)``); what its columns mean is the controller's
documented choice (the tank's PID reads column 0 as the level set-point; the drone's NMPC reads
position and velocity targets).

A controller whose decision is one CasADi function may also offer a :class:`CompiledLoop`
(:meth:`Controller.compiled_loop`): the simulator then runs whole chunks of a flight in single
CasADi calls, with the same result as the step loop above.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from canonid.datagen.compiled_loop import CompiledLoop

__all__ = ["ControlStep", "Controller"]


@dataclass(frozen=True)
class ControlStep:
    """One control decision.

    Attributes:
        u: the command, ``(n_u,)``.
        ok: False when the controller could not compute a trustworthy command (e.g. the MPC
            solver failed and a fallback was used); the simulator counts and records these.
        info: short machine-readable facts (solver status, iterations, solve time in seconds).
    """

    u: np.ndarray
    ok: bool = True
    info: dict[str, Any] = field(default_factory=dict)


class Controller(ABC):
    """A feedback controller used to generate closed-loop data."""

    #: short name stored in dataset metadata
    name: str = "controller"

    @abstractmethod
    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        """Start a new flight: remember the reference, clear internal state (integrators,
        warm starts)."""

    @abstractmethod
    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        """The command for sample ``t`` given the true state ``x[t]``."""

    @abstractmethod
    def settings(self) -> dict[str, Any]:
        """JSON-ready settings (gains, horizon, weights, solver) for dataset metadata."""

    def compiled_loop(self) -> CompiledLoop | None:
        """The closed loop of this controller as CasADi functions (see
        :mod:`canonid.datagen.compiled_loop`), or ``None`` (the default): flights go step by step.
        """
        return None
