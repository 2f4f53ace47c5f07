"""The one interface every identification network implements, and the canonical-model base.

All tensors here are in *normalised* units (see :class:`canonid.learning.data.Normalisation`); the
physical-unit API is :class:`canonid.learning.model.Model`.

Rollout convention. A batch of sub-windows holds samples ``s … s+ℓ+H−1``. The first ℓ samples
(``u_past``, ``y_past``, measured) are the burn-in: they give ``z_{s+ℓ}``. The model then predicts
``y[s+ℓ+k]`` for ``k = 0 … H−1`` in open loop from ``u_future[:, k] = u[s+ℓ+k]`` and its own earlier
predictions — never from measured outputs after the burn-in.

Output options shared by all models:

* ``feedthrough``: the output map sees the current input ``u_t`` (``y_t = H(z_t, u_t)``); without
  it, ``y_t = H(z_t)``.
* ``residual``: the network predicts the increment, ``y_t = y_{t−1} + s ⊙ net(…)`` where ``y_{t−1}``
  is the newest output in the model's state (measured during burn-in, predicted after) and ``s``
  the buffer ``residual_scale`` (set by training to ``dy_std / y_std``, saved with the weights).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import torch
from torch import nn

from canonid.kernel.catalog import LINEAR_PATHS
from canonid.kernel.errors import ShapeError
from canonid.learning.canonical import pairs_to_state, shift

__all__ = [
    "ACTIVATIONS",
    "LINEAR_PATHS",
    "CanonicalModel",
    "SequenceModel",
    "linear_path",
    "mlp",
    "output_error",
]


#: hidden-layer activations of :func:`mlp`, by name
ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh, "silu": nn.SiLU}


def linear_path(value: bool | str) -> str:
    """The affine path's name in :data:`LINEAR_PATHS`; ``False`` / ``True`` (configurations
    written before the skip existed) read as ``"off"`` / ``"arx"``."""
    if isinstance(value, bool):
        return "arx" if value else "off"
    if value not in LINEAR_PATHS:
        raise ShapeError(f"linear must be one of {', '.join(LINEAR_PATHS)}, got {value!r}")
    return str(value)


def mlp(n_in: int, hidden: Sequence[int], n_out: int, *, activation: str = "relu") -> nn.Sequential:
    """A multilayer perceptron ``n_in → hidden[0] → … → n_out`` (linear output).

    ``activation`` names the hidden layers' nonlinearity (:data:`ACTIVATIONS`; ReLU, the
    paper's, by default). ReLU and tanh are 1-Lipschitz, SiLU is not (its slope peaks at about
    1.0998, at x ≈ 2.4); the analysis layer only evaluates the exported network, at data
    points, and assumes neither.
    """
    if activation not in ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, got {activation!r}")
    layers: list[nn.Module] = []
    width = n_in
    for h in hidden:
        layers += [nn.Linear(width, int(h)), ACTIVATIONS[activation]()]
        width = int(h)
    layers.append(nn.Linear(width, n_out))
    return nn.Sequential(*layers)


def output_error(y_pred: torch.Tensor, y_true: torch.Tensor, *, alpha_first: float) -> torch.Tensor:
    """The paper's loss ``(1/H) Σ_k α_k ‖y_k − ŷ_k‖²``, averaged over the batch.

    ``y_pred`` and ``y_true`` are ``(B, H, n_y)``; ``α_0 = alpha_first`` weighs the first predicted
    step, ``α_k = 1`` the others.
    """
    sq = (y_pred - y_true).pow(2).sum(dim=-1)  # (B, H)
    weights = torch.ones(sq.shape[1], dtype=sq.dtype, device=sq.device)
    weights[0] = alpha_first
    return (sq * weights).sum(dim=1).mean() / sq.shape[1]


class SequenceModel(nn.Module, ABC):
    """A model that predicts outputs in open loop after an ℓ-sample measured burn-in.

    Args:
        window: ℓ, the number of measured samples it reads before predicting.
        n_u, n_y: input and output dimensions.
        feedthrough: the output map sees the current input.
        residual: predict ``y_t − y_{t−1}`` (scaled; see the module docstring).

    Subclasses set ``name`` (the registry key), implement :meth:`rollout` and :meth:`one_step`,
    and return their constructor arguments from :meth:`options`.
    """

    name: ClassVar[str] = ""
    #: the table label of the paper
    label: ClassVar[str] = ""
    #: the constructor argument holding the widths of the hidden layers (what
    #: ``canonid train --hidden`` sets), or ``None`` where the sizes are not a list of widths
    hidden_option: ClassVar[str | None] = None
    #: why there are no widths to set, where ``hidden_option`` is ``None``
    no_widths: ClassVar[str] = (
        "its layer sizes follow from the window (⌈ℓ(n_u+n_y)/2⌉, as in the paper)"
    )
    #: whether the network is trained by gradient steps (``False``: fitted in closed form only)
    iterative: ClassVar[bool] = True
    residual_scale: torch.Tensor

    def __init__(
        self, *, window: int, n_u: int, n_y: int, feedthrough: bool = True, residual: bool = False
    ) -> None:
        super().__init__()
        for key, value, low in (("window", window, 1), ("n_u", n_u, 1), ("n_y", n_y, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ShapeError(f"{key} must be an integer >= {low}, got {value!r}")
        self.window, self.n_u, self.n_y = window, n_u, n_y
        self.feedthrough, self.residual = bool(feedthrough), bool(residual)
        self.register_buffer("residual_scale", torch.ones(n_y))

    @property
    def pair_dim(self) -> int:
        """``p = n_u + n_y``."""
        return self.n_u + self.n_y

    @property
    def state_dim(self) -> int:
        """``dim z = ℓ (n_u + n_y)``."""
        return self.window * self.pair_dim

    def config(self) -> dict[str, Any]:
        """JSON-ready constructor arguments: ``type(self)(**config())`` rebuilds the network."""
        return {
            "window": self.window,
            "n_u": self.n_u,
            "n_y": self.n_y,
            "feedthrough": self.feedthrough,
            "residual": self.residual,
            **self.options(),
        }

    def options(self) -> dict[str, Any]:
        """The architecture-specific constructor arguments (sizes)."""
        return {}

    def _head_input(self, features: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return torch.cat([features, u], dim=-1) if self.feedthrough else features

    def _head_width(self, n_features: int) -> int:
        return n_features + (self.n_u if self.feedthrough else 0)

    def _output(self, raw: torch.Tensor, y_prev: torch.Tensor) -> torch.Tensor:
        return y_prev + raw * self.residual_scale if self.residual else raw

    @abstractmethod
    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        """Open-loop predictions ``(B, H, n_y)`` after the burn-in ``u_past`` ``(B, ℓ, n_u)``,
        ``y_past`` ``(B, ℓ, n_y)`` under the inputs ``u_future`` ``(B, H, n_u)``."""

    @abstractmethod
    def one_step(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """The one-step output map ``y_t`` ``(B, n_y)`` from a *measured* window ``z_t``
        ``(B, ℓp)`` (canonid.kernel.canonical ordering) and ``u_t`` ``(B, n_u)``."""

    def training_loss(
        self, u: torch.Tensor, y: torch.Tensor, *, alpha_first: float
    ) -> tuple[torch.Tensor, dict[str, float]]:
        """Loss on a batch of sub-windows ``u`` ``(B, ℓ+H, n_u)``, ``y`` ``(B, ℓ+H, n_y)``.

        The base class returns the output error of the open-loop rollout; models with extra
        terms (Masti et al.) add them. The second value names each term (floats, for logs).
        """
        ell = self.window
        y_pred = self.rollout(u[:, :ell], y[:, :ell], u[:, ell:])
        loss = output_error(y_pred, y[:, ell:], alpha_first=alpha_first)
        return loss, {"output_error": float(loss.detach())}

    def _check_rollout_args(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> None:
        b, ell = u_past.shape[0], self.window
        if (
            u_past.shape != (b, ell, self.n_u)
            or y_past.shape != (b, ell, self.n_y)
            or u_future.ndim != 3
            or u_future.shape[0] != b
            or u_future.shape[2] != self.n_u
        ):
            raise ShapeError(
                f"{self.name}: rollout expects u_past (B, {ell}, {self.n_u}), y_past "
                f"(B, {ell}, {self.n_y}), u_future (B, H, {self.n_u}); got "
                f"{tuple(u_past.shape)}, {tuple(y_past.shape)}, {tuple(u_future.shape)}"
            )


class CanonicalModel(SequenceModel):
    """The output-error canonical model: regressor ``Ĥ`` on ``z_t``, exact shift of ``z``.

    ``ŷ_t = Ĥ(ẑ_t, u_t)`` and ``ẑ_{t+1} = Ā ẑ_t + B̄ u_t + S̄ ŷ_t``
    (:func:`canonid.learning.canonical.shift`), starting from the measured ``z`` of the burn-in.
    Subclasses implement :meth:`regress`, the raw network output before the residual option.

    Args:
        linear: the affine path, ``raw = L·x + c + regress(z, u)`` with ``x`` the head's input
            (``[z_t; u_t]``, or ``z_t`` without feedthrough), one of :data:`LINEAR_PATHS`:
            ``"off"``; ``"skip"``, ``L, c`` started at zero and trained with the network;
            ``"arx"``, :func:`canonid.learning.training.fit` starts ``L, c`` at the least-squares
            (ARX) fit and the nonlinear part's output layer at zero, so training starts from the
            best linear model. ``False`` / ``True`` mean ``"off"`` / ``"arx"``.
        common: ``window``, ``n_u``, ``n_y``, ``feedthrough``, ``residual``.
    """

    def __init__(self, *, linear: bool | str = "off", **common: Any) -> None:
        super().__init__(**common)
        self.linear = linear_path(linear)
        width = self._head_width(self.state_dim)
        self.affine = nn.Linear(width, self.n_y) if self.linear != "off" else None
        if self.affine is not None and self.linear == "skip":  # training starts from the network
            nn.init.zeros_(self.affine.weight)
            nn.init.zeros_(self.affine.bias)

    def config(self) -> dict[str, Any]:
        return {**super().config(), "linear": self.linear}

    @abstractmethod
    def regress(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Raw network output ``(B, n_y)`` for ``z`` ``(B, ℓp)`` and ``u_t`` ``(B, n_u)``."""

    def output_layer(self) -> nn.Linear | None:
        """The last layer of the nonlinear part (zeroed when training starts from the ARX fit),
        or ``None`` when there is no nonlinear part."""
        return None

    def raw(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """The regressor's output before the residual option: ``regress`` plus the affine path."""
        out = self.regress(z, u)
        if self.affine is not None:
            out = out + self.affine(self._head_input(z, u))
        return out

    def one_step(self, z: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return self._output(self.raw(z, u), z[:, -self.n_y :])

    def rollout(
        self, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
    ) -> torch.Tensor:
        self._check_rollout_args(u_past, y_past, u_future)
        z = pairs_to_state(u_past, y_past)
        outputs = []
        for k in range(u_future.shape[1]):
            u_k = u_future[:, k]
            y_k = self.one_step(z, u_k)
            outputs.append(y_k)
            z = shift(z, u_k, y_k)
        return torch.stack(outputs, dim=1)
