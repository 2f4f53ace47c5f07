"""``canonid systems`` — list the registry: dimensions, signals with units, dt, sets."""

from __future__ import annotations

import argparse

from canonid.systems import describe_systems


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "List the registered systems with dimensions, units, sampling time and the "
        "sets X, U, W used by the analysis."
    )
    p.add_argument("--json", action="store_true", help="print the full description as JSON")


def run(args: argparse.Namespace) -> int:
    print(describe_systems(as_json=args.json))
    return 0
