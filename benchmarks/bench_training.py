"""Training throughput of the four models on CPU, the effect of the accelerations tried, and the
time the quick profile takes to reach a target on the tank.

Writes the section "Training throughput" of the records (benchmarks/records/).

* Throughput: the training step of each model (loss of an open-loop rollout + backward + Adam)
  on sub-windows of the tank dataset, ℓ = 10, H = 50, batch 16, one thread: batches/s, windows/s
  and window-steps/s (a window-step is one predicted sample of one sub-window), and epochs/s
  for the quick profile's epoch (its ``windows_per_epoch`` sub-windows).
* Accelerations (Ours (MLP), against the one-thread eager batch-16 baseline of the same run):
  two threads, larger batches (more window-steps per second, fewer optimiser steps per epoch),
  ``torch.compile`` of the regressor; and for evaluation, the 100-step rollouts batched (all
  start times at once) against one at a time.
* Hand-written back-propagation: the training step of canonid's default Ours (MLP) (3 × 256
  SiLU, affine skip, residual, feedthrough; with and without the 16-unit cubic branch), batch 32
  as in the quick profile, by autograd through the step-by-step rollout against
  :mod:`canonid.learning.nets.mlp_bptt`, in the same round-robin.
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

from canonid.kernel.dataset import Dataset  # noqa: E402
from canonid.learning import build_net, fit, model_names  # noqa: E402
from canonid.learning.data import Normalisation, WindowBank  # noqa: E402
from canonid.profiles import train_options  # noqa: E402

WINDOW, HORIZON = 10, 50


class Variant:
    """One training set-up whose step rate is measured: a network, a batch, a thread count."""

    def __init__(self, label: str, net, bank, *, batch: int = 16, threads: int = 1) -> None:
        self.label, self.net, self.bank = label, net, bank
        self.batch, self.threads = batch, threads
        self.rng = np.random.default_rng(0)
        self.starts = bank.starts(WINDOW + HORIZON)
        self.opt = torch.optim.Adam(net.parameters(), lr=1e-4)
        self.rates: list[float] = []
        for _ in range(3):  # warm-up (and compilation, if any)
            self.step()

    def step(self) -> None:
        idx = self.starts[self.rng.integers(0, len(self.starts), size=self.batch)]
        u, y = self.bank.gather(idx, WINDOW + HORIZON)
        loss, _ = self.net.training_loss(u, y, alpha_first=10.0)
        self.opt.zero_grad()
        loss.backward()
        self.opt.step()

    def measure(self, seconds: float) -> None:
        torch.set_num_threads(self.threads)
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            self.step()
            n += 1
        self.rates.append(n / (time.perf_counter() - t0))
        torch.set_num_threads(1)

    @property
    def window_steps(self) -> float:
        """Best measured rate in predicted samples (window-steps) per second."""
        return max(self.rates) * self.batch * HORIZON


def measure_all(variants: list[Variant], seconds: float, rounds: int) -> None:
    """Round-robin measurements; each variant keeps its best round, the one least disturbed by
    other work on a shared machine."""
    for _ in range(rounds):
        for v in variants:
            v.measure(seconds)


def _net(name: str):
    torch.manual_seed(0)
    return build_net(name, window=WINDOW, n_u=1, n_y=1, residual=True)


def _autograd(net):
    """``net`` trained by autograd through the step-by-step rollout (the baseline)."""
    net.bptt = False
    return net


def _default_mlp(cubic: int):
    """canonid train's Ours (MLP) on a SISO record (quick profile)."""
    torch.manual_seed(0)
    return build_net(
        "mlp",
        window=WINDOW,
        n_u=1,
        n_y=1,
        residual=True,
        feedthrough=True,
        activation="silu",
        linear="skip",
        cubic=cubic,
    )


