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

The object holds a float64 copy of the network on the CPU; it never changes the model it came
from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from learning.model import Model, load_state
from learning.nets import build_net
from models.errors import ShapeError

__all__ = ["NumpyModel"]


class NumpyModel:
    """Numpy callables ``H`` and ``simulate`` of a trained :class:`learning.model.Model`."""

    def __init__(self, model: Model) -> None:
        net = build_net(model.name, **model.net.config())
        net.to(dtype=torch.float64)
        load_state(
            net,
            {k: v.detach().cpu() for k, v in model.net.state_dict().items()},
            where="exported model",
        )
        net.eval()
        self._net = net
        self._model = Model(net, model.norm, info=model.info)
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
