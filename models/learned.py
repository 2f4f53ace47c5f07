"""A trained canonical model as a :class:`~canonid.models.base.System`, built in CasADi SX from its
weights.

The weights arrive as a plain description (:mod:`canonid.kernel.network`, exported by
``canonid.learning.NumpyModel.network()``), so this module never sees torch. The SX graph is written
out layer by layer — ReLU as ``fmax(v, 0)``, SiLU as ``v (1 + tanh(v/2)) / 2``, tanh as ``tanh``,
the cubic branch's cube as ``v**3`` (CasADi's constant power) — which keeps it open to the
interval evaluator of :mod:`canonid.analysis.enclosure` (a wrapped torch function would be opaque
to it).

State and maps. For a :class:`~canonid.kernel.network.CanonicalNet` the state is the canonical
``z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1})`` in physical units (:mod:`canonid.kernel.canonical`
ordering) and

    f(z, u) = Ā z + B̄ u + S̄ Ĥ(z, u),      h(z, u) = Ĥ(z, u),

the shift written as a concatenation (drop the oldest pair, append ``[u; Ĥ(z, u)]``). For a
:class:`~canonid.kernel.network.ReducedCanonicalNet` the state is the reduced ``x̄_t`` (no units)
and ``f``, ``h`` are the reduced model's step and output (see :mod:`canonid.kernel.network`).
Either way ``x[t]`` is filled from a measured window by :meth:`LearnedSystem.state_of_window` —
the canonical state is measured by construction, no observer is needed.

Ensembles. Canonical models of the same window and signals (e.g. trained from several seeds) can
be one system whose ``Ĥ`` is the mean of theirs (``members``): the state is the same window
``z_t``, each member applies its own normalisation, and ``f`` shifts in the mean output. A
controller that plans with the mean cannot exploit one member's error where the others disagree
with it.

Sets (:meth:`LearnedSystem.from_data`): X is the box hull of the states of the training windows
(every ``z_t`` of every training trajectory, or its encoding ``x̄``), U the hull of the training
inputs, W the hull of the training noise ``y − y_clean`` when the data has clean outputs.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from canonid.kernel.canonical import cut_windows
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import DataError, ShapeError
from canonid.kernel.io import atomic_write_bytes
from canonid.kernel.network import CanonicalNet, GRULayer, Layer, ReducedCanonicalNet
from canonid.kernel.validate import as_matrix
from canonid.models.base import Linearisation, System
from canonid.models.sets import Box

__all__ = [
    "LearnedSystem",
    "load_function",
    "model_function",
    "network_expr",
    "save_function",
]

_ACTIVATIONS: dict[str, Callable[[ca.SX], ca.SX]] = {
    "linear": lambda v: v,
    "relu": lambda v: ca.fmax(v, 0),
    "tanh": ca.tanh,
    # v σ(v) with σ(v) = (1 + tanh(v/2)) / 2: bounded, so interval enclosures never overflow
    "silu": lambda v: 0.5 * v * (1 + ca.tanh(0.5 * v)),
    "cube": lambda v: v**3,
}


def network_expr(layers: Sequence[Layer], v: ca.SX) -> ca.SX:
    """The layers applied to the column ``v``, as an SX expression."""
    for layer in layers:
        v = _ACTIVATIONS[layer.activation](ca.mtimes(ca.DM(layer.weight), v) + layer.bias)
    return v


def _skip(net: Sequence[Layer], skip: Layer | None, v: ca.SX) -> ca.SX:
    out = network_expr(net, v)
    return out if skip is None else out + network_expr([skip], v)


def _sigmoid(v: ca.SX) -> ca.SX:
    return 0.5 * (1 + ca.tanh(0.5 * v))


def _gru_step(layer: GRULayer, x: ca.SX, h: ca.SX) -> ca.SX:
    """``h⁺`` of one GRU layer (:class:`canonid.kernel.network.GRULayer`)."""
    n = layer.hidden
    gi = ca.mtimes(ca.DM(layer.weight_ih), x) + layer.bias_ih
    gh = ca.mtimes(ca.DM(layer.weight_hh), h) + layer.bias_hh
    r = _sigmoid(gi[:n] + gh[:n])
    z = _sigmoid(gi[n : 2 * n] + gh[n : 2 * n])
    new = ca.tanh(gi[2 * n :] + r * gh[2 * n :])
    return (1 - z) * new + z * h


def _features(net: CanonicalNet, zn: ca.SX) -> ca.SX:
    """``φ``: ``z̃``, or the GRU's last top-layer state after reading the pairs of ``z̃``."""
    if not net.recurrent:
        return zn
    p = net.n_u + net.n_y
    states = [ca.SX.zeros(layer.hidden) for layer in net.recurrent]
    for k in range(net.window):
        x = zn[k * p : (k + 1) * p]
        for i, layer in enumerate(net.recurrent):
            states[i] = x = _gru_step(layer, x, states[i])
    return states[-1]


