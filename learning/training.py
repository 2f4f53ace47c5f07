"""Output-error training (the paper's loss J(H)), with curriculum, early stopping, resume.

One *epoch* draws ``windows_per_epoch`` random sub-windows, uniformly over every start that
fits the current span ``ℓ + H`` in any training trajectory (start ``s`` of trajectory ``i`` with
``0 ≤ s ≤ T_i − ℓ − H``), and splits them into batches of ``batch_size``: an epoch is
``⌈windows_per_epoch / batch_size⌉`` optimiser steps whatever the number of trajectories, so
the same data as one long record or cut into many experiments get the same budget. On each
sub-window the first ℓ measured samples are the burn-in (``ẑ = z``) and the model predicts the
next ``H`` outputs in open loop; the loss is

    (1/H) Σ_{k=0}^{H−1} α_k ‖y_k − ŷ_k‖²   (normalised units, α_0 = alpha_first = 10, α_k = 1),

averaged over the batch (Masti et al. add their terms). Adam with learning rate ``lr``
(paper: 1e-4), optionally cosine-decayed to ``lr_final`` over the epochs.

Curriculum: the rollout length grows linearly from 1 at epoch 1 to ``horizon`` at epoch
``curriculum_epochs`` (*authors' code*), then stays there.

Validation: the mean squared error (normalised units, averaged over outputs and steps) of
``val_horizon``-step open-loop rollouts after an ℓ-sample measured burn-in, from every
``val_stride``-th start of every validation trajectory — at most ``val_windows`` of them, a
subset drawn once from ``seed`` when there are more, so that a long record keeps validation
bounded. The model kept is the best one on it.
Epoch 0 is the untrained network. Early stopping: once the curriculum is complete, training stops
when the best validation loss is ``patience`` epochs old.

Weight averaging (``ema_decay = d``): after every optimiser step the running average
``w̄ ← d_n w̄ + (1 − d_n) w`` of the network's weights is updated, with ``d_n = min(d, (1 + n) /
(10 + n))`` at step ``n`` so that the first steps do not drag the untrained weights along.
Validation then scores ``w̄`` (training goes on from ``w``), and the model kept is the best
average. The average smooths the last epochs' noise of Adam at a small cost per step.

Checkpoints (``run_dir/checkpoint.pt``, every ``checkpoint_every`` epochs and at the end) hold the
network, the optimiser, the best weights, the history and the states of the torch and numpy
random generators, so a resumed run ends exactly where an uninterrupted one would (same options,
same data, same device).

Recovery: a batch whose loss is not finite (an open-loop rollout that blew up) is not stepped
on; the network goes back to the best weights so far, the optimiser's moments are reset and the
learning rate is halved for the rest of the run. After ``MAX_RECOVERIES`` of them the run stops
as diverged, keeping the best model.

Linear start: a canonical model whose affine path is ``linear="arx"`` starts from the
least-squares ARX fit of the training data (:func:`canonid.learning.linear.least_squares`) with the
nonlinear part's output layer at zero (a ``"skip"`` path starts at zero, the network as built); a
model that is not ``iterative`` (ARX) takes no gradient step at all.

:func:`fit` trains a registered identification model from scratch; :func:`fit_net` is the loop
itself, for a network built by the caller (the reduced model of :mod:`canonid.learning.reduction`
uses it with the full model's normalisation and a per-epoch hook that freezes ``Ĥ``).
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import hashlib
import io
import logging
import math
import pickle
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch

from canonid.kernel.catalog import DEVICE_NAMES, MAX_LR, MAX_WINDOWS_PER_EPOCH
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import CheckpointError, OptionError, ShapeError
from canonid.kernel.io import atomic_write_bytes, guarded
from canonid.learning.data import Normalisation, WindowBank
from canonid.learning.linear import feedthrough_test, initialise_linear
from canonid.learning.model import Model, check_same, load_state
from canonid.learning.nets import NETS, CanonicalModel, SequenceModel, UnknownModelError, build_net
from canonid.learning.nets.base import linear_path
from canonid.learning.presets import net_options as preset_net_options

__all__ = [
    "CHECKPOINT_FILE",
    "EpochReport",
    "FitResult",
    "OptionError",
    "TrainOptions",
    "auto_device",
    "fit",
    "fit_net",
    "flush_subnormal_tensors",
    "flushed_subnormals",
    "network_work",
    "resolve_device",
    "simulation_loss",
    "stored_fit",
    "validation_loss",
]

log = logging.getLogger(__name__)

CHECKPOINT_FILE = "checkpoint.pt"
CHECKPOINT_VERSION = 1
#: options that may change when a run is resumed (the others must match the checkpoint)
RESUMABLE_CHANGES = frozenset({"epochs", "patience", "checkpoint_every", "device"})
#: the smallest positive normal float32: anything nearer zero is subnormal
_FLOAT32_TINY = float(torch.finfo(torch.float32).tiny)
#: what validation scores: short open-loop rollouts, or the free-run simulation of each record
VAL_MEASURES = ("rollout", "simulation")
#: non-finite batches recovered from (best weights back, learning rate halved) before a run stops
MAX_RECOVERIES = 5


@dataclass(frozen=True)
class TrainOptions:
    """Options of :func:`fit` (see the module docstring for their meaning).

    Attributes:
        epochs: number of epochs (paper: 10,000).
        batch_size: sub-windows per batch.
        lr: Adam learning rate (paper: 1e-4).
        lr_final: if set, the learning rate follows a cosine from ``lr`` to ``lr_final``.
        weight_decay: Adam weight decay.
        horizon: final rollout length ``H`` of the training sub-windows.
        curriculum_epochs: epochs over which ``H`` grows from 1 to ``horizon`` (0 or 1: none).
        windows_per_epoch: sub-windows drawn per epoch, over all training trajectories.
        alpha_first: weight α of the first predicted step (paper: 10).
        grad_clip: clip the gradient's global norm to this value (``None``: no clipping).
        ema_decay: if set, validate and keep an exponential moving average of the weights
            with this decay per optimiser step (see the module docstring); ``None``: the weights
            themselves.
        patience: early-stopping patience in epochs (``None``: never stop early).
        val_every: validate every this many epochs (and at the last epoch).
        val_stride: stride of the validation start times.
        val_windows: at most this many validation rollouts (a seeded subset; ``None``: all).
        val_horizon: validation rollout length (default ``horizon``).
        val_measure: ``"rollout"``: the ``val_horizon``-step rollouts above; ``"simulation"``:
            the free-run simulation of every validation record to its end, as the field scores
            (:func:`simulation_loss`; ``val_stride``, ``val_windows`` and ``val_horizon`` then
            play no part).
        val_n_init: with ``"simulation"``, the first scored sample of every validation record
            (the burn-in ends there; default ℓ); a search sets it to its largest window so that
            every candidate is scored on the same samples.
        checkpoint_every: write ``checkpoint.pt`` every this many epochs (needs ``run_dir``).
        seed: seeds the initial weights and the sub-window draws.
        device: ``"auto"`` (CUDA when present and the job is large enough to be faster there:
            :func:`auto_device`), ``"cpu"`` or ``"cuda"``.
    """

    epochs: int = 100
    batch_size: int = 64
    lr: float = 1e-4
    lr_final: float | None = None
    weight_decay: float = 0.0
    horizon: int = 100
    curriculum_epochs: int = 0
    windows_per_epoch: int = 256
    alpha_first: float = 10.0
    grad_clip: float | None = None
    ema_decay: float | None = None
    patience: int | None = None
    val_every: int = 1
    val_stride: int = 1
    val_horizon: int | None = None
    val_windows: int | None = None
    val_measure: Literal["rollout", "simulation"] = "rollout"
    val_n_init: int | None = None
    checkpoint_every: int = 10
    seed: int = 0
    device: str = "auto"

    def __post_init__(self) -> None:
        positive_ints = (
            "epochs",
            "batch_size",
            "horizon",
            "windows_per_epoch",
            "val_every",
            "val_stride",
            "checkpoint_every",
        )
        for key in positive_ints:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise OptionError(f"training option {key} must be an integer >= 1, got {value!r}")
        for key in ("curriculum_epochs", "seed"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise OptionError(f"training option {key} must be an integer >= 0, got {value!r}")
        if self.val_measure not in VAL_MEASURES:
            raise OptionError(
                f"training option val_measure must be one of {', '.join(VAL_MEASURES)}, "
                f"got {self.val_measure!r}"
            )
        for key in ("patience", "val_horizon", "val_windows", "val_n_init"):
            value = getattr(self, key)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1
            ):
                raise OptionError(
                    f"training option {key} must be None or an integer >= 1, got {value!r}"
                )
        for key in ("lr", "lr_final", "grad_clip"):
            value = getattr(self, key)
            if value is not None and not (_real(value) and math.isfinite(value) and value > 0):
                raise OptionError(f"training option {key} must be a positive number, got {value}")
        for key, most in (
            ("lr", MAX_LR),
            ("lr_final", MAX_LR),
            ("windows_per_epoch", MAX_WINDOWS_PER_EPOCH),
        ):
            value = getattr(self, key)
            if value is not None and value > most:
                raise OptionError(f"training option {key} must be at most {most:g}, got {value:g}")
        for key in ("weight_decay", "alpha_first"):
            value = getattr(self, key)
            if not (_real(value) and math.isfinite(value) and value >= 0):
                raise OptionError(f"training option {key} must be >= 0, got {value!r}")
        if self.ema_decay is not None and not (_real(self.ema_decay) and 0 < self.ema_decay < 1):
            raise OptionError(
                f"training option ema_decay must be None or in (0, 1), got {self.ema_decay}"
            )
        if not isinstance(self.device, str) or (
            self.device not in DEVICE_NAMES and not self.device.startswith("cuda:")
        ):
            raise OptionError(f"device must be auto, cpu or cuda, got {self.device!r}")

    @property
    def rollout_horizon(self) -> int:
        """The validation rollout length."""
        return self.val_horizon or self.horizon

    def horizon_at(self, epoch: int) -> int:
        """Training rollout length at ``epoch`` (1-based): the curriculum."""
        c = self.curriculum_epochs
        if c <= 1 or epoch >= c:
            return self.horizon
        return 1 + (self.horizon - 1) * (max(epoch, 1) - 1) // (c - 1)

    def lr_at(self, epoch: int) -> float:
        """Learning rate at ``epoch`` (1-based)."""
        if self.lr_final is None or self.epochs <= 1:
            return self.lr
        frac = (epoch - 1) / (self.epochs - 1)
        return self.lr_final + (self.lr - self.lr_final) * 0.5 * (1 + math.cos(math.pi * frac))

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrainOptions:
        """Build from a mapping; unknown keys raise :class:`OptionError` naming them."""
        known = {f.name for f in dataclasses.fields(cls)}
        if "windows_per_trajectory" in data:
            raise OptionError(
                "training option windows_per_trajectory was replaced by windows_per_epoch "
                "(sub-windows per epoch over all trajectories, so that the budget does not depend "
                "on how the data are cut); this run was made by an older canonid"
            )
        unknown = sorted(set(data) - known)
        if unknown:
            raise OptionError(f"unknown training option(s) {unknown}; known: {sorted(known)}")
        return cls(**data)


def _real(value: Any) -> bool:
    """A number as JSON holds one (a boolean is not), for the checks of a recorded option."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@dataclass(frozen=True)
