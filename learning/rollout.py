"""Open-loop simulation of a network in physical units, shared by
:class:`canonid.learning.model.Model` and its numpy export
(:class:`canonid.learning.export.NumpyModel`).

Convention: ``u`` holds samples ``0 … T−1``, ``y_burn_in`` the measured outputs of samples
``0 … ℓ−1``; the result holds the open-loop predictions of samples ``ℓ … T−1`` (``T − ℓ`` rows).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import require_finite
from canonid.learning.data import Normalisation
from canonid.learning.nets import SequenceModel

__all__ = ["rollout_physical", "simulate"]


def _as_batch(value: Any, cols: int, name: str) -> tuple[np.ndarray, bool]:
    """``(N, T, cols)`` float64 from ``(T, cols)`` or ``(N, T, cols)`` (1-D: SISO ``(T,)``)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 1 and cols == 1:
        arr = arr[:, None]
    single = arr.ndim == 2
    if single:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[2] != cols:
        raise ShapeError(f"{name} must have shape (T, {cols}) or (N, T, {cols}), got {arr.shape}")
    return require_finite(arr, name), single


def simulate(net: SequenceModel, norm: Normalisation, u: Any, y_burn_in: Any) -> np.ndarray:
    """Open-loop simulation of ``net`` under ``norm``, validated: ``u`` ``(T, n_u)`` and
    ``y_burn_in`` ``(ℓ, n_y)`` → ``(T − ℓ, n_y)``; or batched, ``(N, T, n_u)`` and
    ``(N, ℓ, n_y)`` → ``(N, T − ℓ, n_y)``."""
    ua, single = _as_batch(u, net.n_u, "u")
    ya, _ = _as_batch(y_burn_in, net.n_y, "y_burn_in")
    if ya.shape[0] != ua.shape[0] or ya.shape[1] != net.window:
        raise ShapeError(
            f"y_burn_in must hold the ℓ = {net.window} measured outputs of each of the "
            f"{ua.shape[0]} sequence(s), shape ({ua.shape[0]}, {net.window}, {net.n_y}); "
            f"got {ya.shape}"
        )
    if ua.shape[1] < net.window:
        raise ShapeError(f"u has {ua.shape[1]} samples, fewer than the window ℓ = {net.window}")
    out = rollout_physical(net, norm, ua, ya)
    return out[0] if single else out


def rollout_physical(
    net: SequenceModel,
    norm: Normalisation,
    u: np.ndarray,
    y_burn_in: np.ndarray,
    *,
    batch_size: int = 4096,
) -> np.ndarray:
    """Run ``net.rollout`` on physical-unit arrays in batches, in the network's own dtype and
    device, without gradients: ``u`` ``(N, T, n_u)``, ``y_burn_in`` ``(N, ℓ, n_y)`` →
    ``(N, T − ℓ, n_y)`` float64."""
    ell = net.window
    param = next(net.parameters())
    out = np.empty((u.shape[0], u.shape[1] - ell, net.n_y))
    if out.shape[1] == 0:
        return out
    was_training = net.training
    net.eval()
    try:
        with torch.no_grad():
            for lo in range(0, u.shape[0], batch_size):
                sl = slice(lo, lo + batch_size)
                un = torch.as_tensor(norm.norm_u(u[sl]), dtype=param.dtype, device=param.device)
                yn = torch.as_tensor(
                    norm.norm_y(y_burn_in[sl]), dtype=param.dtype, device=param.device
                )
                pred = net.rollout(un[:, :ell], yn, un[:, ell:])
                out[sl] = pred.cpu().double().numpy()
    finally:
        net.train(was_training)
    return norm.denorm_y(out)
