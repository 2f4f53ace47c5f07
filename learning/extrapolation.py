"""Whether Ours (MLP) gets its cubic branch: decided on the training part's largest excursions.

A network fitted inside the training range must also hold beyond it: a test record that drives
the system harder than the training record did (Silverbox's "arrow full") is scored where no
sample trained it. The MLP's SiLU units grow linearly there; the cubic branch of
:class:`~canonid.learning.nets.OursMLP` keeps a cubic growth, which suits a hardening spring
and spoils a saturating tank. Which of the two a record needs is decided by the record itself:

* :func:`held_out_peaks` cuts the *training* trajectories around their largest excursions: a
  sample whose largest ``|y − mean| / std`` over the outputs exceeds :data:`HOLD_OUT` × the
  largest of the record is held out, with the context every validation rollout needs around it
  (ℓ + 0.6 H before, 0.5 H after, ``H`` the validation rollout); what lies between trains
  (pieces of at least ℓ + 1 + the longer of the training and validation rollouts);
* :func:`cubic_test` — when those pieces hold at least :data:`MIN_TRAIN_SHARE` of the
  training samples — trains the plain network and the one with :data:`CUBIC_UNITS` cubic units
  briefly on that split (the window screen's share of the epochs), each from up to
  :data:`CUBIC_SEEDS` seeds, and keeps the branch when its best loss on the held-out peaks over
  those seeds is at most :data:`CUBIC_GAIN` × the plain network's best. One pair of such short
  trainings decides by the seed as much as by the record, unless its ratio is far from the
  threshold (:data:`CUBIC_MARGIN`, :func:`decisive`): then the first pair decides alone. The
  arms are independent: given an executor they train side by side, each as it would alone.
* Records too short to hold out their peaks so (or whose pieces between them hold under
  :data:`MIN_TRAIN_SHARE`) cannot ask the question at all. There the branch is a candidate
  like another: :func:`cubic_test` says so (``fallback``, no training), both networks train
  fully and the validation part keeps the branch by the same rule (:func:`arms_verdict`; the
  training loop, :func:`canonid.learning.training.fit`, trains them). A short training on the
  validation part was tried first and misjudged the overflow tanks (benchmarks/RESULTS.md,
  "Cubic test on validation").

The test part plays no part; the validation part only when the peaks cannot be held out. How
the constants were chosen, on validation only: benchmarks/RESULTS.md, "Extrapolation" (and
"Cubic test on validation" for the records too short for it).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import ShapeError
from canonid.learning.window_screen import SCREEN_FRACTION, screen_options

__all__ = [
    "CUBIC_GAIN",
    "CUBIC_MARGIN",
    "CUBIC_SEEDS",
    "CUBIC_UNITS",
    "HOLD_OUT",
    "MIN_TRAIN_SHARE",
    "CubicTest",
    "HeldOutPeaks",
    "arms_verdict",
    "cubic_test",
    "decisive",
    "held_out_peaks",
    "keeps_cubic",
]

log = logging.getLogger(__name__)
#: samples above this share of the record's largest deviation are held out: the held-out peaks
#: reach up to 1 / 0.7 = 1.43 × above everything that trains
HOLD_OUT = 0.7
#: units of the cubic branch when the test keeps it
CUBIC_UNITS = 16
#: the branch is kept when its best held-out loss is at most this share of the plain network's
CUBIC_GAIN = 0.8
#: each arm trains from up to this many seeds (the run's seed and the next ones) and keeps its
#: best: chosen on the held-out peaks of six systems over 8–16 seeds (benchmarks/RESULTS.md,
#: "Cubic test across seeds")
CUBIC_SEEDS = 3
#: the first pair decides alone when its ratio is this factor beyond the threshold, either side
#: (the tank's pairs differ 4–14×): chosen in the same study, the smallest margin that decides
#: as the best of three seeds does on every system there
CUBIC_MARGIN = 3.0
#: the test runs only when the pieces between the peaks hold at least this share of the
#: training samples (the records of the study that chose the rule kept 44–98 %)
MIN_TRAIN_SHARE = 0.4


@dataclass(frozen=True)
class HeldOutPeaks:
    """The training trajectories cut around their largest excursions.

    Attributes:
        train: the pieces between the held-out peaks.
        val: one trajectory per cluster of held-out samples, with its context.
        threshold: the deviation above which a sample is held out (training standard deviations).
        largest_train, largest_val: the largest deviation of each part.
    """

    train: tuple[Trajectory, ...]
    val: tuple[Trajectory, ...]
    threshold: float
    largest_train: float
    largest_val: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "train_samples": sum(t.T for t in self.train),
            "val_samples": sum(t.T for t in self.val),
            "threshold": self.threshold,
            "largest_train": self.largest_train,
            "largest_val": self.largest_val,
        }


def held_out_peaks(
    trajectories: Sequence[Trajectory], *, window: int, horizon: int, val_horizon: int
) -> HeldOutPeaks:
    """Cut ``trajectories`` into training pieces (each at least ℓ + ``horizon`` + 1 samples) and
    held-out peaks (each at least ℓ + ``val_horizon`` samples); see the module docstring.

    Raises :class:`ShapeError` when either part would be empty (records too short for it).
    """
    y = np.concatenate([t.y for t in trajectories])
    mean, std = y.mean(axis=0), np.where(y.std(axis=0) > 0, y.std(axis=0), 1.0)
    devs = [np.max(np.abs(t.y - mean) / std, axis=1) for t in trajectories]
    threshold = HOLD_OUT * max(float(d.max()) for d in devs)
    before, after = window + math.ceil(0.6 * val_horizon), math.ceil(0.5 * val_horizon)
    train: list[Trajectory] = []
    val: list[Trajectory] = []
    for traj, dev in zip(trajectories, devs, strict=True):
        spans: list[list[int]] = []
        for i in np.flatnonzero(dev > threshold):
            lo, hi = max(int(i) - before, 0), min(int(i) + after + 1, traj.T)
            if spans and lo <= spans[-1][1]:
                spans[-1][1] = hi
            else:
                spans.append([lo, hi])
        val += [_piece(traj, lo, hi) for lo, hi in spans if hi - lo >= window + val_horizon]
        edges = [0, *(e for s in spans for e in s), traj.T]
        train += [
            _piece(traj, lo, hi)
            for lo, hi in zip(edges[::2], edges[1::2], strict=True)
            if hi - lo >= window + horizon + 1
        ]
    if not train or not val:
        raise ShapeError(
            "the records are too short to hold out their largest excursions: "
            f"{len(train)} training piece(s) of ℓ + {horizon} + 1 samples, {len(val)} held-out "
            f"peak(s) of ℓ + {val_horizon}"
        )

    def largest(part: list[Trajectory]) -> float:
        return max(float(np.max(np.abs(t.y - mean) / std)) for t in part)

    return HeldOutPeaks(tuple(train), tuple(val), threshold, largest(train), largest(val))


def _piece(traj: Trajectory, lo: int, hi: int) -> Trajectory:
    return Trajectory(u=traj.u[lo:hi], y=traj.y[lo:hi])


@dataclass(frozen=True)
class CubicTest:
    """What :func:`cubic_test` decided (losses normalised, on the held-out peaks).

    Attributes:
        units: the cubic units chosen (0: the plain network).
        plain_loss, cubic_loss: each arm's best held-out loss over its seeds (``None``: not
            run, or no seed reached a finite loss).
        epochs: the epochs of each short training.
        plain_losses, cubic_losses: each seed's best held-out loss, in the order of ``seeds``
            (``None``: that training failed); empty when the test did not run.
        seeds: the seeds each arm trained from (one when the first pair was decisive).
        reason: why the test did not run (a checkpoint from before it; in runs recorded
            before records too short for it trained the branch beside, that), else ``None``.
        split: :meth:`HeldOutPeaks.to_dict` of the split, when there was one.
        fallback: why the held-out peaks could not decide (``None``: they did); then both
            networks train fully and the validation part decides (:func:`arms_verdict`): the
            losses are then the full runs' best validation losses, ``epochs`` the full budget
            (0 before they ran).

    It holds no timing, so that the model's ``config.json`` stays the same bytes for the same
    seed.
    """

    units: int
    plain_loss: float | None
    cubic_loss: float | None
    epochs: int
    reason: str | None
    split: Mapping[str, Any] | None
    plain_losses: tuple[float | None, ...] = ()
    cubic_losses: tuple[float | None, ...] = ()
    seeds: tuple[int, ...] = ()
    fallback: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            **dataclasses.asdict(self),
            "plain_losses": list(self.plain_losses),
            "cubic_losses": list(self.cubic_losses),
            "seeds": list(self.seeds),
            "gain": CUBIC_GAIN,
            "split": dict(self.split or {}),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CubicTest:
        """Read :meth:`to_dict` back (runs written before the test had seeds read as one)."""
        fields = {f.name for f in dataclasses.fields(cls)}
        kept = {k: v for k, v in data.items() if k in fields}
        for name in ("plain_losses", "cubic_losses", "seeds"):
            kept[name] = tuple(kept.get(name, ()))
        return cls(**kept)

    def summary(self) -> str:
        if self.reason is not None:
            return f"cubic branch: not tested ({self.reason}); the plain network trains"
        verdict = f"{self.units} cubic units" if self.units else "the plain network"
        runs = f"best of {len(self.seeds)} seeds, " if len(self.seeds) > 1 else ""
        if self.fallback is not None:
            return (
                f"cubic branch on the validation part, both networks trained fully "
                f"({self.fallback}): loss {_fmt(self.cubic_loss)} against "
                f"{_fmt(self.plain_loss)} without: {verdict} kept"
            )
        return (
            f"cubic branch on the held-out peaks: loss {_fmt(self.cubic_loss)} against "
            f"{_fmt(self.plain_loss)} without ({runs}{self.epochs} epochs each): {verdict} trains"
        )


def _fmt(loss: float | None) -> str:
    return "-" if loss is None else f"{loss:.3g}"


def keeps_cubic(plain: float | None, cubic: float | None) -> bool:
    """The rule: the branch stays when its held-out loss is at most :data:`CUBIC_GAIN` × the
    plain network's (or the plain one reached no finite loss and it did)."""
    return cubic is not None and (plain is None or cubic <= CUBIC_GAIN * plain)