class EpochReport:
    """What :func:`fit` passes to its callback after each epoch (losses in normalised units)."""

    epoch: int
    epochs: int
    horizon: int
    lr: float
    train_loss: float
    val_loss: float | None
    best_val_loss: float
    best_epoch: int
    seconds: float
    parts: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FitResult:
    """The outcome of :func:`fit`.

    Attributes:
        model: the model with the best validation weights.
        history: one row per epoch (epoch 0 = untrained): ``epoch``, ``horizon``, ``lr``,
            ``train_loss``, ``val_loss`` (``None`` when not validated), ``seconds`` and any
            extra loss terms.
        best_epoch, best_val_loss: where the kept weights come from.
        epochs_run: the last epoch trained.
        stopped: ``"completed"``, ``"early_stopping"``, ``"diverged"``, ``"least_squares"``
            (a model fitted in closed form, with no gradient step) or ``"paused"`` (at
            ``until``, to be resumed).
        search: the :class:`canonid.learning.search.Search` that chose the model's window and
            branch (``canonid.fit`` without them fixed), else ``None``.
        cpu_elsewhere: CPU seconds this fit spent in worker processes (a search's candidates),
            which the calling process's own clock does not count.
    """

    model: Model
    history: list[dict[str, Any]]
    best_epoch: int
    best_val_loss: float
    epochs_run: int
    stopped: str
    search: Any = None
    cpu_elsewhere: float = 0.0


