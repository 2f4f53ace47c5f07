"""Silverbox (real data): Ours (MLP) and ARX with canonid's defaults, scored the field's way.

Data: ``SNLS80mV.csv`` (the Silverbox record, 131,072 samples; ``../shared/data/silverbox`` in
this workplace, ``--csv`` elsewhere). The split of ``nonlinear_benchmarks`` 1.0.1, 0-based Python
slices: the multisine part is ``40650:127400``; its first 65,062 samples train and validate
(the last 20 % of them validate, as ``canonid train`` splits a single record) and its last 21,688
are the **multisine test**. Scoring: the model sees the whole test input and the first
``n_init = 50`` measured outputs; a canonical model with window ℓ burns in on samples
``n_init − ℓ … n_init − 1`` and is scored on samples ``n_init … T − 1``; RMSE in mV.

Each variant trains with the ``quick`` profile and the defaults of :func:`learning.fit` (the
options a user gets) unless the variant overrides them, on one torch thread; the CPU time is the
process's over training and scoring. Published baselines on the same test (Champneys et al.
2024): GRU 1.490 mV, LSTM 1.504 mV, RNN 1.640 mV.

Usage: python benchmarks/bench_silverbox.py [--csv FILE] [--window L] [--seeds 0 1 2]
       [--variants default arx ...] [--no-write]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._results import write_section
from canonid.learning import fit
from canonid.profiles import stage_train_options

DEFAULT_CSV = Path(__file__).resolve().parents[2] / "shared" / "data" / "silverbox" / "SNLS80mV.csv"
MULTISINE = slice(40650, 127400)
N_TRAIN_VAL = 65062
N_INIT = 50
BASELINES = {"GRU": 1.490, "LSTM": 1.504, "RNN": 1.640}

#: variant name → (model, net options over the defaults, training option overrides)
VARIANTS: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {
    "default": ("mlp", {}, {}),
    "arx": ("arx", {}, {}),
    "linear": ("mlp", {"linear": "arx"}, {}),
    "no-skip": ("mlp", {"linear": "off"}, {}),
    "paper-options": (
        "mlp",
        {"activation": "relu", "linear": "off", "hidden": [256, 256, 256]},
        {},
    ),
}


@dataclass(frozen=True)
class Row:
    variant: str
    seed: int
    rmse_mv: float
    val_loss: float
    best_epoch: int
    epochs: int
    steps: int
    cpu_s: float
    wall_s: float


def load(csv: Path) -> np.ndarray:
    data = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=(0, 1))
    if data.shape != (131072, 2):
        raise SystemExit(f"{csv}: expected 131,072 rows of V1, V2; got {data.shape}")
    return data


def record(u: np.ndarray, y: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(u=u[:, None], y=y[:, None])


def train_val(data: np.ndarray) -> tuple[SimpleNamespace, SimpleNamespace]:
    """The multisine part's training and validation records (its last 20 % validate)."""
    part = data[MULTISINE][:N_TRAIN_VAL]
    n_val = int(np.ceil(0.2 * len(part)))
    return record(part[:-n_val, 0], part[:-n_val, 1]), record(part[-n_val:, 0], part[-n_val:, 1])


def run(data: np.ndarray, variant: str, seed: int, window: int) -> Row:
    model, net_options, overrides = VARIANTS[variant]
    train, val = train_val(data)
    test = data[MULTISINE][N_TRAIN_VAL:]
    opts = stage_train_options(  # None in overrides switches an option off
        "quick", {"seed": seed, "device": "cpu", "checkpoint_every": 10**6, **overrides}
    )
    c0, w0 = time.process_time(), time.perf_counter()
    result = fit(train, val, model=model, window=window, options=opts, net_options=net_options)
    # the field's rule: whole test input, the n_init first measured outputs, scored after them
    u_test, y_test = test[:, 0:1], test[:, 1:2]
    sim = result.model.simulate(u_test[N_INIT - window :], y_test[N_INIT - window : N_INIT])
    rmse = float(np.sqrt(np.mean((sim - y_test[N_INIT:]) ** 2)))
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    steps = result.epochs_run * -(-opts.windows_per_epoch // opts.batch_size)
    return Row(
        variant,
        seed,
        1000 * rmse,
        result.best_val_loss,
        result.best_epoch,
        result.epochs_run,
        steps,
        cpu,
        wall,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csv", type=Path, default=DEFAULT_CSV)
    parser.add_argument("--window", type=int, default=10)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=["default", "arx"])
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args()
    torch.set_num_threads(1)
    data = load(args.csv)
    rows = []
    for variant in args.variants:
        for seed in args.seeds if VARIANTS[variant][0] != "arx" else args.seeds[:1]:
            row = run(data, variant, seed, args.window)
            rows.append(row)
            print(
                f"{row.variant} seed {row.seed}: {row.rmse_mv:.3f} mV, val {row.val_loss:.3g} "
                f"(epoch {row.best_epoch}/{row.epochs}), {row.steps} steps, "
                f"CPU {row.cpu_s:.0f} s, wall {row.wall_s:.0f} s",
                flush=True,
            )
    load_avg = " / ".join(f"{x:.1f}" for x in __import__("os").getloadavg())
    lines = [
        f"Silverbox multisine test, ℓ = {args.window}, `quick` profile, one torch thread; RMSE of "
        f"the simulation after n_init = {N_INIT} (mV); load average at the end {load_avg} "
        "(the machine was shared: CPU time is the figure to read).",
        "",
        "| variant | seed | test RMSE [mV] | best val loss (norm.) | best epoch / run | "
        "optimiser steps | CPU [s] | wall [s] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {r.variant} | {r.seed} | {r.rmse_mv:.3f} | {r.val_loss:.3g} | {r.best_epoch} / "
        f"{r.epochs} | {r.steps} | {r.cpu_s:.0f} | {r.wall_s:.0f} |"
        for r in rows
    ]
    lines += [
        "",
        "Published on the same test (Champneys et al. 2024, recurrent models from a zero state): "
        + ", ".join(f"{k} {v:.3f} mV" for k, v in BASELINES.items())
        + ".",
    ]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        write_section("Silverbox", text)


if __name__ == "__main__":
    main()
