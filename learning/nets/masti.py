"""Masti & Bemporad (Automatica 2021): an auto-encoder state with learned latent dynamics."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch

from canonid.learning.canonical import pairs_to_state
from canonid.learning.nets.base import SequenceModel, mlp, output_error

__all__ = ["Masti"]


class Masti(SequenceModel):
    """Encoder ``x_t = E(z_t)`` from the measured I/O window to a latent state, latent dynamics
    ``x_{t+1} = F(x_t, u_t)``, output ``y_t = G(x_t, u_t)`` (``G(x_t)`` without feedthrough), and a
    decoder ``D(x_t) ≈ z_t`` for the reconstruction term.

    Rollout: ``x`` at the first predicted sample is ``E`` of the burn-in window; afterwards only
    ``F`` moves it (open loop). Training minimises, on each batch of sub-windows,

        output error (α on the first step, as for every model)
        + consistency_weight · mean_k ‖x̂_k − E(z_k)‖²   (k ≥ 1: rolled-out vs encoded state)
        + reconstruction_weight · mean_k ‖D(E(z_k)) − z_k‖²,

    ``z_k`` the measured window before predicted sample ``k`` (inside the sub-window).

    Args:
        latent_dim: size of ``x``; default ``⌈ℓ (n_u + n_y) / 2⌉``, the state size the paper gives
            the Classic GRU (Masti et al. choose it per system; the paper does not say its value).
        hidden: hidden widths of each of E, F, G and D (default 2 × 64).
        consistency_weight, reconstruction_weight: weights of the extra terms (default 1, 1).
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual`` (see
            :class:`canonid.learning.nets.base.SequenceModel`).
    """

    name = "masti"
    label = "Masti et al."
    hidden_option = "hidden"

    def __init__(
        self,
        *,
        latent_dim: int | None = None,
        hidden: Sequence[int] = (64, 64),
        consistency_weight: float = 1.0,
        reconstruction_weight: float = 1.0,
        **common: Any,
    ) -> None:
        super().__init__(**common)
        self.latent_dim = int(latent_dim or math.ceil(self.state_dim / 2))
        self.hidden = tuple(int(h) for h in hidden)
        self.consistency_weight = float(consistency_weight)
        self.reconstruction_weight = float(reconstruction_weight)
        self.encoder = mlp(self.state_dim, self.hidden, self.latent_dim)
        self.decoder = mlp(self.latent_dim, self.hidden, self.state_dim)
        self.dynamics = mlp(self.latent_dim + self.n_u, self.hidden, self.latent_dim)
        self.output_map = mlp(self._head_width(self.latent_dim), self.hidden, self.n_y)

    def options(self) -> dict[str, Any]:
        return {
            "latent_dim": self.latent_dim,
            "hidden": list(self.hidden),
            "consistency_weight": self.consistency_weight,
            "reconstruction_weight": self.reconstruction_weight,
        }

    def one_step(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        x = self.encoder(z)
        return self._output(self.output_map(self._head_input(x, u)), z[:, -self.n_y :])

    def _latent_rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        self._check_rollout_args(u_past, y_past, u_future)
        x = self.encoder(pairs_to_state(u_past, y_past))
        y_prev = y_past[:, -1]
        outputs, states = [], []
        for k in range(u_future.shape[1]):
            u_k = u_future[:, k]
            y_k = self._output(self.output_map(self._head_input(x, u_k)), y_prev)
            outputs.append(y_k)
            states.append(x)
            x = self.dynamics(torch.cat([x, u_k], dim=-1))
            y_prev = y_k
        return torch.stack(outputs, dim=1), torch.stack(states, dim=1)

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        return self._latent_rollout(u_past, y_past, u_future)[0]

    def training_loss(
        self, u: torch.Tensor, y: torch.Tensor, *, alpha_first: float
    ) -> tuple[torch.Tensor, dict[str, float]]:
        ell = self.window
        horizon = u.shape[1] - ell
        y_pred, x_roll = self._latent_rollout(u[:, :ell], y[:, :ell], u[:, ell:])
        oe = output_error(y_pred, y[:, ell:], alpha_first=alpha_first)
        # measured windows z_k before each predicted sample k = 0 … H−1: samples k … k+ℓ−1
        pairs = torch.cat([u, y], dim=-1)  # (B, ℓ+H, p)
        windows = pairs.unfold(1, ell, 1)[:, :horizon]  # (B, H, p, ℓ)
        z_meas = windows.transpose(2, 3).reshape(u.shape[0], horizon, -1)
        x_enc = self.encoder(z_meas)
        recon = (self.decoder(x_enc) - z_meas).pow(2).mean()
        consist = (x_roll[:, 1:] - x_enc[:, 1:]).pow(2).mean() if horizon > 1 else oe.new_zeros(())
        loss = oe + self.consistency_weight * consist + self.reconstruction_weight * recon
        parts = {
            "output_error": float(oe.detach()),
            "consistency": float(consist.detach()),
            "reconstruction": float(recon.detach()),
        }
        return loss, parts