#: ``device="auto"`` trains on CUDA only when one rollout step of the job takes at least this
#: many multiply-adds (:func:`network_work`): below it one GPU is slower than the CPU, above it
#: faster than 1, 4 or 16 CPU threads
AUTO_CUDA_WORK = 4_900_000


def network_work(net: torch.nn.Module, batch: int, candidates: int = 1) -> int:
    """Multiply-adds of one rollout step: ``candidates × batch ×`` the entries of the
    network's weight matrices (biases and gains aside; each weight is used once a step)."""
    weights = sum(p.numel() for p in net.parameters() if p.dim() >= 2)
    return candidates * batch * weights


def auto_device(work: int, *, cuda_available: bool) -> str:
    """The device ``auto`` picks for a job of ``work`` multiply-adds per rollout step
    (:func:`network_work`): CUDA when there is one and ``work`` reaches
    :data:`AUTO_CUDA_WORK`, else the CPU."""
    return "cuda" if cuda_available and work >= AUTO_CUDA_WORK else "cpu"


def resolve_device(name: str, *, work: int | None = None) -> torch.device:
    """``auto`` → :func:`auto_device` for ``work`` (CUDA when present if ``work`` is not
    given); ``cuda`` without a GPU raises OptionError."""
    if name == "auto":
        cuda = torch.cuda.is_available()
        if work is None:
            return torch.device("cuda" if cuda else "cpu")
        return torch.device(auto_device(work, cuda_available=cuda))
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise OptionError(f"device {name!r} requested but CUDA is not available here")
    return torch.device(name)


def data_fingerprint(*groups: Sequence[Trajectory]) -> str:
    """SHA-256 of the float64 bytes of every ``u`` and ``y`` (to match a run with its data)."""
    h = hashlib.sha256()
    for group in groups:
        h.update(f"group:{len(group)}".encode())
        for tr in group:
            for arr in (tr.u, tr.y):
                h.update(str(arr.shape).encode())
                h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def validation_loss(
    net: SequenceModel, bank: WindowBank, starts: np.ndarray, horizon: int, *, batch: int = 2048
) -> float:
    """Mean squared rollout error (normalised, over windows, steps and outputs)."""
    ell = net.window
    total, count = 0.0, 0
    was_training = net.training
    net.eval()
    try:
        with torch.no_grad():
            for lo in range(0, len(starts), batch):
                u, y = bank.gather(starts[lo : lo + batch], ell + horizon)
                pred = net.rollout(u[:, :ell], y[:, :ell], u[:, ell:])
                total += float((pred - y[:, ell:]).pow(2).sum())
                count += pred.numel()
    finally:
        net.train(was_training)
    return total / count


def simulation_loss(net: SequenceModel, bank: WindowBank, n_init: int) -> float:
    """Mean squared error of the free-run simulation of every record in ``bank`` (normalised
    units, over the outputs and the samples ``n_init … T−1`` of every record, concatenated):
    burn in on the measured samples ``n_init − ℓ … n_init − 1``, then simulate in open loop to
    the record's end, as the field scores a model. Records of at most ``n_init`` samples are left
    out; a simulation that is not finite scores ``inf``."""
    ell = net.window
    by_length: dict[int, list[int]] = {}
    for i, length in enumerate(bank.lengths):
        if length > n_init:
            by_length.setdefault(length, []).append(i)
    total, count = 0.0, 0
    was_training = net.training
    net.eval()
    try:
        with torch.no_grad():
            for length, records in by_length.items():
                starts = np.array([[i, n_init - ell] for i in records], dtype=np.int64)
                u, y = bank.gather(starts, length - (n_init - ell))
                pred = net.rollout(u[:, :ell], y[:, :ell], u[:, ell:])
                total += float((pred - y[:, ell:]).pow(2).sum())
                count += pred.numel()
    finally:
        net.train(was_training)
    loss = total / count if count else math.inf
    return loss if math.isfinite(loss) else math.inf


