"""Is a small batched search better than one default network? Judged on held-out validation.

For each system the validation split is cut in two: ``select`` (what training sees: early
stopping and, for the search, the choice of a candidate) and ``judge`` (seen by neither
procedure; it compares the procedures). Test splits are not read. Procedures, ℓ = 10, the quick
profile, one torch thread:

* ``single``: canonid's default — one Ours (MLP) 3 × 256 by :func:`canonid.learning.fit`;
* ``search``: 8 candidates of 3 × 64 (seeds 0–3 × Adam 3e-3 / 5e-3) trained as one stack by
  :func:`canonid.learning.batched.fit_batched`, the one with the lowest ``select`` loss kept.

Judge score: the paper metric (100-step rollouts from every start, MSE against the measured
outputs; :func:`canonid.learning.evaluate`) on ``judge``, and the CPU seconds of training.
Rows are appended to ``--rows`` (JSON lines); ``table`` writes the section "Search study".

Usage: python benchmarks/search_study.py run SYSTEM [--procedure single|search] [--seed S]
       python benchmarks/search_study.py table
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _data import ensure_dataset  # noqa: E402
from _results import append_row, read_rows, write_section  # noqa: E402

WINDOW = 10
ROWS = ROOT / "benchmarks" / "studies" / "search_study.jsonl"
NOTES = ROOT / "benchmarks" / "studies" / "search_study_notes.md"
GENERATED = {"tank": "tank-s0", "drone2d": "drone2d-small"}
SEEDS, LRS, NARROW = (0, 1, 2, 3), (3e-3, 5e-3), [64, 64, 64]


def splits(system: str) -> tuple[list, list, list]:
    """(train, select, judge): the system's training split and its validation split in two."""
    from canonid.kernel.dataset import Dataset, Trajectory

    if system == "silverbox":
        import bench_silverbox as sb

        train, val = (Trajectory.of(r) for r in sb.train_val(sb.load(sb.DEFAULT_CSV)))
        half = val.T // 2
        return (
            [train],
            [Trajectory(u=val.u[:half], y=val.y[:half])],
            [Trajectory(u=val.u[half:], y=val.y[half:])],
        )
    ds = Dataset.load(ensure_dataset(GENERATED[system]) / "dataset.npz")
    val = ds.split("val")
    half = len(val) // 2
    return ds.split("train"), val[:half], val[half:]


def run(system: str, procedure: str, seed: int) -> dict[str, Any]:
    from canonid.learning import evaluate, fit
    from canonid.learning.batched import candidate_grid, fit_batched
    from canonid.profiles import stage_train_options

    train, select, judge = splits(system)
    opts = stage_train_options("quick", {"seed": seed, "device": "cpu", "checkpoint_every": 10**6})
    start = time.process_time()
    if procedure == "single":
        result = fit(train, select, model="mlp", window=WINDOW, options=opts)
        model, select_loss, label = result.model, result.best_val_loss, "3 × 256"
    else:
        grid = candidate_grid(seed=[seed + s for s in SEEDS], lr=list(LRS))
        found = fit_batched(
            train,
            select,
            grid,
            window=WINDOW,
            options=opts,
            net_options={"hidden": NARROW},
            ensemble=0,
        )
        model = found.runs[found.chosen].model
        select_loss, label = found.runs[found.chosen].best_val_loss, grid[found.chosen].label
    cpu = time.process_time() - start
    scores = evaluate(model, judge, horizon=100)
    return {
        "system": system,
        "procedure": procedure,
        "seed": seed,
        "chosen": label,
        "select_loss": select_loss,
        "judge_mse": scores.measured.rollout_mse,
        "cpu_s": cpu,
        "load": os.getloadavg()[0],
    }


def table(rows: list[dict[str, Any]]) -> str:
    found = {(r["system"], r["seed"], r["procedure"]): r for r in rows}
    cases = sorted({(r["system"], r["seed"]) for r in rows})
    lines = [
        "Each system's validation split cut in two: `select` (early stopping; the search's "
        "choice) and `judge` (seen by neither procedure). ℓ = 10, the quick profile, one torch "
        "thread. `single`: one Ours (MLP) 3 × 256 (canonid's default); `search`: 8 candidates "
        "of 3 × 64 (4 seeds × Adam 3e-3 / 5e-3) as one stack, the lowest `select` loss kept. "
        "Judge: 100-step rollout MSE on `judge` against the measured outputs. Test splits are "
        "not read.",
        "",
        "| system | seed | single: judge MSE | search: judge MSE | search / single | search's "
        "choice | CPU s single / search |",
        "|---|---:|---:|---:|---:|---|---|",
    ]
    ratios: dict[str, list[float]] = {}
    for system, seed in cases:
        a, b = found.get((system, seed, "single")), found.get((system, seed, "search"))
        if a and b:
            ratio = b["judge_mse"] / a["judge_mse"]
            ratios.setdefault(system, []).append(math.log(ratio))
            lines.append(
                f"| {system} | {seed} | {a['judge_mse']:.4g} | {b['judge_mse']:.4g} | "
                f"{ratio:.3f} | {b['chosen']} | {a['cpu_s']:.0f} / {b['cpu_s']:.0f} |"
            )
    if ratios:
        per = {s: math.exp(statistics.fmean(v)) for s, v in ratios.items()}
        mean = math.exp(statistics.fmean(math.log(v) for v in per.values()))
        lines += [
            "",
            "Geometric mean of search / single per system: "
            + ", ".join(f"{s} {v:.3f}" for s, v in sorted(per.items()))
            + f"; over systems **{mean:.3f}** (below 1: the search judged better).",
        ]
    loads = [r["load"] for r in rows]
    lines.append(
        f"Load average (1 min) at the end of the runs: {min(loads):.1f}–{max(loads):.1f} on "
        f"{os.cpu_count()} cores."
    )
    if NOTES.is_file():  # what the rows alone do not say, for a reader who was not there
        lines += ["", NOTES.read_text(encoding="utf-8").strip()]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    one = sub.add_parser("run", help="train one procedure on one system; append its row")
    one.add_argument("system", choices=("tank", "drone2d", "silverbox"))
    one.add_argument("--procedure", choices=("single", "search"), required=True)
    one.add_argument("--seed", type=int, default=0)
    one.add_argument("--rows", type=Path, default=ROWS)
    tab = sub.add_parser("table", help="write the section from the rows")
    tab.add_argument("--rows", type=Path, default=ROWS)
    args = parser.parse_args()
    if args.command == "table":
        rows = read_rows(args.rows)
        body = table(rows)
        write_section("Search study", body)
        print(body)
        return 0
    torch.set_num_threads(1)
    row = run(args.system, args.procedure, args.seed)
    append_row(args.rows, row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