def hand_written(bank, seconds: float, rounds: int) -> str:
    batch = train_options("quick").batch_size
    pairs = [
        (
            cubic,
            Variant("autograd", _autograd(_default_mlp(cubic)), bank, batch=batch),
            Variant("hand-written", _default_mlp(cubic), bank, batch=batch),
        )
        for cubic in (0, 16)
    ]
    measure_all([v for _, a, b in pairs for v in (a, b)], seconds, rounds)
    rows = [
        f"| network (batch {batch}, H = {HORIZON}, 1 thread) | autograd: ms per step | "
        "hand-written: ms per step | speed-up [×] |",
        "|---|---:|---:|---:|",
    ]
    for cubic, a, b in pairs:
        name = "3 × 256 SiLU, skip, residual" + (f", {cubic} cubic units" if cubic else "")
        slow, fast = 1e3 / max(a.rates), 1e3 / max(b.rates)
        rows.append(f"| {name} | {slow:.1f} | {fast:.1f} | **{slow / fast:.2f}** |")
    return "\n".join(rows)


def throughput(bank, seconds: float, rounds: int) -> str:
    windows_per_epoch = train_options("quick").windows_per_epoch
    variants = [Variant(name, _net(name), bank) for name in model_names()]
    measure_all(variants, seconds, rounds)
    rows = [
        "| model | parameters | batches/s | window-steps/s | quick epochs/s (training only) |",
        "|---|---:|---:|---:|---:|",
    ]
    for v in variants:
        params = sum(p.numel() for p in v.net.parameters())
        rows.append(
            f"| {v.label} | {params:,} | {max(v.rates):.1f} | {v.window_steps:,.0f} | "
            f"{v.window_steps / HORIZON / windows_per_epoch:.2f} |"
        )
    return "\n".join(rows)


def accelerations(bank, seconds: float, rounds: int) -> str:
    variants = [
        Variant("baseline: 1 thread, eager, batch 16", _net("mlp"), bank),
        Variant(
            "autograd through the step-by-step rollout, batch 16",
            _autograd(_net("mlp")),
            bank,
        ),
        Variant("2 threads, batch 16", _net("mlp"), bank, threads=2),
        Variant("1 thread, batch 64", _net("mlp"), bank, batch=64),
        Variant("1 thread, batch 256", _net("mlp"), bank, batch=256),
    ]
    failed = ""
    try:
        net = _net("mlp")
        net.net = torch.compile(net.net)  # type: ignore[assignment]
        variants.append(Variant("torch.compile(regressor), batch 16", net, bank))
    except Exception as exc:  # compilation needs a working C++ toolchain
        failed = f"| torch.compile(regressor) | failed: {type(exc).__name__} | — |"
    measure_all(variants, seconds, rounds)
    base = variants[0].window_steps
    rows = ["| variant (Ours (MLP)) | window-steps/s | vs baseline |", "|---|---:|---:|"]
    rows += [
        f"| {v.label} | {v.window_steps:,.0f} | {v.window_steps / base:.2f} |" for v in variants
    ]
    return "\n".join(rows + ([failed] if failed else []))


def batched_rollouts(ds: Dataset) -> str:
    """Open-loop rollouts of the paper metric (100 steps), all at once vs one at a time."""
    from canonid.learning import Model

    torch.set_num_threads(1)
    train = ds.split("train")
    test = ds.split("test")
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
    seen: list[tuple[int, float, float]] = []  # epoch, seconds, validation MSE (physical)
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
    seconds, rounds = (2.0, 3) if args.size == "quick" else (5.0, 5)
    if not (args.data / "dataset.npz").is_file():
        print(
            f"no tank dataset at {args.data}; run `canonid generate tank --out {args.data}`",
            file=sys.stderr,
        )
        return 1
    ds = Dataset.load(args.data)
    train = ds.split("train")
    bank = WindowBank(train, Normalisation.fit(train))
    parts = [
        f"Tank dataset `{args.data.name}` ({len(train)} training trajectories), "
        f"ℓ = {WINDOW}, rollout H = {HORIZON}, residual outputs, float32, CPU. "
        f"Rates: the best of {rounds} round-robin measurements of {seconds:.0f} s each (after 3 "
        "warm-up steps), so that load from other jobs on a shared machine biases no variant.",
        "### Throughput per model (1 thread, batch 16)",
        throughput(bank, seconds, rounds),
        "### Accelerations tried",
        "Baseline: Ours (MLP) as `_net` builds it (ReLU, no affine path), trained by the "
        "hand-written back-propagation (canonid's default since 2026-11-27).",
        accelerations(bank, seconds, rounds),
        "### Hand-written back-propagation",
        hand_written(bank, seconds, rounds),
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
