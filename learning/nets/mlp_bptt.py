"""The training rollout of Ours (MLP) as one autograd node, with back-propagation through time
written out (:func:`bptt_rollout`).

:meth:`CanonicalModel.rollout <canonid.learning.nets.base.CanonicalModel.rollout>` builds the
canonical shift from concatenations and lets autograd record every operation of every step; on
a CPU core, with a batch of 32 windows and 3 × 256 units, that bookkeeping costs as much as the
matrix products. Here the rollout is computed on one sequence buffer and differentiated by hand:

* **One buffer, no shift.** The pairs ``[u_t; y_t]`` of a window lie one after another in a
  ``(B, (ℓ+H)(n_u+n_y))`` buffer ``S`` (the burn-in and the inputs written before the rollout,
  each prediction written once, where the next pair's output goes). The state ``z_t`` is then the
  slice of ℓ pairs that ends before step ``t``, and with feedthrough the head's input
  ``[z_t; u_t]`` is that slice extended by ``u_t``, which follows it: a view, never a copy.
* **One product for the head's input.** The first hidden layer, the cubic branch's input layer
  and the affine path all read the head's input; their weights are stacked into one matrix.
* **Weight gradients after the loop.** Back-propagation runs backwards over the steps for the
  gradients of the activations only (what the next step back needs); the gradients of the
  weights are sums over the steps, computed at the end as one product over all ``H × B`` rows.

The values are those of :meth:`CanonicalModel.rollout` up to rounding (the products are summed in
another order); tests compare both, and their gradients, in float64.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import torch
from torch.autograd.function import once_differentiable

__all__ = ["bptt_rollout", "uses_bptt"]

# ``net`` below is a canonid.learning.nets.OursMLP (typed Any: that module imports this one)

_aten = torch.ops.aten


def _activate(name: str, a: torch.Tensor, out: torch.Tensor) -> None:
    """``out = act(a)``, written in place."""
    if name == "silu":
        _aten.silu.out(a, out=out)
    elif name == "relu":
        torch.clamp_min(a, 0.0, out=out)
    else:
        torch.tanh(a, out=out)


def _activate_back(
    name: str, grad: torch.Tensor, a: torch.Tensor, h: torch.Tensor, out: torch.Tensor
) -> torch.Tensor:
    """``out = grad ⊙ act'(a)`` (``h = act(a)``; ReLU and tanh read their derivative off it)."""
    if name == "silu":
        return _aten.silu_backward.grad_input(grad, a, grad_input=out)
    if name == "relu":
        return _aten.threshold_backward.grad_input(grad, h, 0.0, grad_input=out)
    return _aten.tanh_backward.grad_input(grad, h, grad_input=out)


@dataclass(frozen=True)
class _Shape:
    """What the hand-written rollout needs to know about the network."""

    activation: str
    hidden: int  # number of hidden layers (≥ 1)
    cubic: int  # units of the cubic branch (0: none)
    affine: bool
    feedthrough: bool
    residual: bool
    n_u: int
    n_y: int
    window: int

    @property
    def pair(self) -> int:
        return self.n_u + self.n_y

    @property
    def head_input(self) -> int:
        """Width of the head's input ``[z_t; u_t]`` (``z_t`` without feedthrough)."""
        return self.window * self.pair + (self.n_u if self.feedthrough else 0)


def _parameters(net: Any) -> list[torch.Tensor]:
    """The network's parameters in the order :class:`_Rollout` reads them: each layer's weight
    and bias, then the cubic branch's ``W, b, C``, then the affine path's ``L, c``."""
    layers = [m for m in net.net if isinstance(m, torch.nn.Linear)]
    params = [t for layer in layers for t in (layer.weight, layer.bias)]
    if net.cubic_in is not None and net.cubic_out is not None:
        params += [net.cubic_in.weight, net.cubic_in.bias, net.cubic_out.weight]
    if net.affine is not None:
        params += [net.affine.weight, net.affine.bias]
    return params


def uses_bptt(net: Any, *inputs: torch.Tensor) -> bool:
    """Whether :meth:`OursMLP.rollout` takes :func:`bptt_rollout`: when gradients of the weights
    are recorded, of nothing else (a custom node has no gradient for the data, nor a second
    derivative), and the network has a hidden layer and its own, unwrapped layers."""
    return (
        net.bptt
        and torch.is_grad_enabled()
        and type(net.net) is torch.nn.Sequential  # not wrapped (e.g. by torch.compile)
        and len(net.hidden) > 0
        and not any(x.requires_grad for x in inputs)
        and all(p.requires_grad for p in _parameters(net))
    )


