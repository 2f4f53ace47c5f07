"""The least-squares (ARX) fit of a canonical model's affine path: the linear start of training.

Regression, in the units the network sees (normalised by the training statistics): for every
training trajectory and every sample ``t = ℓ … T−1``,

    x_t = [z_t; u_t]   (``z_t`` alone without feedthrough),
    z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1}),
    target_t = y_t,  or  (y_t − y_{t−1}) / s  for a ``residual`` model (``s = residual_scale``),

and ``(L, c) = argmin Σ_t ‖L x_t + c − target_t‖²`` (minimum-norm solution when the regressors are
collinear, e.g. a constant input). This is the equation-error ARX model of orders ``n_a = n_b = ℓ``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import ShapeError
from canonid.learning.data import Normalisation
from canonid.learning.nets.base import CanonicalModel

__all__ = [
    "FEEDTHROUGH_GAIN",
    "FEEDTHROUGH_ROWS",
    "FeedthroughTest",
    "feedthrough_test",
    "initialise_linear",
    "least_squares",
    "regressors",
]


def regressors(
    trajectories: Sequence[Trajectory],
    norm: Normalisation,
    *,
    window: int,
    feedthrough: bool,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(X, y, y_prev)``: the rows ``x_t`` of the module docstring for every trajectory and
    ``t = ℓ, ℓ + stride, … < T`` in order, with the normalised ``y_t`` and ``y_{t−1}`` beside
    them (only the rows kept are copied)."""
    xs, ys, prev = [], [], []
    for tr in trajectories:
        if tr.T <= window:
            continue
        un, yn = norm.norm_u(tr.u), norm.norm_y(tr.y)
        pairs = np.concatenate([un, yn], axis=1)  # (T, p), one [u_i; y_i] per row
        p = pairs.shape[1]
        # row k of the view holds samples k … k+ℓ−1, i.e. z_{k+ℓ}
        z = np.lib.stride_tricks.sliding_window_view(pairs, (window, p))[
            : tr.T - window : stride, 0
        ]
        z = z.reshape(-1, window * p)
        xs.append(np.concatenate([z, un[window::stride]], axis=1) if feedthrough else z)
        ys.append(yn[window::stride])
        prev.append(yn[window - 1 : -1 : stride])
    if not xs:
        raise ShapeError(f"no training trajectory is longer than the window ℓ = {window}")
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(prev)


def least_squares(
    trajectories: Sequence[Trajectory],
    norm: Normalisation,
    *,
    window: int,
    feedthrough: bool,
    residual_scale: np.ndarray | None = None,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """``(L, c)``, ``L`` ``(n_y, dim x)`` and ``c`` ``(n_y,)``: the least-squares fit of the module
    docstring (``residual_scale`` given: the residual model's target) on every ``stride``-th row."""
    x, y, y_prev = regressors(
        trajectories, norm, window=window, feedthrough=feedthrough, stride=stride
    )
    target = y if residual_scale is None else (y - y_prev) / residual_scale
    design = np.concatenate([x, np.ones((x.shape[0], 1))], axis=1)
    theta, *_ = np.linalg.lstsq(design, target, rcond=None)
    return theta[:-1].T.copy(), theta[-1].copy()


def initialise_linear(
    net: CanonicalModel, trajectories: Sequence[Trajectory], norm: Normalisation
) -> None:
    """Set ``net``'s affine path to the least-squares fit and its nonlinear output layer to zero,
    so that ``net`` starts as the ARX model (``net`` must have the affine path)."""
    if net.affine is None:
        raise ShapeError(f"{net.name}: the model has no affine path (linear='off')")
    scale = net.residual_scale.detach().cpu().numpy().astype(np.float64) if net.residual else None
    L, c = least_squares(
        trajectories, norm, window=net.window, feedthrough=net.feedthrough, residual_scale=scale
    )
    with torch.no_grad():
        net.affine.weight.copy_(torch.as_tensor(L))
        net.affine.bias.copy_(torch.as_tensor(c))
        last = net.output_layer()
        if last is not None:
            last.weight.zero_()
            last.bias.zero_()


#: ``feedthrough="auto"`` gives the output map ``u_t`` when, in the least-squares (ARX) fit of
#: order ℓ, ``u_t`` brings the one-step error on validation below this fraction of the error
#: without it
FEEDTHROUGH_GAIN = 0.8
#: the test fits and scores at most about this many rows of each split (every k-th sample), so
#: that a long record with a long window stays within a few hundred MB and seconds
FEEDTHROUGH_ROWS = 60_000


@dataclass(frozen=True)
class FeedthroughTest:
    """What ``feedthrough="auto"`` measured: the one-step validation MSE (normalised units) of
    the least-squares fits of order ℓ without and with ``u_t``, and the decision (an
    estimate from data: the nonlinear model may gain or lose differently)."""

    window: int
    without_u: float
    with_u: float
    feedthrough: bool

    def to_dict(self) -> dict[str, float | int | bool]:
        return dataclasses.asdict(self)


def feedthrough_test(
    train: Sequence[Trajectory], val: Sequence[Trajectory], norm: Normalisation, *, window: int
) -> FeedthroughTest:
    """Whether ``u_t`` should reach the output map (:data:`FEEDTHROUGH_GAIN`); the fits read
    ``train``, the errors ``val`` (each at most about :data:`FEEDTHROUGH_ROWS` rows)."""

    def stride(group: Sequence[Trajectory]) -> int:
        return max(1, -(-sum(max(tr.T - window, 0) for tr in group) // FEEDTHROUGH_ROWS))

    errors = []
    for feedthrough in (False, True):
        L, c = least_squares(
            train, norm, window=window, feedthrough=feedthrough, stride=stride(train)
        )
        try:
            x, y, _ = regressors(
                val, norm, window=window, feedthrough=feedthrough, stride=stride(val)
            )
        except ShapeError:
            raise ShapeError(
                f"no validation trajectory is longer than the window ℓ = {window}"
            ) from None
        errors.append(float(np.mean((x @ L.T + c - y) ** 2)))
    without_u, with_u = errors
    return FeedthroughTest(window, without_u, with_u, with_u < FEEDTHROUGH_GAIN * without_u)
