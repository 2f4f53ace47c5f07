"""`canonid evaluate` — evaluation (not implemented yet)."""

from __future__ import annotations

import argparse
from typing import Any

from canonid.commands._pending import not_yet


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "evaluate",
        help="evaluation (not implemented yet)",
        description="evaluation (not implemented yet)",
    )
    p.set_defaults(func=not_yet("evaluation"))