def cubic_test(
    train: Sequence[Trajectory],
    *,
    window: int,
    options: Any,
    net_options: Mapping[str, Any],
    fit: Callable[..., Any],
    model: str = "mlp",
    executor: Executor | None = None,
) -> CubicTest:
    """Decide the cubic branch on ``train``'s held-out peaks (see the module docstring).

    ``options`` are the full run's :class:`~canonid.learning.training.TrainOptions`
    (compressed here to the window screen's share; the arms train pair by pair from
    ``options.seed`` on, up to :data:`CUBIC_SEEDS` pairs, one when the first is
    :func:`decisive`); ``net_options`` the network's, resolved but for
    ``cubic``; ``fit`` is :func:`canonid.learning.training.fit`, given by it (this module does
    not import its caller). ``executor``: where the arms train, the first pair side by side and
    then the remaining pairs at once (``None``: one after the other in this process); the
    losses are those of the arms trained alone. Records too short for the peaks give the
    plain network with ``fallback`` set and train nothing here (see the module docstring).
    """
    opts = screen_options(options, SCREEN_FRACTION)
    try:
        # training pieces hold the longer of the two rollouts, as in the study that chose this
        longest = max(opts.horizon, opts.rollout_horizon)
        split = held_out_peaks(
            train, window=window, horizon=longest, val_horizon=opts.rollout_horizon
        )
    except ShapeError as exc:
        return CubicTest(0, None, None, 0, None, None, fallback=str(exc))
    share = sum(t.T for t in split.train) / sum(t.T for t in train)
    if share < MIN_TRAIN_SHARE:
        fallback = (
            f"the pieces between the largest excursions hold {share:.0%} of the training "
            f"samples, under {MIN_TRAIN_SHARE:.0%}"
        )
        return CubicTest(0, None, None, 0, None, split.to_dict(), fallback=fallback)

    def pairs(seeds: Sequence[int]) -> list[float | None]:
        """The (plain, cubic) losses of ``seeds``, flat, in order."""
        calls = [
            (fit, split, model, window, opts, net_options, units, seed)
            for seed in seeds
            for units in (0, CUBIC_UNITS)
        ]
        if executor is None:
            return [_short_loss(*call) for call in calls]
        futures = [executor.submit(_short_loss, *call) for call in calls]
        return [future.result() for future in futures]

    losses = pairs([opts.seed])
    if not decisive(losses[0], losses[1]):
        losses += pairs(range(opts.seed + 1, opts.seed + CUBIC_SEEDS))
    plain_losses, cubic_losses = losses[0::2], losses[1::2]
    plain, cubic = _best(plain_losses), _best(cubic_losses)
    return CubicTest(
        CUBIC_UNITS if keeps_cubic(plain, cubic) else 0,
        plain,
        cubic,
        opts.epochs,
        None,
        split.to_dict(),
        plain_losses=tuple(plain_losses),
        cubic_losses=tuple(cubic_losses),
        seeds=tuple(range(opts.seed, opts.seed + len(plain_losses))),
    )


