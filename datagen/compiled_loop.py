"""The closed loop of :func:`canonid.datagen.simulate.simulate_closed_loop` as CasADi functions, for
controllers whose decision is itself a CasADi function (the NMPC).

A *policy* is a CasADi function ``(memory, x, window) -> (c, memory⁺, ok)``: ``memory`` is what
the controller carries from step to step (the NMPC's warm start), ``x`` the true state ``x[t]``,
``window`` the reference rows ``t, t+1, …, t+W−1`` (rows past the end repeat the last one)
flattened row by row, ``c`` the controller's command and ``ok`` 1 when the decision is
trustworthy (0 sends the flight back to the step loop). A solver failure may also raise.

One closed-loop step repeats the step loop of :mod:`canonid.datagen.simulate` operation for
operation, so that both give the same bits::

    c[t], memory⁺, ok = policy(memory, x[t], window[t])
    c[t] = (u[t−1] if t > 0 else c[t]) + kick[t]     on a loose step
    u[t] = clip(c[t] + e[t], lo, hi)                 (lo, hi = ∓inf without clipping)
    x[t+1] = f(x[t], u[t])

:func:`loop_functions` builds that step and a ``mapaccum`` of :data:`CHUNK` steps of it; the
caller may compile both (with the policy's solver in the same C file). :class:`CompiledLoop`
runs a flight as ``⌊T / CHUNK⌋`` chunk calls and ``T mod CHUNK`` single steps, and returns
``None`` as soon as a step is not ``ok``, raises or leaves a non-finite state or input: the
simulator then runs the flight step by step, which handles failures and divergence.
"""

from __future__ import annotations

import contextlib
import io
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["CHUNK", "CompiledLoop", "loop_functions"]

log = logging.getLogger(__name__)


@contextlib.contextmanager
def casadi_dump_captured() -> Iterator[io.StringIO]:
    """Catch what CasADi writes to ``sys.stderr`` inside the block: before it raises a failed
    evaluation it prints the inputs of every function in the call (hundreds of lines per
    failed flight); callers log the text at debug level instead."""
    text = io.StringIO()
    with contextlib.redirect_stderr(text):
        yield text


#: steps per chunk call (600-sample flights: 12 calls); the rest of a flight goes step by step
CHUNK = 50


def loop_functions(
    system: System, policy: ca.Function, *, name: str, chunk: int = CHUNK
) -> tuple[ca.Function, ca.Function]:
    """``(one step, chunk steps)`` of the closed loop of ``policy`` around ``system``.

    Both have inputs ``(x, memory, u_previous, window, e, kick, loose, started, lo, hi)`` and
    outputs ``(x[t+n], memory after n steps, u, x, ok)`` for ``n`` = 1 or ``chunk`` steps from
    ``x = x[t]``: the first three inputs are carried from step to step, the others have one
    column per step (``lo``, ``hi`` are broadcast), and ``u``, ``x``, ``ok`` one column per
    step (``u[:, -1]`` is the next ``u_previous``).
    """
    nx, nu = system.n_x, system.n_u
    x = ca.MX.sym("x", nx)
    memory = ca.MX.sym("memory", policy.size1_in(0))
    previous = ca.MX.sym("u_previous", nu)
    window = ca.MX.sym("window", policy.size1_in(2))
    e, kick = ca.MX.sym("e", nu), ca.MX.sym("kick", nu)
    loose, started = ca.MX.sym("loose"), ca.MX.sym("started")
    lo, hi = ca.MX.sym("lo", nu), ca.MX.sym("hi", nu)
    command, memory_next, ok = policy(memory, x, window)
    command = ca.if_else(loose, ca.if_else(started, previous, command) + kick, command)
    applied = ca.fmin(ca.fmax(command + e, lo), hi)
    step = ca.Function(
        f"{name}_step",
        [x, memory, previous, window, e, kick, loose, started, lo, hi],
        [system.f(x, applied), memory_next, applied, x, ok],
    )
    carried = [0, 1, 2]
    steps = step.mapaccum(f"{name}_steps", chunk, carried, carried, {})
    inputs = steps.mx_in()
    x_next, memory_next, applied, x, ok = steps(*inputs)
    # mapaccum returns every step's carried values: keep the last state and memory only
    outputs = [x_next[:, -1], memory_next[:, -1], applied, x, ok]
    return step, ca.Function(f"{name}_chunk", inputs, outputs)


@dataclass(frozen=True)
class CompiledLoop:
    """Flights of one policy around one system (see the module docstring).

    Attributes:
        system: the true system the functions were built for (flights of another system go
            step by step).
        step, chunk: the two functions of :func:`loop_functions` (compiled or not).
        window: reference rows per step (the policy's ``W``).
        initial_memory: the policy's memory at the start of a flight, from ``(reference, x0)``.
    """

    system: System
    step: ca.Function
    chunk: ca.Function
    window: int
    initial_memory: Callable[[np.ndarray, np.ndarray], np.ndarray]

    def run(
        self,
        reference: np.ndarray,
        x0: np.ndarray,
        *,
        e: np.ndarray,
        loose: np.ndarray,
        kicks: np.ndarray,
        clip: Box | None,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """States ``(T, n_x)`` and applied inputs ``(T, n_u)`` of a flight, or ``None`` when a
        step failed (the caller then runs the step loop). Arguments as drawn by
        :func:`canonid.datagen.simulate.simulate_closed_loop`, one row per sample."""
        T, nu = reference.shape[0], self.system.n_u
        rows = np.minimum(np.arange(T)[:, None] + np.arange(self.window), T - 1)
        windows = reference[rows].reshape(T, -1).T  # column t: rows t … t+W−1, row by row
        started = np.arange(T) > 0
        per_step = [windows, e.T, kicks.T, loose[None, :] * 1.0, started[None, :] * 1.0]
        lo = np.full(nu, -np.inf) if clip is None else clip.lo
        hi = np.full(nu, np.inf) if clip is None else clip.hi
        carried: list[Any] = [x0, self.initial_memory(reference, x0), np.zeros(nu)]
        size = self.chunk.size2_in(3)
        whole = T - T % size
        pieces = [(t, size, self.chunk) for t in range(0, whole, size)]
        pieces += [(t, 1, self.step) for t in range(whole, T)]
        xs, us, oks = [], [], []
        for t, n, function in pieces:
            try:
                with casadi_dump_captured() as dump:
                    x_next, memory, u, x, ok = function(
                        *carried, *(a[:, t : t + n] for a in per_step), lo, hi
                    )
            except RuntimeError as exc:  # a solver failure (error_on_fail)
                log.debug("compiled loop stopped at sample %d: %s\n%s", t, exc, dump.getvalue())
                return None
            us.append(u.full())
            xs.append(x.full())
            oks.append(ok.full())
            carried = [x_next, memory, us[-1][:, -1]]
        # C order, as the step loop's arrays (np.save records the order: same bytes on disk)
        x_all = np.ascontiguousarray(np.hstack(xs).T)
        u_all = np.ascontiguousarray(np.hstack(us).T)
        x_last = carried[0].full()  # x[T], which the step loop also checks
        finite = all(np.isfinite(a).all() for a in (x_all, u_all, x_last))
        if not (finite and np.all(np.hstack(oks) == 1)):
            return None
        return x_all, u_all
