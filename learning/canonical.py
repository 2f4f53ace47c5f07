"""The canonical state in torch: the shift of :mod:`canonid.kernel.canonical` for batched tensors.

Ordering (the same as :mod:`canonid.kernel.canonical`, the numpy reference): with window ℓ and
``p = n_u + n_y``,

    z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1}) ∈ R^{ℓ p},

pairs ``[u_i; y_i]`` stacked oldest first. The shift ``z_{t+1} = Ā z_t + B̄ u_t + S̄ y_t`` drops the
oldest pair and appends ``[u_t; y_t]``; here it is one concatenation, never a product with the
dense Kronecker matrices (which :func:`canonid.kernel.canonical.shift_matrices` builds for the
tests).
"""

from __future__ import annotations

import torch

from canonid.kernel.errors import ShapeError

__all__ = ["pairs_to_state", "shift", "state_to_pairs"]


def shift(z: torch.Tensor, u: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """``z_{t+1}`` from ``z_t`` ``(..., ℓp)``, ``u_t`` ``(..., n_u)`` and ``y_t`` ``(..., n_y)``.

    Differentiable in all three arguments; batched over the leading dimensions.
    """
    p = u.shape[-1] + y.shape[-1]
    if z.shape[-1] % p != 0 or z.shape[:-1] != u.shape[:-1] or z.shape[:-1] != y.shape[:-1]:
        raise ShapeError(
            f"shift: z {tuple(z.shape)}, u {tuple(u.shape)}, y {tuple(y.shape)} do not fit "
            "z = (..., ℓ·(n_u+n_y))"
        )
    return torch.cat([z[..., p:], u, y], dim=-1)


def pairs_to_state(u: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """``z`` ``(B, ℓp)`` from the ℓ measured samples ``u`` ``(B, ℓ, n_u)``, ``y`` ``(B, ℓ, n_y)``.

    Row ``i`` of the window (oldest first) becomes block ``i`` of ``z``: for a window holding
    samples ``t−ℓ … t−1`` this is ``z_t``.
    """
    if u.ndim != 3 or y.ndim != 3 or u.shape[:2] != y.shape[:2]:
        raise ShapeError(
            f"pairs_to_state: u {tuple(u.shape)} and y {tuple(y.shape)} must be (B, ℓ, n_u) and "
            "(B, ℓ, n_y) with the same B and ℓ"
        )
    return torch.cat([u, y], dim=-1).reshape(u.shape[0], -1)


def state_to_pairs(z: torch.Tensor, n_u: int, n_y: int) -> torch.Tensor:
    """The ℓ pairs ``[u_i; y_i]`` of ``z`` ``(B, ℓp)`` as ``(B, ℓ, p)``, oldest first."""
    p = n_u + n_y
    if z.shape[-1] % p != 0:
        raise ShapeError(f"state_to_pairs: z has {z.shape[-1]} columns, not a multiple of {p}")
    return z.reshape(*z.shape[:-1], z.shape[-1] // p, p)
