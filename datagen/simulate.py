"""Closed-loop simulation of a true system under a data-generation controller.

Time convention (the one of :mod:`canonid.kernel.dataset`): for ``t = 0 … T−1``

* ``x[t]`` is the true state (``x[0] = x0``);
* the controller sees the true state, ``c[t] = controller(t, x[t]).u``;
* on a *loose* step the controller's value is replaced by the previous applied input plus a
  Gaussian perturbation, ``c[t] = u[t−1] + N(0, loose_std²)`` (``u[−1]`` = the controller's
  value), for state-space coverage;
* the applied input is ``u[t] = c[t] + e[t]`` with Gaussian excitation ``e[t] ~ N(0,
  excitation_std²)`` plus the input design's signal ``d[t]`` when one is given
  (:mod:`canonid.datagen.excitation`), clipped to the system's input box U when ``clip_input`` is
  set; ``u[t]`` is what the flight records (the input *as applied*);
* ``x[t+1] = f(x[t], u[t])``, ``y_clean[t] = h(x[t], u[t])`` and ``y[t] = y_clean[t] + w[t]`` with
  ``w[t]`` uniform in the noise box (a sub-box of the system's W).

All random numbers are drawn from ``rng`` before the loop, in a fixed order (noise, excitation,
loose-step mask, loose perturbations), so a flight is a pure function of its generator and the
noise of a flight does not change when its controller does.

A controller that offers a compiled loop (:meth:`Controller.compiled_loop`, the NMPC) for this
very system flies in chunks of steps, each one CasADi call (:mod:`canonid.datagen.compiled_loop`);
the result has the same bytes as the step loop. A flight in which that loop meets a failed solve or
a non-finite value is flown again step by step, which counts failures and cuts divergence.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from canonid.datagen.controllers.base import Controller
from canonid.kernel.errors import SetError, ShapeError
from canonid.kernel.validate import as_matrix, as_vector
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["ClosedLoop", "Excitation", "flight_draws", "noise_box", "simulate_closed_loop"]


@dataclass(frozen=True)
class Excitation:
    """Random changes to the controller's commands (see the module docstring).

    Attributes:
        std: standard deviation of the Gaussian excitation added to every applied input.
        loose_probability: probability, per step, that the command is a random perturbation of
            the previous input instead of the controller's value (0: a normal flight).
        loose_std: standard deviation of that perturbation.
    """

    std: float = 0.0
    loose_probability: float = 0.0
    loose_std: float = 0.0

    def __post_init__(self) -> None:
        if not (self.std >= 0 and self.loose_std >= 0):
            raise ShapeError(
                f"excitation standard deviations must be >= 0, got std={self.std}, "
                f"loose_std={self.loose_std}"
            )
        if not (0.0 <= self.loose_probability <= 1.0):
            raise ShapeError(f"loose_probability must be in [0, 1], got {self.loose_probability}")


@dataclass(frozen=True)
class ClosedLoop:
    """One simulated flight; arrays follow the module's time convention.

    Attributes:
        x: true states, ``(T, n_x)``.
        u: applied inputs, ``(T, n_u)``.
        y_clean: ``h(x[t], u[t])``, ``(T, n_y)``.
        y: ``y_clean + w``, ``(T, n_y)``.
        reference: the reference given to the controller, ``(T, n_r)``.
        failures: steps where the controller reported ``ok=False`` (it used a fallback).
        failure_reasons: how many failed steps each solver status accounts for.
        loose_steps: steps whose command was a random perturbation.
        diverged_at: first sample whose next state was not finite (the arrays are then cut
            there and the flight must not be kept), or ``None``.
    """

    x: np.ndarray
    u: np.ndarray
    y_clean: np.ndarray
    y: np.ndarray
    reference: np.ndarray
    failures: int = 0
    failure_reasons: dict[str, int] = field(default_factory=dict)
    loose_steps: int = 0
    diverged_at: int | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready facts about the flight (no timings: datasets must be byte-identical)."""
        return {
            "solver_failures": self.failures,
            "failure_reasons": dict(self.failure_reasons),
            "loose_steps": self.loose_steps,
            "diverged_at": self.diverged_at,
        }


def noise_box(system: System, level: float | tuple[float, ...] | None) -> Box:
    """The measurement-noise box for ``level``: ``None`` gives the system's W; a number ``a``
    gives ``[−a, a]`` on every output; a tuple gives one half-width per output.

    Raises :class:`SetError` when the box is not inside W (the theory's bounds assume w ∈ W).
    """
    if level is None:
        return system.W
    widths = np.atleast_1d(np.asarray(level, dtype=np.float64))
    if widths.size == 1:
        widths = np.full(system.n_y, float(widths[0]))
    if widths.shape != (system.n_y,) or not np.all(np.isfinite(widths)) or np.any(widths < 0):
        raise SetError(
            f"noise level for {system.name} must be one half-width >= 0 or {system.n_y} of them "
            f"(outputs {', '.join(system.output_names)}), got {level}"
        )
    box = Box(-widths, widths)
    if not (np.all(box.lo >= system.W.lo) and np.all(box.hi <= system.W.hi)):
        raise SetError(
            f"noise level {widths.tolist()} lies outside the system's noise set W = {system.W} "
            f"of {system.name} (the theory assumes w in W); use half-widths <= "
            f"{np.minimum(-system.W.lo, system.W.hi).tolist()}"
        )
    return box


