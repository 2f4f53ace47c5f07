"""Output-error training (SPEC §5, paper eq. J(H)), with curriculum, early stopping, resume.

One *epoch* draws ``windows_per_trajectory`` random sub-windows from every training trajectory
long enough for the current span ``ℓ + H`` (start uniform over ``0 … T − ℓ − H``), shuffles them and
splits them into batches of ``batch_size``. On each sub-window the first ℓ measured samples are the
burn-in (``ẑ = z``) and the model predicts the next ``H`` outputs in open loop; the loss is

    (1/H) Σ_{k=0}^{H−1} α_k ‖y_k − ŷ_k‖²   (normalised units, α_0 = alpha_first = 10, α_k = 1),

averaged over the batch (Masti et al. add their terms). Adam with learning rate ``lr``
(paper: 1e-4), optionally cosine-decayed to ``lr_final`` over the epochs.

Curriculum: the rollout length grows linearly from 1 at epoch 1 to ``horizon`` at epoch
``curriculum_epochs`` (*authors' code*), then stays there.

Validation: the mean squared error (normalised units, averaged over outputs and steps) of
``val_horizon``-step open-loop rollouts after an ℓ-sample measured burn-in, from every
``val_stride``-th start of every validation trajectory. The model kept is the best one on it.
Epoch 0 is the untrained network. Early stopping: once the curriculum is complete, training stops
when the best validation loss is ``patience`` epochs old.

Checkpoints (``run_dir/checkpoint.pt``, every ``checkpoint_every`` epochs and at the end) hold the
network, the optimiser, the best weights, the history and the states of the torch and numpy
random generators, so a resumed run ends exactly where an uninterrupted one would (same options,
same data, same device). A non-finite loss stops training and keeps the best model.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import io
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from learning.data import Normalisation, Series, WindowBank, as_series
from learning.model import Model, check_same, load_state
from learning.nets import SequenceModel, build_net
from models.errors import CanonidError, CheckpointError, ShapeError
from models.io import atomic_write_bytes

__all__ = [
    "CHECKPOINT_FILE",
    "EpochReport",
    "FitResult",
    "OptionError",
    "TrainOptions",
    "fit",
    "resolve_device",
    "validation_loss",
]

log = logging.getLogger(__name__)

CHECKPOINT_FILE = "checkpoint.pt"
CHECKPOINT_VERSION = 1
#: options that may change when a run is resumed (the others must match the checkpoint)
RESUMABLE_CHANGES = frozenset({"epochs", "patience", "checkpoint_every", "device"})


class OptionError(CanonidError, ValueError):
    """A training option is out of range, or the requested device is not available."""


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
        windows_per_trajectory: sub-windows drawn from each training trajectory per epoch.
        alpha_first: weight α of the first predicted step (paper: 10).
        grad_clip: clip the gradient's global norm to this value (``None``: no clipping).
        patience: early-stopping patience in epochs (``None``: never stop early).
        val_every: validate every this many epochs (and at the last epoch).
        val_stride: stride of the validation start times.
        val_horizon: validation rollout length (default ``horizon``).
        checkpoint_every: write ``checkpoint.pt`` every this many epochs (needs ``run_dir``).
        seed: seeds the initial weights and the sub-window draws.
        device: ``"auto"`` (CUDA when present), ``"cpu"`` or ``"cuda"``.
    """

    epochs: int = 100
    batch_size: int = 64
    lr: float = 1e-4
    lr_final: float | None = None
    weight_decay: float = 0.0
    horizon: int = 100
    curriculum_epochs: int = 0
    windows_per_trajectory: int = 1
    alpha_first: float = 10.0
    grad_clip: float | None = None
    patience: int | None = None
    val_every: int = 1
    val_stride: int = 1
    val_horizon: int | None = None
    checkpoint_every: int = 10
    seed: int = 0
    device: str = "auto"

    def __post_init__(self) -> None:
        positive_ints = (
            "epochs",
            "batch_size",
            "horizon",
            "windows_per_trajectory",
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
        for key in ("patience", "val_horizon"):
            value = getattr(self, key)
            if value is not None and (not isinstance(value, int) or value < 1):
                raise OptionError(f"training option {key} must be None or an integer >= 1")
        for key in ("lr", "lr_final", "grad_clip"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise OptionError(f"training option {key} must be a positive number, got {value}")
        for key in ("weight_decay", "alpha_first"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0):
                raise OptionError(f"training option {key} must be >= 0, got {value}")
        if self.device not in ("auto", "cpu", "cuda") and not self.device.startswith("cuda:"):
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
        unknown = sorted(set(data) - known)
        if unknown:
            raise OptionError(f"unknown training option(s) {unknown}; known: {sorted(known)}")
        return cls(**data)


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
        stopped: ``"completed"``, ``"early_stopping"`` or ``"diverged"``.
    """

    model: Model
    history: list[dict[str, Any]]
    best_epoch: int
    best_val_loss: float
    epochs_run: int
    stopped: str


def resolve_device(name: str) -> torch.device:
    """``auto`` → CUDA when available, else CPU; ``cuda`` without a GPU raises OptionError."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise OptionError(f"device {name!r} requested but CUDA is not available here")
    return torch.device(name)


def data_fingerprint(*groups: Sequence[Series]) -> str:
    """SHA-256 of the float64 bytes of every ``u`` and ``y`` (to match a run with its data)."""
    h = hashlib.sha256()
    for group in groups:
        h.update(f"group:{len(group)}".encode())
        for s in group:
            for arr in (s.u, s.y):
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


def _check_lengths(series: Sequence[Series], window: int, what: str) -> None:
    for i, s in enumerate(series):
        if s.T < window + 1:
            raise ShapeError(
                f"{what}, trajectory {i}: has {s.T} samples; window ℓ = {window} needs at least "
                f"ℓ + 1 = {window + 1} (ℓ to burn in, one to predict)"
            )


def _draw_windows(
    rng: np.random.Generator, lengths: Sequence[int], span: int, k: int
) -> np.ndarray:
    fits = np.array([i for i, T in enumerate(lengths) if T >= span], dtype=np.int64)
    highs = np.array([lengths[i] - span + 1 for i in fits], dtype=np.int64)
    traj = np.repeat(fits, k)
    starts = rng.integers(0, np.repeat(highs, k))
    order = rng.permutation(len(traj))
    return np.stack([traj, starts], axis=1)[order]


def _state_bytes(obj: Any) -> bytes:
    buf = io.BytesIO()
    torch.save(obj, buf)
    return buf.getvalue()


def fit(
    train: Any,
    val: Any,
    *,
    model: str = "mlp",
    window: int,
    options: TrainOptions | None = None,
    net_options: Mapping[str, Any] | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    callback: Callable[[EpochReport], None] | None = None,
    info: Mapping[str, Any] | None = None,
) -> FitResult:
    """Train model ``model`` with window ``window`` by output error.

    Args:
        train, val: trajectories (objects with ``.u``, ``.y``; see :mod:`learning.data`), in
            physical units. Normalisation statistics come from ``train`` only.
        model: a registry name (:func:`learning.nets.model_names`).
        window: ℓ.
        options: :class:`TrainOptions` (defaults if ``None``).
        net_options: extra constructor arguments of the network (sizes, ``feedthrough``,
            ``residual``).
        run_dir: where the model and ``checkpoint.pt`` are written (nothing is written if
            ``None``).
        resume: continue from ``run_dir/checkpoint.pt``; the model, its configuration, the
            data and the options (but ``epochs``, ``patience``, ``checkpoint_every``,
            ``device``) must match, or :class:`CheckpointError` names what differs.
        callback: called with an :class:`EpochReport` after every epoch.
        info: extra JSON facts saved in the model's ``config.json``.
    """
    opts = options or TrainOptions()
    train_s = as_series(train, what="training data")
    val_s = as_series(val, what="validation data")
    n_u, n_y = train_s[0].u.shape[1], train_s[0].y.shape[1]
    if (val_s[0].u.shape[1], val_s[0].y.shape[1]) != (n_u, n_y):
        raise ShapeError(
            f"validation data have n_u={val_s[0].u.shape[1]}, n_y={val_s[0].y.shape[1]}; "
            f"training data have n_u={n_u}, n_y={n_y}"
        )
    _check_lengths(train_s, window, "training data")
    _check_lengths(val_s, window, "validation data")
    span = window + opts.horizon
    if max(s.T for s in train_s) < span:
        raise ShapeError(
            f"window ℓ = {window} plus rollout horizon H = {opts.horizon} needs trajectories of "
            f"at least {span} samples; the longest training trajectory has "
            f"{max(s.T for s in train_s)} (lower the horizon)"
        )
    device = resolve_device(opts.device)
    norm = Normalisation.fit(train_s)
    config = {
        "window": window,
        "n_u": n_u,
        "n_y": n_y,
        **dict(net_options or {}),
    }
    fingerprint = data_fingerprint(train_s, val_s)
    run_path = Path(run_dir) if run_dir is not None else None
    if resume and run_path is None:
        raise CheckpointError("resume=True needs the run_dir holding checkpoint.pt")

    cuda_devices = [device.index or 0] if device.type == "cuda" else []
    with torch.random.fork_rng(devices=cuda_devices):
        torch.manual_seed(opts.seed)
        net = build_net(model, **config)
        net.residual_scale.copy_(torch.as_tensor(norm.dy_std / norm.y_std))
        net.to(device)
        optimiser = torch.optim.Adam(net.parameters(), lr=opts.lr, weight_decay=opts.weight_decay)
        rng = np.random.default_rng(opts.seed)
        train_bank = WindowBank(train_s, norm, device=device)
        val_bank = WindowBank(val_s, norm, device=device)
        val_h = opts.rollout_horizon
        val_starts = val_bank.starts(window + val_h, stride=opts.val_stride)
        if len(val_starts) == 0:
            raise ShapeError(
                f"no validation trajectory holds window ℓ = {window} plus validation horizon "
                f"{val_h} = {window + val_h} samples (longest has {max(s.T for s in val_s)}); "
                "lower the horizon"
            )
        identity = {
            "model": model,
            "net": net.config(),
            "data": fingerprint,
            "options": {k: v for k, v in opts.to_dict().items() if k not in RESUMABLE_CHANGES},
        }
        state: dict[str, Any]
        if resume:
            assert run_path is not None
            state = _load_checkpoint(run_path / CHECKPOINT_FILE, identity)
            load_state(net, state["net"], where=str(run_path / CHECKPOINT_FILE))
            optimiser.load_state_dict(state["optimiser"])
            rng.bit_generator.state = _rng_state(state["numpy_rng"], encode=False)
            torch.set_rng_state(state["torch_rng"])
            history = list(state["history"])
            best = {k: v.to(device) for k, v in state["best_state"].items()}
            best_val, best_epoch, start = state["best_val"], state["best_epoch"], state["epoch"]
        else:
            v0 = validation_loss(net, val_bank, val_starts, val_h)
            history = [
                {
                    "epoch": 0,
                    "horizon": 0,
                    "lr": 0.0,
                    "train_loss": None,
                    "val_loss": v0,
                    "seconds": 0.0,
                }
            ]
            best = copy.deepcopy(net.state_dict())
            best_val, best_epoch, start = v0, 0, 0

        def checkpoint(epoch: int) -> None:
            if run_path is None:
                return
            payload = {
                "version": CHECKPOINT_VERSION,
                "identity": identity,
                "epoch": epoch,
                "net": {k: v.detach().cpu() for k, v in net.state_dict().items()},
                "optimiser": _to_cpu(optimiser.state_dict()),
                "best_state": {k: v.detach().cpu() for k, v in best.items()},
                "best_val": best_val,
                "best_epoch": best_epoch,
                "history": history,
                "numpy_rng": _rng_state(rng.bit_generator.state, encode=True),
                "torch_rng": torch.get_rng_state(),
            }
            atomic_write_bytes(run_path / CHECKPOINT_FILE, _state_bytes(payload))

        stopped = "completed"
        epoch = start
        try:
            for epoch in range(start + 1, opts.epochs + 1):
                t0 = time.perf_counter()
                h = opts.horizon_at(epoch)
                lr = opts.lr_at(epoch)
                for group in optimiser.param_groups:
                    group["lr"] = lr
                draws = _draw_windows(
                    rng, train_bank.lengths, window + h, opts.windows_per_trajectory
                )
                losses: list[float] = []
                parts_sum: dict[str, float] = {}
                net.train()
                for lo in range(0, len(draws), opts.batch_size):
                    u, y = train_bank.gather(draws[lo : lo + opts.batch_size], window + h)
                    loss, parts = net.training_loss(u, y, alpha_first=opts.alpha_first)
                    if not torch.isfinite(loss):
                        stopped = "diverged"
                        break
                    optimiser.zero_grad(set_to_none=True)
                    loss.backward()
                    if opts.grad_clip is not None:
                        torch.nn.utils.clip_grad_norm_(net.parameters(), opts.grad_clip)
                    optimiser.step()
                    losses.append(float(loss.detach()))
                    for key, value in parts.items():
                        parts_sum[key] = parts_sum.get(key, 0.0) + value
                if stopped == "diverged":
                    log.warning(
                        "epoch %d: the training loss is not finite; stopping and keeping the "
                        "best model (epoch %d)",
                        epoch,
                        best_epoch,
                    )
                    epoch -= 1
                    break
                val_loss = None
                if epoch % opts.val_every == 0 or epoch == opts.epochs:
                    val_loss = validation_loss(net, val_bank, val_starts, val_h)
                    if not math.isfinite(val_loss):
                        val_loss = None
                    elif val_loss < best_val:
                        best_val, best_epoch = val_loss, epoch
                        best = copy.deepcopy(net.state_dict())
                seconds = time.perf_counter() - t0
                parts_mean = {k: v / max(len(losses), 1) for k, v in parts_sum.items()}
                train_loss = float(np.mean(losses))
                row = {
                    "epoch": epoch,
                    "horizon": h,
                    "lr": lr,
                    "train_loss": train_loss,
                    "val_loss": val_loss,
                    "seconds": seconds,
                    **{f"train_{k}": v for k, v in parts_mean.items() if k != "output_error"},
                }
                history.append(row)
                if callback is not None:
                    callback(
                        EpochReport(
                            epoch=epoch,
                            epochs=opts.epochs,
                            horizon=h,
                            lr=lr,
                            train_loss=train_loss,
                            val_loss=val_loss,
                            best_val_loss=best_val,
                            best_epoch=best_epoch,
                            seconds=seconds,
                            parts=parts_mean,
                        )
                    )
                done_curriculum = epoch >= max(opts.curriculum_epochs, 1)
                if (
                    opts.patience is not None
                    and done_curriculum
                    and epoch - max(best_epoch, opts.curriculum_epochs) >= opts.patience
                ):
                    stopped = "early_stopping"
                    checkpoint(epoch)
                    break
                if epoch % opts.checkpoint_every == 0 or epoch == opts.epochs:
                    checkpoint(epoch)
        finally:
            # interrupted or not: the model kept is the best one seen
            load_state(net, best, where="best weights")
            net.to("cpu").eval()
            result_model = Model(
                net,
                norm,
                info={
                    **dict(info or {}),
                    "training": {
                        "options": opts.to_dict(),
                        "best_epoch": best_epoch,
                        "best_val_loss": best_val,
                        "data_sha256": fingerprint,
                    },
                },
            )
            if run_path is not None:
                result_model.save(run_path)
    return FitResult(
        model=result_model,
        history=history,
        best_epoch=best_epoch,
        best_val_loss=best_val,
        epochs_run=epoch,
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


def _load_checkpoint(path: Path, identity: Mapping[str, Any]) -> dict[str, Any]:
    if not path.is_file():
        raise CheckpointError(f"no checkpoint to resume from: {path} does not exist")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for corrupt or unsafe files
        raise CheckpointError(f"cannot read checkpoint {path}: {exc}") from exc
    if not isinstance(state, dict) or state.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path} is not a canonid training checkpoint (version)")
    found = state["identity"]
    check_same(
        {"model": found.get("model"), "data": found.get("data")},
        {"model": identity["model"], "data": identity["data"]},
        what=f"checkpoint {path} (model / training data)",
    )
    check_same(found.get("net", {}), identity["net"], what=f"checkpoint {path} (network)")
    check_same(
        found.get("options", {}), identity["options"], what=f"checkpoint {path} (training options)"
    )
    return state
