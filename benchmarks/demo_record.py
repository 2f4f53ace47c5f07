"""Table 1 and the compression study of one `canonid reproduce` run, as the Results page quotes.

`make demo` (`canonid reproduce --profile quick --systems tank`) writes its numbers to
``OUT/reproduction.json`` (``OUT`` = ``runs/demo``, or the ``DEMO_OUT`` given to make). This
script reads that file and writes one system's numbers into a section of the records — the tank's
into "make demo: Table 1 and compression", another system's into "Reproduce, quick profile:
SYSTEM" — with the run's software versions, so that the Results page quotes a measurement rather
than typed numbers. The section "make demo" keeps the timings.

Usage: python demo_record.py [OUT] [--system NAME]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from _results import record

ROOT = Path(__file__).resolve().parents[1]
DEMO_SECTION = "make demo: Table 1 and compression"


def section(system: str) -> str:
    return DEMO_SECTION if system == "tank" else f"Reproduce, quick profile: {system}"


def scale(system: str) -> float:
    """The paper's scale of the system's Table 1 (×10⁻⁴ for the tank, ×10⁻² for the drone)."""
    from canonid.paper import TABLE1

    return TABLE1[system].scale


def _scaled(value: float | None, system: str) -> str:
    return "—" if value is None else f"{value / scale(system):.4g}"


def table1_lines(rows: list[dict], system: str = "tank") -> list[str]:
    """One row per (model, options, ℓ) of ``system``: this run against y and y_clean, the paper
    (for the paper's options only: canonid's defaults are not in the paper)."""
    from canonid.reproduce_jobs import PAPER_OPTIONS
    from canonid.reproduce_report import column_label

    lines = [
        "| model | ℓ | measured y | noise-free y | paper |",
        "|---|---:|---:|---:|---:|",
    ]
    for row in sorted(rows, key=lambda r: (column_label(r["model"], r["options"]), r["window"])):
        if row["system"] != system:
            continue
        paper = row["paper"] if row["options"] == PAPER_OPTIONS else None
        lines.append(
            f"| {column_label(row['model'], row['options'])} | {row['window']} | "
            f"{_scaled(row['mean'], system)} | {_scaled(row['mean_clean'], system)} | "
            f"{_scaled(paper, system)} |"
        )
    return lines


def compression_lines(rows: list[dict], system: str = "tank") -> list[str]:
    """One row per compression rate: the reduced model's 100-step MSE against the full one's."""
    lines = [
        "| compression | n̄ of dim z | reduced | full | reduced / full |",
        "|---:|---|---:|---:|---:|",
    ]
    for row in sorted(rows, key=lambda r: r["compression"]):
        ratio = row["rollout_mse_mean"] / row["full_rollout_mse"]
        lines.append(
            f"| {100 * row['compression']:.0f} % | {row['latent_dim']} of {row['state_dim']} | "
            f"{_scaled(row['rollout_mse_mean'], system)} | "
            f"{_scaled(row['full_rollout_mse'], system)} | "
            f"{ratio:.3g} |"
        )
    return lines


def body(result: dict, system: str = "tank") -> str:
    machine = result["machine"]
    versions = ", ".join(
        f"{k} {machine[k]}" for k in ("canonid", "torch", "numpy", "casadi") if machine.get(k)
    )
    compression = result["compression"][system]["rows"]
    power = str(round(math.log10(scale(system))))
    factor = "×10" + power.translate(str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"))
    windows = ", ".join(str(w) for w in sorted({r["window"] for r in compression}))
    return "\n".join(
        [
            f"The numbers of one `canonid reproduce --profile quick --systems {system}` run"
            + (" (`make demo`)" if system == "tank" else "")
            + ", read from its `reproduction.json`; every job is seeded and single-threaded, "
            f"so the same software on the same processor gives them again ({versions}; "
            f"{machine.get('cpus')} CPUs, {machine.get('platform')}).",
            "",
            f"Table 1, {system}: 100-step open-loop MSE, {factor} (the paper's scale), one "
            "seed; the paper's column as printed (against its own noisy data).",
            "",
            *table1_lines(result["table1"], system),
            "",
            f"Compression study (Ours (MLP), ℓ = {windows}, the run's Table-1 model): 100-step "
            f"MSE against the measured y, {factor}.",
            "",
            *compression_lines(compression, system),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=str(ROOT / "runs" / "demo"))
    parser.add_argument("--system", default="tank")
    args = parser.parse_args(argv)
    result = json.loads((Path(args.out) / "reproduction.json").read_text(encoding="utf-8"))
    return record(section(args.system), body(result, args.system))


if __name__ == "__main__":
    raise SystemExit(main())