def _training_pair(
    train: Sequence[Any], val: Sequence[Any]
) -> tuple[tuple[Trajectory, ...], tuple[Trajectory, ...]]:
    """Training and validation data as trajectories (converted once), with the same signals."""
    if val is None:
        raise OptionError(
            "val: validation trajectories are required (training keeps the epoch that scores "
            "best on them); cut some off the training data, e.g. "
            "canonid.datagen.loaders.split_train_val(dataset)"
        )
    train_t = as_trajectories(train, what="training data")
    val_t = as_trajectories(val, what="validation data")
    if (val_t[0].n_u, val_t[0].n_y) != (train_t[0].n_u, train_t[0].n_y):
        raise ShapeError(
            f"validation data have n_u={val_t[0].n_u}, n_y={val_t[0].n_y}; "
            f"training data have n_u={train_t[0].n_u}, n_y={train_t[0].n_y}"
        )
    return train_t, val_t


def _check_rollout_lengths(
    train: Sequence[Trajectory], val: Sequence[Trajectory], window: int, horizon: int
) -> None:
    """Refuse data too short for window ℓ, or for ℓ plus the training rollout ``horizon``."""
    _check_lengths(train, window, "training data")
    _check_lengths(val, window, "validation data")
    longest = max(tr.T for tr in train)
    if longest < window + horizon:
        raise ShapeError(
            f"window ℓ = {window} plus training rollout horizon {horizon} needs "
            f"trajectories of at least {window + horizon} samples; the longest training "
            f"trajectory has {longest} (lower the horizon)"
        )


def _check_simulated(val: Sequence[Trajectory], window: int, n_init: int | None) -> None:
    """Refuse validation data whose records all end before the first scored sample."""
    first = window if n_init is None else n_init
    if n_init is not None and n_init < window:
        raise OptionError(f"training option val_n_init ({n_init}) is below the window ℓ = {window}")
    longest = max(tr.T for tr in val)
    if longest <= first:
        raise ShapeError(
            f"validation data: the longest record has {longest} samples; its simulation is "
            f"scored from sample {first} on (the burn-in), so it needs at least {first + 1}"
        )


def _check_lengths(trajectories: Sequence[Trajectory], window: int, what: str) -> None:
    for i, tr in enumerate(trajectories):
        if tr.T < window + 1:
            raise ShapeError(
                f"{what}, trajectory {i}: has {tr.T} samples; window ℓ = {window} needs at least "
                f"ℓ + 1 = {window + 1} (ℓ to burn in, one to predict)"
            )


@contextlib.contextmanager
def flushed_subnormals(
    device: torch.device, weight_decay: float, *, always: bool = False
) -> Iterator[None]:
    """Flush float32 subnormals to zero in CPU arithmetic while a run with weight decay (or any
    run, ``always``) trains.

    Weight decay pulls many weights into the subnormal range, where a CPU computes several times
    slower; without it the defaults' runs hold none,
    so they are left exactly as they are. A reduction's auto-encoder falls there without weight
    decay: its training flushes ``always``.
    Afterwards flushing is off again (torch's default).
    """
    wanted = always or bool(weight_decay)
    if device.type != "cpu" or not wanted or not torch.set_flush_denormal(True):
        yield
        return
    try:
        yield
    finally:
        torch.set_flush_denormal(False)


def flush_subnormal_tensors(tensors: Iterable[Any]) -> None:
    """Zero the float32 subnormal entries of ``tensors`` in place. :func:`flushed_subnormals`
    flushes the arithmetic of the calling thread only (the CPU's flag is per thread), so what
    torch's other CPU threads computed is flushed here, after each optimiser step."""
    with torch.no_grad():
        for t in tensors:
            if isinstance(t, torch.Tensor) and t.is_floating_point():
                t.masked_fill_(t.abs() < _FLOAT32_TINY, 0.0)


def _fit_validation_horizon(
    opts: TrainOptions, window: int, longest: int, *, warn: bool = True
) -> TrainOptions:
    """``opts`` with the validation rollout cut to what the longest validation trajectory holds
    after its ℓ-sample burn-in, with a warning (unless ``warn`` is false: said already); the
    model's recorded options keep the cut."""
    fits = longest - window
    if fits >= opts.rollout_horizon:
        return opts
    if warn:
        log.warning(
            "validation rollouts cut from %d to %d steps: the longest validation trajectory has "
            "%d samples, window ℓ = %d",
            opts.rollout_horizon,
            fits,
            longest,
            window,
        )
    return dataclasses.replace(opts, val_horizon=fits)


def _draw_windows(
    rng: np.random.Generator, lengths: Sequence[int], span: int, k: int
) -> np.ndarray:
    """``k`` ``(trajectory, start)`` pairs, uniform over every start that fits ``span``."""
    fits = np.array([max(T - span + 1, 0) for T in lengths], dtype=np.int64)
    ends = np.cumsum(fits)
    flat = rng.integers(0, ends[-1], size=k)
    traj = np.searchsorted(ends, flat, side="right")
    starts = flat - (ends[traj] - fits[traj])
    return np.stack([traj, starts], axis=1)


def _validation_starts(bank: WindowBank, span: int, opts: TrainOptions) -> np.ndarray:
    """Every ``val_stride``-th start, or a seeded subset of ``val_windows`` of them (in order)."""
    starts = bank.starts(span, stride=opts.val_stride)
    if opts.val_windows is None or len(starts) <= opts.val_windows:
        return starts
    pick = np.random.default_rng([opts.seed, 1]).choice(len(starts), opts.val_windows, False)
    return starts[np.sort(pick)]


