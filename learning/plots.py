"""Figures of a training run: the training curve and open-loop rollouts against the data.

Both write a PNG and return its path. They draw on a :class:`matplotlib.figure.Figure` of their
own, so they neither need nor change pyplot's backend and never show windows; the file is written
atomically (:func:`canonid.kernel.io.atomic_write_figure`), replacing a symlink planted at its
name rather than writing through it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.io import atomic_write_figure
from canonid.learning.evaluate import simulate_records
from canonid.learning.model import Model

__all__ = ["plot_rollouts", "plot_training_curve"]


def plot_training_curve(history: Sequence[Mapping[str, Any]], path: str | os.PathLike[str]) -> Path:
    """Training and validation losses (normalised units, log scale) and the rollout length."""
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    train = [(r["epoch"], r["train_loss"]) for r in history if r.get("train_loss") is not None]
    val = [(r["epoch"], r["val_loss"]) for r in history if r.get("val_loss") is not None]
    if train:
        ax.plot(*zip(*train), lw=1, label="training loss (α-weighted, current horizon)")
    if val:
        ax.plot(*zip(*val), lw=1.5, label="validation rollout MSE")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss (normalised units)")
    horizon = [(r["epoch"], r["horizon"]) for r in history if r.get("horizon")]
    if horizon:
        ax2 = ax.twinx()
        ax2.plot(*zip(*horizon), color="0.6", ls=":", lw=1)
        ax2.set_ylabel("training rollout length H (dotted)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return atomic_write_figure(path, fig, dpi=120)


def plot_rollouts(
    model: Model,
    data: Sequence[Trajectory],
    path: str | os.PathLike[str],
    *,
    n_init: int,
    output_names: Sequence[str] | None = None,
    count: int = 3,
    dt: float = 1.0,
) -> Path:
    """Open-loop simulation of the first ``count`` records from sample ``n_init`` (burn-in on the
    measured samples ``n_init−ℓ … n_init−1``), against the measured and, if present, noise-free
    outputs; one row per output, one column per record."""
    records = [tr for tr in as_trajectories(data, what="plotted data") if tr.T > n_init][:count]
    sims = simulate_records(model, records, n_init)
    names = list(output_names or (f"y{i + 1}" for i in range(model.n_y)))
    fig = Figure(figsize=(4.2 * len(records), 2.4 * model.n_y))
    axes = fig.subplots(
        model.n_y,
        len(records),
        squeeze=False,
        sharex="col",
    )
    for j, (tr, sim) in enumerate(zip(records, sims)):
        t = np.arange(tr.T) * dt
        for i in range(model.n_y):
            ax = axes[i, j]
            ax.plot(t, tr.y[:, i], ".", ms=2, color="0.55", label="measured")
            if tr.y_clean is not None:
                ax.plot(t, tr.y_clean[:, i], color="k", lw=1, label="noise-free")
            ax.plot(t[n_init:], sim[:, i], color="C3", lw=1.2, label=f"{model.name} (open loop)")
            ax.axvline(t[n_init], color="C0", ls="--", lw=0.8)
            if j == 0:
                ax.set_ylabel(names[i])
            if i == model.n_y - 1:
                ax.set_xlabel("time [s]")
            if i == 0:
                ax.set_title(f"record {j}", fontsize=9)
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.suptitle(
        f"{model.name}, ℓ = {model.window}: simulation from sample {n_init} (dashed line)",
        fontsize=10,
    )
    fig.tight_layout()
    return atomic_write_figure(path, fig, dpi=120)