def arms_verdict(
    test: CubicTest, plain: float | None, cubic: float | None, *, seed: int, epochs: int
) -> CubicTest:
    """``test`` (a :attr:`~CubicTest.fallback`) decided by the best validation losses of the
    plain network's and the branch's full runs (``epochs``, from ``seed``), by
    :func:`keeps_cubic`."""
    return dataclasses.replace(
        test,
        epochs=epochs,
        units=CUBIC_UNITS if keeps_cubic(plain, cubic) else 0,
        plain_loss=plain,
        cubic_loss=cubic,
        plain_losses=(plain,),
        cubic_losses=(cubic,),
        seeds=(seed,),
    )


def decisive(plain: float | None, cubic: float | None) -> bool:
    """Whether one pair of short trainings decides alone: its ratio lies beyond
    :data:`CUBIC_MARGIN` × the threshold on either side."""
    if plain is None or cubic is None:
        return False
    ratio = cubic / plain
    return ratio >= CUBIC_GAIN * CUBIC_MARGIN or ratio <= CUBIC_GAIN / CUBIC_MARGIN


def _short_loss(
    fit: Callable[..., Any],
    split: HeldOutPeaks,
    model: str,
    window: int,
    opts: Any,
    net_options: Mapping[str, Any],
    units: int,
    seed: int,
) -> float | None:
    """One short training's best loss on the held-out peaks (``None``: failed or not finite)."""
    try:
        loss = fit(
            split.train,
            split.val,
            model=model,
            window=window,
            options=dataclasses.replace(opts, seed=seed),
            net_options={**net_options, "cubic": units},
        ).best_val_loss
    except (ArithmeticError, RuntimeError, ValueError) as exc:  # a failed short training
        log.warning(
            "cubic test: the network with %d cubic units (seed %d) failed: %s", units, seed, exc
        )
        return None
    return loss if math.isfinite(loss) else None


def _best(losses: Sequence[float | None]) -> float | None:
    """The lowest finite loss of an arm's seeds (``None`` when none is)."""
    finite = [loss for loss in losses if loss is not None]
    return min(finite) if finite else None
