"""Identification against deepSI: Ours (MLP) and deepSI's SUBNET on the same data, the same
wall-clock budget, scored by the same code.

Writes the section "Identification versus deepSI" of benchmarks/RESULTS.md.

* Contestants. **Ours (MLP)**: ``learning.fit`` with the ``quick`` profile (what ``canonid train
  --profile quick`` runs), ℓ = 10, residual outputs. **deepSI SUBNET** (deepSI 0.4.4,
  ``deepSI.models.SUBNET`` trained by ``deepSI.fit``) with deepSI's defaults (state dimension 10,
  its residual MLPs, Adam at 1e-3, batch 256, rollout T = 50) but for the encoder's past window,
  set to na = nb = ℓ so that both models start every rollout from the same ℓ measured samples.
  Seed 0 for both (torch weights; our window draws; deepSI's batcher is seeded 0 by deepSI).
* Same budget, taking turns. Both trainers run in one process on one torch thread, each in its
  own Python thread, but only one at a time: they pass a baton every ``--slice`` seconds (checked
  between our epochs and at deepSI's validation points), so load from other jobs on the machine
  falls on both alike. Each one's clock counts only its own slices (its validations included);
  it stops at the first check after its clock passes the budget.
* Validation (the time-to-target curve): the same number for both, the mean squared error of
  100-step open-loop rollouts after an ℓ-sample measured burn-in, from every 5th start of every
  validation trajectory, divided per output by the training output variance and averaged over
  the outputs (exactly our trainer's validation loss with the quick profile). Each keeps its
  best model on it. Time to target: the training-clock time of the first validation at or below
  a fixed multiple of the noise floor (noise variance / output variance, averaged over outputs),
  and of the level both reached (the larger of the two best validation MSEs).
* Test scores: :func:`learning.evaluate` on the test split for both (deepSI's SUBNET wrapped as
  a model with the same ``predict``): the paper metric (MSE of 100-step rollouts from every
  start, stride 1) and the simulation RMSE after n_init = 50 samples, against the measured and
  the noise-free outputs.

Usage: python benchmarks/bench_deepsi.py [--size quick|full] [--tank DIR] [--drone DIR]
(quick: 60 s per contestant and dataset; full: 180 s). The datasets come from
``canonid generate tank`` and ``canonid generate drone2d --n-train 40 --n-val 10 --n-test 10
--out runs/data/drone2d-small``; a missing one is generated first.
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("TQDM_DISABLE", "1")  # deepSI draws a progress bar per fit

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import deepSI  # noqa: E402
import deepSI.fitting  # noqa: E402
from _data import ensure_dataset  # noqa: E402
from _results import write_section  # noqa: E402
from nonlinear_benchmarks import Input_output_data  # noqa: E402

from canonid.profiles import train_options  # noqa: E402
from datagen.dataset import Dataset  # noqa: E402
from learning import Model, Normalisation, as_series, evaluate, fit  # noqa: E402

WINDOW, HORIZON, VAL_STRIDE = 10, 100, 5
TARGETS = (30.0, 10.0, 3.0)  # time-to-target levels, in multiples of the noise floor
DEEPSI_VAL_FREQ = 25  # deepSI iterations between validations (batch 256: ~ our 5 epochs' samples)


class OutOfBudget(Exception):
    """Raised from a trainer's callback when its clock has passed the budget."""


