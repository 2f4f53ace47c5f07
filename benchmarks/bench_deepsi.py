"""Identification against deepSI: Ours (MLP) and deepSI's SUBNET on the same data, the same
training budget, scored by the same code.

Writes the section "Identification versus deepSI" of the records (benchmarks/records/).

* Contestants. **Ours (MLP)**: ``learning.fit`` with the ``quick`` profile (what ``canonid train
  --profile quick`` runs), ℓ = 10, with canonid's default options on both systems
  (:data:`canonid.learning.presets.DEFAULT_NET_OPTIONS`: what ``canonid train --model mlp`` gets).
  **deepSI SUBNET** (deepSI 0.4.4, ``deepSI.models.SUBNET`` trained by ``deepSI.fit``) with
  deepSI's defaults (state dimension 10, its residual MLPs, Adam at 1e-3, batch 256, rollout T =
  50) but for the encoder's past window, set to na = nb = ℓ so that both models start every
  rollout from the same ℓ measured samples. Seed 0 for both (torch weights; our window draws;
  deepSI's batcher is seeded 0 by deepSI).
* The budget is **CPU time of the contestant's own thread**, validation excluded. The issue
  asks for the same wall-clock budget; on a dedicated machine with one thread each, CPU and
  wall time coincide. On a shared machine they do not: with 5–8 runnable processes on 2 cores,
  a 60 s wall budget gave each model 8–12 s of CPU, so the measured budget depended on the
  other jobs. Both trainers run in one process with one torch thread (``torch.set_num_threads
  (1)`` before either starts; intra-op work then runs on the calling thread, so
  ``time.thread_time()`` of that thread is all the CPU the trainer used), each in its own Python
  thread, one at a time: they pass a baton every ``--slice`` seconds of wall time (checked
  between our epochs and at deepSI's validation points), so the load from other jobs falls on
  both alike. The wall time of each one's own turns is recorded beside its CPU time.
* What the clock counts, alike for both: everything from the call of the trainer's ``fit`` on
  (its own data preparation — our window bank, deepSI's ``create_arrays`` — and every
  optimiser step) but the validation passes, whose CPU time is recorded apart. The clock stops
  when a validation starts (our ``canonid.learning.training.validation_loss``, wrapped; deepSI's
  ``val_fun``) and runs again when it ends (ours) or at deepSI's next loss evaluation (its
  ``loss_fun``): deepSI also keeps a copy of the best model and pickles a checkpoint file after
  every validation, which at our validation frequency (ten times its default) would cost it
  more than in ordinary use. Ours keeps its best weights inside the clock (a copy of the state
  dictionary, well under a millisecond). Each stops at its first validation at or after the
  budget, or (ours) when its profile's epochs are done. Ours' clock includes the tests its
  defaults run before training (the feedthrough test's least squares, the cubic test's short
  trainings); their validation passes, on their own splits, are not points of its curve (before
  2026-11-29 they were). Before the contest both run for
  ``WARM_UP`` seconds, untimed and thrown away, in the same process: the first use of torch's
  kernels for each layer shape costs about a second of CPU, which would otherwise fall on
  whichever starts first.
* Validation (the time-to-target curve): the same number for both, the mean squared error of
  100-step open-loop rollouts after an ℓ-sample measured burn-in, from every 5th start of every
  validation trajectory, divided per output by the training output variance and averaged over
  the outputs (exactly our trainer's validation loss with the quick profile; ours every 5
  epochs, deepSI every ``DEEPSI_VAL_FREQ`` iterations). Each keeps its best model on it. Time
  to target: the training clock at the first validation at or below a level — fixed multiples
  of the noise floor (noise variance / output variance, averaged over outputs) and the level
  both reached (the larger of the two best validation MSEs).
* Test scores: :func:`canonid.learning.evaluate` on the test split for both (deepSI's SUBNET wrapped
as
  a model with the same ``predict``): the paper metric (MSE of 100-step rollouts from every
  start, stride 1) and the simulation RMSE after n_init = 50 samples, against the measured and
  the noise-free outputs.

Usage: python benchmarks/bench_deepsi.py [--size quick|full] [--tank DIR] [--drone DIR]
(quick: 60 s of CPU per contestant and dataset; full: 300 s). The datasets come from
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
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, redirect_stdout
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

import canonid.learning.training  # noqa: E402
from canonid.kernel.dataset import Dataset  # noqa: E402
from canonid.learning import Model, Normalisation, evaluate, fit  # noqa: E402
from canonid.profiles import train_options  # noqa: E402

WINDOW, HORIZON, VAL_STRIDE = 10, 100, 5
#: time-to-target levels, in multiples of the noise floor
TARGETS = (1000.0, 300.0, 100.0, 30.0, 10.0, 3.0)
WARM_UP = 0.5  # CPU seconds of an untimed run of both before the contest
DEEPSI_VAL_FREQ = 25  # deepSI iterations between validations (batch 256: ~ our 5 epochs' samples)
#: network options of Ours (MLP) per system over the defaults: none, what a user gets
OURS_OPTIONS: dict[str, dict[str, Any]] = {"tank": {}, "drone2d": {}}


class OutOfBudget(Exception):
    """Raised from a trainer's callback when its clock has passed the budget."""


