"""The normalisation of trajectories and their sub-windows, as the learning layer sees them.

Trajectories are the kernel's :class:`canonid.kernel.dataset.Trajectory`: the public functions of
this layer (:func:`canonid.learning.fit`, :func:`canonid.learning.evaluate`, …) turn what they are
given into them once (:func:`canonid.kernel.dataset.as_trajectories`, which also accepts any
objects with ``.u`` and ``.y``); the code below trusts them. ``y_clean`` is used only for
reporting.

Time alignment (the project's convention): sample ``t`` holds ``u[t]`` and ``y[t]``; a model with
window ℓ predicting ``y[t]`` sees samples ``t−ℓ … t−1`` and, with feedthrough, ``u[t]``.

A *sub-window* of length ``ℓ + H`` starting at sample ``s`` holds samples ``s … s+ℓ+H−1``: the
first ℓ are the measured burn-in (they build ``z_{s+ℓ}``), the last ``H`` are predicted in open
loop (``y[s+ℓ] … y[s+ℓ+H−1]``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import DataError

__all__ = ["Normalisation", "WindowBank", "window_starts"]

_STD_FLOOR = 1e-12


@dataclass(frozen=True)
class Normalisation:
    """Affine normalisation by training statistics, saved with every model.

    ``u_n = (u − u_mean) / u_std`` and ``y_n = (y − y_mean) / y_std`` per channel; ``dy_std`` is the
    standard deviation of the one-step increment ``y[t] − y[t−1]`` (physical units), which scales
    the output of a ``residual`` regressor. A constant channel gets a standard deviation of 1.
    """

    u_mean: np.ndarray
    u_std: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    dy_std: np.ndarray

    @classmethod
    def fit(cls, trajectories: Iterable[Trajectory]) -> Normalisation:
        """Statistics over every sample of the given (training) trajectories."""
        items = list(trajectories)
        u = np.concatenate([s.u for s in items])
        y = np.concatenate([s.y for s in items])
        dy = np.concatenate([np.diff(s.y, axis=0) for s in items])

        def std(a: np.ndarray) -> np.ndarray:
            if a.shape[0] < 2:
                return np.ones(a.shape[1])
            sd = a.std(axis=0)
            return np.where(sd > _STD_FLOOR, sd, 1.0)

        with np.errstate(over="ignore", invalid="ignore"):
            stats = (u.mean(axis=0), std(u), y.mean(axis=0), std(y), std(dy))
        # values near the float64 limit (1e308) overflow the mean or the spread
        for name, data, parts in (("input", u, stats[:2]), ("output", y, stats[2:])):
            bad = np.flatnonzero(~np.all(np.isfinite(np.stack(parts)), axis=0))
            if bad.size:
                k = int(bad[0])
                raise DataError(
                    f"training data: {name} {k + 1} (values up to {np.abs(data[:, k]).max():g}) "
                    "overflows float64 in its mean, spread or increments; rescale it"
                )
        return cls(*stats)

    @property
    def n_u(self) -> int:
        return int(self.u_mean.shape[0])

    @property
    def n_y(self) -> int:
        return int(self.y_mean.shape[0])

    def to_dict(self) -> dict[str, list[float]]:
        return {k: [float(v) for v in getattr(self, k)] for k in _NORM_FIELDS}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str = "normalisation") -> Normalisation:
        try:
            arrays = {k: np.asarray(data[k], dtype=np.float64) for k in _NORM_FIELDS}
        except KeyError as exc:
            raise DataError(f"{where}: missing field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise DataError(f"{where}: fields must be lists of numbers ({exc})") from None
        for key, arr in arrays.items():
            if arr.ndim != 1 or not np.all(np.isfinite(arr)):
                raise DataError(f"{where}: field {key!r} must be a finite vector")
        n_u, n_y = arrays["u_mean"].size, arrays["y_mean"].size
        for key, n in (("u_std", n_u), ("y_std", n_y), ("dy_std", n_y)):
            if arrays[key].size != n or not np.all(arrays[key] > 0):
                raise DataError(f"{where}: field {key!r} must hold {n} positive numbers")
        return cls(**arrays)

    def norm_u(self, u: np.ndarray) -> np.ndarray:
        return (u - self.u_mean) / self.u_std

    def norm_y(self, y: np.ndarray) -> np.ndarray:
        return (y - self.y_mean) / self.y_std

    def denorm_y(self, y: np.ndarray) -> np.ndarray:
        return y * self.y_std + self.y_mean


_NORM_FIELDS = ("u_mean", "u_std", "y_mean", "y_std", "dy_std")


def window_starts(lengths: Sequence[int], span: int, *, stride: int = 1) -> np.ndarray:
    """All ``(trajectory, start)`` pairs whose sub-window of ``span`` samples fits, ``(N, 2)``.

    Starts are ``0, stride, 2·stride, …`` up to ``T − span`` in each trajectory, in order.
    """
    rows = [
        np.stack([np.full_like(s, i), s], axis=1)
        for i, T in enumerate(lengths)
        if T >= span
        for s in [np.arange(0, T - span + 1, stride)]
    ]
    return np.concatenate(rows) if rows else np.zeros((0, 2), dtype=np.int64)


class WindowBank:
    """Normalised trajectories stored end to end, for fast gathering of sub-windows.

    Args:
        trajectories: the trajectories (physical units).
        norm: the normalisation applied to them.
        dtype, device: of the stored tensors.
    """

    def __init__(
        self,
        trajectories: Sequence[Trajectory],
        norm: Normalisation,
        *,
        dtype: torch.dtype = torch.float32,
        device: torch.device | str = "cpu",
    ) -> None:
        self.lengths = [tr.T for tr in trajectories]
        self.offsets = np.concatenate([[0], np.cumsum(self.lengths)[:-1]]).astype(np.int64)
        u = np.concatenate([norm.norm_u(tr.u) for tr in trajectories])
        y = np.concatenate([norm.norm_y(tr.y) for tr in trajectories])
        self.u = torch.as_tensor(u, dtype=dtype, device=device)
        self.y = torch.as_tensor(y, dtype=dtype, device=device)

    def starts(self, span: int, *, stride: int = 1) -> np.ndarray:
        """:func:`window_starts` for these trajectories."""
        return window_starts(self.lengths, span, stride=stride)

    def gather(self, starts: np.ndarray, span: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Sub-windows ``starts`` ``(N, 2)`` of ``span`` samples: ``u`` ``(N, span, n_u)`` and
        ``y`` ``(N, span, n_y)``; row ``k`` holds samples ``s … s+span−1`` of trajectory ``i``
        for ``(i, s) = starts[k]``."""
        first = torch.as_tensor(self.offsets[starts[:, 0]] + starts[:, 1], device=self.u.device)
        idx = first[:, None] + torch.arange(span, device=self.u.device)
        return self.u[idx], self.y[idx]
