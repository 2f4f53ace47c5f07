"""Where scored data leave the range the model was trained on.

A model fitted inside its training data extrapolates beyond them, and a score there measures
extrapolation, not fit: a test record that drives an input or an output past anything training
saw explains a test score far below the validation score. Training records each signal's span
over the training part in the model's ``info`` (:data:`INFO_KEY`, :func:`training_ranges`);
:func:`outside_training_range` tells, for the data scored, which signals leave that span, on what
share of their samples and by how far; ``metrics.json`` keeps it and the scores' table prints it.

The module imports numpy only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from canonid.kernel.dataset import Trajectory

__all__ = ["INFO_KEY", "NOTED_BEYOND", "OutsideRange", "outside_training_range", "training_ranges"]

#: the key of the model's ``info`` that holds the training spans
INFO_KEY = "training_range"
#: the printed tables name a signal that goes more than this share of its training span beyond
#: it (``metrics.json`` keeps every one): a record drawn like the training data leaves a finite
#: span a little at its tails, a part made to extrapolate by much more (RESULTS.md, "Test parts
#: outside the training range")
NOTED_BEYOND = 0.05

Kind = Literal["input", "output"]
_KINDS: tuple[tuple[Kind, str, str], ...] = (
    ("input", "inputs", "u"),
    ("output", "outputs", "y"),
)


def training_ranges(trajectories: Sequence[Trajectory]) -> dict[str, list[list[float]]]:
    """``{"inputs": [[low, high], …], "outputs": […]}``: each signal's smallest and largest
    sample over ``trajectories`` (the training part), the form kept in the model's ``info``."""
    spans: dict[str, list[list[float]]] = {}
    for _, key, attr in _KINDS:
        values = np.concatenate([np.asarray(getattr(t, attr), dtype=float) for t in trajectories])
        spans[key] = [[float(lo), float(hi)] for lo, hi in zip(values.min(0), values.max(0))]
    return spans


@dataclass(frozen=True)
class OutsideRange:
    """One signal of the scored data outside its training span ``[low, high]``.

    Attributes:
        name, kind: the signal and whether it is an input or an output.
        train_low, train_high: its span over the training part.
        share: the share of the scored samples outside the span (0 … 1).
        distance: the largest distance of a sample outside the span, in the signal's units.
        beyond: ``distance`` as a multiple of the span's width (``None`` for a signal constant
            in training).
    """

    name: str
    kind: Kind
    train_low: float
    train_high: float
    share: float
    distance: float
    beyond: float | None

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> OutsideRange:
        return cls(
            name=str(data["name"]),
            kind=data["kind"],
            train_low=float(data["train_low"]),
            train_high=float(data["train_high"]),
            share=float(data["share"]),
            distance=float(data["distance"]),
            beyond=None if data.get("beyond") is None else float(data["beyond"]),
        )

    @property
    def noted(self) -> bool:
        """Whether the printed tables name it: beyond :data:`NOTED_BEYOND` of its span, or any
        distance outside a span of width zero."""
        return self.beyond is None or self.beyond > NOTED_BEYOND

    def describe(self) -> str:
        """E.g. ``input u0 on 12.3 % of samples (training span [2.1, 7.9], up to 0.35 × its span
        beyond)``."""
        how_far = (
            f"up to {self.distance:.3g} beyond"
            if self.beyond is None
            else f"up to {self.beyond:.2g} × its span beyond"
        )
        return (
            f"{self.kind} {self.name} on {100 * self.share:.3g} % of samples "
            f"(training span [{self.train_low:.4g}, {self.train_high:.4g}], {how_far})"
        )


def outside_training_range(
    info: Mapping[str, Any],
    trajectories: Sequence[Trajectory],
    *,
    input_names: Sequence[str],
    output_names: Sequence[str],
) -> tuple[OutsideRange, ...] | None:
    """The signals of ``trajectories`` that leave the training spans recorded in ``info``
    (:data:`INFO_KEY`), each with its share of samples outside and its largest distance; ``()``
    when every sample is inside, ``None`` when the model recorded no spans (saved before they
    were recorded, or without data) or spans of another number of signals."""
    spans = info.get(INFO_KEY)
    if not isinstance(spans, Mapping):
        return None
    found: list[OutsideRange] = []
    for kind, key, attr in _KINDS:
        names = input_names if kind == "input" else output_names
        recorded = spans.get(key)
        if not isinstance(recorded, list) or len(recorded) != len(names):
            return None
        values = np.concatenate([np.asarray(getattr(t, attr), dtype=float) for t in trajectories])
        for i, (name, (low, high)) in enumerate(zip(names, recorded)):
            column = values[:, i]
            gap = np.maximum(low - column, column - high)  # > 0 outside the span
            outside = gap > 0
            if not outside.any():
                continue
            width = high - low
            distance = float(gap.max())
            found.append(
                OutsideRange(
                    name=str(name),
                    kind=kind,
                    train_low=float(low),
                    train_high=float(high),
                    share=float(outside.mean()),
                    distance=distance,
                    beyond=distance / width if width > 0 else None,
                )
            )
    return tuple(found)