class TakeTurns:
    """Lets several trainers, each in its own thread, run one at a time in slices.

    ``begin(name)`` waits for ``name``'s turn; ``check(name)`` (called by the trainer between
    steps) hands the turn on once the current slice is ``slice_s`` seconds (wall) old;
    ``end(name)`` hands it on for good. ``wall(name)``: wall seconds of ``name``'s turns.
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

    def wall(self, name: str) -> float:
        return self.used[name] + time.perf_counter() - self.since[name]

    def check(self, name: str) -> None:
        if time.perf_counter() - self.since[name] >= self.slice_s:
            self._hand_on(name)
            self.begin(name)

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


class Clock:
    """One contestant's training clock: CPU seconds of the calling thread since ``start()``,
    minus the spans between ``pause()`` and ``resume()`` (validation), which are summed apart
    (``val_cpu``, and their wall time ``val_wall``). Read and driven from that thread only."""

    def __init__(self) -> None:
        self.cpu0 = 0.0
        self.val_cpu = self.val_wall = 0.0
        self.paused_at: tuple[float, float] | None = None

    def start(self) -> None:
        self.cpu0 = time.thread_time()

    def pause(self) -> None:
        if self.paused_at is None:
            self.paused_at = (time.thread_time(), time.perf_counter())

    def resume(self) -> None:
        if self.paused_at is not None:
            cpu, wall = self.paused_at
            self.val_cpu += time.thread_time() - cpu
            self.val_wall += time.perf_counter() - wall
            self.paused_at = None

    def cpu(self) -> float:
        """Training CPU seconds so far (frozen while paused)."""
        now = self.paused_at[0] if self.paused_at is not None else time.thread_time()
        return now - self.cpu0 - self.val_cpu

    def wall(self, turns_wall: float) -> float:
        """Training wall seconds, given the wall seconds of the contestant's turns so far."""
        current = time.perf_counter() - self.paused_at[1] if self.paused_at is not None else 0.0
        return turns_wall - self.val_wall - current


