"""Candidates of Ours (MLP) trained at once as stacked weights, and chosen on validation.

:func:`fit_batched` trains ``K`` variants of the ``mlp`` model — other seeds, learning rates,
weight decays, gradient-clipping norms, widths, windows — in one loop. Candidates of one window
and one set of hidden widths form a *stack*: their weights are held as tensors with a leading
candidate axis, and every layer of every candidate is one batched matrix product
(``torch.baddbmm``), so the ``K`` rollouts advance together. Each candidate keeps what
:func:`canonid.learning.training.fit` keeps for one network, applied per candidate:

* its own Adam moments and step count, learning rate (and cosine schedule), weight decay and
  gradient-clipping norm — Adam and the clipping are written out here on the stacked tensors,
  with every hyper-parameter a per-candidate factor and the clipping norm the norm of that
  candidate's gradient alone;
* its own validation loss, best-epoch snapshot, weight average (``ema_decay``), recoveries from
  non-finite losses and early stop: a candidate that stops leaves the stack (its weights stop
  changing) and the others go on.

Every stack of one window trains on the *same* sub-windows at every step: they are drawn from
``options.seed`` exactly as :func:`fit` draws them, and the validation windows are :func:`fit`'s
too. A candidate's ``seed`` seeds its initial weights only. So a candidate whose seed is
``options.seed`` ends with the weights and losses that :func:`fit` gives the same options alone,
to float tolerance (``tests/test_batched.py``): the sums inside a batched product are not
grouped as in a single one, so the last bits differ.

Selection reads validation losses only (the function is never given test data): the chosen
candidate has the lowest best validation loss (the first on a tie); the ``ensemble`` best
candidates of the chosen one's window, their open-loop outputs averaged, replace it when their
validation loss is lower, and :class:`BatchedResult` records which was kept.
"""

from __future__ import annotations

import copy
import dataclasses
import io
import itertools
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import CheckpointError, OptionError, ShapeError
from canonid.kernel.io import atomic_write_bytes
from canonid.learning.canonical import pairs_to_state
from canonid.learning.data import Normalisation, WindowBank
from canonid.learning.linear import feedthrough_test, initialise_linear
from canonid.learning.model import Model, load_state
from canonid.learning.nets import OursMLP, build_net
from canonid.learning.presets import net_options as preset_net_options
from canonid.learning.training import (
    CHECKPOINT_FILE,
    CHECKPOINT_VERSION,
    MAX_RECOVERIES,
    RESUMABLE_CHANGES,
    FitResult,
    TrainOptions,
    _check_rollout_lengths,
    _draw_windows,
    _fit_validation_horizon,
    _load_checkpoint,
    _rng_state,
    _to_cpu,
    _training_pair,
    _validation_starts,
    data_fingerprint,
    flush_subnormal_tensors,
    flushed_subnormals,
    network_work,
    resolve_device,
    resolve_weight_decay,
)

__all__ = [
    "CANDIDATE_KEYS",
    "BatchedResult",
    "Candidate",
    "Ensemble",
    "candidate_grid",
    "fit_batched",
]

#: what a candidate may change: training options applied per candidate, then the network's
#: ``hidden`` widths and the window ℓ (candidates of one window and widths share a stack)
CANDIDATE_KEYS = ("seed", "lr", "lr_final", "weight_decay", "grad_clip", "hidden", "window")
_TRAIN_KEYS = ("seed", "lr", "lr_final", "weight_decay", "grad_clip")
log = logging.getLogger(__name__)

_ADAM_BETAS, _ADAM_EPS = (0.9, 0.999), 1e-8  # torch.optim.Adam's defaults, as fit uses them


