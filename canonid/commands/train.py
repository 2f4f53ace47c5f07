"""`canonid train` — training (not implemented yet)."""

from __future__ import annotations

import argparse
from typing import Any

from canonid.commands._pending import not_yet


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "train", help="training (not implemented yet)", description="training (not implemented yet)"
    )
    p.set_defaults(func=not_yet("training"))
