"""A progress bar that appears at the first report, so that an error raised before any work
is done prints alone, as one line."""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["LazyBar"]


class LazyBar:
    """``tqdm`` over ``total`` epochs, created at the first :meth:`show` (never if disabled)."""

    def __init__(self, total: int, desc: str, *, enabled: bool, **options: Any) -> None:
        self.total, self.desc, self.enabled, self.options = total, desc, enabled, options
        self._bar: Any = None

    def show(self, n: int, postfix: str) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(
                total=self.total, desc=self.desc, unit="epoch", file=sys.stderr, **self.options
            )
        self._bar.n = n
        self._bar.set_postfix_str(postfix)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