class SubnetModel:
    """deepSI's SUBNET behind the ``predict`` of :class:`canonid.learning.Model`, so that
    :func:`canonid.learning.evaluate` scores it with the same code: ``u`` ``(N, T, n_u)`` and the
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
    """Validation MSE (normalised) against the contestant's training clock (CPU and wall
    seconds of training), its optimiser steps, and how it stopped."""

    seconds: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)
    val: list[float] = field(default_factory=list)
    clock: Clock = field(default_factory=Clock)
    steps: int = 0
    epochs: int = 0
    stopped: str = "budget"
    #: Ours: validations before its training's first epoch report (the feedthrough and cubic
    #: tests' short trainings, on their own splits): held back, not the curve's
    pending: list[tuple[float, float, float]] = field(default_factory=list)
    started: bool = True

    def add(self, seconds: float, wall: float, val: float) -> None:
        self.seconds.append(seconds)
        self.wall.append(wall)
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


@contextmanager
def validations_recorded(curve: Curve, turns: TakeTurns) -> Iterator[None]:
    """While active, every validation pass of our trainer (``fit`` looks ``validation_loss`` up
    in its module at each call; only the ``ours`` thread calls it) stops ``curve.clock`` and is
    added to ``curve``."""
    original, clock = canonid.learning.training.validation_loss, curve.clock

    def validation_loss(*args: Any, **kwargs: Any) -> float:
        clock.pause()
        v = original(*args, **kwargs)
        point = (clock.cpu(), clock.wall(turns.wall("ours")), v)
        if curve.started:
            curve.add(*point)
        else:
            curve.pending.append(point)
        clock.resume()
        return v

    canonid.learning.training.validation_loss = validation_loss
    try:
        yield
    finally:
        canonid.learning.training.validation_loss = original


def train_ours(
    ds: Dataset,
    turns: TakeTurns,
    budget: float,
    curve: Curve,
    *,
    net_options: Mapping[str, Any],
    overrides: Mapping[str, Any] | None = None,
) -> Model:
    """Ours (MLP): the quick profile (with ``overrides``, for the drone study) until its
    epochs are done or its clock passes ``budget`` at a validation."""
    opts = train_options("quick", device="cpu", seed=0, checkpoint_every=10**6, **(overrides or {}))
    train, val = ds.split("train"), ds.split("val")
    clock = curve.clock

    def watch(report: Any) -> None:
        if not curve.started:  # the training's first epoch: earlier passes were the tests'
            curve.started = True
            if report.val_loss is not None and curve.pending:
                curve.add(*curve.pending[-1])  # this epoch's own validation
            curve.pending.clear()
        curve.steps += -(-opts.windows_per_epoch // opts.batch_size)
        curve.epochs = report.epoch
        turns.check("ours")
        if report.epoch % opts.val_every == 0 and curve.seconds[-1] >= budget:
            raise OutOfBudget

    turns.begin("ours")
    curve.started = False
    clock.start()
    with tempfile.TemporaryDirectory() as tmp, validations_recorded(curve, turns):
        try:
            res = fit(
                train,
                val,
                model="mlp",
                window=WINDOW,
                options=opts,
                net_options=net_options,
                run_dir=tmp,
                callback=watch,
            )
            model = res.model
            curve.stopped = f"{opts.epochs} epochs done"
        except OutOfBudget:  # the best model so far was saved to the run folder
            model = Model.load(tmp)
            curve.stopped = f"budget, epoch {curve.epochs}"
    turns.end("ours")
    return model


def train_deepsi(ds: Dataset, turns: TakeTurns, budget: float, curve: Curve) -> SubnetModel:
    """deepSI's SUBNET with its defaults (na = nb = ℓ) until its clock passes ``budget`` at a
    validation."""

    def records(split: str) -> list[Input_output_data]:
        return [Input_output_data(u=t.u, y=t.y) for t in ds.split(split)]

    train, val = records("train"), ds.split("val")
    norm = Normalisation.fit(ds.split("train"))
    n_u, n_y = train[0].u.shape[1], train[0].y.shape[1]
    _, _, auto_norm = deepSI.get_nu_ny_and_auto_norm(train)
    torch.manual_seed(0)
    net = deepSI.SUBNET(n_u, n_y, auto_norm, nb=WINDOW, na=WINDOW)
    wrapped = SubnetModel(net, WINDOW, n_u, n_y)
    best: dict[str, Any] = {"val": float("inf"), "state": copy.deepcopy(net.state_dict())}
    clock = curve.clock

    def loss_fun(model: Any, *arrays: Any) -> torch.Tensor:
        clock.resume()  # a training step starts: validation and its bookkeeping are over
        return deepSI.fitting.compute_NMSE(model, *arrays)

    def val_fun(model: Any, *_arrays: Any) -> torch.Tensor:
        turns.check("deepsi")
        clock.pause()
        curve.steps = len(curve.val) * DEEPSI_VAL_FREQ
        v = validation_mse(wrapped, val, norm)
        curve.add(clock.cpu(), clock.wall(turns.wall("deepsi")), v)
        if v < best["val"]:
            best.update(val=v, state=copy.deepcopy(net.state_dict()))
        if clock.cpu() >= budget:
            raise KeyboardInterrupt  # deepSI.fit's own way to stop early
        return torch.tensor(v)

    turns.begin("deepsi")
    home_dir = deepSI.fitting.get_checkpoint_dir
    with tempfile.TemporaryDirectory() as tmp, open(os.devnull, "w") as quiet:
        # deepSI writes a checkpoint per validation under the home folder; keep it in tmp
        deepSI.fitting.get_checkpoint_dir = lambda: tmp
        try:
            with redirect_stdout(quiet):
                clock.start()
                deepSI.fit(
                    net,
                    train,
                    records("val"),
                    n_its=10**8,
                    val_freq=DEEPSI_VAL_FREQ,
                    loss_fun=loss_fun,
                    val_fun=val_fun,
                )
        finally:
            deepSI.fitting.get_checkpoint_dir = home_dir
    net.load_state_dict(best["state"])
    turns.end("deepsi")
    return wrapped


def noise_floor(ds: Dataset) -> float:
    """Noise variance over output variance (training split), averaged over the outputs."""
    y = np.concatenate([t.y for t in ds.split("train")])
    box = ds.metadata["noise"]["box"]
    half = (np.asarray(box["upper"]) - np.asarray(box["lower"])) / 2
    return float(np.mean(half**2 / 3 / y.var(axis=0)))


def run_turns(
    trainers: Mapping[str, Callable[[TakeTurns, Curve], Any]], slice_s: float
) -> tuple[dict[str, Any], dict[str, Curve]]:
    """Run ``trainers`` (name → ``f(turns, curve)`` returning a model), each in its own thread,
    taking turns; their models and curves."""
    turns = TakeTurns(list(trainers), slice_s)
    curves = {k: Curve() for k in trainers}
    models: dict[str, Any] = {}
    errors: list[BaseException] = []

    def run(key: str) -> None:
        try:
            if torch.get_num_threads() != 1:  # thread_time() would miss the other threads' work
                raise RuntimeError(f"{key}: torch uses {torch.get_num_threads()} threads, not 1")
            models[key] = trainers[key](turns, curves[key])
        except BaseException as exc:  # report it from the main thread
            errors.append(exc)
            turns.end(key)

    threads = [threading.Thread(target=run, args=(k,)) for k in trainers]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    if errors:
        raise errors[0]
    return models, curves


def _seconds(t: float | None) -> str:
    return "not reached" if t is None else f"{t:.0f} s"


def compare(name: str, ds: Dataset, budget: float, slice_s: float) -> str:
    net_options = OURS_OPTIONS[name]

    def contest(budget: float) -> tuple[dict[str, Any], dict[str, Curve]]:
        return run_turns(
            {
                "ours": lambda turns, curve: train_ours(
                    ds, turns, budget, curve, net_options=net_options
                ),
                "deepsi": lambda turns, curve: train_deepsi(ds, turns, budget, curve),
            },
            slice_s,
        )

    contest(WARM_UP)  # untimed: the first use of each layer shape costs a second or so
    load0, cpu0 = os.getloadavg()[0], time.process_time()
    models, curves = contest(budget)
    load1, process_cpu = os.getloadavg()[0], time.process_time() - cpu0

    floor = noise_floor(ds)
    # the level both reached: the worse of the two best validation MSEs
    both = max(c.best for c in curves.values())
    test = ds.split("test")
    labels = {"ours": "Ours (MLP)", "deepsi": "deepSI SUBNET"}
    rows = [
        "| model | parameters | training CPU s (wall s) | validation CPU s (excluded) | "
        "optimiser steps | stopped | best val MSE (norm.) | 100-step MSE, y | "
        "100-step MSE, y_clean | RMSE after n_init, y | RMSE after n_init, y_clean |",
        "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|",
    ]
    for key in ("ours", "deepsi"):
        model, curve = models[key], curves[key]
        ev = evaluate(model, test, horizon=HORIZON)
        clean = ev.clean
        params = sum(p.numel() for p in model.net.parameters())
        stopped = curve.stopped if key == "ours" else "budget"
        rows.append(
            f"| {labels[key]} | {params:,} | {curve.seconds[-1]:.0f} ({curve.wall[-1]:.0f}) | "
            f"{curve.clock.val_cpu:.0f} | {curve.steps:,} | {stopped} | {curve.best:.3g} | "
            f"{ev.measured.rollout_mse:.3g} | "
            f"{clean.rollout_mse if clean else float('nan'):.3g} | {ev.measured.rmse:.3g} | "
            f"{clean.rmse if clean else float('nan'):.3g} |"
        )
    target_rows = [
        "| validation MSE (norm.) | " + " | ".join(labels.values()) + " |",
        "|---|---:|---:|",
    ]
    for level, what in [(m * floor, f"{m:g}× floor") for m in TARGETS] + [(both, "both reached")]:
        target_rows.append(
            f"| {level:.3g} ({what}) | "
            + " | ".join(_seconds(curves[k].time_to(level)) for k in labels)
            + " |"
        )
    curve_rows = ["| training CPU s | " + " | ".join(labels.values()) + " |", "|---:|---:|---:|"]
    for t in np.linspace(0, budget, 7)[1:]:
        best = [
            min((v for s, v in zip(curves[k].seconds, curves[k].val) if s <= t), default=None)
            for k in labels
        ]
        curve_rows.append(
            f"| {t:.0f} | " + " | ".join("—" if b is None else f"{b:.3g}" for b in best) + " |"
        )
    train = ds.split("train")
    options = ", ".join(f"{k}={v}" for k, v in net_options.items()) or "the defaults"
    return "\n\n".join(
        [
            f"### {name}: {len(train)}/{len(ds.split('val'))}/{len(test)} trajectories × "
            f"{train[0].u.shape[0]} samples",
            f"Budget {budget:.0f} s of training CPU each (validation excluded), turns of "
            f"{slice_s:.0f} s wall; Ours (MLP) network options: {options}. Load average "
            f"{load0:.1f} before, {load1:.1f} after (2 cores shared with other jobs); the "
            f"process used {process_cpu:.0f} s of CPU for both trainings (the two clocks and "
            f"validations above account for "
            f"{sum(c.seconds[-1] + c.clock.val_cpu for c in curves.values()):.0f} s). Noise floor "
            f"(normalised) {floor:.3g}; test scores by `canonid.learning.evaluate` "
            f"({ev.n_rollouts} rollouts of {HORIZON} steps; RMSE over {ev.n_scored_samples} "
            "samples after "
            f"n_init = {ev.n_init}).",
            "\n".join(rows),
            "Training CPU time to reach a validation MSE (normalised):",
            "\n".join(target_rows),
            "Best validation MSE so far (normalised) against the training CPU time:",
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
    parser.add_argument("--budget", type=float, help="CPU seconds per contestant and dataset")
    parser.add_argument("--slice", type=float, default=2.0, help="wall seconds per turn")
    parser.add_argument("--only", choices=("tank", "drone2d"), help="one dataset only")
    args = parser.parse_args()
    budget = args.budget or (60.0 if args.size == "quick" else 300.0)
    torch.set_num_threads(1)
    cases = {"tank": ("tank-s0", args.tank), "drone2d": ("drone2d-small", args.drone)}
    parts = [
        "Ours (MLP) (`canonid.learning.fit`, quick profile, ℓ = 10, canonid's default options) "
        "against deepSI 0.4.4's SUBNET (`deepSI.fit`, its defaults, na = nb = ℓ), seed 0, one "
        "torch thread each, taking turns in one process; both scored by "
        "`canonid.learning.evaluate`. "
        "**The budget is CPU time**: each one's training clock is the CPU time of its own "
        "thread, validation passes excluded for both; the wall time of its turns is recorded "
        "beside it. The issue asks for the same wall-clock budget; on a dedicated machine with "
        "one thread each the two coincide, but on this shared machine a wall budget measures "
        "the other jobs (an earlier 60 s wall budget gave each model 8–12 s of CPU). Ours stops "
        "at its first validation past the budget or when the quick profile's 600 epochs are "
        "done, deepSI at its first validation past the budget. See the script's docstring for "
        "the exact protocol. Validation MSEs and the noise floor are in units of the training "
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
