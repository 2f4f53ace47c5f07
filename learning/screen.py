"""The window ℓ chosen on validation by a short screen of the candidate windows.

:func:`screen_windows` trains the model once per candidate window with the training options
compressed to a fraction of their epochs (:func:`screen_options`: the epochs, the curriculum and
the early-stopping patience scaled by ``fraction``, the learning-rate schedule run over the
shorter budget), and chooses the shortest window whose best validation loss is within
:data:`SCREEN_TOLERANCE` of the lowest: a tenth of the budget ranks windows whose losses differ
several-fold, not near-ties (benchmarks/RESULTS.md, "Window on validation"). Each candidate
is :func:`canonid.learning.training.fit` itself, so the screen ranks the
model that will be trained, not a proxy; a linear (ARX) fit's best window is not one (it chose
ℓ = 2 on Silverbox, where the network prefers longer windows). A candidate that diverges or
fails is recorded and left out of the choice.

The candidates are independent: given an ``executor`` (worker processes of one torch thread
each, :func:`canonid.jobs.candidate_pool`) they train side by side, each as it would alone with
one thread, so the screen chooses what ``--threads 1`` chooses, sooner.

Only the training and validation trajectories are given: the choice never reads test data.
The outcome is a :class:`WindowScreen` (written by ``canonid train`` to the run folder as
:data:`SCREEN_FILE`); it, the rule and the constants live in
:mod:`canonid.learning.window_screen` and are named here too.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any

from canonid.kernel.errors import OptionError
from canonid.learning.window_screen import (
    FOLLOWUPS_DIR,
    SCREEN_FILE,
    SCREEN_FRACTION,
    SCREEN_TOLERANCE,
    SCREEN_WINDOWS,
    ScreenCandidate,
    WindowScreen,
    choose_window,
    screen_options,
)

if TYPE_CHECKING:  # torch loads when a screen runs, not for the command line's --help
    from canonid.learning.training import FitResult, TrainOptions

__all__ = [
    "FOLLOWUPS_DIR",
    "SCREEN_FILE",
    "SCREEN_FRACTION",
    "SCREEN_TOLERANCE",
    "SCREEN_WINDOWS",
    "ScreenCandidate",
    "WindowScreen",
    "choose_window",
    "fit_row",
    "fitting_windows",
    "screen_options",
    "screen_windows",
]


def fit_row(result: FitResult, cpu_seconds: float = 0.0) -> ScreenCandidate:
    """The row of a training's outcome in the screen's table (a loss that is not finite:
    ``None``)."""
    loss = result.best_val_loss
    return ScreenCandidate(
        window=result.model.window,
        best_val_loss=loss if math.isfinite(loss) else None,
        best_epoch=result.best_epoch,
        epochs_run=result.epochs_run,
        stopped=result.stopped,
        error=None,
        cpu_seconds=round(cpu_seconds, 3),
    )


def fitting_windows(
    train: Sequence[Any], val: Sequence[Any], windows: Sequence[int], options: TrainOptions
) -> list[int]:
    """The ``windows`` that the records allow: every training and validation record holds
    ℓ + 1 samples, the longest training record the training rollout after ℓ, the longest
    validation record at least half the validation rollout after ℓ (the screen scores every
    candidate on the rollout length that the longest of them leaves: :func:`screen_windows`)."""
    lengths = [len(t.y) for t in [*train, *val]]
    longest_train, longest_val = max(len(t.y) for t in train), max(len(t.y) for t in val)
    return [
        int(ell)
        for ell in windows
        if min(lengths) >= ell + 1
        and longest_train >= ell + options.horizon
        and longest_val - ell >= math.ceil(options.rollout_horizon / 2)
    ]


def screen_windows(
    train: Sequence[Any],
    val: Sequence[Any],
    *,
    windows: Sequence[int],
    model: str = "mlp",
    options: TrainOptions | None = None,
    net_options: Mapping[str, Any] | None = None,
    fraction: float = SCREEN_FRACTION,
    tolerance: float = SCREEN_TOLERANCE,
    progress: Callable[[int, ScreenCandidate], None] | None = None,
    executor: Executor | None = None,
) -> WindowScreen:
    """Train ``model`` at each of ``windows`` for :func:`screen_options` ``(options, fraction)``
    and choose the shortest window whose best validation loss is at most ``tolerance`` times the
    lowest (see the module docstring).
    Every candidate is validated on rollouts of one length: the profile's, or what the longest
    validation record leaves after the longest window when that is shorter (a longer window
    must not win by being scored on shorter rollouts).

    Args:
        train, val: trajectories in physical units, as for :func:`fit`.
        windows: the candidate windows, each one the data allow (the caller checks).
        model, options, net_options: as for :func:`fit` (``options``: the full run's).
        fraction: the share of ``options.epochs`` each candidate trains for.
        tolerance: ≥ 1; 1 chooses the lowest loss (the shortest window on a tie).
        progress: called as ``progress(index, row)`` after each candidate, in their order.
        executor: where the candidates train (module docstring); ``None``: one after the other
            in this process.

    One window alone is chosen without training. Raises :class:`OptionError` when no window is
    given or none reaches a finite validation loss.
    """
    from canonid.learning.training import TrainOptions

    if not windows:
        raise OptionError("the window screen needs at least one candidate window")
    if not tolerance >= 1:
        raise OptionError(f"the window screen's tolerance must be at least 1, got {tolerance}")
    opts = screen_options(options or TrainOptions(), fraction)
    if len(windows) == 1:  # nothing to choose between: no training spent on it
        only = ScreenCandidate(
            int(windows[0]), None, 0, 0, "not screened: the only window", None, 0.0
        )
        return WindowScreen((only,), only.window, float(fraction), opts.to_dict(), float(tolerance))
    # the windows are ranked on the plain network; the chosen window's run tests the branch
    net_options = {**(net_options or {}), "cubic": 0} if model == "mlp" else net_options
    longest_val = max(len(t.y) for t in val)
    common = min(opts.rollout_horizon, longest_val - max(windows))
    opts = dataclasses.replace(opts, val_horizon=max(common, 1))
    calls = [(train, val, model, int(ell), opts, net_options) for ell in windows]
    if executor is None:
        outcomes = (_candidate(*call) for call in calls)
    else:
        futures = [executor.submit(_candidate, *call) for call in calls]
        outcomes = (future.result() for future in futures)
    rows = []
    for i, row in enumerate(outcomes):
        rows.append(row)
        if progress is not None:
            progress(i, row)
    scored = [r for r in rows if r.best_val_loss is not None]
    if not scored:
        reasons = "; ".join(f"ℓ = {r.window}: {r.error or r.stopped}" for r in rows)
        raise OptionError(f"no candidate window reached a finite validation loss ({reasons})")
    chosen = choose_window({r.window: r.best_val_loss for r in scored}, tolerance)  # type: ignore[misc]
    return WindowScreen(tuple(rows), chosen, float(fraction), opts.to_dict(), float(tolerance))


def _candidate(
    train: Sequence[Any],
    val: Sequence[Any],
    model: str,
    window: int,
    options: TrainOptions,
    net_options: Mapping[str, Any] | None,
) -> ScreenCandidate:
    """One candidate's short training and its row, with the CPU time of the process it ran in
    (this one or a worker)."""
    from canonid.learning.training import fit

    cpu0 = time.process_time()
    try:
        result = fit(
            train, val, model=model, window=window, options=options, net_options=net_options
        )
    except Exception as exc:  # one candidate's failure leaves the others to choose from
        message = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        row = ScreenCandidate(window, None, 0, 0, "failed", message, 0.0)
    else:
        row = fit_row(result)
    return dataclasses.replace(row, cpu_seconds=round(time.process_time() - cpu0, 3))