class TakeTurns:
    """Lets several trainers, each in its own thread, run one at a time in slices.

    ``begin(name)`` waits for ``name``'s turn; ``check(name)`` (called by the trainer between
    steps) hands the turn on once the current slice is ``slice_s`` old and returns ``name``'s
    clock (seconds of its own slices so far); ``end(name)`` hands it on for good.
    """

    def __init__(self, names: Sequence[str], slice_s: float) -> None:
        self.names, self.slice_s = list(names), slice_s
        self.turn = self.names[0]
        self.used = dict.fromkeys(self.names, 0.0)
        self.since = dict.fromkeys(self.names, 0.0)
        self.done: set[str] = set()
        self.cv = threading.Condition()

    def begin(self, name: str) -> None:
        with self.cv:
            self.cv.wait_for(lambda: self.turn == name)
        self.since[name] = time.perf_counter()

    def clock(self, name: str) -> float:
        return self.used[name] + time.perf_counter() - self.since[name]

    def check(self, name: str) -> float:
        if time.perf_counter() - self.since[name] >= self.slice_s:
            self._hand_on(name)
            self.begin(name)
        return self.clock(name)

    def end(self, name: str) -> None:
        self._hand_on(name, finished=True)

    def _hand_on(self, name: str, *, finished: bool = False) -> None:
        with self.cv:
            self.used[name] += time.perf_counter() - self.since[name]
            if finished:
                self.done.add(name)
            waiting = [n for n in self.names if n not in self.done]
            if waiting:
                i = self.names.index(name)
                order = self.names[i + 1 :] + self.names[: i + 1]
                self.turn = next(n for n in order if n in waiting)
            self.cv.notify_all()


class SubnetModel:
    """deepSI's SUBNET behind the ``predict`` of :class:`learning.Model`, so that
    :func:`learning.evaluate` scores it with the same code: ``u`` ``(N, T, n_u)`` and the
    measured burn-in ``y`` ``(N, ℓ, n_y)`` → predicted ``y`` ``(N, T − ℓ, n_y)`` (the encoder
    reads the ℓ past inputs and outputs, the state then runs in open loop on ``u[:, ℓ:]``)."""

    name = "deepSI SUBNET"

    def __init__(self, net: Any, window: int, n_u: int, n_y: int) -> None:
        self.net, self.window, self.n_u, self.n_y = net, window, n_u, n_y

    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        ell = self.window
        ut = torch.as_tensor(u, dtype=torch.float32)
        yt = torch.as_tensor(y_burn_in, dtype=torch.float32)
        was_training = self.net.training
        self.net.eval()
        try:
            with torch.no_grad():
                out = self.net(ut[:, :ell], yt, ut[:, ell:])
        finally:
            self.net.train(was_training)
        return out.numpy().astype(np.float64)


@dataclass
class Curve:
    """Validation MSE (normalised) against the contestant's training clock."""

    seconds: list[float] = field(default_factory=list)
    val: list[float] = field(default_factory=list)
    cpu_seconds: float = 0.0
    steps: int = 0

    def add(self, seconds: float, val: float) -> None:
        self.seconds.append(seconds)
        self.val.append(val)

    @property
    def best(self) -> float:
        """The lowest validation MSE (infinite before the first validation)."""
        return min(self.val, default=float("inf"))

    def time_to(self, level: float) -> float | None:
        return next((t for t, v in zip(self.seconds, self.val) if v <= level), None)


def validation_mse(model: Any, val: Sequence[Any], norm: Normalisation) -> float:
    """The shared validation number (see the module docstring)."""
    ell, errs = WINDOW, []
    for tr in val:
        starts = range(0, tr.u.shape[0] - ell - HORIZON + 1, VAL_STRIDE)
        u = np.stack([tr.u[s : s + ell + HORIZON] for s in starts])
        y = np.stack([tr.y[s : s + ell + HORIZON] for s in starts])
        pred = model.predict(u, y[:, :ell])
        errs.append((((pred - y[:, ell:]) / norm.y_std) ** 2).reshape(-1, norm.n_y))
    return float(np.concatenate(errs).mean())