def bptt_rollout(
    net: Any, u_past: torch.Tensor, y_past: torch.Tensor, u_future: torch.Tensor
) -> torch.Tensor:
    """``net.rollout(u_past, y_past, u_future)`` ``(B, H, n_y)``, differentiable in the weights
    by the hand-written back-propagation of the module docstring."""
    b, ell, n_u = u_past.shape
    horizon = u_future.shape[1]
    shape = _Shape(
        activation=net.activation,
        hidden=len(net.hidden),
        cubic=net.cubic,
        affine=net.affine is not None,
        feedthrough=net.feedthrough,
        residual=net.residual,
        n_u=n_u,
        n_y=net.n_y,
        window=ell,
    )
    seq = u_past.new_zeros(b, ell + horizon, shape.pair)
    seq[:, :ell, :n_u] = u_past
    seq[:, :ell, n_u:] = y_past
    seq[:, ell:, :n_u] = u_future
    out: torch.Tensor = _Rollout.apply(
        shape, seq.view(b, -1), net.residual_scale, *_parameters(net)
    )
    return out


def _unpack(shape: _Shape, params: Sequence[torch.Tensor]) -> dict[str, Any]:
    """Name the parameters of :func:`_parameters`: the hidden layers, the output layer, and the
    stacked weights of the three maps that read the head's input (first layer, cubic, affine)."""
    n = shape.hidden + 1
    layers = [(params[2 * i], params[2 * i + 1]) for i in range(n)]
    rest = list(params[2 * n :])
    first_w, first_b = [layers[0][0]], [layers[0][1]]
    cubic_out = None
    if shape.cubic:
        first_w.append(rest[0])
        first_b.append(rest[1])
        cubic_out = rest[2]
        rest = rest[3:]
    if shape.affine:
        first_w.append(rest[0])
        first_b.append(rest[1])
    return {
        "layers": layers,
        "head_w": torch.cat(first_w),
        "head_b": torch.cat(first_b),
        "cubic_out": cubic_out,
    }


