"""Output folders given on the command line (``--out``)."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["folder"]


def folder(text: str) -> Path:
    """argparse type of ``--out``: a path, not an empty string (which would mean the current
    folder without saying so); the application checks it before any work is done
    (:func:`canonid.jobs.check_folder`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder, got an empty string")
    return Path(text)
