"""Where the certified bounds of an analysis are out of reach, and why — in words.

:func:`limitations` reads the brackets of :func:`canonid.analysis.report.analyze` and lists, per
kind of shortfall, the windows it concerns and the reason recorded by the search:

* reachable hulls whose enclosure stopped at the budget (rigorous, but loose: how much they
  grow step after step is the interval wrapping the certified γ bounds inherit);
* a reachable hull ``H_i`` with no finite certified box (the enclosure overflowed or could not
  be made finite within the budget), so γ over it has only the trivial upper bound ``∞``;
* a certified γ upper bound that is not finite, or that stayed far from the sampled lower
  bound when the budget ran out (the bracket is honest but loose);
* α_ℓ = 0 exactly (Proposition 2's bound is then infinite whatever γ_f is), or no certified
  lower bound of α_ℓ beyond the trivial 0, or a pair search stopped by the budget.

The system's own explanation (:attr:`canonid.models.base.System.analysis_note`) follows when any
certified bound is out of reach. Sampled bounds are always produced; these lines only say how
far the certified side got.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from canonid.analysis.estimate import Bracket
from canonid.analysis.reach import ReachableHulls
from canonid.models.base import System

__all__ = ["limitations"]

#: a certified γ upper bound more than this many times the sampled lower bound is "loose"
LOOSE_FACTOR = 10.0


class _Window(Protocol):
    """One window's brackets (``canonid.analysis.report.WindowResult``)."""

    @property
    def window(self) -> int: ...
    @property
    def gamma_f(self) -> Bracket: ...
    @property
    def gamma_h(self) -> Bracket: ...
    @property
    def alpha(self) -> Bracket: ...


def _windows(ells: Sequence[int]) -> str:
    return (
        ("ℓ = " if len(ells) == 1 else "ℓ ∈ {")
        + ", ".join(map(str, ells))
        + ("" if len(ells) == 1 else "}")
    )


def _group(items: list[tuple[int, str]]) -> list[tuple[list[int], str]]:
    """``(window, reason)`` pairs → one entry per reason, with the windows it concerns."""
    grouped: dict[str, list[int]] = {}
    for ell, reason in items:
        grouped.setdefault(reason, []).append(ell)
    return [(ells, reason) for reason, ells in grouped.items()]


def _gamma_lines(results: Sequence[_Window]) -> list[str]:
    lines = []
    for quantity, label in (("gamma_f", "γ_f"), ("gamma_h", "γ_h")):
        infinite: list[tuple[int, str]] = []
        loose: list[str] = []
        for r in results:
            bracket: Bracket = getattr(r, quantity)
            up, low = bracket.upper, bracket.lower
            if not math.isfinite(up.value):
                infinite.append((r.window, str(up.details.get("why", up.method))))
            elif low.value > 0 and up.value > LOOSE_FACTOR * low.value:
                d = up.details
                loose.append(
                    f"ℓ = {r.window}: upper/lower = {up.value / low.value:.3g}, "
                    f"{d.get('stop', 'stopped')} after {d.get('boxes', '?')} boxes split along "
                    f"{len(d.get('split_dims', ()))} dimensions"
                )
        for ells, why in _group(infinite):
            lines.append(f"{label}, {_windows(ells)}: no finite certified upper bound — {why}")
        if loose:
            lines.append(
                f"{label}: the certified upper bound stayed over {LOOSE_FACTOR:g}× the sampled "
                f"lower bound when the search stopped ({'; '.join(loose)})"
            )
    return lines


def _alpha_lines(results: Sequence[_Window]) -> list[str]:
    zero: list[tuple[int, str]] = []
    trivial: list[tuple[int, str]] = []
    stopped: list[tuple[int, str]] = []
    for r in results:
        low = r.alpha.lower
        if low.value == 0 and low.details.get("exact"):
            zero.append((r.window, low.method))
        elif low.value == 0:
            trivial.append((r.window, low.method))
        elif str(low.details.get("stop", "")).endswith("budget exhausted"):
            stopped.append(
                (r.window, f"{low.details['stop']} after {low.details.get('boxes', '?')} boxes")
            )
    lines = [
        f"α_ℓ = 0 exactly for {_windows(ells)} ({why}): Proposition 2 bounds no state error "
        "there, whatever γ_f is"
        for ells, why in _group(zero)
    ]
    lines += [
        f"α_ℓ, {_windows(ells)}: no certified lower bound above 0 — {why}"
        for ells, why in _group(trivial)
    ]
    lines += [
        f"α_ℓ, {_windows(ells)}: the certified lower bound is what the pair search reached "
        f"when it stopped ({why})"
        for ells, why in _group(stopped)
    ]
    return lines


def _hull_lines(reach: ReachableHulls) -> list[str]:
    lines = []
    stopped = [s for s in reach.steps if s["stop"] != "tolerance reached"]
    if stopped:
        growth = " → ".join(f"{float(abs(np.r_[h.lo, h.hi]).max()):.3g}" for h in reach.hulls)
        steps = ", ".join(f"H_{s['step']}: {s['stop']} after {s['boxes']} boxes" for s in stopped)
        lines.append(
            f"reachable hulls: the enclosures stopped at the budget ({steps}); the hulls are "
            f"rigorous but loose, their largest |entry| grows {growth} from X on"
        )
    if reach.unbounded:
        lines.append(f"reachable hulls: {reach.unbounded}")
    return lines


def limitations(
    system: System,
    results: Sequence[_Window],
    *,
    reach: ReachableHulls | None = None,
) -> list[str]:
    """Plain sentences saying which certified bounds are out of reach and why (module doc).

    Args:
        system: the analysed system (its ``analysis_note`` ends the list when it is not empty).
        results: the per-window brackets (``window``, ``gamma_f``, ``gamma_h``, ``alpha``).
        reach: the reachable hulls the γ bounds were computed on (their budget stops and
            growth, and why they stop being finite, are reported).

    Returns:
        The sentences, empty when every certified bound is finite and within
        :data:`LOOSE_FACTOR` of its sampled counterpart and α_ℓ > 0.
    """
    lines = _hull_lines(reach) if reach is not None else []
    lines += _gamma_lines(results)
    lines += _alpha_lines(results)
    if lines and system.analysis_note:
        lines.append(f"why ({system.name}): {system.analysis_note}")
    return lines
