"""Table 1 and the compression study of one `make demo` run, as the docs' Results page quotes them.

`make demo` writes its numbers to ``OUT/reproduction.json`` (``OUT`` = ``runs/demo``, or the
``DEMO_OUT`` given to make). This script reads that file and writes them into the section
"make demo: Table 1 and compression" of RESULTS.md, with the run's software versions, so that the
Results page quotes a measurement rather than typed numbers. The section "make demo" keeps the
timings.

Usage: python demo_record.py [OUT]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from _results import record

ROOT = Path(__file__).resolve().parents[1]
SECTION = "make demo: Table 1 and compression"
SCALE = 1e-4  # the paper's scale of Table 1


def _scaled(value: float | None) -> str:
    return "—" if value is None else f"{value / SCALE:.4g}"


def table1_lines(rows: list[dict]) -> list[str]:
    """One row per (model, options, ℓ) of the tank: this run against y and y_clean, the paper
    (for the paper's options only: canonid's defaults are not in the paper)."""
    from canonid.reproduce_jobs import PAPER_OPTIONS
    from canonid.reproduce_report import column_label

    lines = [
        "| model | ℓ | measured y | noise-free y | paper |",
        "|---|---:|---:|---:|---:|",
    ]
    for row in sorted(rows, key=lambda r: (column_label(r["model"], r["options"]), r["window"])):
        if row["system"] != "tank":
            continue
        lines.append(
            f"| {column_label(row['model'], row['options'])} | {row['window']} | "
            f"{_scaled(row['mean'])} | {_scaled(row['mean_clean'])} | "
            f"{_scaled(row['paper'] if row['options'] == PAPER_OPTIONS else None)} |"
        )
    return lines


def compression_lines(rows: list[dict]) -> list[str]:
    """One row per compression rate: the reduced model's 100-step MSE against the full one's."""
    lines = [
        "| compression | n̄ of dim z | reduced | full | reduced / full |",
        "|---:|---|---:|---:|---:|",
    ]
    for row in sorted(rows, key=lambda r: r["compression"]):
        ratio = row["rollout_mse_mean"] / row["full_rollout_mse"]
        lines.append(
            f"| {100 * row['compression']:.0f} % | {row['latent_dim']} of {row['state_dim']} | "
            f"{_scaled(row['rollout_mse_mean'])} | {_scaled(row['full_rollout_mse'])} | "
            f"{ratio:.3g} |"
        )
    return lines


def body(result: dict) -> str:
    machine = result["machine"]
    versions = ", ".join(
        f"{k} {machine[k]}" for k in ("canonid", "torch", "numpy", "casadi") if machine.get(k)
    )
    compression = result["compression"]["tank"]["rows"]
    return "\n".join(
        [
            "The numbers of one `make demo` run (`canonid reproduce --profile quick --systems "
            "tank`), read from its `reproduction.json`; every job is seeded and single-threaded, "
            f"so the same software on the same processor gives them again ({versions}; "
            f"{machine.get('cpus')} CPUs, {machine.get('platform')}).",
            "",
            "Table 1, tank: 100-step open-loop MSE, ×10⁻⁴ (the paper's scale), one seed; the "
            "paper's column as printed (against its own noisy data).",
            "",
            *table1_lines(result["table1"]),
            "",
            "Compression study (Ours (MLP), ℓ = 10, the run's Table-1 model): 100-step MSE "
            "against the measured y, ×10⁻⁴.",
            "",
            *compression_lines(compression),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=str(ROOT / "runs" / "demo"))
    args = parser.parse_args(argv)
    result = json.loads((Path(args.out) / "reproduction.json").read_text(encoding="utf-8"))
    return record(SECTION, body(result))


if __name__ == "__main__":
    raise SystemExit(main())
