"""Axis-aligned boxes: the compact sets X, U, W on which the theory is evaluated."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.errors import SetError

__all__ = ["Box"]

_Bounds = Sequence[float] | np.ndarray


@dataclass(frozen=True)
class Box:
    """The box ``{v : lower <= v <= upper}`` (component-wise, closed, finite).

    Stored as tuples so a box is hashable and serialises to JSON unchanged.
    """

    lower: tuple[float, ...]
    upper: tuple[float, ...]

    def __init__(self, lower: _Bounds, upper: _Bounds) -> None:
        lo = np.atleast_1d(np.asarray(lower, dtype=np.float64))
        hi = np.atleast_1d(np.asarray(upper, dtype=np.float64))
        if lo.ndim != 1 or hi.ndim != 1 or lo.shape != hi.shape:
            raise SetError(
                f"box bounds must be 1-D of equal length, got lower {lo.shape} and upper {hi.shape}"
            )
        if lo.size == 0:
            raise SetError("a box needs at least one dimension")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise SetError(
                f"box bounds must be finite, got lower={lo.tolist()} upper={hi.tolist()}"
            )
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            i = int(bad[0])
            raise SetError(
                f"box has lower > upper in component {i}: {lo[i]} > {hi[i]} "
                "(expected lower <= upper)"
            )
        object.__setattr__(self, "lower", tuple(float(v) for v in lo))
        object.__setattr__(self, "upper", tuple(float(v) for v in hi))

    @classmethod
    def symmetric(cls, half_width: Sequence[float] | float, dim: int | None = None) -> Box:
        """The box ``[-a, a]`` per component (``a`` broadcast to ``dim`` if a scalar)."""
        a = np.asarray(half_width, dtype=np.float64)
        if a.ndim == 0:
            a = np.full(dim or 1, float(a))
        return cls(-a, a)

    @property
    def dim(self) -> int:
        return len(self.lower)

    @property
    def lo(self) -> np.ndarray:
        """Lower corner as a float64 array."""
        return np.asarray(self.lower)

    @property
    def hi(self) -> np.ndarray:
        """Upper corner as a float64 array."""
        return np.asarray(self.upper)

    @property
    def center(self) -> np.ndarray:
        return 0.5 * (self.lo + self.hi)

    @property
    def width(self) -> np.ndarray:
        return self.hi - self.lo

    @property
    def radius(self) -> float:
        """Largest Euclidean norm of a point of the box (e.g. the bound on ‖w‖ for W)."""
        return float(np.linalg.norm(np.maximum(np.abs(self.lo), np.abs(self.hi))))

    def contains(self, v: np.ndarray, *, atol: float = 0.0) -> bool:
        """True when every row of ``v`` (shape ``(dim,)`` or ``(N, dim)``) lies in the box."""
        v = np.asarray(v, dtype=np.float64)
        return bool(np.all(v >= self.lo - atol) and np.all(v <= self.hi + atol))

    def contains_rows(self, v: np.ndarray) -> np.ndarray:
        """Per row of ``v`` (shape ``(N, dim)``): whether it lies in the box, ``(N,)`` bools."""
        v = np.asarray(v, dtype=np.float64)
        return np.all((v >= self.lo) & (v <= self.hi), axis=1)

    def clip(self, v: np.ndarray) -> np.ndarray:
        return np.clip(v, self.lo, self.hi)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points drawn uniformly in the box, shape ``(n, dim)``."""
        return rng.uniform(self.lo, self.hi, size=(n, self.dim))

    def to_dict(self) -> dict[str, list[float]]:
        return {"lower": list(self.lower), "upper": list(self.upper)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Box:
        """The box of a :meth:`to_dict` record."""
        return cls(data["lower"], data["upper"])

    def __repr__(self) -> str:
        parts = ", ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(self.lower, self.upper))
        return f"Box({parts})"
