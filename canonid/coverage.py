"""Where scored data leave the range the model was trained on.

A model fitted inside its training data extrapolates beyond them, and a score there measures
extrapolation, not fit: a test record that drives an input or an output past anything training
saw explains a test score far below the validation score. Training records each signal's span
over the training part in the model's ``info`` (:data:`INFO_KEY`, :func:`training_ranges`);
:func:`outside_training_range` tells, for the data scored, which signals leave that span, on what
share of their samples and by how far; ``metrics.json`` keeps it and the scores' table prints it.
The same measure of the training part against the validation part's spans (:func:`unvalidated`)
tells which levels no choice made on validation can judge; ``canonid train`` and ``canonid
benchmark`` print them (:func:`unvalidated_line`).

The module imports numpy only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from canonid.kernel.catalog import INFO_TRAINING_RANGE, INFO_UNVALIDATED
from canonid.kernel.dataset import Trajectory
from canonid.kernel.io import is_outside_record

__all__ = [
    "INFO_KEY",
    "NOTED_BEYOND",
    "UNVALIDATED_SHARE",
    "VALIDATION_KEY",
    "OutsideRange",
    "outside_training_range",
    "recorded_unvalidated",
    "training_ranges",
    "unvalidated",
    "unvalidated_line",
]

#: the key of the model's ``info`` that holds the training spans
INFO_KEY = INFO_TRAINING_RANGE
#: the key of the model's ``info`` that holds where the training part leaves the validation
#: part's spans (:func:`unvalidated`)
VALIDATION_KEY = INFO_UNVALIDATED
#: ``canonid train`` names a signal whose training samples leave the validation span by more
#: than :data:`NOTED_BEYOND` of it on at least this share of them: a few extreme samples do not
#: make a validation part unrepresentative, a level held for a hundredth of the record does
UNVALIDATED_SHARE = 0.01
#: the printed tables name a signal that goes more than this share of its training span beyond
#: it (``metrics.json`` keeps every one): a record drawn like the training data leaves a finite
#: span a little at its tails, a part made to extrapolate by much more
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
    """One signal of some samples outside a reference span ``[span_low, span_high]``: the
    training part's span for scored data (:func:`outside_training_range`), the validation
    part's for the training part (:func:`unvalidated`).

    Attributes:
        name, kind: the signal and whether it is an input or an output.
        span_low, span_high: the reference span.
        share: the share of the samples outside the span (0 … 1).
        distance: the largest distance of a sample outside the span, in the signal's units.
        beyond: ``distance`` as a multiple of the span's width (``None`` for a span of width
            zero: a signal constant there).
    """

    name: str
    kind: Kind
    span_low: float
    span_high: float
    share: float
    distance: float
    beyond: float | None

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Any) -> OutsideRange:
        """The record of :meth:`to_json`; ``ValueError`` says what a damaged or hand-edited one
        lacks."""
        if not is_outside_record(data):
            raise ValueError(
                "expected an object with name, kind (input or output), span_low, span_high, "
                f"share, distance and beyond (a number or null), got {data!r}"
            )
        return cls(
            name=str(data["name"]),
            kind=data["kind"],
            span_low=float(data["span_low"]),
            span_high=float(data["span_high"]),
            share=float(data["share"]),
            distance=float(data["distance"]),
            beyond=None if data.get("beyond") is None else float(data["beyond"]),
        )

    @property
    def noted(self) -> bool:
        """Whether the printed tables name it: beyond :data:`NOTED_BEYOND` of its span, or any
        distance outside a span of width zero."""
        return self.beyond is None or self.beyond > NOTED_BEYOND

    def describe(self, *, samples: str = "samples", span: str = "training span") -> str:
        """E.g. ``input u0 on 12.3 % of samples (training span [2.1, 7.9], up to 0.35 × its span
        beyond)``; ``samples`` and ``span`` name what was counted and against what."""
        how_far = (
            f"up to {self.distance:.3g} beyond"
            if self.beyond is None
            else f"up to {self.beyond:.2g} × its span beyond"
        )
        return (
            f"{self.kind} {self.name} on {100 * self.share:.3g} % of {samples} "
            f"({span} [{self.span_low:.4g}, {self.span_high:.4g}], {how_far})"
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
                    span_low=float(low),
                    span_high=float(high),
                    share=float(outside.mean()),
                    distance=distance,
                    beyond=distance / width if width > 0 else None,
                )
            )
    return tuple(found)


def unvalidated(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    input_names: Sequence[str],
    output_names: Sequence[str],
) -> tuple[OutsideRange, ...]:
    """The signals whose training samples leave the validation part's span: levels the model is
    trained on that validation never shows it, so that a choice made on validation (the epoch,
    the window, the network) cannot judge how the model treats them. Each
    :class:`OutsideRange` is of the training part against the validation part's span."""
    spans = {INFO_KEY: training_ranges(val)}
    found = outside_training_range(spans, train, input_names=input_names, output_names=output_names)
    assert found is not None  # the spans were made for these signals
    return found


def recorded_unvalidated(info: Mapping[str, Any]) -> tuple[OutsideRange, ...]:
    """What a model's ``info`` recorded under :data:`VALIDATION_KEY` (none for a model saved
    before it was recorded)."""
    return tuple(OutsideRange.from_json(o) for o in info.get(VALIDATION_KEY) or [])


def unvalidated_line(found: Sequence[OutsideRange]) -> str | None:
    """What ``canonid train`` and ``canonid benchmark`` print of :func:`unvalidated`'s result:
    the signals beyond :data:`NOTED_BEYOND` of their validation span on at least
    :data:`UNVALIDATED_SHARE` of the training samples; ``None`` if there are none."""
    said = "; ".join(
        o.describe(samples="the training samples", span="validation span")
        for o in found
        if o.noted and o.share >= UNVALIDATED_SHARE
    )
    if not said:
        return None
    return (
        f"validation does not reach every level the training part holds: {said}; the choices "
        "made on validation cannot judge the model there (give --val data that reach them)"
    )