@dataclass(frozen=True)
class Candidate:
    """One variant: the options it changes (keys of :data:`CANDIDATE_KEYS`) over the shared
    training options, network options and window given to :func:`fit_batched`.

    Build it as ``Candidate.of(seed=1, lr=1e-3, hidden=(64, 64))``.
    """

    changes: tuple[tuple[str, Any], ...] = ()

    @classmethod
    def of(cls, **changes: Any) -> Candidate:
        unknown = sorted(set(changes) - set(CANDIDATE_KEYS))
        if unknown:
            raise OptionError(
                f"candidate option(s) {unknown} cannot vary between stacked candidates; "
                f"known: {list(CANDIDATE_KEYS)}"
            )
        if "hidden" in changes:
            changes["hidden"] = tuple(int(h) for h in changes["hidden"])
        return cls(tuple(sorted(changes.items())))

    @property
    def label(self) -> str:
        """``key=value`` pairs, or ``"base"`` for a candidate that changes nothing."""
        return ", ".join(f"{k}={v}" for k, v in self.changes) or "base"

    def get(self, key: str, default: Any) -> Any:
        return dict(self.changes).get(key, default)

    def train_options(self, base: TrainOptions) -> TrainOptions:
        """``base`` with this candidate's training options (what :func:`fit` would get)."""
        return dataclasses.replace(base, **{k: v for k, v in self.changes if k in _TRAIN_KEYS})


def candidate_grid(**values: Sequence[Any]) -> list[Candidate]:
    """Every combination of the given values, e.g. ``candidate_grid(seed=[0, 1], lr=[1e-3,
    3e-3])`` → 4 candidates, the last key varying fastest."""
    keys = list(values)
    return [Candidate.of(**dict(zip(keys, combo))) for combo in itertools.product(*values.values())]


class Ensemble:
    """Members of one window whose open-loop outputs are averaged (physical units).

    :meth:`simulate` and :meth:`predict` take the arguments of
    :meth:`canonid.learning.model.Model.simulate` and :meth:`~canonid.learning.model.Model.predict`.
    """

    def __init__(self, members: Sequence[Model]) -> None:
        if len({m.window for m in members}) != 1:
            raise ShapeError("ensemble members must share one window")
        self.members = tuple(members)

    @property
    def window(self) -> int:
        return self.members[0].window

    def __repr__(self) -> str:
        return f"Ensemble({len(self.members)} members, window={self.window})"

    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        return np.mean([m.predict(u, y_burn_in) for m in self.members], axis=0)

    def simulate(self, u: Any, y_burn_in: Any) -> np.ndarray:
        return np.mean([m.simulate(u, y_burn_in) for m in self.members], axis=0)


@dataclass(frozen=True)
class BatchedResult:
    """The outcome of :func:`fit_batched`.

    Attributes:
        candidates: the candidates, in the order given.
        runs: one :class:`~canonid.learning.training.FitResult` per candidate (its best model,
            history, best epoch and validation loss, how it stopped).
        chosen: index of the candidate with the lowest best validation loss (first on a tie).
        ensemble: indices of the averaged members when their ensemble was kept (its validation
            loss below the chosen candidate's), else ``None``.
        ensemble_val_loss: the validation loss of the best-``k`` ensemble that was scored
            (``None`` when none was: fewer than two candidates of the chosen window, or
            ``ensemble < 2``).
    """

    candidates: tuple[Candidate, ...]
    runs: tuple[FitResult, ...]
    chosen: int
    ensemble: tuple[int, ...] | None
    ensemble_val_loss: float | None

    @property
    def model(self) -> Model | Ensemble:
        """What validation chose: the ensemble when it was kept, else the chosen candidate."""
        if self.ensemble is not None:
            return Ensemble([self.runs[i].model for i in self.ensemble])
        return self.runs[self.chosen].model

    @property
    def val_loss(self) -> float:
        """The validation loss of :attr:`model`."""
        if self.ensemble is not None:
            assert self.ensemble_val_loss is not None
            return self.ensemble_val_loss
        return self.runs[self.chosen].best_val_loss

    def table(self) -> list[dict[str, Any]]:
        """One row per candidate: its label, best validation loss and epoch, how it stopped."""
        return [
            {
                "candidate": c.label,
                "best_val_loss": r.best_val_loss,
                "best_epoch": r.best_epoch,
                "epochs_run": r.epochs_run,
                "stopped": r.stopped,
                "chosen": i == self.chosen,
                "in_ensemble": self.ensemble is not None and i in self.ensemble,
            }
            for i, (c, r) in enumerate(zip(self.candidates, self.runs, strict=True))
        ]


