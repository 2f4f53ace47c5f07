"""Ours (MLP) with 2 × 2048 hidden units on a generated quadrotor dataset (SIMULATED stand-in).

The paper trains its MLP regressor with two hidden layers of 2048 units on the real Blackbird
flights ("3D Drone" column of Table 1). This script trains the same architecture on a dataset
generated here from the simulated quadrotor and reports the paper metric (MSE of 100-step
open-loop rollouts after an ℓ-step burn-in, physical units, averaged over the 6 IMU outputs and
the steps; ``canonid.learning.evaluate``), beside the paper's figures for the real data. The two are
NOT comparable as results: different data (simulation vs real flights), a CPU budget of minutes
instead of the paper's 10,000 epochs, and outputs whose scale depends on the stand-in's noise
and excitation. The table says so.

Needs the identification layer (``learning``, issue 4). Usage::

    python -m canonid generate quadrotor --out DATA --n-train 20 --n-val 4 --n-test 4
    python benchmarks/studies/quadrotor/quadrotor_mlp.py DATA --window 10 --epochs 40

Writes the section "Quadrotor Ours (MLP), simulated stand-in" of its notes
(``benchmarks/records/``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))

import numpy as np

from benchmarks._results import write_section
from canonid.kernel.dataset import Dataset

#: paper, Table 1, 3D Drone, Ours (MLP), ×1e-2, for ℓ = 5, 10, 15, 20, 25, 30 (real data)
PAPER_3D_DRONE_MLP = {5: 15.2, 10: 14.2, 15: 13.6, 20: 13.5, 25: 13.6, 30: 13.1}


def hold_last_mse(trajectories, window: int, horizon: int) -> tuple[float, int]:
    """The naive baseline on the paper metric's rollouts: predict ``y[s−1]`` (the last burn-in
    sample) for ``y[s] … y[s+H−1]``, every start ``s = ℓ … T − H``; mean over rollouts."""
    errors = [
        float(np.mean((tr.y[s : s + horizon] - tr.y[s - 1]) ** 2))
        for tr in trajectories
        for s in range(window, tr.T - horizon + 1)
    ]
    return float(np.mean(errors)), len(errors)


def _section(
    args: argparse.Namespace, dataset: Dataset, rows: list[str], results: dict[int, Any]
) -> str:
    counts = dataset.counts()
    test_y = np.concatenate([tr.y for tr in dataset.split("test")])
    variance = float(np.mean(test_y.var(axis=0)))
    body = (
        "Ours (MLP), 2 × 2048 ReLU hidden units, feedthrough, trained by output error with the "
        f"`quick` profile's options but {args.epochs} epochs, Adam from lr {args.lr:g} (cosine "
        f"to 1e-5), rollout curriculum 1 → {args.horizon} steps over the first "
        f"{max(1, 3 * args.epochs // 4)} epochs, CPU, {args.threads} thread(s). "
        "Data: **SIMULATED stand-in** "
        f"(`canonid generate quadrotor`, {counts['train']} / {counts['val']} / {counts['test']} "
        "chunks of 200 samples). Metric: MSE of 100-step open-loop rollouts after the ℓ-step "
        "burn-in, physical units (m/s² and rad/s mixed), averaged over the 6 IMU outputs, all "
        "start times of every test chunk. The paper's column is **real Blackbird data** with "
        "10,000 epochs: a reference point, not a like-for-like comparison.\n\n"
        "| ℓ | simulated stand-in, vs measured y (×1e-2) | vs noise-free y (×1e-2) | "
        "hold-last baseline, same rollouts (×1e-2) | paper, real Blackbird (×1e-2) | epochs | "
        "training time |\n|---|---|---|---|---|---|---|\n"
        + "\n".join(rows)
        + f"\n\nFor scale: the test outputs' variance, averaged over the 6 outputs, is "
        f"{100 * variance:.2f} ×1e-2. Per-output MSE (measured y): `"
        + json.dumps({w: r["per_output"] for w, r in results.items()})
        + "` (order "
        + ", ".join(dataset.output_names)
        + ").\n"
    )
    return body


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("data", type=Path, help="a generated quadrotor dataset (folder)")
    parser.add_argument("--window", type=int, nargs="+", default=[10])
    parser.add_argument("--epochs", type=int, default=40)
    parser.add_argument("--horizon", type=int, default=50, help="final training rollout length")
    parser.add_argument(
        "--lr", type=float, default=1e-3, help="Adam learning rate at the start (cosine to 1e-5)"
    )
    parser.add_argument("--out", type=Path, default=Path("runs/quadrotor-mlp"))
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    try:
        import torch

        from canonid.learning import fit
        from canonid.learning.evaluate import evaluate
        from canonid.profiles import train_options
    except ImportError as exc:
        print(f"this script needs the identification layer (issue 4): {exc}", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    dataset = Dataset.load(args.data)
    if dataset.metadata.get("simulated_stand_in_for") is None:
        print(f"{args.data} is not a generated quadrotor dataset", file=sys.stderr)
        return 2
    rows, results = [], {}
    for window in args.window:
        options = train_options(
            "quick",
            epochs=args.epochs,
            horizon=args.horizon,
            curriculum_epochs=max(1, 3 * args.epochs // 4),
            lr=args.lr,
            seed=0,
        )
        start = time.perf_counter()
        result = fit(
            dataset.split("train"),
            dataset.split("val"),
            model="mlp",
            window=window,
            options=options,
            net_options={"hidden": (2048, 2048), "feedthrough": True, "residual": False},
            run_dir=args.out / f"l{window}",
        )
        seconds = time.perf_counter() - start
        scores = evaluate(
            result.model,
            dataset.split("test"),
            horizon=100,
            output_names=list(dataset.output_names),
        )
        mse = scores.measured.rollout_mse
        naive, n_naive = hold_last_mse(dataset.split("test"), window, 100)
        clean = scores.clean.rollout_mse if scores.clean else float("nan")
        results[window] = {
            "rollout_mse": mse,
            "rollout_mse_clean": clean,
            "per_output": scores.measured.rollout_mse_per_output,
            "best_epoch": result.best_epoch,
            "epochs_run": result.epochs_run,
            "train_seconds": seconds,
            "n_rollouts": scores.n_rollouts,
            "hold_last_mse": naive,
            "hold_last_rollouts": n_naive,
        }
        paper = PAPER_3D_DRONE_MLP.get(window)
        rows.append(
            f"| {window} | {100 * mse:.2f} | {100 * clean:.2f} | {100 * naive:.2f} | "
            f"{'—' if paper is None else f'{paper:.1f}'} | {result.epochs_run} "
            f"(best {result.best_epoch}) | {seconds / 60:.1f} min |"
        )
        print(rows[-1], flush=True)
        # written after every window, so the finished ones survive an interrupted run
        body = _section(args, dataset, rows, results)
        write_section("Quadrotor Ours (MLP), simulated stand-in", body)
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