def regressor_expr(net: CanonicalNet, zn: ca.SX, un: ca.SX) -> ca.SX:
    """``ỹ = Ĥ̃(z̃, ũ)`` in normalised units (see :mod:`canonid.kernel.network`)."""
    features = _features(net, zn)
    a = ca.vertcat(features, un) if net.feedthrough else features
    raw = network_expr(net.layers, a)
    x = ca.vertcat(zn, un) if net.feedthrough else zn
    if net.affine is not None:
        raw = raw + ca.mtimes(ca.DM(net.affine[0]), x) + net.affine[1]
    if net.cubic is not None:
        raw = raw + network_expr(net.cubic, x)
    if net.residual_scale is None:
        return raw
    return zn[net.state_dim - net.n_y :] + raw * net.residual_scale


class LearnedSystem(System):
    """A trained canonical model (or reduced model) as a system (see the module docstring).

    Args:
        net: the exported weights (:class:`CanonicalNet` or :class:`ReducedCanonicalNet`).
        dt: the sampling time of the data it was trained on, seconds.
        input_names, output_names: signal names from the data.
        input_units, output_units: their units (``"-"`` when not given).
        X, U, W: the sets (see :meth:`from_data` for the ones taken from the data).
        name: the system's name (e.g. the run folder's).
        members: further canonical models of the same window and signals; ``Ĥ`` is then the
            mean of ``net``'s and theirs (module docstring, "Ensembles"). ``net`` itself must
            then be a :class:`CanonicalNet`.
    """

    description = "A trained canonical model (Ours (MLP/GRU), or reduced), from its weights"

    def __init__(
        self,
        net: CanonicalNet | ReducedCanonicalNet,
        *,
        dt: float,
        input_names: Sequence[str],
        output_names: Sequence[str],
        X: Box,
        U: Box,
        W: Box,
        input_units: Sequence[str] | None = None,
        output_units: Sequence[str] | None = None,
        name: str = "learned",
        members: Sequence[CanonicalNet] = (),
    ) -> None:
        if not isinstance(net, (CanonicalNet, ReducedCanonicalNet)):
            raise ShapeError(
                "LearnedSystem needs a CanonicalNet or ReducedCanonicalNet, got "
                f"{type(net).__name__}"
            )
        self.network = net
        self.regressor = reg = net.regressor if isinstance(net, ReducedCanonicalNet) else net
        #: the canonical models whose mean output this system is: ``(net,)`` for one canonical
        #: model, empty for a reduced one
        self.members: tuple[CanonicalNet, ...] = _members(net, members, name)
        input_units = tuple(input_units or ("-",) * len(input_names))
        output_units = tuple(output_units or ("-",) * len(output_names))
        if (len(input_names), len(output_names)) != (reg.n_u, reg.n_y):
            raise ShapeError(
                f"{name}: the model has n_u={reg.n_u}, n_y={reg.n_y}; got {len(input_names)} "
                f"input and {len(output_names)} output names"
            )
        if isinstance(net, ReducedCanonicalNet):
            states = tuple(f"xbar{i}" for i in range(net.latent_dim))
            units = ("-",) * net.latent_dim
            kind = f"reduced canonical model, n̄ = {net.latent_dim}"
        else:
            pair_names = (*input_names, *output_names)
            states = tuple(
                f"{n}[t-{reg.window - k}]" for k in range(reg.window) for n in pair_names
            )
            units = (*input_units, *output_units) * reg.window
            kind = "canonical model"
        self._z_mean, self._z_std = reg.z_mean, reg.z_std
        regressor = "GRU" if reg.recurrent else "MLP"
        branch = "" if reg.cubic is None else " with a cubic branch"
        if len(self.members) > 1:
            kind = f"mean of {len(self.members)} canonical models"
        super().__init__(
            name=name,
            dt=dt,
            state_names=states,
            state_units=units,
            input_names=input_names,
            input_units=input_units,
            output_names=output_names,
            output_units=output_units,
            X=X,
            U=U,
            W=W,
            discretisation=f"learned ({kind}: canonical shift + {regressor} regressor{branch})",
            parameters={
                "window": reg.window,
                "feedthrough": reg.feedthrough,
                "residual": reg.residual_scale is not None,
                "affine": reg.affine is not None,
                "regressor": regressor,
                "hidden": [layer.n_out for layer in reg.layers[:-1]],
                "gru_hidden": [layer.hidden for layer in reg.recurrent],
                "activation": reg.layers[0].activation if len(reg.layers) > 1 else "linear",
                # only with the branch, so that the description of a plain network is unchanged
                **({"cubic": reg.cubic[0].n_out} if reg.cubic is not None else {}),
                # only for an ensemble, for the same reason (the other entries are its first's)
                **({"members": len(self.members)} if len(self.members) > 1 else {}),
            },
        )
        z = ca.SX.sym("z", reg.state_dim)
        #: ``x[t]`` of a measured window ``z_t`` (physical units): ``z_t`` itself, or ``E(z̃_t)``
        self.encoder = ca.Function("encode", [z], [self._state_expr(z)], ["z"], ["x"])

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_data(
        cls,
        net: CanonicalNet | ReducedCanonicalNet,
        trajectories: Sequence[Trajectory],
        *,
        dt: float,
        input_names: Sequence[str],
        output_names: Sequence[str],
        W: Box | None = None,
        **options: Any,
    ) -> LearnedSystem:
        """The system with X, U (and W unless given) from the training ``trajectories``
        (:class:`~canonid.kernel.dataset.Trajectory`, or objects with ``u``, ``y`` and optionally
        ``y_clean``, converted once; see the module docstring). Without ``W`` and without clean
        outputs, W is ``{0}``."""
        reg = net.regressor if isinstance(net, ReducedCanonicalNet) else net
        items = as_trajectories(trajectories, what="training trajectories (for X, U, W)")
        windows = np.concatenate([cut_windows(t.u, t.y, reg.window) for t in items])
        u_all = np.concatenate([t.u for t in items])
        U = Box(u_all.min(axis=0), u_all.max(axis=0))
        if W is None:
            if all(t.y_clean is not None for t in items):
                w = np.concatenate([t.y - t.y_clean for t in items if t.y_clean is not None])
                W = Box(w.min(axis=0), w.max(axis=0))
            else:
                W = Box(np.zeros(reg.n_y), np.zeros(reg.n_y))
        states = windows
        if isinstance(net, ReducedCanonicalNet):
            zn = ca.SX.sym("zn", reg.state_dim)
            encode = ca.Function("encode", [zn], [_encode_reduced(net, zn)])
            normalised = (windows - reg.z_mean) / reg.z_std
            states = np.asarray(encode.map(windows.shape[0])(normalised.T)).T
        X = Box(states.min(axis=0), states.max(axis=0))
        return cls(
            net,
            dt=dt,
            input_names=input_names,
            output_names=output_names,
            X=X,
            U=U,
            W=W,
            **options,
        )

    @property
    def reduced(self) -> bool:
        """Whether the state is a reduced model's ``x̄`` (else the canonical ``z_t``)."""
        return isinstance(self.network, ReducedCanonicalNet)

    # ------------------------------------------------------------------ symbolic definition
    def _state_expr(self, z: ca.SX) -> ca.SX:
        if isinstance(self.network, ReducedCanonicalNet):
            return _encode_reduced(self.network, (z - self._z_mean) / self._z_std)
        return z

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        reg = self.regressor
        un = (u - reg.u_mean) / reg.u_std
        p = reg.n_u + reg.n_y
        if isinstance(self.network, ReducedCanonicalNet):
            zn = _skip(self.network.decoder, self.network.decoder_skip, x)
            y = regressor_expr(reg, zn, un)
            return _encode_reduced(self.network, ca.vertcat(zn[p:], un, y))
        y = self._h_expr(x, u)
        return ca.vertcat(x[p:], u, y)

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        if isinstance(self.network, ReducedCanonicalNet):
            reg = self.regressor
            zn = _skip(self.network.decoder, self.network.decoder_skip, x)
            return regressor_expr(reg, zn, (u - reg.u_mean) / reg.u_std) * reg.y_std + reg.y_mean
        outputs = [
            regressor_expr(m, (x - m.z_mean) / m.z_std, (u - m.u_mean) / m.u_std) * m.y_std
            + m.y_mean
            for m in self.members
        ]
        return outputs[0] if len(outputs) == 1 else sum(outputs[1:], outputs[0]) / len(outputs)

    # ------------------------------------------------------------------ numeric helpers
    def linearise(self, x: Any, u: Any) -> Linearisation:
        """:meth:`System.linearise`; for an MLP canonical model in numpy (same numbers, much
        faster for wide networks), else by CasADi."""
        net = self.network
        if isinstance(net, ReducedCanonicalNet) or any(m.recurrent for m in self.members):
            return super().linearise(x, u)
        xm = as_matrix(x, self.n_x, f"{self.name}: states x")
        um = as_matrix(u, self.n_u, f"{self.name}: inputs u", rows=xm.shape[0])
        parts = [_mlp_linearisation(m, xm, um) for m in self.members]
        if len(parts) == 1:
            return parts[0]
        # f = [shift; u; Ĥ] is affine in Ĥ: the mean's values and Jacobians are the means
        return Linearisation(
            *(np.mean([getattr(lin, k) for lin in parts], axis=0) for k in _LINEARISATION)
        )

    def state_of_window(self, z: Any) -> np.ndarray:
        """The state ``x[t]`` of a measured window ``z_t`` (physical,
        :mod:`canonid.kernel.canonical` ordering): ``z_t`` itself for a canonical model, ``E(z̃_t)``
        for a reduced one. ``(ℓp,)`` → ``(n_x,)`` or ``(N, ℓp)`` → ``(N, n_x)``."""
        reg = self.regressor
        za = np.asarray(z, dtype=np.float64)
        single = za.ndim == 1
        za = np.atleast_2d(za)
        if za.ndim != 2 or za.shape[1] != reg.state_dim:
            raise ShapeError(
                f"{self.name}: a window z must have {reg.state_dim} entries (ℓ = {reg.window} "
                f"pairs of {reg.n_u + reg.n_y}), got shape {np.shape(z)}"
            )
        out = np.asarray(self.encoder.map(za.shape[0])(za.T)).T.reshape(za.shape[0], self.n_x)
        return out[0] if single else out


