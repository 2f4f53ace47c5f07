"""Model reduction (paper §IV-B): train an auto-encoder around a trained canonical model.

Given a trained canonical model (Ours (MLP) or Ours (GRU)) with regressor ``Ĥ`` and window ℓ,
:func:`reduce_model` trains the reduced model of :class:`canonid.learning.nets.ReducedNet`,

    x̄_{t+1} = E(Ā D(x̄_t) + B̄ u_t + S̄ Ĥ(D(x̄_t), u_t)),      ȳ_t = Ĥ(D(x̄_t), u_t),

whose state has ``n̄ = ⌊dim z · (1 − r)⌋ + 1`` entries for a compression rate ``r`` in (0, 1)
(*authors' code*; ``dim z = ℓ (n_u + n_y)``), so ``n̄ = dim z`` exactly when ``r ≤ 1 / dim z``.

Training goes through the output-error loop of :mod:`canonid.learning.training` (sub-windows,
curriculum, validation on the reduced model's open-loop rollouts, best-on-validation kept,
checkpoints and resume, seeds) with the three-term loss of :mod:`canonid.learning.nets.reduced`,
under the full model's normalisation. ``Ĥ`` starts from the full model's weights and is frozen
during epochs ``1 … ⌊f · epochs⌋`` (``f = freeze_fraction``, *authors' code*: 0.75), then fine-tuned
with ``E`` and ``D`` (the reduced model keeps its own copy of ``Ĥ``; the full model is not changed).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from canonid.kernel.canonical import cut_windows
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import ShapeError
from canonid.learning.model import Model
from canonid.learning.nets import ReducedNet, SequenceModel
from canonid.learning.nets.reduced import NotReducibleError, check_reducible
from canonid.learning.training import EpochReport, FitResult, OptionError, TrainOptions, fit_net

__all__ = [
    "NotReducibleError",
    "ReductionOptions",
    "latent_size",
    "principal_directions",
    "reconstruction_mse",
    "reduce_model",
]


def latent_size(state_dim: int, compression: float) -> int:
    """``n̄ = ⌊dim z · (1 − r)⌋ + 1`` for ``r = compression`` strictly between 0 and 1.

    The floor allows 1e-9 of rounding, so that e.g. ``dim z = 20``, ``r = 0.3`` gives 15 whatever
    the last bit of ``20 · 0.7``. Raises :class:`OptionError` for ``r`` outside (0, 1) (a rate in
    percent, such as 60, is refused) and :class:`ShapeError` for ``state_dim < 1``.
    """
    if isinstance(state_dim, bool) or not isinstance(state_dim, int) or state_dim < 1:
        raise ShapeError(f"state_dim must be an integer >= 1, got {state_dim!r}")
    r = float(compression)
    if not (math.isfinite(r) and 0.0 < r < 1.0):
        raise OptionError(
            f"compression rate must be strictly between 0 and 1 (a fraction, e.g. 0.6 for 60 %), "
            f"got {compression!r}"
        )
    return math.floor(state_dim * (1.0 - r) + 1e-9) + 1


@dataclass(frozen=True)
class ReductionOptions:
    """The reduction-specific options of :func:`reduce_model` (training budgets are
    :class:`canonid.learning.training.TrainOptions`).

    Attributes:
        encoder_hidden, decoder_hidden: hidden widths of ``E`` and ``D`` (paper: 2 × 512).
        freeze_fraction: share ``f`` of the epochs during which ``Ĥ`` is frozen (0: fine-tuned
            from the start; 1: never trained).
        linear_skip: give ``E`` and ``D`` an affine path each, started from the principal
            components of the training windows (:func:`principal_directions`), the MLPs' output
            layers from zero: training starts at the linear (PCA) reduction. Off: the paper's
            plain MLPs, randomly initialised.
        reconstruction_weight, consistency_weight, output_weight: weights of the three loss
            terms (:mod:`canonid.learning.nets.reduced`).
    """

    encoder_hidden: tuple[int, ...] = (512, 512)
    decoder_hidden: tuple[int, ...] = (512, 512)
    freeze_fraction: float = 0.75
    reconstruction_weight: float = 1.0
    consistency_weight: float = 1.0
    output_weight: float = 1.0
    linear_skip: bool = False

    def __post_init__(self) -> None:
        for key in ("encoder_hidden", "decoder_hidden"):
            value = getattr(self, key)
            if isinstance(value, str | bytes) or not isinstance(value, Sequence):
                raise OptionError(f"reduction option {key} must be a list of widths, got {value!r}")
            widths = tuple(value)
            if any(isinstance(w, bool) or not isinstance(w, int) or w < 1 for w in widths):
                raise OptionError(
                    f"reduction option {key} must hold integers >= 1, got {list(widths)}"
                )
            object.__setattr__(self, key, widths)
        f = self.freeze_fraction
        if not (math.isfinite(f) and 0.0 <= f <= 1.0):
            raise OptionError(f"reduction option freeze_fraction must be in [0, 1], got {f}")
        for key in ("reconstruction_weight", "consistency_weight", "output_weight"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0):
                raise OptionError(f"reduction option {key} must be >= 0, got {value}")
        if not isinstance(self.linear_skip, bool):
            raise OptionError(
                f"reduction option linear_skip must be true or false, got {self.linear_skip!r}"
            )

    def frozen_epochs(self, epochs: int) -> int:
        """``⌊f · epochs⌋``: ``Ĥ`` is frozen during epochs ``1 … frozen_epochs(epochs)``."""
        return math.floor(self.freeze_fraction * epochs + 1e-9)

    def net_options(self) -> dict[str, Any]:
        """The constructor arguments of :class:`ReducedNet` set by these options."""
        return {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in self.to_dict().items()
            if k != "freeze_fraction"
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ReductionOptions:
        """Build from a mapping; unknown keys raise :class:`OptionError` naming them."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise OptionError(f"unknown reduction option(s) {unknown}; known: {sorted(known)}")
        return cls(**data)