class _Run:
    """The mutable state of one training run and its steps (used by :func:`fit` only)."""

    def __init__(
        self,
        net: SequenceModel,
        opts: TrainOptions,
        train_bank: WindowBank,
        val_bank: WindowBank,
        identity: dict[str, Any],
        before_epoch: Callable[[SequenceModel, int], None] | None = None,
        flush: bool = False,
    ) -> None:
        self.net, self.opts, self.identity = net, opts, identity
        self.before_epoch = before_epoch
        self.train_bank, self.val_bank = train_bank, val_bank
        self.val_horizon = opts.rollout_horizon
        self.val_n_init = opts.val_n_init or net.window
        if opts.val_measure == "simulation":
            self.val_starts = np.zeros((0, 2), dtype=np.int64)
        else:
            self.val_starts = _validation_starts(val_bank, net.window + self.val_horizon, opts)
        self.optimiser = torch.optim.Adam(
            net.parameters(), lr=opts.lr, weight_decay=float(opts.weight_decay)
        )
        # flushing on a CPU (:func:`fit_net`): subnormal weights and moments are zeroed after
        # every step
        self.flush = flush and all(p.device.type == "cpu" for p in net.parameters())
        self.rng = np.random.default_rng(opts.seed)
        self.history: list[dict[str, Any]] = []
        self.best: dict[str, torch.Tensor] = {}
        self.best_val, self.best_epoch, self.epoch = math.inf, 0, 0
        # the weight average (ema_decay), and the number of steps it has seen
        self.ema: dict[str, torch.Tensor] | None = None
        self.ema_steps = 0
        # the learning-rate factor left by recoveries from non-finite losses, and their count
        self.lr_scale, self.recoveries = 1.0, 0
        if opts.ema_decay is not None:
            self.ema = {k: v.detach().clone() for k, v in net.named_parameters()}

    # ---------------------------------------------------------------- state
    def start(self) -> None:
        """Epoch 0: the untrained network is the first candidate."""
        v0 = self.validate()
        self.history = [
            {
                "epoch": 0,
                "horizon": 0,
                "lr": 0.0,
                "train_loss": None,
                "val_loss": v0,
                "seconds": 0.0,
            }
        ]
        self.best = copy.deepcopy(self.net.state_dict())
        self.best_val, self.best_epoch, self.epoch = v0, 0, 0

    def save(self, path: Path) -> None:
        payload = {
            "version": CHECKPOINT_VERSION,
            "identity": self.identity,
            "epoch": self.epoch,
            "net": _to_cpu(self.net.state_dict()),
            "optimiser": _to_cpu(self.optimiser.state_dict()),
            "best_state": _to_cpu(self.best),
            "best_val": self.best_val,
            "best_epoch": self.best_epoch,
            "history": self.history,
            "numpy_rng": _rng_state(self.rng.bit_generator.state, encode=True),
            "torch_rng": torch.get_rng_state(),
            "ema": None if self.ema is None else _to_cpu(self.ema),
            "ema_steps": self.ema_steps,
            "lr_scale": self.lr_scale,
            "recoveries": self.recoveries,
        }
        buf = io.BytesIO()
        torch.save(payload, buf)
        atomic_write_bytes(path, buf.getvalue())

    def restore(self, path: Path) -> None:
        state = _load_checkpoint(path, self.identity)
        device = next(self.net.parameters()).device
        load_state(self.net, state["net"], where=str(path))
        self.optimiser.load_state_dict(state["optimiser"])
        self.rng.bit_generator.state = _rng_state(state["numpy_rng"], encode=False)
        torch.set_rng_state(state["torch_rng"])
        self.history = list(state["history"])
        self.best = {k: v.to(device) for k, v in state["best_state"].items()}
        self.best_val, self.best_epoch = state["best_val"], state["best_epoch"]
        self.epoch = state["epoch"]
        if self.ema is not None:
            self.ema = {k: v.to(device) for k, v in state["ema"].items()}
            self.ema_steps = int(state["ema_steps"])
        self.lr_scale = float(state.get("lr_scale", 1.0))
        self.recoveries = int(state.get("recoveries", 0))

    # ---------------------------------------------------------------- steps
    def _measure(self) -> float:
        """The validation loss of the network's current weights (``opts.val_measure``)."""
        if self.opts.val_measure == "simulation":
            return simulation_loss(self.net, self.val_bank, self.val_n_init)
        return validation_loss(self.net, self.val_bank, self.val_starts, self.val_horizon)

    def validate(self) -> float:
        """The validation loss of the weights that would be kept (the average, if any)."""
        if self.ema is None:
            return self._measure()
        params = dict(self.net.named_parameters())
        current = {k: p.detach().clone() for k, p in params.items()}
        try:
            with torch.no_grad():
                for k, p in params.items():
                    p.copy_(self.ema[k])
            return self._measure()
        finally:
            with torch.no_grad():
                for k, p in params.items():
                    p.copy_(current[k])

    def kept_state(self) -> dict[str, torch.Tensor]:
        """A copy of the weights that validation scores: the network's, or the average's."""
        state = copy.deepcopy(self.net.state_dict())
        if self.ema is not None:
            state.update({k: v.clone() for k, v in self.ema.items()})
        return state

    def update_average(self) -> None:
        if self.ema is None:
            return
        assert self.opts.ema_decay is not None
        n = self.ema_steps
        decay = min(self.opts.ema_decay, (1 + n) / (10 + n))
        with torch.no_grad():
            for k, p in self.net.named_parameters():
                self.ema[k].lerp_(p.detach(), 1.0 - decay)
        self.ema_steps = n + 1

    def recover(self, epoch: int) -> bool:
        """After a non-finite loss: back to the best weights with fresh optimiser moments and
        half the learning rate; ``False`` once :data:`MAX_RECOVERIES` are spent."""
        if self.recoveries >= MAX_RECOVERIES:
            return False
        self.recoveries += 1
        self.lr_scale *= 0.5
        load_state(self.net, self.best, where="best weights")
        self.optimiser.state.clear()
        if self.ema is not None:
            self.ema = {k: v.detach().clone() for k, v in self.net.named_parameters()}
        for group in self.optimiser.param_groups:
            group["lr"] = self.opts.lr_at(epoch) * self.lr_scale
        log.warning(
            "epoch %d: a training loss is not finite; back to the best weights (epoch %d) with "
            "the learning rate halved (recovery %d of %d)",
            epoch,
            self.best_epoch,
            self.recoveries,
            MAX_RECOVERIES,
        )
        return True

    def train_epoch(self, epoch: int) -> dict[str, Any] | None:
        """One epoch; its history row, or ``None`` once a non-finite loss cannot be recovered
        from (see :meth:`recover`)."""
        opts, net, ell = self.opts, self.net, self.net.window
        t0 = time.perf_counter()
        if self.before_epoch is not None:
            self.before_epoch(net, epoch)
        horizon, lr = opts.horizon_at(epoch), opts.lr_at(epoch) * self.lr_scale
        for group in self.optimiser.param_groups:
            group["lr"] = lr
        draws = _draw_windows(
            self.rng, self.train_bank.lengths, ell + horizon, opts.windows_per_epoch
        )
        losses: list[float] = []
        parts_sum: dict[str, float] = {}
        net.train()
        for lo in range(0, len(draws), opts.batch_size):
            u, y = self.train_bank.gather(draws[lo : lo + opts.batch_size], ell + horizon)
            loss, parts = net.training_loss(u, y, alpha_first=opts.alpha_first)
            if not torch.isfinite(loss):
                if not self.recover(epoch):
                    return None
                lr = opts.lr_at(epoch) * self.lr_scale
                continue
            self.optimiser.zero_grad(set_to_none=True)
            loss.backward()
            if opts.grad_clip is not None:
                torch.nn.utils.clip_grad_norm_(net.parameters(), opts.grad_clip)
            self.optimiser.step()
            if self.flush:
                state = self.optimiser.state.values()
                flush_subnormal_tensors(
                    [*net.parameters(), *(t for st in state for t in st.values())]
                )
            self.update_average()
            losses.append(float(loss.detach()))
            for key, value in parts.items():
                parts_sum[key] = parts_sum.get(key, 0.0) + value
        val_loss = None
        if epoch % opts.val_every == 0 or epoch == opts.epochs:
            val_loss = self.validate()
            if not math.isfinite(val_loss):
                val_loss = None
            elif val_loss < self.best_val:
                self.best_val, self.best_epoch = val_loss, epoch
                self.best = self.kept_state()
        self.epoch = epoch
        row = {
            "epoch": epoch,
            "horizon": horizon,
            "lr": lr,
            "train_loss": float(np.mean(losses)) if losses else math.nan,
            "val_loss": val_loss,
            "seconds": time.perf_counter() - t0,
            **{
                f"train_{k}": v / len(losses)
                for k, v in parts_sum.items()
                if k != "output_error" and losses
            },
        }
        self.history.append(row)
        return row

    def report(self, row: Mapping[str, Any]) -> EpochReport:
        return EpochReport(
            epoch=row["epoch"],
            epochs=self.opts.epochs,
            horizon=row["horizon"],
            lr=row["lr"],
            train_loss=row["train_loss"],
            val_loss=row["val_loss"],
            best_val_loss=self.best_val,
            best_epoch=self.best_epoch,
            seconds=row["seconds"],
            parts={
                k[len("train_") :]: v
                for k, v in row.items()
                if k.startswith("train_") and k != "train_loss"
            },
        )

    def should_stop_early(self) -> bool:
        opts, epoch = self.opts, self.epoch
        return (
            opts.patience is not None
            and epoch >= max(opts.curriculum_epochs, 1)
            and epoch - max(self.best_epoch, opts.curriculum_epochs) >= opts.patience
        )


