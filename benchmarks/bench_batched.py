"""CPU time of Ours (MLP) candidates trained as one stack against one candidate trained alone.

Writes the section "Batched candidates" of benchmarks/RESULTS.md.

On one thread (``torch.set_num_threads(1)``), on the generated tank (``runs/data/tank-s0``),
ℓ = 10, the default network and the default training options (``canonid train``'s quick profile)
with ``epochs`` epochs and no curriculum (the full horizon from the first epoch, as in most of a
default run), the process CPU time of:

* one candidate by :func:`canonid.learning.fit` (what ``canonid train`` runs);
* one candidate by :func:`canonid.learning.batched.fit_batched` (a stack of one);
* 8 candidates (seeds 0–7) by :func:`fit_batched`, one stack;
* the same 8 by :func:`fit`, one after another;

for the default widths 3 × 256 and for 3 × 64. Then the throughput of the matrix product that
dominates a step (32 rows × 256 × 256) against 256 rows and against 8 stacked products, which
bounds what stacking can gain on a CPU core.

Usage: python benchmarks/bench_batched.py [--epochs N] [--data DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _data import ensure_dataset  # noqa: E402
from _results import load_line, write_section  # noqa: E402

from canonid.kernel.dataset import Dataset  # noqa: E402
from canonid.learning import fit  # noqa: E402
from canonid.learning.batched import candidate_grid, fit_batched  # noqa: E402
from canonid.profiles import train_options  # noqa: E402

WINDOW, K = 10, 8


def cpu_seconds(train_fn, *args, **kwargs) -> float:
    """Process CPU seconds of ``train_fn(*args, **kwargs)``."""
    start = time.process_time()
    train_fn(*args, **kwargs)
    return time.process_time() - start


def matmul_rate(a: torch.Tensor, b: torch.Tensor, product, flops: float) -> float:
    """GFLOP/s of ``product(a, b)`` over 200 calls after 10 of warm-up."""
    for _ in range(10):
        product(a, b)
    start = time.process_time()
    for _ in range(200):
        product(a, b)
    return flops * 200 / (time.process_time() - start) / 1e9


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--data", type=Path, default=None)
    args = parser.parse_args()
    torch.set_num_threads(1)
    t_start = time.perf_counter()
    load = [os.getloadavg()[0]]
    folder = args.data or ensure_dataset("tank-s0")
    ds = Dataset.load(folder / "dataset.npz")
    train, val = ds.splits["train"], ds.splits["val"]
    opts = train_options("quick", epochs=args.epochs, curriculum_epochs=0, device="cpu")
    seeds = candidate_grid(seed=list(range(K)))

    # warm-up: the first training run of a process pays one-time costs (imports, allocators)
    warm = {"window": WINDOW, "options": train_options("quick", epochs=1, device="cpu")}
    fit(train, val, **warm)
    fit_batched(train, val, seeds[:2], **warm)
    rows, ratios = [], {}
    for hidden in ((256, 256, 256), (64, 64, 64)):
        net = {"hidden": list(hidden)}
        common = {"window": WINDOW, "options": opts, "net_options": net}
        single = cpu_seconds(fit, train, val, **common)
        stack1 = cpu_seconds(fit_batched, train, val, seeds[:1], **common)
        stack8 = cpu_seconds(fit_batched, train, val, seeds, **common)
        one_by_one = sum(
            cpu_seconds(fit, train, val, **{**common, "options": c.train_options(opts)})
            for c in seeds
        )
        load.append(os.getloadavg()[0])
        width = " × ".join(map(str, hidden))
        ratios[width] = stack8 / single
        rows.append(
            f"| {width} | {single:.1f} | {stack1:.1f} | {stack8:.1f} | {one_by_one:.1f} | "
            f"**{stack8 / single:.2f}×** | {stack8 / stack1:.2f}× | {one_by_one / stack8:.2f}× |"
        )
        print(rows[-1], flush=True)

    x32, x256 = torch.randn(32, 256), torch.randn(256, 256)
    w, xs, ws = torch.randn(256, 256), torch.randn(K, 32, 256), torch.randn(K, 256, 256)
    rates = {
        "32 × 256 by 256 × 256 (one candidate's batch)": matmul_rate(
            x32, w, torch.mm, 2 * 32 * 256 * 256
        ),
        "256 × 256 by 256 × 256": matmul_rate(x256, w, torch.mm, 2 * 256**3),
        f"{K} stacked 32 × 256 by 256 × 256 (bmm)": matmul_rate(
            xs, ws, torch.bmm, 2 * K * 32 * 256 * 256
        ),
    }
    load.append(os.getloadavg()[0])
    sentence, _ = load_line(load, "CPU times of one thread are less affected than wall times")
    lines = [
        f"Ours (MLP) on the generated tank ({len(train)} training, {len(val)} validation "
        f"records of {train[0].T} samples), ℓ = {WINDOW}, the quick profile's training options "
        f"with {args.epochs} epochs and no curriculum (horizon {opts.horizon} from epoch 1, "
        f"batch {opts.batch_size}, {opts.windows_per_epoch} windows per epoch, validation every "
        f"{opts.val_every} epochs on {opts.val_windows} rollouts of {opts.val_horizon} steps), "
        "one thread. Process CPU seconds after a warm-up run; the 8 candidates are seeds 0–7.",
        "",
        "| widths | 1 by `fit` | 1 stacked | 8 stacked | 8 by `fit`, one after another | "
        "8 stacked / 1 by `fit` | 8 stacked / 1 stacked | gain over one after another |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        "Matrix-product throughput on this core (GFLOP/s, float32):",
        "",
        *(f"- {label}: {rate:.0f}" for label, rate in rates.items()),
        "",
        f"Target (issue 27): 8 candidates in at most 3× the CPU time of one. At the default "
        f"widths 3 × 256 the ratio is {ratios['256 × 256 × 256']:.2f}×"
        + (
            " — the target is met."
            if ratios["256 × 256 × 256"] <= 3
            else (
                " — **the target is not met**: one candidate's 32-row products already run at "
                "about the rate of wide ones on this core (above), so stacking saves the "
                "per-operation overhead, not the arithmetic, which grows with the number of "
                "candidates. At 3 × 64, where one candidate is dominated by overhead, the ratio "
                f"is {ratios['64 × 64 × 64']:.2f}×."
            )
        ),
        "",
        sentence,
        "",
        f"This benchmark took {(time.perf_counter() - t_start) / 60:.1f} min.",
    ]
    write_section("Batched candidates", "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
