"""A trained network as plain numpy arrays: what ``learning`` exports and ``models`` rebuilds.

This module is the meeting point of three layers: :mod:`canonid.learning.export` writes these
descriptions from torch weights, :mod:`canonid.models.learned` builds CasADi SX expressions from
them, and :mod:`canonid.analysis` reads the weights for its layer-norm bound. It needs only numpy,
so that ``learning`` can import it without CasADi.

Units and conventions
---------------------
Every network works in the *normalised* units of the model's training statistics:
``ũ = (u − u_mean) / u_std`` per input channel, ``ỹ = (y − y_mean) / y_std`` per output channel
and ``z̃`` the window of normalised pairs, in the :mod:`canonid.kernel.canonical` ordering
``z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1})`` (oldest pair first).

A :class:`Layer` is ``v ↦ σ(W v + b)``; a network is a tuple of layers applied in order, the last
one with ``activation="linear"``. ``σ`` is one of :data:`ACTIVATIONS`; ``"cube"`` (``σ(h) = h³``)
serves the cubic branch below. A :class:`GRULayer` is one layer of a GRU (PyTorch's equations).

:class:`CanonicalNet` is the regressor ``Ĥ`` of Ours (MLP) or Ours (GRU), in normalised units::

    φ   = z̃ (Ours (MLP)), or the last top-layer state of the GRU layers reading the ℓ pairs of
          z̃ oldest first from zero states (Ours (GRU))
    a   = [φ; ũ] with feedthrough, φ without
    x   = [z̃; ũ] with feedthrough, z̃ without (the regression vector: affine path, cubic branch)
    raw = layers(a) + (L x + c if affine is not None) + (C (W x + b)³ + c_C if cubic is not None)
    ỹ   = ỹ_{t−1} + s ⊙ raw   with residual (ỹ_{t−1}: the newest y of z̃, s: residual_scale)
        = raw                 without

and ``Ĥ(z, u) = y_mean + y_std ⊙ ỹ`` in physical units.

The cubic branch of Ours (MLP) (net option ``cubic=K``) is the pair of layers
``cubic = (x ↦ (W x + b)³, v ↦ C v + c_C)``: ``W`` ``(K, dim x)``, ``C`` ``(n_y, K)``, the cube
taken elementwise and ``c_C = 0`` as exported. Its slope ``3 h²`` is unbounded on the whole
space, so a network whose branch reads ``z̃`` has no finite global Lipschitz bound
(:data:`ACTIVATIONS` gives ``inf`` for the cube); on a bounded region it has one.

:class:`ReducedCanonicalNet` adds the auto-encoder of :mod:`canonid.learning.nets.reduced`
(whose torch module is ``ReducedNet``) around it: ``E(z̃) = encoder(z̃) (+ encoder_skip(z̃))``
and ``D(x̄) = decoder(x̄) (+ decoder_skip(x̄))``, and the reduced model
``x̄_{t+1} = E(Ā D(x̄_t) + B̄ ũ_t + S̄ Ĥ̃(D(x̄_t), ũ_t))``,
``ȳ_t = y_mean + y_std ⊙ Ĥ̃(D(x̄_t), ũ_t)`` (``x̄`` has no units).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import require_finite

__all__ = ["ACTIVATIONS", "CanonicalNet", "GRULayer", "Layer", "ReducedCanonicalNet"]

#: activation name → an upper bound of |σ'| over R, for Lipschitz bounds (SiLU's slope peaks at
#: 1.0998 near x = 2.4, rounded up here; the cube's slope 3h² has no bound: ``inf``)
ACTIVATIONS: dict[str, float] = {
    "linear": 1.0,
    "relu": 1.0,
    "tanh": 1.0,
    "silu": 1.1,
    "cube": math.inf,
}


def _array(value: Any, ndim: int, name: str) -> np.ndarray:
    arr = np.array(value, dtype=np.float64)
    if arr.ndim != ndim:
        raise ShapeError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    arr.flags.writeable = False
    return require_finite(arr, name)


@dataclass(frozen=True)
class Layer:
    """``v ↦ activation(weight @ v + bias)``: ``weight`` ``(n_out, n_in)``, ``bias`` ``(n_out,)``,
    ``activation`` one of :data:`ACTIVATIONS`."""

    weight: np.ndarray
    bias: np.ndarray
    activation: str = "linear"

    def __post_init__(self) -> None:
        weight = _array(self.weight, 2, "layer weight")
        bias = _array(self.bias, 1, "layer bias")
        if bias.shape != (weight.shape[0],):
            raise ShapeError(
                f"layer bias must have shape ({weight.shape[0]},) to fit weight "
                f"{weight.shape}, got {bias.shape}"
            )
        if self.activation not in ACTIVATIONS:
            raise ShapeError(
                f"layer activation must be one of {sorted(ACTIVATIONS)}, got {self.activation!r}"
            )
        object.__setattr__(self, "weight", weight)
        object.__setattr__(self, "bias", bias)

    @property
    def n_in(self) -> int:
        return int(self.weight.shape[1])

    @property
    def n_out(self) -> int:
        return int(self.weight.shape[0])


@dataclass(frozen=True)
class GRULayer:
    """One GRU layer, gates in PyTorch's order (reset r, update z, new n), hidden size ``H``::

        r = σ(W_ir x + b_ir + W_hr h + b_hr),   z = σ(W_iz x + b_iz + W_hz h + b_hz)
        n = tanh(W_in x + b_in + r ⊙ (W_hn h + b_hn)),   h⁺ = (1 − z) ⊙ n + z ⊙ h

    ``weight_ih`` ``(3H, n_in)``, ``weight_hh`` ``(3H, H)``, ``bias_ih`` and ``bias_hh`` ``(3H,)``.
    """

    weight_ih: np.ndarray
    weight_hh: np.ndarray
    bias_ih: np.ndarray
    bias_hh: np.ndarray

    def __post_init__(self) -> None:
        w_ih = _array(self.weight_ih, 2, "GRU weight_ih")
        w_hh = _array(self.weight_hh, 2, "GRU weight_hh")
        hidden = w_hh.shape[1]
        if w_ih.shape[0] != 3 * hidden or w_hh.shape != (3 * hidden, hidden):
            raise ShapeError(
                f"GRU weights must be (3H, n_in) and (3H, H); got {w_ih.shape} and {w_hh.shape}"
            )
        object.__setattr__(self, "weight_ih", w_ih)
        object.__setattr__(self, "weight_hh", w_hh)
        for name in ("bias_ih", "bias_hh"):
            bias = _array(getattr(self, name), 1, f"GRU {name}")
            if bias.shape != (3 * hidden,):
                raise ShapeError(f"GRU {name} must have shape ({3 * hidden},), got {bias.shape}")
            object.__setattr__(self, name, bias)

    @property
    def n_in(self) -> int:
        return int(self.weight_ih.shape[1])

    @property
    def hidden(self) -> int:
        return int(self.weight_hh.shape[1])


def _check_chain(layers: Sequence[Layer], n_in: int, n_out: int, name: str) -> tuple[Layer, ...]:
    """``layers`` as a tuple, checked to map ``n_in`` to ``n_out`` and to end linear."""
    layers = tuple(layers)
    if not layers:
        raise ShapeError(f"{name}: a network needs at least one layer")
    width = n_in
    for i, layer in enumerate(layers):
        if not isinstance(layer, Layer):
            raise ShapeError(f"{name}: layer {i} must be a Layer, got {type(layer).__name__}")
        if layer.n_in != width:
            raise ShapeError(f"{name}: layer {i} reads {layer.n_in} values, expected {width}")
        width = layer.n_out
    if width != n_out:
        raise ShapeError(f"{name}: the last layer gives {width} values, expected {n_out}")
    if layers[-1].activation != "linear":
        raise ShapeError(f"{name}: the last layer must be linear, got {layers[-1].activation!r}")
    return layers


@dataclass(frozen=True)
class CanonicalNet:
    """The regressor ``Ĥ`` of a canonical model with its normalisation (module docstring).

    Attributes:
        window, n_u, n_y: ``ℓ`` and the signal dimensions.
        feedthrough: the network reads ``ũ_t``.
        layers: the MLP on ``a`` (see the module docstring).
        recurrent: the GRU layers of Ours (GRU); empty for Ours (MLP).
        u_mean, u_std, y_mean, y_std: the training statistics (physical units).
        residual_scale: ``s`` of the residual option, ``(n_y,)``, or ``None`` without it.
        affine: ``(L, c)`` of an affine path on ``x`` added to the network's output, ``L``
            ``(n_y, dim x)``, ``c`` ``(n_y,)``, or ``None``.
        cubic: the cubic branch on ``x`` added to the network's output, a ``"cube"`` layer
            ``(W, b)`` then a linear layer ``(C, c_C)`` (module docstring), or ``None``.
    """

    window: int
    n_u: int
    n_y: int
    feedthrough: bool
    layers: tuple[Layer, ...]
    u_mean: np.ndarray
    u_std: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    residual_scale: np.ndarray | None = None
    affine: tuple[np.ndarray, np.ndarray] | None = None
    recurrent: tuple[GRULayer, ...] = ()
    cubic: tuple[Layer, Layer] | None = None

    def __post_init__(self) -> None:
        for key in ("window", "n_u", "n_y"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ShapeError(f"{key} must be an integer >= 1, got {value!r}")
            object.__setattr__(self, key, int(value))
        object.__setattr__(self, "feedthrough", bool(self.feedthrough))
        recurrent = tuple(self.recurrent)
        width = self.n_u + self.n_y
        for i, layer in enumerate(recurrent):
            if not isinstance(layer, GRULayer) or layer.n_in != width:
                raise ShapeError(f"recurrent layer {i} must be a GRULayer reading {width} values")
            width = layer.hidden
        object.__setattr__(self, "recurrent", recurrent)
        object.__setattr__(
            self, "layers", _check_chain(self.layers, self.input_dim, self.n_y, "regressor")
        )
        for key, n in (("u_mean", self.n_u), ("u_std", self.n_u)):
            object.__setattr__(self, key, self._vector(key, n))
        for key in ("y_mean", "y_std"):
            object.__setattr__(self, key, self._vector(key, self.n_y))
        for key in ("u_std", "y_std"):
            if np.any(getattr(self, key) <= 0):
                raise ShapeError(f"{key} must be positive, got {getattr(self, key).tolist()}")
        if self.residual_scale is not None:
            object.__setattr__(self, "residual_scale", self._vector("residual_scale", self.n_y))
        if self.affine is not None:
            if len(self.affine) != 2:
                raise ShapeError("affine must be a pair (L, c)")
            L = _array(self.affine[0], 2, "affine L")
            c = _array(self.affine[1], 1, "affine c")
            if L.shape != (self.n_y, self.regression_dim) or c.shape != (self.n_y,):
                raise ShapeError(
                    f"affine (L, c) must have shapes ({self.n_y}, {self.regression_dim}) and "
                    f"({self.n_y},), got {L.shape} and {c.shape}"
                )
            object.__setattr__(self, "affine", (L, c))
        if self.cubic is not None:
            branch = tuple(self.cubic)
            if len(branch) != 2:
                raise ShapeError("cubic must be a pair of layers ((W, b) cubed, then C)")
            _check_chain(branch, self.regression_dim, self.n_y, "cubic branch")
            if branch[0].activation != "cube":
                raise ShapeError(
                    f"cubic branch: its first layer must cube, got {branch[0].activation!r}"
                )
            object.__setattr__(self, "cubic", branch)

    def _vector(self, name: str, n: int) -> np.ndarray:
        arr = _array(getattr(self, name), 1, name)
        if arr.shape != (n,):
            raise ShapeError(f"{name} must have shape ({n},), got {arr.shape}")
        return arr

    @property
    def state_dim(self) -> int:
        """``dim z = ℓ (n_u + n_y)``."""
        return self.window * (self.n_u + self.n_y)

    @property
    def regression_dim(self) -> int:
        """``dim x``: ``z̃`` and, with feedthrough, ``ũ``."""
        return self.state_dim + (self.n_u if self.feedthrough else 0)

    @property
    def feature_dim(self) -> int:
        """``dim φ``: ``ℓ (n_u + n_y)``, or the top GRU layer's hidden size."""
        return self.recurrent[-1].hidden if self.recurrent else self.state_dim

    @property
    def input_dim(self) -> int:
        """``dim a``: the network reads ``φ`` and, with feedthrough, ``ũ``."""
        return self.feature_dim + (self.n_u if self.feedthrough else 0)

    @property
    def z_mean(self) -> np.ndarray:
        """The normalisation offsets of ``z`` (the pair offsets tiled ℓ times)."""
        return np.tile(np.concatenate([self.u_mean, self.y_mean]), self.window)

    @property
    def z_std(self) -> np.ndarray:
        """The normalisation scales of ``z``."""
        return np.tile(np.concatenate([self.u_std, self.y_std]), self.window)

    @property
    def output_scale(self) -> np.ndarray:
        """The factor ``s`` on ``raw`` in ``ỹ`` (ones without the residual option)."""
        return np.ones(self.n_y) if self.residual_scale is None else self.residual_scale

    def linear_part(self) -> np.ndarray:
        """``∂ỹ/∂x`` of the linear terms outside the network: ``s ⊙ L`` and, with residual, the
        identity on the newest ``ỹ`` of ``z̃`` — ``(n_y, dim x)``. The cubic branch is not
        linear and is not part of it (:meth:`cubic_branch` gives its ``∂raw/∂x``)."""
        out = np.zeros((self.n_y, self.regression_dim))
        if self.affine is not None:
            out += self.output_scale[:, None] * self.affine[0]
        if self.residual_scale is not None:
            out[:, self.state_dim - self.n_y : self.state_dim] += np.eye(self.n_y)
        return out

    def cubic_branch(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cubic branch's term of ``raw`` at the rows of ``x`` ``(N, dim x)`` and its
        Jacobian ``C diag(3 h²) W`` with ``h = W x + b``: ``(N, n_y)`` and ``(N, n_y, dim x)``
        (zeros without the branch)."""
        n = x.shape[0]
        if self.cubic is None:
            return np.zeros((n, self.n_y)), np.zeros((n, self.n_y, self.regression_dim))
        first, second = self.cubic
        h = x @ first.weight.T + first.bias
        value = (h * h * h) @ second.weight.T + second.bias
        jac = (second.weight[None] * (3.0 * h * h)[:, None, :]) @ first.weight
        return value, jac

    def cubic_reads_state(self) -> bool:
        """Whether the cubic branch's output depends on ``z̃``: some unit with a non-zero column
        of ``C`` reads ``z̃`` (``False`` without the branch, or with ``C = 0`` as training
        starts)."""
        if self.cubic is None:
            return False
        first, second = self.cubic
        used = np.any(second.weight != 0, axis=0)
        return bool(np.any(first.weight[used, : self.state_dim] != 0))


@dataclass(frozen=True)
class ReducedCanonicalNet:
    """A :class:`CanonicalNet` with the auto-encoder of the reduced model (module docstring).

    Attributes:
        regressor: ``Ĥ``.
        latent_dim: ``n̄``.
        encoder, decoder: the MLPs ``z̃ → x̄`` and ``x̄ → z̃``.
        encoder_skip, decoder_skip: their affine paths, or ``None``.
    """

    regressor: CanonicalNet
    latent_dim: int
    encoder: tuple[Layer, ...]
    decoder: tuple[Layer, ...]
    encoder_skip: Layer | None = None
    decoder_skip: Layer | None = None

    def __post_init__(self) -> None:
        n, d = self.latent_dim, self.regressor.state_dim
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ShapeError(f"latent_dim must be an integer >= 1, got {n!r}")
        object.__setattr__(self, "latent_dim", int(n))
        object.__setattr__(self, "encoder", _check_chain(self.encoder, d, n, "encoder"))
        object.__setattr__(self, "decoder", _check_chain(self.decoder, n, d, "decoder"))
        for name, skip, n_in, n_out in (
            ("encoder_skip", self.encoder_skip, d, n),
            ("decoder_skip", self.decoder_skip, n, d),
        ):
            if skip is not None:
                _check_chain([skip], n_in, n_out, name)