def fit(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    model: str = "mlp",
    window: int,
    options: TrainOptions | None = None,
    net_options: Mapping[str, Any] | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    callback: Callable[[EpochReport], None] | None = None,
    info: Mapping[str, Any] | None = None,
    until: int | None = None,
) -> FitResult:
    """Train model ``model`` with window ``window`` by output error.

    Args:
        train, val: trajectories in physical units (:class:`~canonid.kernel.dataset.Trajectory`,
            or any objects with ``.u``, ``.y``: they are converted once by
            :func:`~canonid.kernel.dataset.as_trajectories`). Normalisation statistics come from
            ``train`` only.
        model: a registry name (:func:`canonid.learning.nets.model_names`).
        window: ℓ.
        options: :class:`TrainOptions` (defaults if ``None``).
        net_options: constructor arguments of the network (sizes, ``feedthrough``,
            ``residual``, ``activation``, ``linear``, ``cubic``) over the model's defaults
            (:data:`canonid.learning.presets.DEFAULT_NET_OPTIONS`); ``feedthrough="auto"``
            decides on validation (:func:`canonid.learning.linear.feedthrough_test`), recorded
            in the model's info; ``cubic="auto"`` trains the plain network (whether the branch
            pays is the search's question: :func:`canonid.fit`, ``canonid train``).
        run_dir: where the model and ``checkpoint.pt`` are written (nothing is written if
            ``None``).
        resume: continue from ``run_dir/checkpoint.pt``; the model, its configuration, the
            data and the options (but ``epochs``, ``patience``, ``checkpoint_every``,
            ``device``) must match, or :class:`CheckpointError` names what differs.
        callback: called with an :class:`EpochReport` after every epoch.
        info: extra JSON facts saved in the model's ``config.json``.
        until: pause after this epoch (see :func:`fit_net`).

    If training is interrupted (an exception, Ctrl-C), the best model so far is still written
    to ``run_dir`` before the exception propagates.
    """
    if model not in NETS:
        raise UnknownModelError(f"unknown model {model!r}; expected one of {list(NETS)}")
    train = as_trajectories(train, what="training data")
    options_all = preset_net_options(model, net_options)
    if options_all.get("cubic") == "auto":  # the branch is the search's to choose
        options_all = {**options_all, "cubic": 0}
    if options_all.get("feedthrough") == "auto":  # decided on validation by the linear path
        train, val = _training_pair(train, val)
        test = feedthrough_test(train, val, Normalisation.fit(train), window=window)
        options_all = {**options_all, "feedthrough": test.feedthrough}
        info = {**dict(info or {}), "feedthrough_test": test.to_dict()}

    def build(norm: Normalisation) -> SequenceModel:
        net = build_net(model, window=window, n_u=norm.n_u, n_y=norm.n_y, **options_all)
        net.residual_scale.copy_(torch.as_tensor(norm.dy_std / norm.y_std))
        if isinstance(net, CanonicalModel) and net.linear == "arx":
            initialise_linear(net, train, norm)
        return net

    return fit_net(
        build,
        train,
        val,
        window=window,
        options=options,
        run_dir=run_dir,
        resume=resume,
        callback=callback,
        info=info,
        until=until,
    )