def train_ours(ds: Dataset, turns: TakeTurns, budget: float, curve: Curve) -> Model:
    opts = train_options("quick", device="cpu", seed=0, checkpoint_every=10**6)
    train, val = ds.split("train"), ds.split("val")

    def watch(report: Any) -> None:
        curve.steps += -(-len(train) * opts.windows_per_trajectory // opts.batch_size)
        clock = turns.check("ours")
        if report.val_loss is not None:
            curve.add(clock, report.val_loss)
        if clock >= budget:
            raise OutOfBudget

    turns.begin("ours")
    t_cpu = time.thread_time()
    with tempfile.TemporaryDirectory() as tmp:
        try:
            res = fit(
                train,
                val,
                model="mlp",
                window=WINDOW,
                options=opts,
                net_options={"residual": True},
                run_dir=tmp,
                callback=watch,
            )
            model = res.model
        except OutOfBudget:  # the best model so far was saved to the run folder
            model = Model.load(tmp)
    curve.cpu_seconds = time.thread_time() - t_cpu
    turns.end("ours")
    return model


def train_deepsi(ds: Dataset, turns: TakeTurns, budget: float, curve: Curve) -> SubnetModel:
    def records(split: str) -> list[Input_output_data]:
        return [Input_output_data(u=t.u, y=t.y) for t in ds.split(split)]

    train, val = records("train"), ds.split("val")
    norm = Normalisation.fit(as_series(ds.split("train")))
    n_u, n_y = train[0].u.shape[1], train[0].y.shape[1]
    _, _, auto_norm = deepSI.get_nu_ny_and_auto_norm(train)
    torch.manual_seed(0)
    net = deepSI.SUBNET(n_u, n_y, auto_norm, nb=WINDOW, na=WINDOW)
    wrapped = SubnetModel(net, WINDOW, n_u, n_y)
    best: dict[str, Any] = {"val": float("inf"), "state": copy.deepcopy(net.state_dict())}

    def val_fun(model: Any, *_arrays: Any) -> torch.Tensor:
        clock = turns.check("deepsi")
        curve.steps = len(curve.val) * DEEPSI_VAL_FREQ
        v = validation_mse(wrapped, val, norm)
        curve.add(clock, v)
        if v < best["val"]:
            best.update(val=v, state=copy.deepcopy(net.state_dict()))
        if clock >= budget:
            raise KeyboardInterrupt  # deepSI.fit's own way to stop early
        return torch.tensor(v)

    turns.begin("deepsi")
    t_cpu = time.thread_time()
    home_dir = deepSI.fitting.get_checkpoint_dir
    with tempfile.TemporaryDirectory() as tmp, open(os.devnull, "w") as quiet:
        # deepSI writes a checkpoint per validation under the home folder; keep it in tmp
        deepSI.fitting.get_checkpoint_dir = lambda: tmp
        try:
            with redirect_stdout(quiet):
                deepSI.fit(
                    net,
                    train,
                    records("val"),
                    n_its=10**8,
                    val_freq=DEEPSI_VAL_FREQ,
                    val_fun=val_fun,
                )
        finally:
            deepSI.fitting.get_checkpoint_dir = home_dir
    net.load_state_dict(best["state"])
    curve.cpu_seconds = time.thread_time() - t_cpu
    turns.end("deepsi")
    return wrapped


def noise_floor(ds: Dataset) -> float:
    """Noise variance over output variance (training split), averaged over the outputs."""
    y = np.concatenate([t.y for t in ds.split("train")])
    box = ds.metadata["noise"]["box"]
    half = (np.asarray(box["upper"]) - np.asarray(box["lower"])) / 2
    return float(np.mean(half**2 / 3 / y.var(axis=0)))


def compare(name: str, ds: Dataset, budget: float, slice_s: float) -> str:
    turns = TakeTurns(["ours", "deepsi"], slice_s)
    curves = {"ours": Curve(), "deepsi": Curve()}
    models: dict[str, Any] = {}
    trainers: dict[str, Callable[..., Any]] = {"ours": train_ours, "deepsi": train_deepsi}
    errors: list[BaseException] = []

    def run(key: str) -> None:
        try:
            models[key] = trainers[key](ds, turns, budget, curves[key])
        except BaseException as exc:  # report it from the main thread
            errors.append(exc)
            turns.end(key)

    load0 = os.getloadavg()[0]
    threads = [threading.Thread(target=run, args=(k,)) for k in trainers]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    load1 = os.getloadavg()[0]
    if errors:
        raise errors[0]

    floor = noise_floor(ds)
    # the level both reached: the worse of the two best validation MSEs
    both = max(c.best for c in curves.values())
    test = ds.split("test")
    labels = {"ours": "Ours (MLP)", "deepsi": "deepSI SUBNET"}
    rows = [
        "| model | parameters | training clock s (CPU s) | optimiser steps | "
        "best val MSE (norm.) | 100-step MSE, y | 100-step MSE, y_clean | "
        "RMSE after n_init, y | RMSE after n_init, y_clean | "
        + " | ".join(f"time to {m:g}× floor" for m in TARGETS)
        + f" | time to {both:.3g} (both reached) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|" + "---:|" * (len(TARGETS) + 1),
    ]
    for key in ("ours", "deepsi"):
        model, curve = models[key], curves[key]
        ev = evaluate(model, test, horizon=HORIZON)
        clean = ev.clean
        params = sum(p.numel() for p in model.net.parameters())
        hits = [curve.time_to(m * floor) for m in TARGETS] + [curve.time_to(both)]
        rows.append(
            f"| {labels[key]} | {params:,} | {turns.used[key]:.0f} ({curve.cpu_seconds:.0f}) | "
            f"{curve.steps:,} | {curve.best:.3g} | {ev.measured.rollout_mse:.3g} | "
            f"{clean.rollout_mse if clean else float('nan'):.3g} | {ev.measured.rmse:.3g} | "
            f"{clean.rmse if clean else float('nan'):.3g} | "
            + " | ".join("not reached" if h is None else f"{h:.0f} s" for h in hits)
            + " |"
        )
    curve_rows = ["| training clock s | " + " | ".join(labels.values()) + " |", "|---:|---:|---:|"]
    grid = np.linspace(0, budget, 7)[1:]
    for t in grid:
        best = [
            min((v for s, v in zip(curves[k].seconds, curves[k].val) if s <= t), default=None)
            for k in ("ours", "deepsi")
        ]
        curve_rows.append(
            f"| {t:.0f} | " + " | ".join("—" if b is None else f"{b:.3g}" for b in best) + " |"
        )
    train = ds.split("train")
    return "\n\n".join(
        [
            f"### {name}: {len(train)}/{len(ds.split('val'))}/{len(test)} trajectories × "
            f"{train[0].u.shape[0]} samples",
            f"Budget {budget:.0f} s of training clock each, slices of {slice_s:.0f} s; load "
            f"average {load0:.1f} before, {load1:.1f} after (2 cores shared with other jobs). "
            f"Noise floor (normalised) {floor:.3g}; test scores by `learning.evaluate` "
            f"({ev.n_rollouts} rollouts of {HORIZON} steps; RMSE over {ev.n_scored_samples} "
            f"samples after n_init = {ev.n_init}).",
            "\n".join(rows),
            "Best validation MSE so far (normalised) against the training clock:",
            "\n".join(curve_rows),
        ]
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--tank", type=Path, help="tank dataset (default runs/data/tank-s0)")
    parser.add_argument(
        "--drone", type=Path, help="planar-drone dataset (default runs/data/drone2d-small)"
    )
    parser.add_argument("--budget", type=float, help="seconds per contestant and dataset")
    parser.add_argument("--slice", type=float, default=2.0, help="seconds per turn")
    parser.add_argument("--only", choices=("tank", "drone2d"), help="one dataset only")
    args = parser.parse_args()
    budget = args.budget or (60.0 if args.size == "quick" else 180.0)
    torch.set_num_threads(1)
    cases = {"tank": ("tank-s0", args.tank), "drone2d": ("drone2d-small", args.drone)}
    parts = [
        "Ours (MLP) (`learning.fit`, quick profile, ℓ = 10, residual) against deepSI 0.4.4's "
        "SUBNET (`deepSI.fit`, its defaults, na = nb = ℓ), seed 0, one torch thread, taking "
        "turns in one process; both scored by `learning.evaluate`. See the script's docstring "
        "for the exact protocol. Validation and the noise floor are in units of the training "
        "output variance; test MSEs and RMSEs in physical units."
    ]
    for name, (dataset, path) in cases.items():
        if args.only in (None, name):
            ds = Dataset.load(ensure_dataset(dataset, path))
            parts.append(compare(name, ds, budget, args.slice))
    body = "\n\n".join(parts)
    write_section("Identification versus deepSI", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