class _Rollout(torch.autograd.Function):
    """The rollout on the sequence buffer ``seq`` ``(B, (ℓ+H) p)`` (inputs and burn-in filled);
    returns the predictions ``(B, H, n_y)``; gradients for the parameters only."""

    @staticmethod
    def forward(
        ctx: Any, shape: _Shape, seq: torch.Tensor, scale: torch.Tensor, *params: torch.Tensor
    ) -> torch.Tensor:
        named = _unpack(shape, params)
        layers, head_w, head_b = named["layers"], named["head_w"], named["head_b"]
        cubic_out = named["cubic_out"]
        p, ell, n_u, n_y, k = shape.pair, shape.window, shape.n_u, shape.n_y, shape.cubic
        b, horizon = seq.shape[0], seq.shape[1] // p - ell
        h1, width = layers[0][0].shape[0], head_w.shape[0]
        # per step: the head's products (first layer | cubic input | affine), each hidden
        # layer's pre-activation and activation, the cubes; all read again by the backward pass
        head = seq.new_empty(horizon, b, width)
        pre = [seq.new_empty(horizon, b, w.shape[0]) for w, _ in layers[1:-1]]
        act = [seq.new_empty(horizon, b, w.shape[0]) for w, _ in layers[:-1]]
        cubes = seq.new_empty(horizon, b, k) if k else None
        raw = seq.new_empty(b, n_y)
        out_w, out_b = layers[-1]
        n_in = shape.head_input
        for t in range(horizon):
            x = seq[:, t * p : t * p + n_in]  # [z_t; u_t]: the ℓ pairs before step t, then u_t
            torch.addmm(head_b, x, head_w.t(), out=head[t])
            _activate(shape.activation, head[t, :, :h1], act[0][t])
            for i, (w, bias) in enumerate(layers[1:-1]):
                torch.addmm(bias, act[i][t], w.t(), out=pre[i][t])
                _activate(shape.activation, pre[i][t], act[i + 1][t])
            torch.addmm(out_b, act[-1][t], out_w.t(), out=raw)
            if cubes is not None:
                torch.pow(head[t, :, h1 : h1 + k], 3, out=cubes[t])
                raw.addmm_(cubes[t], cubic_out.t())
            if shape.affine:
                raw += head[t, :, h1 + k :]
            y_at = (t + ell) * p + n_u  # where y_t goes: the output slot of pair t + ℓ
            if shape.residual:  # y_t = y_{t−1} + s ⊙ raw, y_{t−1} the newest output in z_t
                y_prev = seq[:, y_at - p : y_at - p + n_y]
                seq[:, y_at : y_at + n_y] = torch.addcmul(y_prev, raw, scale)
            else:
                seq[:, y_at : y_at + n_y] = raw
        ctx.shape = shape
        kept = [seq, scale, head_w, *(w for w, _ in layers), head, *pre, *act]
        if cubes is not None:
            kept += [cubic_out, cubes]
        ctx.save_for_backward(*kept)
        return seq.view(b, ell + horizon, p)[:, ell:, n_u:].clone()

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad_y: torch.Tensor) -> tuple[torch.Tensor | None, ...]:
        shape: _Shape = ctx.shape
        saved = list(ctx.saved_tensors)
        n_hidden, k = shape.hidden, shape.cubic
        seq, scale, head_w = saved[:3]
        weights = saved[3 : 4 + n_hidden]
        head = saved[4 + n_hidden]
        pre = saved[5 + n_hidden : 4 + 2 * n_hidden]
        act = saved[4 + 2 * n_hidden : 4 + 3 * n_hidden]
        cubic_out, cubes = saved[4 + 3 * n_hidden :] if k else (None, None)
        p, ell, n_u, n_y = shape.pair, shape.window, shape.n_u, shape.n_y
        b, horizon = seq.shape[0], seq.shape[1] // p - ell
        h1, width, n_in = weights[0].shape[0], head_w.shape[0], shape.head_input
        grad_seq = seq.new_zeros(b, seq.shape[1])  # ∂L/∂(buffer entry), read by the outputs
        grad_head = seq.new_empty(horizon, b, width)
        grad_pre = [seq.new_empty(horizon, b, w.shape[0]) for w in weights[1:-1]]
        # the affine path's gradient is the raw output's: keep it where the head's is
        grad_raw = grad_head[:, :, h1 + k :] if shape.affine else seq.new_empty(horizon, b, n_y)
        for t in range(horizon - 1, -1, -1):
            y_at = (t + ell) * p + n_u
            # every later step that read y_t has added its share to grad_seq by now
            grad = grad_y[:, t] + grad_seq[:, y_at : y_at + n_y]
            if shape.residual:
                torch.mul(grad, scale, out=grad_raw[t])
                grad_seq[:, y_at - p : y_at - p + n_y] += grad
            else:
                grad_raw[t].copy_(grad)
            grad_h = grad_raw[t] @ weights[-1]
            for i in range(n_hidden - 2, -1, -1):  # hidden layers 2 … n, last first
                _activate_back(shape.activation, grad_h, pre[i][t], act[i + 1][t], grad_pre[i][t])
                grad_h = grad_pre[i][t] @ weights[i + 1]
            _activate_back(
                shape.activation, grad_h, head[t, :, :h1], act[0][t], grad_head[t, :, :h1]
            )
            if cubic_out is not None:
                c = head[t, :, h1 : h1 + k]
                torch.mul(grad_raw[t] @ cubic_out, 3.0 * c * c, out=grad_head[t, :, h1 : h1 + k])
            grad_seq[:, t * p : t * p + n_in].addmm_(grad_head[t], head_w)
        # the weights' gradients: sums over the steps, one product over all H × B rows each
        rows = horizon * b
        x = seq.as_strided((horizon, b, n_in), (p, seq.stride(0), 1)).reshape(rows, n_in)
        g_head = grad_head.reshape(rows, width)
        head_grad_w, head_grad_b = g_head.t() @ x, g_head.sum(0)
        grads = [head_grad_w[:h1], head_grad_b[:h1]]
        for i in range(n_hidden - 1):
            g = grad_pre[i].reshape(rows, -1)
            grads += [g.t() @ act[i].reshape(rows, -1), g.sum(0)]
        g_raw = grad_raw.reshape(rows, n_y)
        grads += [g_raw.t() @ act[-1].reshape(rows, -1), g_raw.sum(0)]
        if cubes is not None:
            cube_rows = cubes.reshape(rows, k)
            grads += [head_grad_w[h1 : h1 + k], head_grad_b[h1 : h1 + k], g_raw.t() @ cube_rows]
        if shape.affine:
            grads += [head_grad_w[h1 + k :], head_grad_b[h1 + k :]]
        return (None, None, None, *grads)
