"""Small argument validators: every error names the argument and what was expected."""

from __future__ import annotations

from typing import Any

import numpy as np

from canonid.kernel.errors import ShapeError

__all__ = ["as_matrix", "as_vector", "require_finite"]


def require_finite(array: np.ndarray, name: str) -> np.ndarray:
    """Raise :class:`ShapeError` naming ``name`` if ``array`` holds NaN or Inf."""
    if not np.all(np.isfinite(array)):
        bad = np.argwhere(~np.isfinite(array))
        first = tuple(int(i) for i in bad[0])
        raise ShapeError(
            f"{name} contains {len(bad)} non-finite value(s) (NaN or Inf), first at index {first}"
        )
    return array


def as_vector(value: Any, size: int, name: str) -> np.ndarray:
    """Return ``value`` as a finite float64 vector of length ``size``.

    A scalar is accepted when ``size == 1``; a ``(size, 1)`` or ``(1, size)`` array is flattened.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if arr.ndim == 0 and size == 1:
        arr = arr.reshape(1)
    elif arr.ndim == 2 and 1 in arr.shape and arr.size == size:
        arr = arr.reshape(size)
    if arr.shape != (size,):
        raise ShapeError(f"{name} must have shape ({size},), got {arr.shape}")
    return require_finite(arr, name)


def as_matrix(value: Any, cols: int, name: str, *, rows: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float64 array of shape ``(rows, cols)``.

    A 1-D array is read as a single column when ``cols == 1`` (a SISO signal).
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if arr.ndim == 1 and cols == 1:
        arr = arr.reshape(-1, 1)
    expected = f"({rows if rows is not None else 'T'}, {cols})"
    if arr.ndim != 2 or arr.shape[1] != cols or (rows is not None and arr.shape[0] != rows):
        raise ShapeError(f"{name} must have shape {expected}, got {arr.shape}")
    return require_finite(arr, name)
