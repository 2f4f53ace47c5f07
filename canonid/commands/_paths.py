"""Output folders given on the command line (``--out``): checked before any work is done."""

from __future__ import annotations

import argparse
from pathlib import Path

from canonid.kernel.errors import OutputError

__all__ = ["check_folder", "folder"]


def folder(text: str) -> Path:
    """argparse type of ``--out``: a path, not an empty string (which would mean the current
    folder without saying so)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder, got an empty string")
    return Path(text)


def check_folder(path: Path, *, flag: str = "--out") -> Path:
    """``path`` if it is a folder or can become one; else :class:`OutputError` naming the file
    in the way (``path`` itself or one of its parents)."""
    for part in (path, *path.parents):
        if part.exists():
            if not part.is_dir():
                what = "is a file" if part == path else f"lies below the file {part}"
                raise OutputError(f"{flag} {path} {what}; expected a folder")
            break
    return path
