"""The window screen's outcome: its candidates' table, the rule that chooses the window, and its
file in a run folder (:mod:`canonid.learning.screen` runs the screen).

Kept apart from the screen so that :class:`~canonid.learning.training.FitResult` can carry the
table without the trainer and the screen importing each other.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from canonid.kernel.errors import CheckpointError, OptionError
from canonid.kernel.io import atomic_write_json, read_json

__all__ = [
    "FOLLOWUPS_DIR",
    "FOLLOWUP_SHARE",
    "SCREEN_FILE",
    "SCREEN_FRACTION",
    "SCREEN_TOLERANCE",
    "SCREEN_WINDOWS",
    "ScreenCandidate",
    "WindowScreen",
    "choose_window",
    "screen_options",
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
#: full runs that together stopped before this share of the profile's epochs (early stopping:
#: they overfitted early, as on small records) leave that budget to the screen's next near-tied
#: window, trained fully too; the lowest full-run validation loss then chooses. One budget: a run
#: that stopped early spends what it did not use (benchmarks/studies/window_study_notes.md, "Full
#: runs of the near ties")
FOLLOWUP_SHARE = 1.0
#: the folder of a run folder that holds the near ties' full runs, one ``lL`` folder each
FOLLOWUPS_DIR = "followups"
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
    """The candidates of a screen, the window its rule chose (the shortest whose best
    validation loss is within ``tolerance`` of the lowest) and the full runs that followed.

    The screened window is trained fully; when the full runs so far ended before
    :data:`FOLLOWUP_SHARE` of the profile's epochs, the next of the screen's near-tied windows
    (:meth:`near_ties`, shortest first) is trained fully too (:meth:`next_followup`), and the
    lowest best validation loss of the full runs chooses the model.

    Attributes:
        candidates: one row per window screened, in the order tried.
        chosen: the window of the model (the screened one until a full run beats it).
        fraction: the share of the profile's epochs each candidate trained for.
        options: the candidates' training options (:func:`screen_options`), as a mapping.
        tolerance: the factor over the lowest loss within which the shortest window is chosen
            (1: the lowest loss itself).
        screened: the window the screen's rule chose (``None``: ``chosen``).
        full_runs: the full runs recorded, in the order trained (the screened window first).
        full_epochs: the profile's epochs of a full run (``None`` until one is recorded).
    """

    candidates: tuple[ScreenCandidate, ...]
    chosen: int
    fraction: float
    options: Mapping[str, Any]
    tolerance: float = SCREEN_TOLERANCE
    screened: int | None = None
    full_runs: tuple[ScreenCandidate, ...] = ()
    full_epochs: int | None = None

    @property
    def epochs(self) -> int:
        """The epochs each candidate had."""
        return int(self.options["epochs"])

    @property
    def screened_window(self) -> int:
        return self.chosen if self.screened is None else self.screened

    @property
    def cpu_seconds(self) -> float:
        return sum(c.cpu_seconds for c in self.candidates)

    def near_ties(self) -> list[int]:
        """The windows screened within ``tolerance`` of the lowest loss, shortest first."""
        scored = {c.window: c.best_val_loss for c in self.candidates if c.best_val_loss is not None}
        if not scored:
            return []
        lowest = min(scored.values())
        return sorted(w for w, loss in scored.items() if loss <= self.tolerance * lowest)

    def next_followup(self) -> int | None:
        """The window to train fully next, or ``None``: the shortest near-tied window not yet
        trained fully, while the full runs so far used less than :data:`FOLLOWUP_SHARE` of the
        profile's epochs (none before the screened window's own full run is recorded)."""
        if not self.full_runs or self.full_epochs is None:
            return None
        if sum(r.epochs_run for r in self.full_runs) >= FOLLOWUP_SHARE * self.full_epochs:
            return None
        done = {r.window for r in self.full_runs}
        return next((w for w in self.near_ties() if w not in done), None)

    def with_full_run(self, row: ScreenCandidate, full_epochs: int) -> WindowScreen:
        """This screen with ``row``, a full run, recorded: ``chosen`` becomes the full run of
        lowest best validation loss (the earlier one on a tie)."""
        runs = (*self.full_runs, row)
        scored = [r for r in runs if r.best_val_loss is not None]
        best = min(scored, key=lambda r: r.best_val_loss) if scored else runs[0]  # type: ignore[arg-type, return-value]
        return dataclasses.replace(
            self,
            chosen=best.window,
            screened=self.screened_window,
            full_runs=runs,
            full_epochs=int(full_epochs),
        )

    def summary(self) -> str:
        """The choice in one line (what ``canonid train`` prints)."""
        windows = ", ".join(str(c.window) for c in self.candidates)
        screen = (
            f"{windows} (screen of {self.epochs} epoch{'' if self.epochs == 1 else 's'} each, "
            f"the shortest within {self.tolerance:g}× of the lowest loss)"
        )
        if len(self.full_runs) < 2:
            return (
                f"window ℓ = {self.chosen} chosen on validation from {screen}; --window L trains L"
            )
        first = self.full_runs[0]
        others = ", ".join(str(r.window) for r in self.full_runs[1:])
        return (
            f"window ℓ = {self.chosen} chosen on validation: the screen of {windows} "
            f"({self.epochs} epochs each) kept ℓ = {self.screened_window}, the shortest within "
            f"{self.tolerance:g}× of the lowest loss; its full run ended at epoch "
            f"{first.epochs_run} of {self.full_epochs}, so the near-tied ℓ = {others} trained "
            f"fully too, and ℓ = {self.chosen} has the lowest full-run validation loss; "
            "--window L trains L"
        )

    def table(self) -> str:
        """The candidates and the full runs in aligned columns, the chosen one marked."""
        rows = [
            ("ℓ", "run", "best validation loss (normalised)", "at epoch", "stopped", "CPU s", "")
        ]
        full = [("full", r) for r in self.full_runs]
        for kind, c in [*(("screen", c) for c in self.candidates), *full]:
            loss = "-" if c.best_val_loss is None else f"{c.best_val_loss:.4g}"
            stopped = c.stopped if c.error is None else f"failed: {c.error}"
            is_model = c.window == self.chosen and (kind == "full" or not self.full_runs)
            mark = "chosen" if is_model else ""
            if kind == "screen" and self.full_runs and c.window == self.screened_window:
                mark = "screened"
            rows.append(
                (
                    str(c.window),
                    kind,
                    loss,
                    str(c.best_epoch),
                    stopped,
                    f"{c.cpu_seconds:.0f}",
                    mark,
                )
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": SCREEN_FORMAT,
            "version": 3,
            "criterion": "shortest window with best_val_loss <= tolerance × the lowest; then "
            "the lowest best_val_loss of the full runs",
            "chosen": self.chosen,
            "screened": self.screened,
            "fraction": self.fraction,
            "tolerance": self.tolerance,
            "followup_share": FOLLOWUP_SHARE,
            "full_epochs": self.full_epochs,
            "options": dict(self.options),
            "candidates": [dataclasses.asdict(c) for c in self.candidates],
            "full_runs": [dataclasses.asdict(c) for c in self.full_runs],
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> WindowScreen:
        if not isinstance(data, Mapping) or data.get("format") != SCREEN_FORMAT:
            raise CheckpointError(f"{where} is not a canonid window screen")
        try:
            rows = tuple(ScreenCandidate(**row) for row in data["candidates"])
            full = tuple(ScreenCandidate(**row) for row in data.get("full_runs", ()))
            epochs = data.get("full_epochs")
            screen = cls(
                rows,
                int(data["chosen"]),
                float(data["fraction"]),
                data["options"],
                # version 1 chose the lowest loss itself
                float(data.get("tolerance", 1.0)),
                None if data.get("screened") is None else int(data["screened"]),
                full,
                None if epochs is None else int(epochs),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{where}: malformed window screen ({exc})") from exc
        if screen.screened_window not in [c.window for c in rows]:
            raise CheckpointError(
                f"{where}: chosen window {screen.screened_window} is not a candidate"
            )
        if full and screen.chosen not in [r.window for r in full]:
            raise CheckpointError(f"{where}: chosen window {screen.chosen} is not a full run")
        return screen

    @classmethod
    def read(cls, run_dir: Path) -> WindowScreen:
        path = Path(run_dir) / SCREEN_FILE
        return cls.from_dict(read_json(path, what="window screen"), where=str(path))

    def write(self, run_dir: Path) -> None:
        atomic_write_json(Path(run_dir) / SCREEN_FILE, self.to_dict())


def choose_window(losses: Mapping[int, float], tolerance: float = SCREEN_TOLERANCE) -> int:
    """The shortest window whose loss is at most ``tolerance`` times the lowest of ``losses``
    (window → finite best validation loss)."""
    lowest = min(losses.values())
    return min(window for window, loss in losses.items() if loss <= tolerance * lowest)


def screen_options(options: Any, fraction: float = SCREEN_FRACTION) -> Any:
    """``options`` (:class:`~canonid.learning.training.TrainOptions`, typed loosely in this
    module, which does not import the trainer) compressed to ``fraction`` of their epochs (at
    least one): the curriculum and the early-stopping patience scaled alike, so the candidates
    see the whole schedule."""
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