def fit_net(
    build: Callable[[Normalisation], SequenceModel],
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    window: int,
    norm: Normalisation | None = None,
    options: TrainOptions | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    callback: Callable[[EpochReport], None] | None = None,
    info: Mapping[str, Any] | None = None,
    identity: Mapping[str, Any] | None = None,
    before_epoch: Callable[[SequenceModel, int], None] | None = None,
    flush: bool = False,
    until: int | None = None,
) -> FitResult:
    """The training loop of :func:`fit` for a network built by the caller.

    Args:
        build: called once as ``build(norm)``, under ``torch.manual_seed(options.seed)``, to
            make the network (window ``window``, the data's ``n_u``, ``n_y``); its
            :meth:`~canonid.learning.nets.SequenceModel.training_loss` is the loss minimised.
        train, val, window, options, run_dir, resume, callback, info: as for :func:`fit`.
        norm: the normalisation to train under (default: fitted on ``train``).
        identity: extra JSON facts that a resumed run must match (saved in the checkpoint).
        before_epoch: called as ``before_epoch(net, epoch)`` before each epoch (1-based), also
            after a resume; it must depend on nothing but its arguments.
        flush: on a CPU, flush float32 subnormals to zero whatever the weight decay
            (:func:`flushed_subnormals`).
        until: pause after this epoch (``stopped="paused"``, the checkpoint written): the
            schedule stays that of ``options.epochs``, so that resuming with a later ``until``
            trains exactly what one uninterrupted run would (a search's rungs).
    """
    opts = options or TrainOptions()
    train, val = _training_pair(train, val)
    n_u, n_y = train[0].n_u, train[0].n_y
    if norm is not None and (norm.n_u, norm.n_y) != (n_u, n_y):
        raise ShapeError(
            f"the normalisation is for n_u={norm.n_u}, n_y={norm.n_y}; the training data have "
            f"n_u={n_u}, n_y={n_y}"
        )
    _check_rollout_lengths(train, val, window, opts.horizon)
    if opts.val_measure == "simulation":
        _check_simulated(val, window, opts.val_n_init)
    else:
        opts = _fit_validation_horizon(opts, window, max(tr.T for tr in val))
    flush = flush or bool(float(opts.weight_decay))  # weight decay makes subnormals: flushed
    run_path = Path(run_dir) if run_dir is not None else None
    if resume and run_path is None:
        raise CheckpointError("resume=True needs the run_dir holding checkpoint.pt")
    resolve_device(opts.device)  # "cuda" without a GPU fails before any work
    norm = norm if norm is not None else Normalisation.fit(train)
    fingerprint = data_fingerprint(train, val)
    on_gpu = opts.device != "cpu" and torch.cuda.is_available()
    gpu = (torch.device(opts.device).index or 0) if opts.device.startswith("cuda") else 0

    with torch.random.fork_rng(devices=[gpu] if on_gpu else []):
        torch.manual_seed(opts.seed)
        net = build(norm)
        device = resolve_device(opts.device, work=network_work(net, opts.batch_size))
        if net.window != window:
            raise ShapeError(f"the network has window {net.window}, the data were cut for {window}")
        net.to(device)
        identity_all = {
            "model": net.name,
            "net": net.config(),
            "data": fingerprint,
            "options": {k: v for k, v in opts.to_dict().items() if k not in RESUMABLE_CHANGES},
            "extra": dict(identity or {}),
        }
        state = _Run(
            net,
            opts,
            WindowBank(train, norm, device=device),
            WindowBank(val, norm, device=device),
            identity_all,
            before_epoch,
            flush=flush,
        )
        if resume:
            assert run_path is not None
            state.restore(run_path / CHECKPOINT_FILE)
        else:
            state.start()
            if run_path is not None and not net.iterative:
                state.save(run_path / CHECKPOINT_FILE)
        stopped = "completed" if net.iterative else "least_squares"
        # a run resumed after it stopped early trains no further epoch: it ended there
        ended = resume and net.iterative and state.should_stop_early()
        if ended:
            stopped = "early_stopping"
        try:
            with flushed_subnormals(device, float(opts.weight_decay), always=flush):
                last = state.epoch if ended else (opts.epochs if net.iterative else 0)
                if until is not None and not ended and until < last:
                    last = max(until, state.epoch)
                    stopped = "paused"
                for epoch in range(state.epoch + 1, last + 1):
                    row = state.train_epoch(epoch)
                    if row is None:
                        stopped = "diverged"
                        log.warning(
                            "epoch %d: the training loss is not finite; stopping and keeping "
                            "the best model (epoch %d)",
                            epoch,
                            state.best_epoch,
                        )
                        break
                    if callback is not None:
                        callback(state.report(row))
                    if state.should_stop_early():
                        stopped = "early_stopping"
                    end = stopped not in ("completed", "paused") or epoch == last
                    if run_path is not None and (end or epoch % opts.checkpoint_every == 0):
                        state.save(run_path / CHECKPOINT_FILE)
                    if stopped not in ("completed", "paused"):
                        break
        finally:
            # interrupted or not, the model kept is the best one seen
            load_state(net, state.best, where="best weights")
            net.to("cpu").eval()
            result = Model(
                net,
                norm,
                info={
                    **dict(info or {}),
                    "training": {
                        "options": opts.to_dict(),
                        "device": device.type,  # what "auto" resolved to
                        "best_epoch": state.best_epoch,
                        "best_val_loss": state.best_val,
                        "data_sha256": fingerprint,
                    },
                },
            )
            if run_path is not None:
                result.save(run_path)
    return FitResult(
        model=result,
        history=state.history,
        best_epoch=state.best_epoch,
        best_val_loss=state.best_val,
        epochs_run=state.epoch,
        stopped=stopped,
    )


