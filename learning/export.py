"""The plain numpy view of a trained model, for the analysis layer (no torch in its signatures).

Contract (what ``analysis`` may rely on)
----------------------------------------
:class:`NumpyModel` has attributes ``name`` (registry name), ``window`` (ℓ), ``n_u``, ``n_y``,
``feedthrough`` (whether ``H`` reads ``u_t``) and two methods, float64 in and out, physical units:

``H(z, u) -> y``
    The one-step output map. ``z`` is ``(N, ℓ (n_u + n_y))`` in the :mod:`models.canonical`
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

A reduced model (:class:`learning.nets.ReducedNet`) exports a :class:`ReducedNumpyModel`: the same
``H`` (``Ĥ(D(E(z_t)), u_t)``, the prediction from a measured window) and ``simulate``, plus its
state-space form — ``latent_dim`` (``n̄``) and

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
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from learning.nets import ReducedNet, build_net
from models._validate import require_finite
from models.errors import ShapeError

if TYPE_CHECKING:  # learning.model imports this module for Model.export()
    from learning.model import Model

__all__ = ["NumpyModel", "ReducedNumpyModel"]


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
    """Numpy callables ``H`` and ``simulate`` of a trained :class:`learning.model.Model`."""

    def __init__(self, model: Model) -> None:
        net = build_net(model.name, **model.net.config())
        net.to(dtype=torch.float64)
        net.load_state_dict({k: v.detach().cpu() for k, v in model.net.state_dict().items()})
        net.eval()
        self._net = net
        self._model = type(model)(net, model.norm, info=model.info)  # the float64 twin
        norm = model.norm
        self.name: str = model.name
        self.window: int = model.window
        self.n_u: int = model.n_u
        self.n_y: int = model.n_y
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
        return self._model.simulate(u, y_burn_in)


class ReducedNumpyModel(NumpyModel):
    """:class:`NumpyModel` of a reduced model, with ``encode``, ``step`` and ``output``."""

    _net: ReducedNet

    def __init__(self, model: Model) -> None:
        if not isinstance(model.net, ReducedNet):
            raise ShapeError(f"ReducedNumpyModel needs a reduced model, got {model.name!r}")
        super().__init__(model)
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