def flight_draws(
    rng: np.random.Generator,
    T: int,
    *,
    box: Box,
    n_u: int,
    excitation: Excitation | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The random numbers of one flight, drawn from ``rng`` in the module's fixed order: the
    noise ``w`` ``(T, n_y)`` uniform in ``box``, the Gaussian excitation ``e`` ``(T, n_u)``, the
    loose-step mask ``(T,)`` and the loose perturbations ``(T, n_u)``.

    :func:`simulate_closed_loop` draws through this function, so a fresh generator of the same
    seed gives back the very ``e`` a flight applied (:func:`canonid.datagen.generate.
    flight_excitation`)."""
    exc = excitation or Excitation()
    w = box.lo + (box.hi - box.lo) * rng.random((T, box.dim))
    e = exc.std * rng.standard_normal((T, n_u))
    loose = np.less(rng.random(T), exc.loose_probability)
    kicks = exc.loose_std * rng.standard_normal((T, n_u))
    return w, e, loose, kicks


def simulate_closed_loop(
    system: System,
    controller: Controller,
    reference: np.ndarray,
    *,
    x0: np.ndarray,
    rng: np.random.Generator,
    noise: Box | None = None,
    excitation: Excitation | None = None,
    clip_input: bool = False,
    step_by_step: bool = False,
    input_signal: np.ndarray | None = None,
) -> ClosedLoop:
    """Run ``controller`` on ``system`` for ``T = len(reference)`` samples from ``x0``.

    Args:
        system: the true system (its ``f`` and ``h`` are used as they are).
        controller: reset here with ``(reference, x0)``.
        reference: ``(T, n_r)``, row ``t`` the target of sample ``t``.
        x0: initial state ``x[0]``.
        rng: the flight's generator; consumed in the fixed order of the module docstring.
        noise: measurement-noise box, default the system's W (use :func:`noise_box`).
        excitation: excitation and loose-step settings (default: none).
        clip_input: clip applied inputs to the system's U (after excitation).
        step_by_step: call the controller once per step even when it offers a compiled loop
            (the reference the compiled loop is tested and benchmarked against).
        input_signal: ``(T, n_u)`` design signal added to every command with the excitation.
    """
    ref = np.asarray(reference, dtype=np.float64)
    ref = as_matrix(ref, ref.shape[1] if ref.ndim == 2 else 1, "reference")
    T = ref.shape[0]
    state = as_vector(x0, system.n_x, f"{system.name}: initial state x0")
    box = system.W if noise is None else noise
    if box.dim != system.n_y:
        raise SetError(f"noise box has dimension {box.dim}, expected n_y = {system.n_y}")
    w, e, loose, kicks = flight_draws(rng, T, box=box, n_u=system.n_u, excitation=excitation)
    if input_signal is not None:
        e = e + as_matrix(
            np.asarray(input_signal, dtype=np.float64), system.n_u, "input signal", rows=T
        )

    compiled = None if step_by_step else controller.compiled_loop()
    if compiled is not None and compiled.system is system:
        flown = compiled.run(
            ref, state, e=e, loose=loose, kicks=kicks, clip=system.U if clip_input else None
        )
        if flown is not None:
            return _closed_loop(system, *flown, w=w, reference=ref, loose=loose)
    xs = np.empty((T, system.n_x))
    us = np.empty((T, system.n_u))
    reasons: Counter[str] = Counter()
    failures = 0
    controller.reset(ref, state)
    f = system.f
    previous: np.ndarray | None = None
    steps = T
    diverged_at = None
    for t in range(T):
        xs[t] = state
        decision = controller(t, state)
        if not decision.ok:
            failures += 1
            reasons[str(decision.info.get("status", "unknown"))] += 1
        command = np.asarray(decision.u, dtype=np.float64).reshape(system.n_u)
        if loose[t]:
            command = (command if previous is None else previous) + kicks[t]
        applied = command + e[t]
        if clip_input:
            applied = system.U.clip(applied)
        us[t] = applied
        previous = applied
        state = np.asarray(f(state, applied), dtype=np.float64).reshape(system.n_x)
        if not np.all(np.isfinite(state)):
            diverged_at, steps = t, t + 1
            break
    return _closed_loop(
        system,
        xs[:steps],
        us[:steps],
        w=w,
        reference=ref,
        loose=loose,
        failures=failures,
        failure_reasons=dict(sorted(reasons.items())),
        diverged_at=diverged_at,
    )


def _closed_loop(
    system: System,
    xs: np.ndarray,
    us: np.ndarray,
    *,
    w: np.ndarray,
    reference: np.ndarray,
    loose: np.ndarray,
    failures: int = 0,
    failure_reasons: dict[str, int] | None = None,
    diverged_at: int | None = None,
) -> ClosedLoop:
    """The flight of states ``xs`` and inputs ``us`` (the first ``len(xs)`` samples)."""
    steps = xs.shape[0]
    y_clean = system.h_batch(xs, us)
    return ClosedLoop(
        x=xs,
        u=us,
        y_clean=y_clean,
        y=y_clean + w[:steps],
        reference=reference[:steps],
        failures=failures,
        failure_reasons=failure_reasons or {},
        loose_steps=int(loose[:steps].sum()),
        diverged_at=diverged_at,
    )
