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

Only the training and validation trajectories are given: the choice never reads test data.
The outcome is a :class:`WindowScreen` (written by ``canonid train`` to the run folder as
:data:`SCREEN_FILE`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.errors import CheckpointError, OptionError
from canonid.kernel.io import atomic_write_json, read_json

if TYPE_CHECKING:  # torch loads when a screen runs, not for the command line's --help
    from canonid.learning.training import TrainOptions

__all__ = [
    "SCREEN_FILE",
    "SCREEN_FRACTION",
    "SCREEN_TOLERANCE",
    "SCREEN_WINDOWS",
    "ScreenCandidate",
    "WindowScreen",
    "choose_window",
    "fitting_windows",
    "screen_options",
    "screen_windows",
]

#: the windows the screen tries (those the data allow): a doubling ladder from canonid's earlier
#: fixed ℓ = 10, long enough for the slowest modes of the registry's lightly damped systems (the
#: chain of masses chose ℓ = 40); shorter windows are there with ``--window L``
SCREEN_WINDOWS = (10, 20, 40, 80)
#: the share of the profile's epochs each candidate trains for (benchmarks/RESULTS.md,
#: "Window on validation")
SCREEN_FRACTION = 0.1
#: the screen keeps the shortest window whose loss is at most this factor above the lowest: a
#: longer window must be clearly better in the short training to be chosen (chosen on the full
#: runs' validation losses: benchmarks/RESULTS.md, "Window on validation")
SCREEN_TOLERANCE = 1.6
#: the screen's table in a run folder
SCREEN_FILE = "window-screen.json"
SCREEN_FORMAT = "canonid-window-screen"


@dataclass(frozen=True)
class ScreenCandidate:
    """One window of the screen (losses normalised).

    Attributes:
        window: ℓ.
        best_val_loss: the lowest validation loss of its short training (``None``: none was
            finite, or it failed).
        best_epoch, epochs_run: where that loss was reached; the epochs trained.
        stopped: how its training ended (:class:`~canonid.learning.training.FitResult`), or
            ``"failed"``.
        error: the failure's message, else ``None``.
        cpu_seconds: the CPU time of its training.
    """

    window: int
    best_val_loss: float | None
    best_epoch: int
    epochs_run: int
    stopped: str
    error: str | None
    cpu_seconds: float


@dataclass(frozen=True)
class WindowScreen:
    """The candidates of a screen and the window chosen (the shortest whose best validation
    loss is within ``tolerance`` of the lowest).

    Attributes:
        candidates: one row per window screened, in the order tried.
        chosen: the window chosen.
        fraction: the share of the profile's epochs each candidate trained for.
        options: the candidates' training options (:func:`screen_options`), as a mapping.
        tolerance: the factor over the lowest loss within which the shortest window is chosen
            (1: the lowest loss itself).
    """

    candidates: tuple[ScreenCandidate, ...]
    chosen: int
    fraction: float
    options: Mapping[str, Any]
    tolerance: float = SCREEN_TOLERANCE

    @property
    def epochs(self) -> int:
        """The epochs each candidate had."""
        return int(self.options["epochs"])

    @property
    def cpu_seconds(self) -> float:
        return sum(c.cpu_seconds for c in self.candidates)

    def summary(self) -> str:
        """The choice in one line (what ``canonid train`` prints)."""
        windows = ", ".join(str(c.window) for c in self.candidates)
        return (
            f"window ℓ = {self.chosen} chosen on validation from {windows} (screen of "
            f"{self.epochs} epoch{'' if self.epochs == 1 else 's'} each, the shortest within "
            f"{self.tolerance:g}× of the lowest loss); --window L trains L"
        )

    def table(self) -> str:
        """The candidates in aligned columns, the chosen one marked."""
        rows = [("ℓ", "best validation loss (normalised)", "at epoch", "stopped", "CPU s", "")]
        for c in self.candidates:
            loss = "-" if c.best_val_loss is None else f"{c.best_val_loss:.4g}"
            stopped = c.stopped if c.error is None else f"failed: {c.error}"
            mark = "chosen" if c.window == self.chosen else ""
            rows.append(
                (str(c.window), loss, str(c.best_epoch), stopped, f"{c.cpu_seconds:.0f}", mark)
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": SCREEN_FORMAT,
            "version": 2,
            "criterion": "shortest window with best_val_loss <= tolerance × the lowest",
            "chosen": self.chosen,
            "fraction": self.fraction,
            "tolerance": self.tolerance,
            "options": dict(self.options),
            "candidates": [dataclasses.asdict(c) for c in self.candidates],
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> WindowScreen:
        if not isinstance(data, Mapping) or data.get("format") != SCREEN_FORMAT:
            raise CheckpointError(f"{where} is not a canonid window screen")
        try:
            rows = tuple(ScreenCandidate(**row) for row in data["candidates"])
            screen = cls(
                rows,
                int(data["chosen"]),
                float(data["fraction"]),
                data["options"],
                # version 1 chose the lowest loss itself
                float(data.get("tolerance", 1.0)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{where}: malformed window screen ({exc})") from exc
        if screen.chosen not in [c.window for c in rows]:
            raise CheckpointError(f"{where}: chosen window {screen.chosen} is not a candidate")
        return screen

    @classmethod
    def read(cls, run_dir: Path) -> WindowScreen:
        path = Path(run_dir) / SCREEN_FILE
        return cls.from_dict(read_json(path, what="window screen"), where=str(path))

    def write(self, run_dir: Path) -> None:
        atomic_write_json(Path(run_dir) / SCREEN_FILE, self.to_dict())


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


def screen_options(options: TrainOptions, fraction: float = SCREEN_FRACTION) -> TrainOptions:
    """``options`` compressed to ``fraction`` of their epochs (at least one): the curriculum and
    the early-stopping patience scaled alike, so the candidates see the whole schedule."""
    if not (isinstance(fraction, (int, float)) and 0 < fraction <= 1):
        raise OptionError(f"screen fraction must be in (0, 1], got {fraction!r}")

    def scaled(n: int) -> int:
        return max(1, round(n * fraction))

    return dataclasses.replace(
        options,
        epochs=scaled(options.epochs),
        curriculum_epochs=round(options.curriculum_epochs * fraction),
        patience=None if options.patience is None else scaled(options.patience),
    )


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
        progress: called as ``progress(index, row)`` after each candidate.

    One window alone is chosen without training. Raises :class:`OptionError` when no window is
    given or none reaches a finite validation loss.
    """
    from canonid.learning.training import TrainOptions, fit

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
    longest_val = max(len(t.y) for t in val)
    common = min(opts.rollout_horizon, longest_val - max(windows))
    opts = dataclasses.replace(opts, val_horizon=max(common, 1))
    rows = []
    for i, ell in enumerate(windows):
        cpu0 = time.process_time()
        try:
            result = fit(
                train, val, model=model, window=int(ell), options=opts, net_options=net_options
            )
        except Exception as exc:  # one candidate's failure leaves the others to choose from
            message = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            row = ScreenCandidate(int(ell), None, 0, 0, "failed", message, 0.0)
        else:
            loss = result.best_val_loss
            row = ScreenCandidate(
                window=int(ell),
                best_val_loss=loss if math.isfinite(loss) else None,
                best_epoch=result.best_epoch,
                epochs_run=result.epochs_run,
                stopped=result.stopped,
                error=None,
                cpu_seconds=0.0,
            )
        row = dataclasses.replace(row, cpu_seconds=round(time.process_time() - cpu0, 3))
        rows.append(row)
        if progress is not None:
            progress(i, row)
    scored = [r for r in rows if r.best_val_loss is not None]
    if not scored:
        reasons = "; ".join(f"ℓ = {r.window}: {r.error or r.stopped}" for r in rows)
        raise OptionError(f"no candidate window reached a finite validation loss ({reasons})")
    chosen = choose_window({r.window: r.best_val_loss for r in scored}, tolerance)  # type: ignore[misc]
    return WindowScreen(tuple(rows), chosen, float(fraction), opts.to_dict(), float(tolerance))


def choose_window(losses: Mapping[int, float], tolerance: float = SCREEN_TOLERANCE) -> int:
    """The shortest window whose loss is at most ``tolerance`` times the lowest of ``losses``
    (window → finite best validation loss)."""
    lowest = min(losses.values())
    return min(window for window, loss in losses.items() if loss <= tolerance * lowest)
