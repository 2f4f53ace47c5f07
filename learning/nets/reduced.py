"""The reduced model (paper §IV-B): a canonical model whose state is compressed by an
auto-encoder.

With the regressor ``Ĥ`` of a canonical model (Ours MLP / Ours GRU), an encoder ``E: R^{ℓp} →
R^{n̄}`` and a decoder ``D: R^{n̄} → R^{ℓp}`` (``p = n_u + n_y``, all in normalised units):

    x̄_{t+1} = E(Ā D(x̄_t) + B̄ u_t + S̄ Ĥ(D(x̄_t), u_t)),      ȳ_t = Ĥ(D(x̄_t), u_t),

where ``Ā z + B̄ u + S̄ y`` is the canonical shift (:func:`canonid.learning.canonical.shift`). The
reduced state is initialised from the measured burn-in window: ``x̄ = E(z)`` with ``z`` the samples
``s … s+ℓ−1`` (the rollout convention of :mod:`canonid.learning.nets.base`). ``Ĥ`` is the
regressor's :meth:`~canonid.learning.nets.base.CanonicalModel.one_step`, residual option included
(the previous output it adds is the newest ``y`` of the *decoded* window).

Training loss on a sub-window of ``ℓ + H`` samples (*authors' code*; means over every entry):

    reconstruction_weight · mean_k ‖z_k − D(E(z_k))‖²          k = 0 … H
    + consistency_weight  · mean_k ‖E(z_k) − x̄_k‖²             k = 1 … H
    + output_weight       · output error of ȳ_0 … ȳ_{H−1}       (α on the first step)

``z_k`` is the measured window of samples ``k … k+ℓ−1`` of the sub-window (the window before
predicted sample ``k``), and ``x̄_k`` the reduced state after ``k`` open-loop steps from
``x̄_0 = E(z_0)``.

``E`` and ``D`` are ReLU MLPs (the paper's); with ``linear_skip`` each also has an affine path,
which :func:`canonid.learning.reduction.reduce_model` starts from the principal components of the
training windows, so that training begins at the linear (PCA) reduction and learns a nonlinear
correction.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
from torch import nn

from canonid.kernel.errors import ShapeError
from canonid.learning.canonical import pairs_to_state, shift
from canonid.learning.nets.base import CanonicalModel, SequenceModel, mlp, output_error
from canonid.learning.nets.registry import ALL_NETS, NotReducibleError, check_reducible

__all__ = ["NotReducibleError", "ReducedNet", "check_reducible"]


class ReducedNet(SequenceModel):
    """``Ĥ`` of a canonical model with an auto-encoder ``(E, D)`` around its state.

    Args:
        regressor: registry name of the canonical model (``"mlp"`` or ``"gru"``).
        regressor_config: its constructor arguments (:meth:`SequenceModel.config`); ``window``,
            ``n_u``, ``n_y``, ``feedthrough`` and ``residual`` must equal the common ones.
        latent_dim: ``n̄``, the size of the reduced state (see
            :func:`canonid.learning.reduction.latent_size`).
        encoder_hidden, decoder_hidden: hidden widths of the ReLU MLPs ``E`` and ``D`` (paper:
            2 × 512).
        reconstruction_weight, consistency_weight, output_weight: weights of the three loss
            terms (see the module docstring; default 1 each).
        linear_skip: ``E`` and ``D`` each add a linear map (affine) to their MLP, ``E(z) =
            MLP_E(z) + W_E z + b_E`` and likewise ``D``; :meth:`init_linear` starts them from a
            linear reduction (off by default: the paper's plain MLPs).
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual``.

    Raises:
        NotReducibleError: ``regressor`` is not a canonical model.
    """

    name = "reduced"
    label = "Reduced"

    def __init__(
        self,
        *,
        regressor: str,
        regressor_config: Mapping[str, Any],
        latent_dim: int,
        encoder_hidden: Sequence[int] = (512, 512),
        decoder_hidden: Sequence[int] = (512, 512),
        reconstruction_weight: float = 1.0,
        consistency_weight: float = 1.0,
        output_weight: float = 1.0,
        linear_skip: bool = False,
        **common: Any,
    ) -> None:
        super().__init__(**common)
        cls = check_reducible(regressor)
        mismatched = [
            f"{key} ({regressor_config.get(key)!r} in the regressor, {value!r} here)"
            for key, value in common.items()
            if regressor_config.get(key) != value
        ]
        if mismatched:
            raise ShapeError(
                "the reduced model and its regressor disagree on " + ", ".join(mismatched)
            )
        if isinstance(latent_dim, bool) or not isinstance(latent_dim, int) or latent_dim < 1:
            raise ShapeError(f"latent_dim must be an integer >= 1, got {latent_dim!r}")
        self.regressor: CanonicalModel = cls(**regressor_config)
        self.latent_dim = latent_dim
        self.encoder_hidden = tuple(int(h) for h in encoder_hidden)
        self.decoder_hidden = tuple(int(h) for h in decoder_hidden)
        self.reconstruction_weight = float(reconstruction_weight)
        self.consistency_weight = float(consistency_weight)
        self.output_weight = float(output_weight)
        self.encoder = mlp(self.state_dim, self.encoder_hidden, latent_dim)
        self.decoder = mlp(latent_dim, self.decoder_hidden, self.state_dim)
        self.linear_skip = bool(linear_skip)
        self.encoder_skip = nn.Linear(self.state_dim, latent_dim) if linear_skip else None
        self.decoder_skip = nn.Linear(latent_dim, self.state_dim) if linear_skip else None
        self.residual_scale.copy_(self.regressor.residual_scale)

    @classmethod
    def around(cls, regressor: SequenceModel, *, latent_dim: int, **options: Any) -> ReducedNet:
        """A reduced net holding a copy of ``regressor`` (weights included) and a freshly
        initialised auto-encoder; ``options`` are the other constructor arguments."""
        config = regressor.config()
        common = {k: config[k] for k in ("window", "n_u", "n_y", "feedthrough", "residual")}
        net = cls(
            regressor=regressor.name,
            regressor_config=config,
            latent_dim=latent_dim,
            **options,
            **common,
        )
        net.regressor.load_state_dict(regressor.state_dict())
        net.residual_scale.copy_(net.regressor.residual_scale)
        return net.to(next(regressor.parameters()).dtype)

    def options(self) -> dict[str, Any]:
        return {
            "regressor": self.regressor.name,
            "regressor_config": self.regressor.config(),
            "latent_dim": self.latent_dim,
            "encoder_hidden": list(self.encoder_hidden),
            "decoder_hidden": list(self.decoder_hidden),
            "reconstruction_weight": self.reconstruction_weight,
            "consistency_weight": self.consistency_weight,
            "output_weight": self.output_weight,
            "linear_skip": self.linear_skip,
        }

    def freeze_regressor(self, frozen: bool) -> None:
        """Stop (``True``) or allow (``False``) gradient updates of ``Ĥ``'s weights."""
        for p in self.regressor.parameters():
            p.requires_grad_(not frozen)

    # ------------------------------------------------------------------ the reduced model
    def encode(self, z: torch.Tensor) -> torch.Tensor:
        """``x̄ = E(z)``: ``(…, ℓp)`` → ``(…, n̄)``."""
        x = self.encoder(z)
        return x + self.encoder_skip(z) if self.encoder_skip is not None else x

    def decode(self, x: torch.Tensor) -> torch.Tensor:
        """``D(x̄)``: ``(…, n̄)`` → ``(…, ℓp)``."""
        z = self.decoder(x)
        return z + self.decoder_skip(x) if self.decoder_skip is not None else z

    def init_linear(self, mean: torch.Tensor, components: torch.Tensor) -> None:
        """Start from the linear reduction ``E(z) = C (z − m)``, ``D(x̄) = Cᵀ x̄ + m``: set the
        skip paths to it and the MLPs' output layers to zero.

        ``mean`` ``m`` is ``(ℓp,)``; ``components`` ``C`` is ``(n̄, ℓp)`` with orthonormal rows
        (e.g. the leading principal directions of training windows). Needs ``linear_skip``.
        """
        if self.encoder_skip is None or self.decoder_skip is None:
            raise ShapeError("init_linear needs a reduced model built with linear_skip=True")
        d, n = self.state_dim, self.latent_dim
        if tuple(mean.shape) != (d,) or tuple(components.shape) != (n, d):
            raise ShapeError(
                f"init_linear: mean must be ({d},) and components ({n}, {d}); got "
                f"{tuple(mean.shape)} and {tuple(components.shape)}"
            )
        with torch.no_grad():
            self.encoder_skip.weight.copy_(components)
            self.encoder_skip.bias.copy_(-(components @ mean))
            self.decoder_skip.weight.copy_(components.T)
            self.decoder_skip.bias.copy_(mean)
            for net in (self.encoder, self.decoder):
                last = net[-1]
                assert isinstance(last, nn.Linear)
                nn.init.zeros_(last.weight)
                nn.init.zeros_(last.bias)

    def output(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """``ȳ_t = Ĥ(D(x̄_t), u_t)``: ``x`` ``(B, n̄)``, ``u`` ``(B, n_u)`` → ``(B, n_y)``."""
        return self.regressor.one_step(self.decode(x), u)

    def step(self, x: torch.Tensor, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(x̄_{t+1}, ȳ_t)`` from ``x̄_t`` ``(B, n̄)`` and ``u_t`` ``(B, n_u)``."""
        z = self.decode(x)
        y = self.regressor.one_step(z, u)
        return self.encode(shift(z, u, y)), y

    def one_step(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return self.output(self.encode(z), u)

    def _latent_rollout(
        self, x: torch.Tensor, u_future: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Outputs ``(B, H, n_y)`` and states ``x̄_0 … x̄_H`` ``(B, H+1, n̄)`` from ``x̄_0 = x``."""
        outputs, states = [], [x]
        for k in range(u_future.shape[1]):
            x, y = self.step(x, u_future[:, k])
            outputs.append(y)
            states.append(x)
        return torch.stack(outputs, dim=1), torch.stack(states, dim=1)

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        self._check_rollout_args(u_past, y_past, u_future)
        return self._latent_rollout(self.encode(pairs_to_state(u_past, y_past)), u_future)[0]

    def training_loss(
        self, u: torch.Tensor, y: torch.Tensor, *, alpha_first: float
    ) -> tuple[torch.Tensor, dict[str, float]]:
        ell = self.window
        # measured windows z_k, k = 0 … H: samples k … k+ℓ−1 of the sub-window
        pairs = torch.cat([u, y], dim=-1)  # (B, ℓ+H, p)
        z_meas = pairs.unfold(1, ell, 1).transpose(2, 3).reshape(u.shape[0], -1, self.state_dim)
        x_enc = self.encode(z_meas)  # (B, H+1, n̄)
        recon = (self.decode(x_enc) - z_meas).pow(2).mean()
        y_pred, x_roll = self._latent_rollout(x_enc[:, 0], u[:, ell:])
        consist = (x_roll[:, 1:] - x_enc[:, 1:]).pow(2).mean()
        oe = output_error(y_pred, y[:, ell:], alpha_first=alpha_first)
        loss = (
            self.reconstruction_weight * recon
            + self.consistency_weight * consist
            + self.output_weight * oe
        )
        parts = {
            "output_error": float(oe.detach()),
            "consistency": float(consist.detach()),
            "reconstruction": float(recon.detach()),
        }
        return loss, parts


# a saved model may hold the reduced model: registered here, where its class is defined
ALL_NETS[ReducedNet.name] = ReducedNet
