"""The registered true systems, described for ``canonid systems``: dimensions, signals with
units, sampling time and the sets X, U, W of the analysis."""

from __future__ import annotations

import json
from typing import Any

__all__ = ["describe_systems"]


def _box(d: dict[str, list[float]]) -> str:
    return " × ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(d["lower"], d["upper"]))


def describe_systems(*, as_json: bool = False) -> str:
    """Every registered system's description, as text or (``as_json``) as a JSON list."""
    from canonid.models.registry import get_system, system_names

    descriptions: list[dict[str, Any]] = [get_system(n).describe() for n in system_names()]
    if as_json:
        return json.dumps(descriptions, indent=2)
    lines = []
    for d in descriptions:
        tag = (
            f"  (simulated stand-in for {d['simulated_stand_in_for']})"
            if d["simulated_stand_in_for"]
            else ""
        )
        lines += [
            f"{d['name']}: {d['description']}{tag}",
            f"  n_x={d['n_x']}  n_u={d['n_u']}  n_y={d['n_y']}  dt={d['dt']:.6g} s  "
            f"({d['discretisation']})",
            f"  states : {', '.join(d['states'])}",
            f"  inputs : {', '.join(d['inputs'])}",
            f"  outputs: {', '.join(d['outputs'])}",
            f"  X = {_box(d['X'])}",
            f"  U = {_box(d['U'])}",
            f"  W = {_box(d['W'])}",
            "",
        ]
    return "\n".join(lines)