# ---------------------------------------------------------------------------- the stacked net
class _StackedMLP:
    """The rollout of ``K`` :class:`OursMLP` of one shape with stacked weights ``(K, …)``: the
    same operations as :meth:`CanonicalModel.rollout`, each layer a batched product."""

    def __init__(self, template: OursMLP) -> None:
        self.n_u, self.n_y, self.p = template.n_u, template.n_y, template.pair_dim
        self.feedthrough, self.residual = template.feedthrough, template.residual
        self.window = template.window
        self.layers = [
            (f"net.{i}.weight", f"net.{i}.bias")
            for i, m in enumerate(template.net)
            if isinstance(m, torch.nn.Linear)
        ]
        self.activation = copy.deepcopy(template.net[1])
        self.affine = template.affine is not None

    @staticmethod
    def _linear(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(b.unsqueeze(1), x, w.transpose(1, 2))

    def rollout(
        self,
        params: Mapping[str, torch.Tensor],
        scale: torch.Tensor,
        u: torch.Tensor,
        y: torch.Tensor,
        horizon: int,
    ) -> torch.Tensor:
        """Predictions ``(K, B, H, n_y)`` for sub-windows ``u``, ``y`` ``(B, ℓ+H, ·)`` shared by
        all candidates (burn-in: the first ℓ samples)."""
        ell = self.window
        k = params[self.layers[0][0]].shape[0]
        z0 = pairs_to_state(u[:, :ell], y[:, :ell])
        z = z0.expand(k, *z0.shape)
        outputs = []
        for step in range(horizon):
            u_k = u[:, ell + step].expand(k, -1, -1)
            x = torch.cat([z, u_k], dim=-1) if self.feedthrough else z
            h = x
            for j, (w, b) in enumerate(self.layers):
                h = self._linear(h, params[w], params[b])
                if j < len(self.layers) - 1:
                    h = self.activation(h)
            if self.affine:
                h = h + self._linear(x, params["affine.weight"], params["affine.bias"])
            y_k = z[..., -self.n_y :] + h * scale if self.residual else h
            outputs.append(y_k)
            z = torch.cat([z[..., self.p :], u_k, y_k], dim=-1)
        return torch.stack(outputs, dim=2)


def _per_candidate(values: Sequence[float], like: torch.Tensor) -> torch.Tensor:
    """A ``(K, 1, 1)`` factor to scale stacked 3-D tensors, in ``like``'s dtype and device."""
    return torch.tensor(values, dtype=like.dtype, device=like.device).view(-1, 1, 1)


def _expand(factor: torch.Tensor, tensor: torch.Tensor) -> torch.Tensor:
    """``factor`` ``(K, 1, 1)`` shaped to broadcast over ``tensor`` ``(K, …)``."""
    return factor.view(-1, *([1] * (tensor.ndim - 1)))


class _Stack:
    """Candidates of one window and one shape: stacked weights, Adam, validation, early stop."""

    def __init__(
        self,
        indices: list[int],
        nets: list[OursMLP],
        opts: list[TrainOptions],
        train_bank: WindowBank,
        val_bank: WindowBank,
        shared: TrainOptions,
        device: torch.device,
    ) -> None:
        self.indices, self.opts, self.shared = list(indices), opts, shared
        self.nets = nets
        self.model = _StackedMLP(nets[0])
        self.window = nets[0].window
        self.names = [name for name, _ in nets[0].named_parameters()]
        self.params = {
            name: torch.stack([dict(n.named_parameters())[name].detach() for n in nets]).to(device)
            for name in self.names
        }
        self.scale = nets[0].residual_scale.to(device)
        self.train_bank, self.val_bank = train_bank, val_bank
        self.val_horizon = shared.rollout_horizon
        self.val_starts = _validation_starts(val_bank, self.window + self.val_horizon, shared)
        # the sub-windows, drawn as fit draws them: every stack of one window gets the same
        self.rng = np.random.default_rng(shared.seed)
        zeros = {k: torch.zeros_like(v) for k, v in self.params.items()}
        self.m, self.v = zeros, {k: torch.zeros_like(v) for k, v in self.params.items()}
        n = len(indices)
        self.steps = [0] * n
        self.ema = {k: v.clone() for k, v in self.params.items()} if shared.ema_decay else None
        self.ema_steps = [0] * n
        self.lr_scale, self.recoveries = [1.0] * n, [0] * n
        # per candidate (all, stopped or not): history, best snapshot
        self.history: list[list[dict[str, Any]]] = [[] for _ in indices]
        self.best: list[dict[str, torch.Tensor]] = [{} for _ in indices]
        self.best_val, self.best_epoch = [math.inf] * n, [0] * n
        self.epochs_run, self.stopped = [0] * n, ["completed"] * n
        # positions (into the lists above) of the candidates still in the stack
        self.active = list(range(n))

    # -------------------------------------------------------------- checkpoint
    _LISTS = (
        "steps",
        "ema_steps",
        "lr_scale",
        "recoveries",
        "history",
        "best_val",
        "best_epoch",
        "epochs_run",
        "stopped",
        "active",
    )

    def state(self) -> dict[str, Any]:
        """Everything training changes, on the CPU (what :meth:`load` restores)."""
        return {
            "params": _to_cpu(self.params),
            "m": _to_cpu(self.m),
            "v": _to_cpu(self.v),
            "ema": None if self.ema is None else _to_cpu(self.ema),
            "best": [_to_cpu(b) for b in self.best],
            "rng": _rng_state(self.rng.bit_generator.state, encode=True),
            **{name: copy.deepcopy(getattr(self, name)) for name in self._LISTS},
        }

    def load(self, state: Mapping[str, Any]) -> None:
        device = self.scale.device
        for name in ("params", "m", "v"):
            setattr(self, name, {k: v.to(device) for k, v in state[name].items()})
        if self.ema is not None:
            self.ema = {k: v.to(device) for k, v in state["ema"].items()}
        self.best = [{k: v.to(device) for k, v in b.items()} for b in state["best"]]
        self.rng.bit_generator.state = _rng_state(state["rng"], encode=False)
        for name in self._LISTS:
            setattr(self, name, list(state[name]))

    # -------------------------------------------------------------- validation
    def kept(self) -> dict[str, torch.Tensor]:
        """The stacked weights validation scores: the average when there is one."""
        return self.ema if self.ema is not None else self.params

    def validate(self, *, batch: int = 2048) -> list[float]:
        """Each active candidate's validation loss, as :func:`validation_loss` computes it."""
        ell, params = self.window, self.kept()
        totals = torch.zeros(len(self.active), dtype=torch.float64)
        count = 0
        with torch.no_grad():
            for lo in range(0, len(self.val_starts), batch):
                u, y = self.val_bank.gather(
                    self.val_starts[lo : lo + batch], ell + self.val_horizon
                )
                pred = self.model.rollout(params, self.scale, u, y, self.val_horizon)
                err = (pred - y[:, ell:]).pow(2).sum(dim=(1, 2, 3))
                totals += err.double().cpu()
                count += pred[0].numel()
        return [float(t) / count for t in totals]

    def record_validation(self, epoch: int) -> list[float | None]:
        losses: list[float | None] = []
        kept = self.kept()
        for row, loss in enumerate(self.validate()):
            c = self.active[row]
            if not math.isfinite(loss):
                losses.append(None)
                continue
            losses.append(loss)
            if loss < self.best_val[c]:
                self.best_val[c], self.best_epoch[c] = loss, epoch
                self.best[c] = {k: v[row].detach().clone() for k, v in kept.items()}
        return losses

    def start(self) -> None:
        """Epoch 0: the untrained networks are the first candidates (kept as fit keeps them,
        whatever their loss)."""
        for row, loss in enumerate(self.validate()):
            c = self.active[row]
            self.history[c].append(
                {
                    "epoch": 0,
                    "horizon": 0,
                    "lr": 0.0,
                    "train_loss": None,
                    "val_loss": loss,
                    "seconds": 0.0,
                }
            )
            self.best[c] = {k: v[row].clone() for k, v in self.params.items()}
            self.best_val[c] = loss

    # -------------------------------------------------------------- stack bookkeeping
    def drop(self, rows: list[int]) -> None:
        """Take the candidates at ``rows`` of the stack out of it (they stop changing)."""
        keep = [r for r in range(len(self.active)) if r not in rows]
        index = torch.tensor(keep, dtype=torch.long, device=self.scale.device)
        for store in (self.params, self.m, self.v, *([self.ema] if self.ema else [])):
            for k in store:
                store[k] = store[k].index_select(0, index)
        for name in ("steps", "ema_steps", "lr_scale", "recoveries"):
            values = getattr(self, name)
            setattr(self, name, [values[r] for r in keep])
        self.active = [self.active[r] for r in keep]

    def recover(self, row: int, epoch: int) -> bool:
        """:meth:`_Run.recover` for one candidate: best weights back, fresh Adam moments, half
        the learning rate; ``False`` once :data:`MAX_RECOVERIES` are spent."""
        if self.recoveries[row] >= MAX_RECOVERIES:
            return False
        self.recoveries[row] += 1
        self.lr_scale[row] *= 0.5
        best = self.best[self.active[row]]
        with torch.no_grad():
            for k in self.params:
                self.params[k][row] = best[k]
                self.m[k][row] = 0.0
                self.v[k][row] = 0.0
                if self.ema is not None:
                    self.ema[k][row] = best[k]
        self.steps[row] = 0
        log.warning(
            "epoch %d, candidate %d: a training loss is not finite; back to its best weights "
            "(epoch %d) with the learning rate halved (recovery %d of %d)",
            epoch,
            self.indices[self.active[row]],
            self.best_epoch[self.active[row]],
            self.recoveries[row],
            MAX_RECOVERIES,
        )
        return True

    # -------------------------------------------------------------- one step
    def step(self, losses: torch.Tensor, epoch: int) -> tuple[list[int], list[float | None]]:
        """Adam on the rows whose loss is finite; recovery on the others. Returns the rows that
        diverged for good and each row's loss (``None`` when not stepped on)."""
        # one device-to-host copy per step (one per candidate would stall a GPU K times)
        values = losses.detach().cpu().tolist()
        finite = [math.isfinite(v) for v in values]
        grads = torch.autograd.grad(
            torch.where(torch.isfinite(losses), losses, 0.0).sum(), list(self.params.values())
        )
        diverged: list[int] = []
        out: list[float | None] = []
        for row, ok in enumerate(finite):
            if ok:
                out.append(values[row])
            else:
                out.append(None)
                if not self.recover(row, epoch):
                    diverged.append(row)
        rows = [r for r, ok in enumerate(finite) if ok]
        if not rows:
            return diverged, out
        grads_by_name = dict(zip(self.params, grads, strict=True))
        opts = [self.opts[self.active[r]] for r in range(len(self.active))]
        # gradient clipping, per candidate (clip_grad_norm_'s formula on that candidate's slice)
        norms = torch.stack(
            [torch.linalg.vector_norm(g.flatten(1), 2, dim=1) for g in grads], dim=1
        )
        total = torch.linalg.vector_norm(norms, 2, dim=1)
        max_norm = torch.tensor(
            [o.grad_clip if o.grad_clip is not None else math.inf for o in opts],
            dtype=total.dtype,
            device=total.device,
        )
        clip = torch.clamp(max_norm / (total + 1e-6), max=1.0)
        beta1, beta2 = _ADAM_BETAS
        stepping = [r in rows for r in range(len(self.active))]
        for r in rows:
            self.steps[r] += 1
        lr = [o.lr_at(epoch) * s for o, s in zip(opts, self.lr_scale, strict=True)]
        step_size = [
            lr[r] / (1 - beta1 ** self.steps[r]) if stepping[r] else 0.0
            for r in range(len(self.active))
        ]
        bc2_sqrt = [
            (1 - beta2 ** self.steps[r]) ** 0.5 if stepping[r] else 1.0
            for r in range(len(self.active))
        ]
        ref = next(iter(self.params.values()))
        mask = _per_candidate([1.0 if s else 0.0 for s in stepping], ref)
        decay = _per_candidate([float(o.weight_decay) for o in opts], ref)  # resolved
        size, bc2 = _per_candidate(step_size, ref), _per_candidate(bc2_sqrt, ref)
        clip3 = clip.to(ref.dtype).view(-1, 1, 1)
        with torch.no_grad():
            for name, p in self.params.items():
                g = grads_by_name[name] * _expand(clip3, p)
                g = g + _expand(decay, p) * p
                on = _expand(mask, p)
                # torch.optim.Adam (single-tensor): lerp / mul-addcmul / sqrt-div-add / addcdiv;
                # a row that is not stepped on keeps its moments (factor 0 on the update)
                m_new = self.m[name].lerp(g, 1 - beta1)
                v_new = self.v[name].mul(beta2).addcmul(g, g, value=1 - beta2)
                self.m[name] = torch.where(on > 0, m_new, self.m[name])
                self.v[name] = torch.where(on > 0, v_new, self.v[name])
                denom = (self.v[name].sqrt() / _expand(bc2, p)).add_(_ADAM_EPS)
                p.sub_(_expand(size, p) * self.m[name] / denom)
                if p.device.type == "cpu" and bool(decay.any()):
                    flush_subnormal_tensors((p, self.m[name], self.v[name]))
            if self.ema is not None:
                self.update_average(rows)
        return diverged, out

    def update_average(self, rows: list[int]) -> None:
        """:meth:`_Run.update_average` for each stepped row: ``d_n = min(d, (1+n)/(10+n))``."""
        assert self.ema is not None and self.shared.ema_decay is not None
        weights = []
        for r in range(len(self.active)):
            if r in rows:
                n = self.ema_steps[r]
                weights.append(1.0 - min(self.shared.ema_decay, (1 + n) / (10 + n)))
                self.ema_steps[r] = n + 1
            else:
                weights.append(0.0)
        ref = next(iter(self.params.values()))
        w = _per_candidate(weights, ref)
        for name, p in self.params.items():
            self.ema[name].lerp_(p, _expand(w, p))

    def train_epoch(self, epoch: int) -> None:
        """One epoch of the active candidates on the same sub-windows (:meth:`_Run.train_epoch`)."""
        shared, ell = self.shared, self.window
        t0 = time.perf_counter()
        horizon = shared.horizon_at(epoch)
        draws = _draw_windows(
            self.rng, self.train_bank.lengths, ell + horizon, shared.windows_per_epoch
        )
        losses: dict[int, list[float]] = {c: [] for c in self.active}
        for lo in range(0, len(draws), shared.batch_size):
            if not self.active:
                break
            u, y = self.train_bank.gather(draws[lo : lo + shared.batch_size], ell + horizon)
            for p in self.params.values():
                p.requires_grad_(True)
            pred = self.model.rollout(self.params, self.scale, u, y, horizon)
            sq = (pred - y[:, ell:]).pow(2).sum(dim=-1)  # (K, B, H), as output_error
            weights = torch.ones(horizon, dtype=sq.dtype, device=sq.device)
            weights[0] = shared.alpha_first
            batch_losses = (sq * weights).sum(dim=2).mean(dim=1) / horizon
            diverged, values = self.step(batch_losses, epoch)
            for p in self.params.values():
                p.requires_grad_(False)
            for row, value in enumerate(values):
                if value is not None:
                    losses[self.active[row]].append(value)
            if diverged:
                for r in diverged:
                    self.stopped[self.active[r]] = "diverged"
                self.drop(diverged)
        val = (
            self.record_validation(epoch)
            if epoch % shared.val_every == 0 or epoch == shared.epochs
            else [None] * len(self.active)
        )
        seconds = time.perf_counter() - t0
        for row, c in enumerate(self.active):
            self.epochs_run[c] = epoch
            self.history[c].append(
                {
                    "epoch": epoch,
                    "horizon": horizon,
                    "lr": self.opts[c].lr_at(epoch) * self.lr_scale[row],
                    "train_loss": float(np.mean(losses[c])) if losses[c] else math.nan,
                    "val_loss": val[row],
                    "seconds": seconds,
                }
            )
        patience = shared.patience
        if patience is not None and epoch >= max(shared.curriculum_epochs, 1):
            done = [
                row
                for row, c in enumerate(self.active)
                if epoch - max(self.best_epoch[c], shared.curriculum_epochs) >= patience
            ]
            for row in done:
                self.stopped[self.active[row]] = "early_stopping"
            if done:
                self.drop(done)


# ---------------------------------------------------------------------------- the entry point
def _build(
    candidate: Candidate,
    opts: TrainOptions,
    net_options: Mapping[str, Any],
    window: int,
    train: Sequence[Trajectory],
    norm: Normalisation,
) -> OursMLP:
    """The candidate's network, initialised exactly as :func:`fit` initialises it."""
    config = dict(net_options)
    if candidate.get("hidden", None) is not None:
        config["hidden"] = list(candidate.get("hidden", ()))
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(opts.seed)
        net = build_net("mlp", window=window, n_u=norm.n_u, n_y=norm.n_y, **config)
        assert isinstance(net, OursMLP)
        net.residual_scale.copy_(torch.as_tensor(norm.dy_std / norm.y_std))
        if net.linear == "arx":
            initialise_linear(net, train, norm)
    return net


def _ensemble_loss(
    nets: Sequence[OursMLP], bank: WindowBank, starts: np.ndarray, horizon: int
) -> float:
    """The validation loss of the members' averaged open-loop outputs (normalised units)."""
    ell = nets[0].window
    total, count = 0.0, 0
    with torch.no_grad():
        for lo in range(0, len(starts), 2048):
            u, y = bank.gather(starts[lo : lo + 2048], ell + horizon)
            pred = torch.stack([n.rollout(u[:, :ell], y[:, :ell], u[:, ell:]) for n in nets])
            total += float((pred.mean(dim=0) - y[:, ell:]).pow(2).sum())
            count += y[:, ell:].numel()
    return total / count


def fit_batched(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    candidates: Sequence[Candidate],
    *,
    window: int,
    options: TrainOptions | None = None,
    net_options: Mapping[str, Any] | None = None,
    ensemble: int = 3,
    callback: Callable[[int], None] | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
) -> BatchedResult:
    """Train ``candidates`` of Ours (MLP) at once and choose among them on validation.

    Args:
        train, val: trajectories in physical units, as for :func:`fit` (normalisation from
            ``train``). No test data are taken: the choice reads ``val`` only.
        candidates: what each candidate changes (:class:`Candidate`, :func:`candidate_grid`).
        window: ℓ for candidates that do not set their own.
        options: the shared training options; a candidate's ``seed``, ``lr``, ``lr_final``,
            ``weight_decay``, ``grad_clip`` replace them for that candidate (its ``seed`` seeds
            its initial weights; the sub-windows and validation windows follow
            ``options.seed``). ``device`` applies to all.
        net_options: the network's options over the ``mlp`` defaults, as for :func:`fit`; a
            candidate's ``hidden`` replaces the widths.
        ensemble: how many of the best candidates of the chosen window to average and score
            (< 2: no ensemble).
        callback: called with the epoch number after every epoch (after its checkpoint).
        run_dir: where to write :data:`CHECKPOINT_FILE` every ``options.checkpoint_every``
            epochs, at the last epoch and when every candidate has stopped (atomically).
        resume: continue from ``run_dir``'s checkpoint, which must have been written for the
            same candidates, network, data and training options (``epochs``, ``patience``,
            ``checkpoint_every`` and ``device`` may change): the result has the bytes of a run
            that was never interrupted.
    """
    base = options or TrainOptions()
    if not candidates:
        raise OptionError("fit_batched: give at least one candidate")
    config = preset_net_options("mlp", net_options)
    if config.get("cubic") not in (None, 0, "auto"):
        raise OptionError("stacked candidates have no cubic branch: train it with fit")
    config["cubic"] = 0  # "auto" too: stacked candidates train the plain network
    train, val = _training_pair(train, val)
    base = resolve_weight_decay(base, train)
    windows = [int(c.get("window", window)) for c in candidates]
    shared: dict[int, TrainOptions] = {}
    for ell in dict.fromkeys(windows):
        _check_rollout_lengths(train, val, ell, base.horizon)
        shared[ell] = _fit_validation_horizon(base, ell, max(tr.T for tr in val))
    opts = [
        resolve_weight_decay(c.train_options(shared[ell]), train)
        for c, ell in zip(candidates, windows, strict=True)
    ]
    resolve_device(base.device)  # "cuda" without a GPU fails before any work
    norm = Normalisation.fit(train)
    fingerprint = data_fingerprint(train, val)
    configs = {ell: dict(config) for ell in shared}  # feedthrough "auto": decided per window
    tests = {}
    for ell in configs if config.get("feedthrough") == "auto" else ():
        tests[ell] = feedthrough_test(train, val, norm, window=ell)
        configs[ell]["feedthrough"] = tests[ell].feedthrough
    nets = [
        _build(c, o, configs[ell], ell, train, norm)
        for c, o, ell in zip(candidates, opts, windows, strict=True)
    ]
    groups: dict[tuple[int, tuple[int, ...]], list[int]] = {}
    for i, net in enumerate(nets):
        groups.setdefault((net.window, net.hidden), []).append(i)
    # "auto" weighs the largest stack: a step advances one stack's candidates together
    work = max(network_work(nets[idx[0]], base.batch_size, len(idx)) for idx in groups.values())
    device = resolve_device(base.device, work=work)
    train_bank = WindowBank(train, norm, device=device)
    val_bank = WindowBank(val, norm, device=device)

    stacks = [
        _Stack(
            idx,
            [nets[i] for i in idx],
            [opts[i] for i in idx],
            train_bank,
            val_bank,
            shared[key[0]],
            device,
        )
        for key, idx in groups.items()
    ]
    identity = {
        "model": "mlp-batched",
        "net": dict(config),
        "data": fingerprint,
        "options": {k: v for k, v in base.to_dict().items() if k not in RESUMABLE_CHANGES},
        "extra": {
            "candidates": [[c.label, ell] for c, ell in zip(candidates, windows, strict=True)]
        },
    }
    checkpoint = Path(run_dir) / CHECKPOINT_FILE if run_dir is not None else None
    first = 1
    if resume:
        if checkpoint is None:
            raise CheckpointError("resume=True needs the run_dir holding the checkpoint")
        state = _load_checkpoint(checkpoint, identity)
        for stack, saved in zip(stacks, state["stacks"], strict=True):
            stack.load(saved)
        first = int(state["epoch"]) + 1
    else:
        for stack in stacks:
            stack.start()

    def save(epoch: int) -> None:
        if checkpoint is None:
            return
        payload = {
            "version": CHECKPOINT_VERSION,
            "identity": identity,
            "epoch": epoch,
            "stacks": [stack.state() for stack in stacks],
        }
        buf = io.BytesIO()
        torch.save(payload, buf)
        atomic_write_bytes(checkpoint, buf.getvalue())

    with flushed_subnormals(device, max(float(o.weight_decay) for o in opts)):
        for epoch in range(first, base.epochs + 1):
            live = [s for s in stacks if s.active]
            if not live:
                break
            for stack in live:
                stack.train_epoch(epoch)
            if (
                epoch % base.checkpoint_every == 0
                or epoch == base.epochs
                or not any(s.active for s in stacks)
            ):
                save(epoch)
            if callback is not None:
                callback(epoch)

    runs: list[FitResult | None] = [None] * len(candidates)
    for stack in stacks:
        for pos, i in enumerate(stack.indices):
            net = nets[i]
            best = {k: v.detach().cpu() for k, v in stack.best[pos].items()}
            load_state(net, {**net.state_dict(), **best}, where="best weights")
            net.eval()
            model = Model(
                net,
                norm,
                info={
                    "training": {
                        "options": opts[i].to_dict(),
                        "device": device.type,  # what "auto" resolved to
                        "best_epoch": stack.best_epoch[pos],
                        "best_val_loss": stack.best_val[pos],
                        "data_sha256": fingerprint,
                    },
                    "candidate": candidates[i].label,
                    **(
                        {"feedthrough_test": tests[windows[i]].to_dict()}
                        if windows[i] in tests
                        else {}
                    ),
                },
            )
            runs[i] = FitResult(
                model=model,
                history=stack.history[pos],
                best_epoch=stack.best_epoch[pos],
                best_val_loss=stack.best_val[pos],
                epochs_run=stack.epochs_run[pos],
                stopped=stack.stopped[pos],
            )
    done = [r for r in runs if r is not None]

    def rank(i: int) -> tuple[float, int]:
        loss = done[i].best_val_loss
        return (loss if math.isfinite(loss) else math.inf, i)

    chosen = min(range(len(done)), key=rank)
    members = sorted((i for i in range(len(done)) if windows[i] == windows[chosen]), key=rank)
    members = members[: max(ensemble, 0)]
    kept, ensemble_val = None, None
    if len(members) >= 2:
        ell = windows[chosen]
        cpu_bank = WindowBank(val, norm)
        horizon = shared[ell].rollout_horizon
        starts = _validation_starts(cpu_bank, ell + horizon, shared[ell])
        member_nets = [nets[i] for i in members]
        ensemble_val = _ensemble_loss(member_nets, cpu_bank, starts, horizon)
        # the chosen candidate scored by the same code, so that rounding cannot decide
        if ensemble_val < _ensemble_loss(member_nets[:1], cpu_bank, starts, horizon):
            kept = tuple(members)
    return BatchedResult(
        candidates=tuple(candidates),
        runs=tuple(done),
        chosen=chosen,
        ensemble=kept,
        ensemble_val_loss=ensemble_val,
    )
