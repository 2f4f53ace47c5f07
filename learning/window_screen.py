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

from canonid.kernel.errors import CheckpointError
from canonid.kernel.io import atomic_write_json, read_json

__all__ = [
    "SCREEN_FILE",
    "SCREEN_FRACTION",
    "SCREEN_TOLERANCE",
    "SCREEN_WINDOWS",
    "ScreenCandidate",
    "WindowScreen",
    "choose_window",
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


def choose_window(losses: Mapping[int, float], tolerance: float = SCREEN_TOLERANCE) -> int:
    """The shortest window whose loss is at most ``tolerance`` times the lowest of ``losses``
    (window → finite best validation loss)."""
    lowest = min(losses.values())
    return min(window for window, loss in losses.items() if loss <= tolerance * lowest)
