"""Cutting long records into consecutive fixed-length chunks (the paper's 200-step chunks).

Chunk ``c`` of a record of ``n`` samples holds samples ``c·L … (c+1)·L − 1`` for
``c = 0 … ⌊n/L⌋ − 1``; the last ``n mod L`` samples are dropped. Chunks do not overlap, so a
chunk never shares a sample with another one (and, split by record, never with another split).
"""

from __future__ import annotations

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import DataError

__all__ = ["chunk_bounds", "cut_chunks"]


def chunk_bounds(n_samples: int, chunk_length: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of every chunk: ``[c·L, (c+1)·L)`` for ``c = 0 … ⌊n/L⌋ − 1``."""
    if chunk_length < 1:
        raise DataError(f"chunk_length must be >= 1, got {chunk_length}")
    return [(c * chunk_length, (c + 1) * chunk_length) for c in range(n_samples // chunk_length)]


def cut_chunks(trajectory: Trajectory, chunk_length: int) -> tuple[Trajectory, ...]:
    """The chunks of ``trajectory`` as trajectories.

    Every stored field (``u``, ``y``, ``y_clean``, ``x``, ``reference``) is sliced alike; each
    chunk's ``info`` is the record's, plus ``chunk`` (its index) and ``chunk_start`` (the
    record's sample at which it starts).
    """
    return tuple(
        trajectory.part(a, b, chunk=c, chunk_start=a)
        for c, (a, b) in enumerate(chunk_bounds(trajectory.T, chunk_length))
    )
