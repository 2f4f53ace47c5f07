"""Exception types shared by every layer of canonid.

All errors raised on purpose by the project derive from :class:`CanonidError`, so the CLI can
print them as one readable line. Each also derives from the closest built-in type
(``ValueError``, ``KeyError``, ...) so callers that catch those keep working.
"""

from __future__ import annotations

__all__ = [
    "CanonidError",
    "CheckpointError",
    "DataError",
    "OptionError",
    "OutputError",
    "SetError",
    "ShapeError",
    "UnknownSplitError",
    "UnknownSystemError",
    "WorkerError",
]


class CanonidError(Exception):
    """Base class of every error canonid raises on purpose."""


class ShapeError(CanonidError, ValueError):
    """An array has the wrong shape or holds non-finite values."""


class SetError(CanonidError, ValueError):
    """A box (X, U, W) is malformed or unsuitable for the requested computation."""


class UnknownSystemError(CanonidError, KeyError):
    """A system name that is not in the registry."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class DataError(CanonidError, ValueError):
    """A data file or dataset is missing, corrupt, truncated or inconsistent."""


class UnknownSplitError(DataError, KeyError):
    """A split name that the dataset does not have."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class OptionError(CanonidError, ValueError):
    """An option out of range or of the wrong kind: a command-line flag, a function's keyword, a
    profile's key, or a device that is not available."""


class CheckpointError(CanonidError, ValueError):
    """A checkpoint or saved model cannot be used (corrupt, or from another model)."""


class OutputError(CanonidError, OSError):
    """A file or folder cannot be written: a file where a folder is expected, a full disk, a
    read-only file system, missing permissions."""


class WorkerError(CanonidError, RuntimeError):
    """A worker process that trained side by side ended abruptly (killed by the system, most
    often for lack of memory): its work is lost, not the finished work of the others."""