_LINEARISATION = ("f", "h", "f_x", "f_u", "h_x", "h_u")


def _members(
    net: CanonicalNet | ReducedCanonicalNet, members: Sequence[CanonicalNet], name: str
) -> tuple[CanonicalNet, ...]:
    """``(net, *members)`` checked to share the window and the signals (ShapeError if not)."""
    if not members:
        return (net,) if isinstance(net, CanonicalNet) else ()
    if not isinstance(net, CanonicalNet):
        raise ShapeError(f"{name}: an ensemble averages canonical models, not reduced ones")
    for i, m in enumerate(members, start=2):
        if not isinstance(m, CanonicalNet):
            raise ShapeError(
                f"{name}: ensemble member {i} is a {type(m).__name__}, expected a CanonicalNet"
            )
        mine, theirs = (m.window, m.n_u, m.n_y), (net.window, net.n_u, net.n_y)
        if mine != theirs:
            raise ShapeError(
                f"{name}: ensemble member {i} has (ℓ, n_u, n_y) = {mine}, the first {theirs}: "
                "the members must share the window state"
            )
    return (net, *members)


def _forward_with_slopes(layer: Layer, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The layer on the rows of ``v`` and the slopes ``σ'`` of its activation there (numpy)."""
    pre = v @ layer.weight.T + layer.bias
    if layer.activation == "relu":
        return np.maximum(pre, 0.0), (pre > 0).astype(np.float64)
    if layer.activation == "tanh":
        t = np.tanh(pre)
        return t, 1.0 - t * t
    if layer.activation == "silu":  # the SX form above: v (1 + tanh(v/2)) / 2
        t = np.tanh(0.5 * pre)
        return 0.5 * pre * (1.0 + t), 0.5 * (1.0 + t) + 0.25 * pre * (1.0 - t * t)
    if layer.activation == "cube":
        return pre * pre * pre, 3.0 * pre * pre
    return pre, np.ones_like(pre)


def _mlp_linearisation(net: CanonicalNet, x: np.ndarray, u: np.ndarray) -> Linearisation:
    """:meth:`System.linearise` of a canonical MLP model in numpy: one batched forward pass and
    ``n_y`` reverse sweeps through the layers, as matrix products (a 3 × 256 network's SX graph
    has about 700,000 instructions; BLAS does the same arithmetic much faster)."""
    n, d, p, n_y = x.shape[0], net.state_dim, net.n_u + net.n_y, net.n_y
    zn = (x - net.z_mean) / net.z_std
    un = (u - net.u_mean) / net.u_std
    a = np.hstack([zn, un]) if net.feedthrough else zn
    v, slopes = a, []
    for layer in net.layers:
        v, slope = _forward_with_slopes(layer, v)
        slopes.append(slope)
    raw = v
    grad = np.broadcast_to(net.layers[-1].weight, (n, n_y, net.layers[-1].n_in))
    for layer, slope in zip(net.layers[-2::-1], slopes[-2::-1]):
        grad = (grad * slope[:, None, :]) @ layer.weight  # d raw / d(layer input)
    if net.affine is not None:
        raw = raw + a @ net.affine[0].T + net.affine[1]
        grad = grad + net.affine[0]
    if net.cubic is not None:  # on x = a (an MLP reads the regression vector itself)
        cubic, d_cubic = net.cubic_branch(a)
        raw, grad = raw + cubic, grad + d_cubic
    if net.residual_scale is None:
        yn, d_yn = raw, np.array(grad)
    else:
        yn = zn[:, d - n_y :] + raw * net.residual_scale
        d_yn = net.residual_scale[:, None] * grad
        d_yn[:, :, d - n_y : d] += np.eye(n_y)
    y = yn * net.y_std + net.y_mean
    y_z = net.y_std[:, None] * d_yn[:, :, :d] / net.z_std
    y_u = (
        net.y_std[:, None] * d_yn[:, :, d:] / net.u_std
        if net.feedthrough
        else np.zeros((n, n_y, net.n_u))
    )
    f_x = np.zeros((n, d, d))
    f_x[:, : d - p, p:] = np.eye(d - p)
    f_x[:, d - n_y :, :] = y_z
    f_u = np.zeros((n, d, net.n_u))
    f_u[:, d - p : d - n_y, :] = np.eye(net.n_u)
    f_u[:, d - n_y :, :] = y_u
    f = np.hstack([x[:, p:], u, y])
    return Linearisation(f=f, h=y, f_x=f_x, f_u=f_u, h_x=y_z, h_u=y_u)


def _encode_reduced(net: ReducedCanonicalNet, zn: ca.SX) -> ca.SX:
    return _skip(net.encoder, net.encoder_skip, zn)


#: the signature of an exported model function: ``(x, u) -> (x_next, y)``
FUNCTION_INPUTS, FUNCTION_OUTPUTS = ("x", "u"), ("x_next", "y")


def model_function(system: System, name: str = "learned_model") -> ca.Function:
    """``(x, u) -> (f(x, u), h(x, u))`` of ``system`` as one SX ``casadi.Function``."""
    x = ca.SX.sym("x", system.n_x)
    u = ca.SX.sym("u", system.n_u)
    return ca.Function(
        name,
        [x, u],
        [system.f(x, u), system.h(x, u)],
        list(FUNCTION_INPUTS),
        list(FUNCTION_OUTPUTS),
    )


def save_function(fun: ca.Function, path: str | os.PathLike[str]) -> Path:
    """Write ``fun`` in CasADi's serialised format (``Function.save``), atomically."""
    target = Path(path)
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp) / "function.casadi"
        fun.save(str(scratch))
        return atomic_write_bytes(target, scratch.read_bytes())


def load_function(path: str | os.PathLike[str]) -> ca.Function:
    """Read a function written by :func:`save_function` (or ``canonid export --casadi``).

    Raises:
        DataError: the file is missing or is not a serialised ``casadi.Function``.
    """
    source = Path(path)
    if not source.is_file():
        raise DataError(f"{source}: no such file (expected a .casadi function)")
    try:
        fun = ca.Function.load(str(source))
    except RuntimeError as exc:
        why = str(exc).strip().splitlines()[-1]
        raise DataError(
            f"{source} is not a serialised CasADi Function (as written by `canonid export "
            f"--casadi` or casadi.Function.save): {why}"
        ) from None
    return fun
