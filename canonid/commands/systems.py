"""``canonid systems`` — list the registry: dimensions, signals with units, dt, sets."""

from __future__ import annotations

import argparse
import json
from typing import Any

from canonid.models.registry import get_system, system_names


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "systems",
        description="List the registered systems with dimensions, units, sampling time and the "
        "sets X, U, W used by the analysis.",
    )
    p.add_argument("--json", action="store_true", help="print the full description as JSON")
    p.set_defaults(func=run)


def _box(d: dict[str, list[float]]) -> str:
    return " × ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(d["lower"], d["upper"]))


def run(args: argparse.Namespace) -> int:
    descriptions = [get_system(name).describe() for name in system_names()]
    if args.json:
        print(json.dumps(descriptions, indent=2))
        return 0
    for d in descriptions:
        tag = (
            f"  (simulated stand-in for {d['simulated_stand_in_for']})"
            if d["simulated_stand_in_for"]
            else ""
        )
        print(f"{d['name']}: {d['description']}{tag}")
        print(
            f"  n_x={d['n_x']}  n_u={d['n_u']}  n_y={d['n_y']}  dt={d['dt']:.6g} s  "
            f"({d['discretisation']})"
        )
        print(f"  states : {', '.join(d['states'])}")
        print(f"  inputs : {', '.join(d['inputs'])}")
        print(f"  outputs: {', '.join(d['outputs'])}")
        print(f"  X = {_box(d['X'])}")
        print(f"  U = {_box(d['U'])}")
        print(f"  W = {_box(d['W'])}")
        print()
    return 0
