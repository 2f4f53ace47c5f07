"""Figures of a training run: the training curve and open-loop rollouts against the data.

Both write a figure in the format of the path's suffix (``.png``, ``.pdf``, ``.svg``) and return
its path. They draw on a :class:`matplotlib.figure.Figure` of their own, so they neither need nor
change pyplot's backend and never show windows; the file is written atomically
(:func:`canonid.kernel.io.atomic_write_figure`), replacing a symlink planted at its name rather
than writing through it. Legends sit below the panels, never over the data; the model is named
as tables name it (:func:`canonid.kernel.catalog.model_label`), each record by its experiment
(:func:`record_title`), each output with its unit when known.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from canonid.kernel.catalog import model_label
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.io import atomic_write_figure
from canonid.learning.evaluate import simulate_records
from canonid.learning.model import Model

__all__ = [
    "DPI",
    "axis_label",
    "plot_rollouts",
    "plot_training_curve",
    "record_title",
    "rollouts_figure",
    "training_curve_figure",
]

#: resolution of the raster (PNG) figures
DPI = 150


def axis_label(name: str, unit: str | None) -> str:
    """``name [unit]``; the name alone when the unit is unknown or ``-`` (dimensionless)."""
    return f"{name} [{unit}]" if unit and unit != "-" else name


def record_title(tr: Trajectory, index: int) -> str:
    """A record's name from what its loader recorded in ``info``: the CSV experiment, the
    flight (and chunk), the benchmark part, or the split and index of a generated dataset;
    ``record INDEX`` when none is known. A part cut from a record adds its sample range."""
    info = tr.info
    if "experiment" in info:
        name = str(info["experiment"])
    elif "flight" in info:
        chunk = f", chunk {info['chunk']}" if "chunk" in info else ""
        name = f"flight {info['flight']}{chunk}"
    elif "part" in info:
        name = str(info["part"])
    elif "split" in info and "index" in info:
        name = f"{info['split']} experiment {info['index']}"
    else:
        name = f"record {index}"
    samples = info.get("samples")
    if isinstance(samples, (list, tuple)) and len(samples) == 2:
        name += f" (samples {samples[0]}–{samples[1] - 1})"
    return name


def _kept_epoch(history: Sequence[Mapping[str, Any]]) -> int | None:
    """The first epoch of least validation loss: the one whose weights training keeps."""
    best, kept = math.inf, None
    for row in history:
        value = row.get("val_loss")
        if value is not None and value < best:
            best, kept = value, row["epoch"]
    return kept


def plot_training_curve(
    history: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    best_epoch: int | None = None,
) -> Path:
    """Write :func:`training_curve_figure` to ``path``."""
    return atomic_write_figure(path, training_curve_figure(history, best_epoch=best_epoch), dpi=DPI)


def training_curve_figure(
    history: Sequence[Mapping[str, Any]], *, best_epoch: int | None = None
) -> Figure:
    """Two panels over the epochs, both log scale in normalised units: the training loss
    (α-weighted, at the current training rollout length H, dotted on the right axis) and the
    validation rollout MSE; the kept epoch (``best_epoch``, default the first of least
    validation loss) is marked in both."""
    fig = Figure(figsize=(7, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    train = [(r["epoch"], r["train_loss"]) for r in history if _finite(r.get("train_loss"))]
    val = [(r["epoch"], r["val_loss"]) for r in history if _finite(r.get("val_loss"))]
    handles = []
    if train:
        handles += top.plot(*zip(*train), lw=1, color="C0", label="training loss")
        top.set_yscale("log")
    top.set_ylabel("training loss\n(α-weighted, normalised)")
    horizon = [(r["epoch"], r["horizon"]) for r in history if r.get("horizon")]
    if horizon:
        right = top.twinx()
        handles += right.plot(
            *zip(*horizon), color="0.5", ls=":", lw=1, label="training rollout length H"
        )
        right.set_ylabel("H [samples]")
    if val:
        handles += bottom.plot(
            *zip(*val), lw=1.5, color="C1", marker=".", ms=3, label="validation rollout MSE"
        )
        bottom.set_yscale("log")
    bottom.set_ylabel("validation rollout MSE\n(normalised)")
    bottom.set_xlabel("epoch")
    kept = best_epoch if best_epoch is not None else _kept_epoch(history)
    if kept is not None:
        for ax in (top, bottom):
            ax.axvline(kept, color="C2", ls="--", lw=1)
        kept_val = dict(val).get(kept)
        if kept_val is not None:
            bottom.plot([kept], [kept_val], "*", color="C2", ms=11, zorder=3)
        handles += bottom.plot(
            [], [], color="C2", ls="--", marker="*", label=f"kept weights (epoch {kept})"
        )
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
    fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    return fig


def _finite(value: Any) -> bool:
    return value is not None and math.isfinite(value)


def plot_rollouts(
    model: Model, data: Sequence[Trajectory], path: str | os.PathLike[str], **options: Any
) -> Path:
    """Write :func:`rollouts_figure` (``options`` are its keywords) to ``path``."""
    return atomic_write_figure(path, rollouts_figure(model, data, **options), dpi=DPI)


def rollouts_figure(
    model: Model,
    data: Sequence[Trajectory],
    *,
    n_init: int,
    output_names: Sequence[str] | None = None,
    output_units: Sequence[str | None] | None = None,
    count: int = 3,
    dt: float = 1.0,
    source: str | None = None,
) -> Figure:
    """Open-loop simulation of the first ``count`` records from sample ``n_init`` (burn-in on the
    measured samples ``n_init−ℓ … n_init−1``), against the measured and, if present, noise-free
    outputs; one row per output (labelled with ``output_units`` when known), one column per
    record (titled by :func:`record_title`); ``source`` (the data scored) goes in the title."""
    trajs = as_trajectories(data, what="plotted data")
    shown = [(i, tr) for i, tr in enumerate(trajs) if tr.T > n_init][:count]
    records = [tr for _, tr in shown]
    titles = [record_title(tr, i) for i, tr in shown]
    sims = simulate_records(model, records, n_init)
    names = list(output_names or (f"y{i + 1}" for i in range(model.n_y)))
    units = list(output_units or [None] * model.n_y)
    label = model_label(model.name)
    # a readable panel each, at least a 7 × 4.5 in page figure; room below for the legend
    width = max(7.0, 3.6 * len(records))
    height = max(4.5, 2.0 * model.n_y + 1.2)
    fig = Figure(figsize=(width, height), layout="constrained")
    axes = fig.subplots(model.n_y, len(records), squeeze=False, sharex="col")
    for j, (tr, sim) in enumerate(zip(records, sims)):
        t = np.arange(tr.T) * dt
        for i in range(model.n_y):
            ax = axes[i, j]
            ax.plot(t, tr.y[:, i], ".", ms=2, color="0.55", label="measured")
            if tr.y_clean is not None:
                ax.plot(t, tr.y_clean[:, i], color="k", lw=1, label="noise-free")
            ax.plot(t[n_init:], sim[:, i], color="C3", lw=1.2, label=f"{label}, open loop")
            ax.axvline(t[n_init], color="C0", ls="--", lw=0.8, label="end of burn-in")
            ax.grid(True, alpha=0.3)
            if j == 0:
                ax.set_ylabel(axis_label(names[i], units[i]))
            if i == model.n_y - 1:
                ax.set_xlabel("time [s]")
            if i == 0:
                ax.set_title(titles[j], fontsize=9)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), frameon=False)
    on = f" on {source}" if source else ""
    fig.suptitle(f"{label}, ℓ = {model.window}{on}: open-loop simulation from sample {n_init}")
    return fig