def _weights_sha256(net: torch.nn.Module) -> str:
    h = hashlib.sha256()
    for key, value in sorted(net.state_dict().items()):
        h.update(key.encode())
        h.update(value.detach().cpu().double().numpy().tobytes())
    return h.hexdigest()


def reduce_model(
    model: Model,
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    compression: float,
    options: TrainOptions | None = None,
    reduction: ReductionOptions | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    callback: Callable[[EpochReport], None] | None = None,
    info: Mapping[str, Any] | None = None,
) -> FitResult:
    """Train the reduced model of the canonical ``model`` at compression rate ``compression``.

    Args:
        model: a trained Ours (MLP) or Ours (GRU) model (:class:`canonid.learning.model.Model`).
        train, val: trajectories in physical units (as for
            :func:`canonid.learning.training.fit`); they are normalised with ``model``'s
            statistics.
        compression: ``r`` in (0, 1); the reduced state has :func:`latent_size` entries.
        options: training options (sub-windows, curriculum, epochs, learning rate, seed, ...).
        reduction: :class:`ReductionOptions` (defaults if ``None``).
        run_dir, resume, callback: as for :func:`canonid.learning.training.fit`; a resumed run must
            also match the full model's weights and the reduction options.
        info: extra JSON facts saved in the reduced model's ``config.json``.

    Returns:
        the :class:`~canonid.learning.training.FitResult` whose ``model`` is the reduced model (its
        validation losses are the reduced model's rollout MSE, normalised units).

    Raises:
        NotReducibleError: ``model`` is not a canonical model.
        OptionError: ``compression`` outside (0, 1) or a bad option.
    """
    check_reducible(model.name)
    opts = options or TrainOptions()
    red = reduction or ReductionOptions()
    state_dim = model.net.state_dim
    latent = latent_size(state_dim, compression)
    frozen = red.frozen_epochs(opts.epochs)
    full_net = model.net
    train = as_trajectories(train, what="training data")

    start = principal_directions(model, train, latent) if red.linear_skip else None

    def build(_norm: Any) -> SequenceModel:
        net = ReducedNet.around(full_net, latent_dim=latent, **red.net_options())
        if start is not None:
            dtype = next(net.parameters()).dtype
            net.init_linear(*(torch.as_tensor(a, dtype=dtype) for a in start))
        return net

    def freeze(net: SequenceModel, epoch: int) -> None:
        assert isinstance(net, ReducedNet)
        net.freeze_regressor(epoch <= frozen)

    facts = {
        "compression": float(compression),
        "state_dim": state_dim,
        "latent_dim": latent,
        "regressor": model.name,
        "regressor_weights_sha256": _weights_sha256(full_net),
        "frozen_epochs": frozen,
        "options": red.to_dict(),
    }
    result = fit_net(
        build,
        train,
        val,
        window=model.window,
        norm=model.norm,
        options=opts,
        run_dir=run_dir,
        resume=resume,
        callback=callback,
        info={**dict(info or {}), "reduction": facts},
        identity={k: v for k, v in facts.items() if k != "frozen_epochs"},
        before_epoch=freeze,
        flush=True,  # the auto-encoder's weights fall into float32's subnormals on a CPU
    )
    reduced = result.model.net
    assert isinstance(reduced, ReducedNet)
    reduced.freeze_regressor(False)
    return result


def _normalised_windows(model: Model, data: Sequence[Trajectory]) -> np.ndarray:
    """Every window ``z_t`` (``t = ℓ … T``) of every trajectory, normalised by ``model``."""
    norm, ell = model.norm, model.window
    windows = [
        cut_windows(norm.norm_u(tr.u), norm.norm_y(tr.y), ell)
        for tr in as_trajectories(data, what="data")
        if tr.T >= ell
    ]
    if not windows:
        raise ShapeError(f"no trajectory holds a window of ℓ = {ell} samples")
    return np.concatenate(windows)


def principal_directions(
    model: Model, data: Sequence[Trajectory], count: int
) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``(ℓp,)`` and the ``count`` leading principal directions ``(count, ℓp)``
    (orthonormal rows, by singular value decomposition) of the normalised windows of ``data``
    (every ``z_t`` of every trajectory, as :func:`reconstruction_mse` uses)."""
    z = _normalised_windows(model, data)
    if count > z.shape[1]:
        raise ShapeError(f"{count} principal directions asked of windows of size {z.shape[1]}")
    mean = z.mean(axis=0)
    _, _, vt = np.linalg.svd(z - mean, full_matrices=False)
    return mean, vt[:count]


def reconstruction_mse(model: Model, data: Sequence[Trajectory]) -> float:
    """Mean squared auto-encoder error ``‖z − D(E(z))‖² / dim z`` of a reduced ``model`` over
    every window ``z_t`` (``t = ℓ … T``, samples ``t−ℓ … t−1``) of every trajectory in ``data``,
    in normalised units (each input and output channel divided by its training standard
    deviation, so channels of different units weigh alike)."""
    net = model.net
    if not isinstance(net, ReducedNet):
        raise NotReducibleError(f"reconstruction_mse needs a reduced model, got {model.name!r}")
    z = _normalised_windows(model, data)
    param = next(net.parameters())
    with torch.no_grad():
        zt = torch.as_tensor(z, dtype=param.dtype, device=param.device)
        err = (net.decode(net.encode(zt)) - zt).pow(2).mean()
    return float(err)
