"""The one result type of every estimator: a value that says what it is.

An :class:`Estimate` is a **lower bound**, an **upper bound** or a plain **estimate** of one
quantity (``gamma_f``, ``gamma_h`` or ``alpha``), together with the sets on which it holds, the
method that produced it, the budget it was given and the wall time it took. A lower and an upper
bound of the same quantity form a :class:`Bracket`.

"Certified" in a method name means the bound is proved by outward-rounded interval arithmetic
(:mod:`canonid.analysis.interval`); sampled bounds are exact evaluations at points (a sampled
‖∂f/∂x‖ is a lower bound of the supremum up to float rounding, a sampled ratio an upper bound of the
infimum).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Literal

from canonid.kernel.errors import SetError
from canonid.models.sets import Box

__all__ = ["KINDS", "QUANTITIES", "Bracket", "Budget", "Estimate", "Kind", "OutOfTime"]

Kind = Literal["lower", "upper", "estimate"]
KINDS: tuple[str, ...] = ("lower", "upper", "estimate")
#: γ_f (Lipschitz constant of f in x), γ_h (of h in x), α_ℓ (Definition 2)
QUANTITIES: tuple[str, ...] = ("gamma_f", "gamma_h", "alpha")


@dataclass(frozen=True)
class Budget:
    """What an estimator may spend.

    Attributes:
        seconds: wall-clock limit of each stage (``None``: no limit): of a branch-and-bound
            search, its set-up included, and of a sampled bound (its samples and local
            searches). A stage checks it between steps, so it overruns by at most one step
            (one batch of boxes or points; one CasADi Jacobian built). Tests use ``boxes``
            instead, so that results do not depend on the machine.
        boxes: largest number of boxes a branch-and-bound search evaluates.
        samples: random points (or pairs) evaluated by a sampled bound.
        starts: local optimisations started from the best samples.
    """

    seconds: float | None = None
    boxes: int = 20_000
    samples: int = 4096
    starts: int = 8

    def __post_init__(self) -> None:
        if self.seconds is not None and not (0 < self.seconds < math.inf):
            raise SetError(f"budget seconds must be finite and > 0, or None; got {self.seconds}")
        for name in ("boxes", "samples", "starts"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise SetError(f"budget {name} must be an integer >= 1, got {value!r}")

    def exhausted(self, evaluated: int, started: float) -> str | None:
        """Why a search that has evaluated ``evaluated`` boxes since ``started``
        (``time.perf_counter()``) must stop, or ``None``."""
        if evaluated >= self.boxes:
            return "box budget exhausted"
        if self.seconds is not None and time.perf_counter() - started > self.seconds:
            return "time budget exhausted"
        return None

    def deadline(self, started: float) -> float:
        """When a stage started at ``started`` (``time.perf_counter()``) must stop: ``inf``
        without a limit in seconds."""
        return math.inf if self.seconds is None else started + self.seconds

    def used(self, evaluated: int, started: float) -> float:
        """Fraction of the budget spent (boxes or time, whichever is further), for progress."""
        spent = evaluated / self.boxes
        if self.seconds is not None:
            spent = max(spent, (time.perf_counter() - started) / self.seconds)
        return min(spent, 1.0)

    def to_dict(self) -> dict[str, Any]:
        return {
            "seconds": self.seconds,
            "boxes": self.boxes,
            "samples": self.samples,
            "starts": self.starts,
        }


class OutOfTime(Exception):
    """A stage's deadline passed in the middle of an evaluation it cannot split further (an
    interval evaluation of a large graph, a local optimisation). Internal: the stage that set
    the deadline catches it and reports what it has, saying that the time ran out."""


@dataclass(frozen=True)
class Estimate:
    """One bound or estimate of a quantity.

    Attributes:
        quantity: ``"gamma_f"``, ``"gamma_h"`` or ``"alpha"``.
        value: the number (``inf`` is allowed for an upper bound that could not be made finite).
        kind: ``"lower"``, ``"upper"`` or ``"estimate"``.
        sets: the boxes on which it holds, by name (``"X"``, ``"U"``; for γ over a reachable
            hull, ``"X"`` is that hull).
        method: how it was obtained (short, human-readable).
        window: ``ℓ`` for α_ℓ and for γ over the hull reached in ``ℓ − 1`` steps; ``None`` else.
        budget: the budget the estimator was given (``Budget.to_dict()``), or ``{}``.
        seconds: wall time spent.
        details: method-specific facts (boxes evaluated, bracket width, argmin point, ...).
    """

    quantity: str
    value: float
    kind: Kind
    sets: Mapping[str, Box]
    method: str
    window: int | None = None
    budget: Mapping[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    details: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.quantity not in QUANTITIES:
            raise SetError(f"quantity must be one of {QUANTITIES}, got {self.quantity!r}")
        if self.kind not in KINDS:
            raise SetError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if math.isnan(self.value):
            raise SetError(f"{self.quantity} {self.kind} bound ({self.method}) is NaN")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record (an infinite value is written as ``null``)."""
        return {
            "quantity": self.quantity,
            "window": self.window,
            "value": self.value if math.isfinite(self.value) else None,
            "kind": self.kind,
            "method": self.method,
            "seconds": round(self.seconds, 6),
            "sets": {name: box.to_dict() for name, box in self.sets.items()},
            "budget": dict(self.budget),
            "details": dict(self.details),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Estimate:
        """The estimate of a :meth:`to_dict` record (``value: null`` is ``+∞``)."""
        value = data["value"]
        return cls(
            quantity=data["quantity"],
            value=math.inf if value is None else float(value),
            kind=data["kind"],
            sets={name: Box.from_dict(box) for name, box in data["sets"].items()},
            method=data["method"],
            window=data["window"],
            budget=dict(data.get("budget", {})),
            seconds=float(data.get("seconds", 0.0)),
            details=dict(data.get("details", {})),
        )


@dataclass(frozen=True)
class Bracket:
    """A lower and an upper bound of the same quantity on the same sets."""

    lower: Estimate
    upper: Estimate

    def __post_init__(self) -> None:
        if self.lower.kind != "lower" or self.upper.kind != "upper":
            raise SetError(
                f"a bracket needs a lower and an upper bound, got {self.lower.kind} and "
                f"{self.upper.kind}"
            )
        if self.lower.quantity != self.upper.quantity:
            raise SetError(f"bracket mixes {self.lower.quantity} and {self.upper.quantity}")
        if self.lower.value > self.upper.value:
            raise SetError(
                f"{self.lower.quantity}: lower bound {self.lower.value!r} ({self.lower.method}) "
                f"exceeds upper bound {self.upper.value!r} ({self.upper.method}); "
                "expected lower <= upper — one of the two is wrong"
            )

    @classmethod
    def reconcile(cls, lower: Estimate, upper: Estimate, *, rtol: float = 1e-9) -> Bracket:
        """The bracket of ``lower`` and ``upper``, allowing for the rounding of sampled values.

        A sampled value is a bound only up to float rounding (a ratio computed in float64 can
        land a few ulps below the exact one). When the two bounds cross by at most ``rtol``
        (relative), the sampled side is moved onto the other and the move is recorded in its
        ``details``; a larger crossing is a real contradiction and raises ``SetError``.
        """
        gap = lower.value - upper.value
        if gap <= 0 or gap > rtol * max(abs(lower.value), abs(upper.value)):
            return cls(lower, upper)
        sampled_upper = not upper.method.startswith(("certified", "exact"))
        side, other = (upper, lower) if sampled_upper else (lower, upper)
        moved = replace(
            side,
            value=other.value,
            details={**side.details, "rounding_adjusted_from": side.value},
        )
        return cls(lower, moved) if sampled_upper else cls(moved, upper)

    @property
    def width(self) -> float:
        return self.upper.value - self.lower.value

    @property
    def relative_width(self) -> float:
        """``(upper − lower) / upper`` (0 for an exact value, ``inf`` when undefined)."""
        if self.upper.value == 0:
            return 0.0 if self.lower.value == 0 else math.inf
        return self.width / self.upper.value
