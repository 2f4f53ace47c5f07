"""Training throughput of the four models on CPU, the effect of the accelerations tried, and the
time the quick profile takes to reach a target on the tank.

Writes the section "Training throughput" of benchmarks/RESULTS.md.

* Throughput: the training step of each model (loss of an open-loop rollout + backward + Adam)
  on sub-windows of the tank dataset, ℓ = 10, H = 50, batch 16, one thread: batches/s, windows/s
  and window-steps/s (a window-step is one predicted sample of one sub-window), and epochs/s
  for the quick profile's epoch (4 windows per training trajectory).
* Accelerations (Ours (MLP), against the one-thread eager batch-16 baseline of the same run):
  two threads, larger batches (more window-steps per second, fewer optimiser steps per epoch),
  ``torch.compile`` of the regressor; and for evaluation, the 100-step rollouts batched (all
  start times at once) against one at a time.
* Time to target: Ours (MLP) with the quick profile on the tank; the epoch and wall time at
  which the validation rollout MSE (physical units, against the measured outputs) first comes
  within 4×, 2×, 1.5×, 1.1× and 1× of the run's final best.

Usage: python benchmarks/bench_training.py [--size quick|full] [--data DIR]
(``--data``: a tank dataset from ``canonid generate tank``; default runs/data/tank-s0).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import write_section  # noqa: E402

from canonid.profiles import train_options  # noqa: E402
from datagen.dataset import Dataset  # noqa: E402
from learning import build_net, fit, model_names  # noqa: E402
from learning.data import Normalisation, WindowBank, as_series  # noqa: E402

WINDOW, HORIZON = 10, 50


def steps_per_second(net, bank, *, batch: int, seconds: float, threads: int) -> float:
    """Training steps per second on random sub-windows of ``bank``."""
    torch.set_num_threads(threads)
    rng = np.random.default_rng(0)
    starts = bank.starts(WINDOW + HORIZON)
    opt = torch.optim.Adam(net.parameters(), lr=1e-4)

    def step() -> None:
        idx = starts[rng.integers(0, len(starts), size=batch)]
        u, y = bank.gather(idx, WINDOW + HORIZON)
        loss, _ = net.training_loss(u, y, alpha_first=10.0)
        opt.zero_grad()
        loss.backward()
        opt.step()

    for _ in range(3):  # warm-up (and compilation, if any)
        step()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        step()
        n += 1
    return n / (time.perf_counter() - t0)


def throughput(bank, n_train: int, seconds: float) -> str:
    windows_per_epoch = 4 * n_train
    rows = [
        "| model | parameters | batches/s | windows/s | window-steps/s | quick epochs/s |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name in model_names():
        torch.manual_seed(0)
        net = build_net(name, window=WINDOW, n_u=1, n_y=1, residual=True)
        rate = steps_per_second(net, bank, batch=16, seconds=seconds, threads=1)
        params = sum(p.numel() for p in net.parameters())
        windows = 16 * rate
        rows.append(
            f"| {name} | {params:,} | {rate:.1f} | {windows:.0f} | {windows * HORIZON:,.0f} | "
            f"{windows / windows_per_epoch:.2f} |"
        )
    return "\n".join(rows)


def accelerations(bank, seconds: float) -> str:
    def mlp():
        torch.manual_seed(0)
        return build_net("mlp", window=WINDOW, n_u=1, n_y=1, residual=True)

    base = steps_per_second(mlp(), bank, batch=16, seconds=seconds, threads=1) * 16
    rows = [
        "| variant (Ours (MLP)) | window-steps/s | vs baseline |",
        "|---|---:|---:|",
        f"| baseline: 1 thread, eager, batch 16 | {base * HORIZON:,.0f} | 1.00 |",
    ]

    def add(label: str, windows: float) -> None:
        rows.append(f"| {label} | {windows * HORIZON:,.0f} | {windows / base:.2f} |")

    add(
        "2 threads, batch 16",
        steps_per_second(mlp(), bank, batch=16, seconds=seconds, threads=2) * 16,
    )
    for b in (64, 256):
        add(
            f"1 thread, batch {b}",
            steps_per_second(mlp(), bank, batch=b, seconds=seconds, threads=1) * b,
        )
    try:
        net = mlp()
        net.net = torch.compile(net.net)  # type: ignore[assignment]
        add(
            "torch.compile(regressor), batch 16",
            steps_per_second(net, bank, batch=16, seconds=seconds, threads=1) * 16,
        )
    except Exception as exc:  # compilation needs a working C++ toolchain
        rows.append(f"| torch.compile(regressor) | failed: {type(exc).__name__} | — |")
    torch.set_num_threads(1)
    return "\n".join(rows)


def batched_rollouts(ds: Dataset) -> str:
    """Open-loop rollouts of the paper metric (100 steps), all at once vs one at a time."""
    from learning import Model

    torch.set_num_threads(1)
    train = as_series(ds.split("train"))
    test = as_series(ds.split("test"))
    torch.manual_seed(0)
    model = Model(
        build_net("mlp", window=WINDOW, n_u=1, n_y=1, residual=True), Normalisation.fit(train)
    )
    span = WINDOW + 100
    starts = [(i, s) for i, tr in enumerate(test) for s in range(tr.T - span + 1)]
    u = np.stack([test[i].u[s : s + span] for i, s in starts])
    y0 = np.stack([test[i].y[s : s + WINDOW] for i, s in starts])
    t0 = time.perf_counter()
    model.predict(u, y0)
    batched = (time.perf_counter() - t0) / len(starts)
    k = min(50, len(starts))
    t0 = time.perf_counter()
    for j in range(k):
        model.predict(u[j : j + 1], y0[j : j + 1])
    single = (time.perf_counter() - t0) / k
    return (
        f"Evaluation, Ours (MLP), {len(starts)} rollouts of 100 steps (the tank test set): "
        f"batched {batched * 1e3:.3f} ms per rollout, one at a time {single * 1e3:.2f} ms per "
        f"rollout ({single / batched:.0f}× slower; `evaluate` batches them)."
    )


def time_to_target(ds: Dataset) -> str:
    """Ours (MLP), quick profile on the tank: wall time to reach validation MSE targets."""
    torch.set_num_threads(1)
    train, val = ds.split("train"), ds.split("val")
    y_var = float(np.concatenate([t.y for t in train]).var(axis=0).mean())
    seen: list[tuple[int, float, float]] = []  # (epoch, seconds, validation MSE, physical)
    t0 = time.perf_counter()

    def watch(report) -> None:
        if report.val_loss is not None:
            # normalised → physical: the tank has one output, scaled by its training std
            seen.append((report.epoch, time.perf_counter() - t0, report.val_loss * y_var))

    opts = train_options("quick", device="cpu")
    res = fit(
        train,
        val,
        model="mlp",
        window=WINDOW,
        options=opts,
        net_options={"residual": True, "feedthrough": False},
        callback=watch,
    )
    total = time.perf_counter() - t0
    best = res.best_val_loss * y_var
    rows = [
        "| target (validation MSE, physical, vs measured y) | epoch | wall time [s] |",
        "|---|---:|---:|",
    ]
    for factor in (4.0, 2.0, 1.5, 1.1, 1.0):
        hit = next(((e, t) for e, t, v in seen if v <= factor * best * (1 + 1e-9)), None)
        label = f"≤ {factor:g} × final best ({factor * best:.3g})"
        rows.append(f"| {label} | {hit[0]} | {hit[1]:.0f} |" if hit else f"| {label} | — | — |")
    return (
        f"Ours (MLP), ℓ = {WINDOW}, `--residual --no-feedthrough`, quick profile "
        f"({opts.epochs} epochs), 1 thread: {total:.0f} s wall, "
        f"{res.epochs_run / total:.2f} epochs/s including validation; best validation MSE "
        f"{best:.3g} (physical units, measured outputs; noise variance 1.33e-4) at epoch "
        f"{res.best_epoch}.\n\n" + "\n".join(rows)
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--data", type=Path, default=ROOT / "runs" / "data" / "tank-s0")
    args = parser.parse_args()
    seconds = 3.0 if args.size == "quick" else 15.0
    if not (args.data / "dataset.npz").is_file():
        print(
            f"no tank dataset at {args.data}; run `canonid generate tank --out {args.data}`",
            file=sys.stderr,
        )
        return 1
    ds = Dataset.load(args.data)
    train = as_series(ds.split("train"))
    bank = WindowBank(train, Normalisation.fit(train))
    parts = [
        f"Tank dataset `{args.data.name}` ({len(train)} training trajectories), "
        f"ℓ = {WINDOW}, rollout H = {HORIZON}, residual outputs, float32, CPU. "
        f"Each rate is measured for {seconds:.0f} s after 3 warm-up steps.",
        "### Throughput per model (1 thread, batch 16)",
        throughput(bank, len(train), seconds),
        "### Accelerations tried",
        accelerations(bank, seconds),
        batched_rollouts(ds),
        "### Time to target on the tank",
        time_to_target(ds),
    ]
    body = "\n\n".join(parts)
    write_section("Training throughput", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
