"""The plain numpy view of a trained model, for the analysis layer (no torch in its signatures).

Contract (what ``analysis`` may rely on)
----------------------------------------
:class:`NumpyModel` has attributes ``name`` (registry name), ``window`` (ℓ), ``n_u``, ``n_y``,
``feedthrough`` (whether ``H`` reads ``u_t``) and two methods, float64 in and out, physical units:

``H(z, u) -> y``
    The one-step output map. ``z`` is ``(N, ℓ (n_u + n_y))`` in the :mod:`canonid.kernel.canonical`
    ordering — ``z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1})``, oldest pair first — ``u`` is
    ``u_t``, ``(N, n_u)``; returns ``ŷ_t``, ``(N, n_y)``. A single ``z`` ``(ℓ(n_u+n_y),)`` with
    ``u`` ``(n_u,)`` gives ``(n_y,)``. For Ours (MLP/GRU) this is the regressor ``Ĥ`` of the
    canonical model; for the baselines it is their prediction from a *measured* window (Classic
    GRU: warm-up from a zero hidden state; Masti et al.: ``G(E(z_t), u_t)``).
``simulate(u, y_burn_in) -> y``
    Open-loop simulation. ``u`` ``(T, n_u)`` holds samples ``0 … T−1``, ``y_burn_in`` ``(ℓ, n_y)``
    the measured outputs of samples ``0 … ℓ−1``; returns the predictions of samples ``ℓ … T−1``,
    ``(T − ℓ, n_y)``. Batched: ``(N, T, n_u)``, ``(N, ℓ, n_y)`` → ``(N, T − ℓ, n_y)``. For the
    canonical models this is ``ẑ_{t+1} = Ā ẑ_t + B̄ u_t + S̄ H(ẑ_t, u_t)`` from the measured
    ``z_ℓ``.

A reduced model (:class:`canonid.learning.nets.ReducedNet`) exports a :class:`ReducedNumpyModel`:
the same ``H`` (``Ĥ(D(E(z_t)), u_t)``, the prediction from a measured window) and ``simulate``, plus
its state-space form — ``latent_dim`` (``n̄``) and

``encode(z) -> x``
    ``x̄ = E(z)``: ``z`` ``(N, ℓ (n_u + n_y))`` physical, as for ``H`` → ``(N, n̄)``.
``step(x, u) -> x_next``
    ``x̄_{t+1} = E(Ā D(x̄_t) + B̄ u_t + S̄ Ĥ(D(x̄_t), u_t))``: ``(N, n̄)``, ``(N, n_u)`` → ``(N, n̄)``.
``output(x, u) -> y``
    ``ȳ_t = Ĥ(D(x̄_t), u_t)``: ``(N, n̄)``, ``(N, n_u)`` → ``(N, n_y)``, physical units.

The reduced state ``x̄`` has no units (the auto-encoder works on the normalised window); single
vectors give single vectors, as for ``H``. ``simulate`` equals ``encode`` of the burn-in window
followed by ``output``/``step``.

The object holds a float64 copy of the network on the CPU; it never changes the model it came
from.

``network()`` returns the weights themselves as plain numpy (:mod:`canonid.kernel.network`): a
:class:`~canonid.kernel.network.CanonicalNet` for Ours (MLP) (its cubic branch included) and
Ours (GRU), a :class:`~canonid.kernel.network.ReducedCanonicalNet` for their reduced models.
:mod:`canonid.models.learned` builds CasADi expressions from it; the other models raise
:class:`NotExportableError`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from canonid.kernel import network as plain
from canonid.kernel.errors import CanonidError, ShapeError
from canonid.kernel.validate import require_finite
from canonid.learning.data import Normalisation
from canonid.learning.nets import (
    ALL_NETS,
    ARX,
    OursGRU,
    OursMLP,
    ReducedNet,
    SequenceModel,
    build_net,
)
from canonid.learning.nets.base import ACTIVATIONS
from canonid.learning.rollout import simulate

__all__ = ["NotExportableError", "NumpyModel", "ReducedNumpyModel"]


class NotExportableError(CanonidError, ValueError):
    """A model whose layers have no plain description (only canonical models export)."""


def _not_exportable(name: str) -> NotExportableError:
    label = ALL_NETS[name].label if name in ALL_NETS else name
    return NotExportableError(
        f"only canonical models export to CasADi: Ours (MLP) ('mlp'), Ours (GRU) ('gru'), ARX "
        f"('arx') and their reduced models ('reduced'); got {label} ({name!r})"
    )


def _layers(seq: nn.Sequential, activation: str) -> tuple[plain.Layer, ...]:
    """The layers of an :func:`canonid.learning.nets.base.mlp`: each ``Linear`` with the activation
    that follows it (``"linear"`` for the output layer)."""
    linears = [m for m in seq if isinstance(m, nn.Linear)]
    expected = ACTIVATIONS[activation]
    if any(not isinstance(m, (nn.Linear, expected)) for m in seq):
        raise ShapeError(f"expected an MLP of Linear and {expected.__name__} layers, got {seq}")
    return tuple(
        _layer(m, activation if i < len(linears) - 1 else "linear") for i, m in enumerate(linears)
    )


def _layer(linear: nn.Linear, activation: str = "linear") -> plain.Layer:
    return plain.Layer(
        linear.weight.detach().cpu().numpy().copy(),
        linear.bias.detach().cpu().numpy().copy(),
        activation,
    )


def _gru_layers(gru: nn.GRU) -> tuple[plain.GRULayer, ...]:
    """The layers of a ``batch_first`` :class:`torch.nn.GRU` (PyTorch's gate order)."""
    if gru.bidirectional or not gru.bias:
        raise ShapeError("only unidirectional GRUs with biases export")

    def weight(name: str, k: int) -> np.ndarray:
        return getattr(gru, f"{name}_l{k}").detach().cpu().numpy().copy()

    return tuple(
        plain.GRULayer(
            weight("weight_ih", k),
            weight("weight_hh", k),
            weight("bias_ih", k),
            weight("bias_hh", k),
        )
        for k in range(gru.num_layers)
    )


def _affine_path(regressor: nn.Module) -> tuple[np.ndarray, np.ndarray] | None:
    """``(L, c)`` of the regressor's affine path on ``[z̃; ũ]`` (its ``affine`` layer, see
    :class:`canonid.kernel.network.CanonicalNet`), or ``None`` where it has none."""
    affine = getattr(regressor, "affine", None)
    if affine is None:
        return None
    return affine.weight.detach().cpu().numpy().copy(), affine.bias.detach().cpu().numpy().copy()


def _cubic_branch(regressor: nn.Module) -> tuple[plain.Layer, plain.Layer] | None:
    """The cubic branch ``C (W x + b)³`` of an Ours (MLP) (its ``cubic_in`` and ``cubic_out``
    layers, see :class:`canonid.kernel.network.CanonicalNet`), or ``None`` where it has none."""
    first, second = getattr(regressor, "cubic_in", None), getattr(regressor, "cubic_out", None)
    if first is None or second is None:
        return None
    weight = second.weight.detach().cpu().numpy().copy()
    return _layer(first, "cube"), plain.Layer(weight, np.zeros(weight.shape[0]))


def _batch(name: str, value: Any, cols: int) -> tuple[np.ndarray, bool]:
    """``(N, cols)`` float64 and whether a single vector ``(cols,)`` was given."""
    arr = np.asarray(value, dtype=np.float64)
    single = arr.ndim == 1
    if single:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise ShapeError(f"{name} must have shape (N, {cols}) or ({cols},), got {arr.shape}")
    return require_finite(arr, name), single


class NumpyModel:
    """Numpy callables ``H`` and ``simulate`` of a trained network and its normalisation (what
    :meth:`canonid.learning.model.Model.export` returns)."""

    def __init__(self, trained: SequenceModel, norm: Normalisation) -> None:
        net = build_net(trained.name, **trained.config())  # a float64 twin on the CPU
        net.to(dtype=torch.float64)
        net.load_state_dict({k: v.detach().cpu() for k, v in trained.state_dict().items()})
        net.eval()
        self._net = net
        self.name: str = net.name
        self.window: int = net.window
        self.n_u: int = net.n_u
        self.n_y: int = net.n_y
        self.feedthrough: bool = net.feedthrough
        ell = self.window
        self._z_mean = np.tile(np.concatenate([norm.u_mean, norm.y_mean]), ell)
        self._z_std = np.tile(np.concatenate([norm.u_std, norm.y_std]), ell)
        self._norm = norm

    def __repr__(self) -> str:
        return f"NumpyModel({self.name!r}, window={self.window}, n_u={self.n_u}, n_y={self.n_y})"

    def H(self, z: Any, u: Any) -> np.ndarray:
        """``ŷ_t = H(z_t, u_t)`` (see the module docstring for shapes and ordering)."""
        dim = self.window * (self.n_u + self.n_y)
        za = np.asarray(z, dtype=np.float64)
        ua = np.asarray(u, dtype=np.float64)
        single = za.ndim == 1
        if single:
            za, ua = za[None], ua.reshape(1, -1)
        if ua.ndim == 1 and self.n_u == 1:
            ua = ua[:, None]
        if za.ndim != 2 or za.shape[1] != dim or ua.shape != (za.shape[0], self.n_u):
            raise ShapeError(
                f"H expects z (N, {dim}) and u (N, {self.n_u}); got {za.shape} and {ua.shape}"
            )
        if not (np.all(np.isfinite(za)) and np.all(np.isfinite(ua))):
            raise ShapeError("H: z or u contains NaN or Inf")
        zt = torch.from_numpy((za - self._z_mean) / self._z_std)
        ut = torch.from_numpy(self._norm.norm_u(ua))
        with torch.no_grad():
            y = self._net.one_step(zt, ut).numpy()
        y = self._norm.denorm_y(y)
        return y[0] if single else y

    def simulate(self, u: Any, y_burn_in: Any) -> np.ndarray:
        """Open-loop simulation after a measured burn-in (see the module docstring)."""
        return simulate(self._net, self._norm, u, y_burn_in)

    def network(self) -> plain.CanonicalNet | plain.ReducedCanonicalNet:
        """The weights as plain numpy (see the module docstring).

        Raises:
            NotExportableError: the model is not Ours (MLP) or a reduced Ours (MLP).
        """
        return self._regressor(self._net)

    def _regressor(self, net: Any) -> plain.CanonicalNet:
        recurrent: tuple[plain.GRULayer, ...]
        if isinstance(net, OursMLP):
            layers, recurrent, affine = _layers(net.net, net.activation), (), _affine_path(net)
        elif isinstance(net, OursGRU):
            layers, recurrent = _layers(net.head, "relu"), _gru_layers(net.gru)
            affine = _affine_path(net)
        elif isinstance(net, ARX):  # the affine path beside a zero layer: Ĥ = L·x + c
            width = net._head_width(net.state_dim)
            zero = plain.Layer(np.zeros((net.n_y, width)), np.zeros(net.n_y), "linear")
            layers, recurrent, affine = (zero,), (), _affine_path(net)
        else:
            raise _not_exportable(net.name)
        norm = self._norm
        return plain.CanonicalNet(
            window=net.window,
            n_u=net.n_u,
            n_y=net.n_y,
            feedthrough=net.feedthrough,
            layers=layers,
            u_mean=norm.u_mean,
            u_std=norm.u_std,
            y_mean=norm.y_mean,
            y_std=norm.y_std,
            residual_scale=net.residual_scale.detach().cpu().numpy() if net.residual else None,
            affine=affine,
            recurrent=recurrent,
            cubic=_cubic_branch(net),
        )


class ReducedNumpyModel(NumpyModel):
    """:class:`NumpyModel` of a reduced model, with ``encode``, ``step`` and ``output``."""

    _net: ReducedNet

    def __init__(self, trained: SequenceModel, norm: Normalisation) -> None:
        if not isinstance(trained, ReducedNet):
            raise ShapeError(f"ReducedNumpyModel needs a reduced model, got {trained.name!r}")
        super().__init__(trained, norm)
        self.latent_dim: int = self._net.latent_dim

    def __repr__(self) -> str:
        return (
            f"ReducedNumpyModel(window={self.window}, latent_dim={self.latent_dim}, "
            f"n_u={self.n_u}, n_y={self.n_y})"
        )

    def _xu(self, x: Any, u: Any) -> tuple[torch.Tensor, torch.Tensor, bool]:
        xa, single = _batch("x", x, self.latent_dim)
        ua = np.asarray(u, dtype=np.float64)
        if single:
            ua = ua.reshape(1, -1)
        elif ua.ndim == 1 and self.n_u == 1:
            ua = ua[:, None]
        ua, _ = _batch("u", ua, self.n_u)
        if ua.shape[0] != xa.shape[0]:
            raise ShapeError(f"x has {xa.shape[0]} rows but u has {ua.shape[0]}")
        return torch.from_numpy(xa), torch.from_numpy(self._norm.norm_u(ua)), single

    def network(self) -> plain.ReducedCanonicalNet:
        """The regressor and the auto-encoder as plain numpy (see the module docstring)."""
        net = self._net
        return plain.ReducedCanonicalNet(
            regressor=self._regressor(net.regressor),
            latent_dim=net.latent_dim,
            encoder=_layers(net.encoder, "relu"),
            decoder=_layers(net.decoder, "relu"),
            encoder_skip=None if net.encoder_skip is None else _layer(net.encoder_skip),
            decoder_skip=None if net.decoder_skip is None else _layer(net.decoder_skip),
        )

    def encode(self, z: Any) -> np.ndarray:
        """``x̄ = E(z)`` (see the module docstring)."""
        za, single = _batch("z", z, self.window * (self.n_u + self.n_y))
        with torch.no_grad():
            x = self._net.encode(torch.from_numpy((za - self._z_mean) / self._z_std)).numpy()
        return x[0] if single else x

    def step(self, x: Any, u: Any) -> np.ndarray:
        """``x̄_{t+1}`` from ``x̄_t`` and ``u_t`` (see the module docstring)."""
        xt, ut, single = self._xu(x, u)
        with torch.no_grad():
            x_next = self._net.step(xt, ut)[0].numpy()
        return x_next[0] if single else x_next

    def output(self, x: Any, u: Any) -> np.ndarray:
        """``ȳ_t = Ĥ(D(x̄_t), u_t)`` in physical units (see the module docstring)."""
        xt, ut, single = self._xu(x, u)
        with torch.no_grad():
            y = self._norm.denorm_y(self._net.output(xt, ut).numpy())
        return y[0] if single else y
