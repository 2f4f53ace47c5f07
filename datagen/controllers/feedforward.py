"""Open loop: the command is the reference itself (no feedback), for experiments on systems that
are stable on their own.

With ``r[t]`` the reference's row ``t`` (one column per input)::

    u[t] = r[t]

so an open-loop flight is driven by its reference plus the scenario's input design, which
:mod:`canonid.datagen.simulate` adds to the command (the mass chain's ``masses-id``: a zero
reference and a multisine).

Given the system it drives, the controller also offers that law as a compiled loop
(:meth:`Controller.compiled_loop`, :mod:`canonid.datagen.compiled_loop`): the policy
``(memory, x, r[t]) -> (r[t], memory, 1)`` flies whole chunks of a flight in single CasADi calls,
with the same bytes as the step loop and tens of times faster on long records (the vibrating
structure's flights of 100,000 samples).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix

if TYPE_CHECKING:
    from canonid.datagen.compiled_loop import CompiledLoop
    from canonid.models.base import System

__all__ = ["Feedforward"]


class Feedforward(Controller):
    """Applies the reference's row ``t`` as the command of sample ``t``.

    Args:
        n_u: the number of inputs, which the reference's columns must match.
        system: the system the controller drives; given, flights of that system go through the
            compiled loop (module docstring), else step by step.
        chunk: steps per call of the compiled loop.
    """

    name = "feedforward"

    def __init__(self, n_u: int, *, system: System | None = None, chunk: int = 500) -> None:
        if n_u < 1:
            raise ShapeError(f"feedforward: n_u must be >= 1, got {n_u}")
        if system is not None and system.n_u != n_u:
            raise ShapeError(f"feedforward: n_u = {n_u} but {system.name} has {system.n_u} inputs")
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
            raise ShapeError(f"feedforward: chunk must be an integer >= 1, got {chunk!r}")
        self.n_u = int(n_u)
        self._reference: np.ndarray | None = None
        self._loop = None if system is None else _compiled_loop(system, chunk)

    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        self._reference = as_matrix(reference, self.n_u, "feedforward reference")

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        if self._reference is None:
            raise ShapeError("feedforward called before reset(reference, x0)")
        return ControlStep(u=self._reference[t].copy())

    def settings(self) -> dict[str, Any]:
        return {"type": self.name, "n_u": self.n_u, "law": "u[t] = reference[t] (open loop)"}

    def compiled_loop(self) -> CompiledLoop | None:
        return self._loop


def _compiled_loop(system: System, chunk: int) -> CompiledLoop:
    """The feedforward law around ``system`` as CasADi functions: the command is the window (the
    reference's row ``t``), the one-number memory is carried unchanged, every step is ``ok``."""
    import casadi as ca

    from canonid.datagen.compiled_loop import CompiledLoop, loop_functions

    memory, x, window = ca.MX.sym("memory"), ca.MX.sym("x", system.n_x), ca.MX.sym("r", system.n_u)
    policy = ca.Function("feedforward", [memory, x, window], [window, memory, ca.MX(1)])
    step, chunked = loop_functions(system, policy, name="feedforward", chunk=chunk)
    return CompiledLoop(system, step, chunked, 1, lambda reference, x0: np.zeros(1))