def stored_fit(run_dir: str | Path, *, stopped: str) -> FitResult:
    """The :class:`FitResult` of the run stored in ``run_dir`` (its model and checkpoint), as
    :func:`fit` returned it when the run ended (``stopped``: how it ended)."""
    state = _read_checkpoint(Path(run_dir) / CHECKPOINT_FILE)
    return FitResult(
        model=Model.load(run_dir),
        history=list(state["history"]),
        best_epoch=int(state["best_epoch"]),
        best_val_loss=float(state["best_val"]),
        epochs_run=int(state["epoch"]),
        stopped=stopped,
    )


def _to_cpu(obj: Any) -> Any:
    if isinstance(obj, torch.Tensor):
        return obj.detach().cpu()
    if isinstance(obj, dict):
        return {k: _to_cpu(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_to_cpu(v) for v in obj]
    return obj


def _rng_state(state: Mapping[str, Any], *, encode: bool) -> dict[str, Any]:
    """numpy's bit-generator state with its 128-bit integers as decimal strings (``encode``),
    so that ``torch.load(weights_only=True)`` reads it back, or the reverse."""

    def convert(value: Any) -> Any:
        if isinstance(value, Mapping):
            return _rng_state(value, encode=encode)
        if encode and isinstance(value, int):
            return str(value)
        if not encode and isinstance(value, str) and value.lstrip("-").isdigit():
            return int(value)
        return value

    return {k: convert(v) for k, v in state.items()}


#: training options newer than some checkpoints, with the value those runs trained with
_ADDED_OPTIONS = {"val_measure": "rollout", "val_n_init": None}


def _load_checkpoint(path: Path, identity: Mapping[str, Any]) -> dict[str, Any]:
    state = _read_checkpoint(path)
    found = state["identity"]
    check_same(
        {"model": found.get("model"), "data": found.get("data")},
        {"model": identity["model"], "data": identity["data"]},
        what=f"checkpoint {path} (model / training data)",
    )
    net = dict(found.get("net", {}))
    if isinstance(net.get("linear"), bool):  # written before the linear skip: True / False
        net["linear"] = linear_path(net["linear"])
    check_same(net, identity["net"], what=f"checkpoint {path} (network)")
    # options added since a checkpoint was written hold what that checkpoint's run did
    options = {**_ADDED_OPTIONS, **found.get("options", {})}
    check_same(options, identity["options"], what=f"checkpoint {path} (training options)")
    check_same(found.get("extra", {}), identity["extra"], what=f"checkpoint {path}")
    return state


def _read_checkpoint(path: Path) -> dict[str, Any]:
    """A canonid training checkpoint (tensors and plain data only), or :class:`CheckpointError`
    naming what is wrong with the file."""
    if not guarded(path).is_file():
        raise CheckpointError(f"no checkpoint to resume from: {path} does not exist")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:  # torch's advice to unpickle is wrong for user files
        raise CheckpointError(
            f"cannot read checkpoint {path}: it holds Python objects besides tensors, which "
            "canonid never unpickles (a file not written by canonid, or tampered with)"
        ) from exc
    except Exception as exc:  # torch raises several types for corrupt files; its first line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CheckpointError(
            f"cannot read checkpoint {path}: corrupt or truncated ({first})"
        ) from exc
    if not isinstance(state, dict) or state.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path} is not a canonid training checkpoint (version)")
    if not isinstance(state.get("identity"), Mapping):
        raise CheckpointError(f"{path} is not a canonid training checkpoint (no identity)")
    return state
