"""``canonid systems`` — list the registry: dimensions, signals with units, dt, sets."""

from __future__ import annotations

import argparse
from typing import Any

from canonid.systems import describe_systems


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "systems",
        description="List the registered systems with dimensions, units, sampling time and the "
        "sets X, U, W used by the analysis.",
    )
    p.add_argument("--json", action="store_true", help="print the full description as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    print(describe_systems(as_json=args.json))
    return 0
