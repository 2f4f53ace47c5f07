"""γ_f of a learned model: the Lipschitz constant in its state of ``f = Ā z + B̄ u + S̄ Ĥ(z, u)``.

The learned model is a :class:`canonid.models.learned.LearnedSystem` (its SX graph built from the
weights), so the estimators of :mod:`canonid.analysis.lipschitz` run on it unchanged, on the box
hull X of the training windows and the training inputs U:

* ``lower`` — **lower bound**: sampled and locally maximised ``‖∂f/∂z‖₂`` (:func:`lipschitz_lower`);
* ``upper`` — **certified upper bound**: interval branch-and-bound (:func:`lipschitz_upper`),
  valid whenever it stops, on the network's layers for Ours (MLP)
  (:mod:`canonid.analysis.network_enclosure`, 1–30 ms per box) and on the SX graph otherwise (a
  reduced or GRU model); in ℓ(n_u+n_y) dimensions the budget usually ends long before the
  bracket closes;
* ``layer_norms`` — **certified upper bound, loose**: the product of the layer norms (below), a
  Lipschitz constant on the whole space, so also on X × U; finite for Ours (MLP) and its reduced
  model, except where a cubic branch reads the window (below); for a GRU regressor it is the
  trivial ``∞``.

Layer-norm bound. With ``Ĥ = y_mean + D_y ỹ``, ``ỹ = C a + diag(s) MLP(a)``, ``a`` the normalised
``[z; u]`` (``C``: the residual and affine terms,
:meth:`canonid.kernel.network.CanonicalNet.linear_part`),

    ‖∂Ĥ/∂z‖₂ ≤ ‖D_y C_z D_z⁻¹‖₂ + ‖D_y diag(s) W_L‖₂ ∏_{k<L} (σ'_max ‖W_k‖₂) with W_1 → W_1,z D_z⁻¹,

and since the rows of ``∂f/∂z = [Ā_top; 0; ∂Ĥ/∂z]`` split into the shift (norm 1 for ℓ ≥ 2, 0 for
ℓ = 1) and ``∂Ĥ/∂z``, ``γ_f ≤ √(‖Ā‖² + ‖∂Ĥ/∂z‖²)``. For a reduced model ``f = E ∘ g ∘ D`` with
``g`` the same map in normalised units, ``γ_f ≤ Lip(E) · √(‖Ā‖² + Lip(g_y)²) · Lip(D)``, each
auto-encoder half bounded by its layer product plus its skip path's norm. Every matrix norm is a
verified bound (:func:`canonid.analysis.matrix_bounds.spectral_upper`) and every product and sum is
rounded upwards.

A cubic branch ``C (W x + b)³`` (:class:`canonid.kernel.network.CanonicalNet`) has the slope
``C diag(3 h²) W``, unbounded on the whole space when some unit with a non-zero column of ``C``
reads ``z``: a network with one has **no finite global bound**, and ``layer_norms`` is the
trivial ``∞`` with that reason in its ``method`` and alone in ``details["unbounded"]`` (an
activation without a finite slope bound in :data:`canonid.kernel.network.ACTIVATIONS`, the cube,
anywhere in the layers likewise; a GRU regressor, which has no layer-norm bound, too). The
bracket on X × U is unaffected: the enclosures bound the slope on each box. A branch that does
not read ``z`` (``C = 0``, as training starts) adds nothing to ``∂f/∂z``, and the bound is the
network's.

The true system's γ_f on its own X (for the same window ℓ) is a different quantity — its state is
the physical ``x``, not the window ``z`` — set beside this one by ``canonid analyze --run``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.analysis.estimate import Bracket, Budget, Estimate
from canonid.analysis.interval import Interval
from canonid.analysis.lipschitz import lipschitz_bracket
from canonid.analysis.matrix_bounds import spectral_upper
from canonid.analysis.network_enclosure import network_enclosure
from canonid.kernel.network import ACTIVATIONS, CanonicalNet, Layer, ReducedCanonicalNet
from canonid.models.learned import LearnedSystem

__all__ = ["LearnedGamma", "layer_norm_bound", "layer_norm_words", "learned_gamma"]

Progress = Callable[[str, float], None]


def _up(value: float) -> float:
    return float(np.nextafter(value, np.inf))


def _norm(matrix: np.ndarray) -> float:
    """A verified upper bound of ``‖matrix‖₂``."""
    if matrix.size == 0 or not np.any(matrix):
        return 0.0
    return float(spectral_upper(Interval.point(np.asarray(matrix, dtype=np.float64)[None]))[0])


def _chain(weights: Sequence[np.ndarray], slopes: Sequence[float]) -> float:
    """``∏_k ‖W_k‖₂ · slope_k`` rounded upwards (``slopes`` of the activations after each)."""
    out = 1.0
    for w, slope in zip(weights, slopes):
        out = _up(_up(out * _norm(w)) * slope)
    return out


def _network(layers: Sequence[Layer], skip: Layer | None) -> float:
    """A Lipschitz constant of ``layers`` plus an optional affine ``skip`` path."""
    out = _chain([layer.weight for layer in layers], [ACTIVATIONS[x.activation] for x in layers])
    return out if skip is None else _up(out + _norm(skip.weight))


def _regressor_z(net: CanonicalNet, z_scale: np.ndarray, y_scale: np.ndarray) -> float:
    """A Lipschitz constant in ``z`` of ``y_scale ⊙ ỹ(z / z_scale, ·)`` (module docstring)."""
    d = net.state_dim
    weights = [layer.weight for layer in net.layers]
    weights[0] = weights[0][:, :d] / z_scale
    weights[-1] = (y_scale * net.output_scale)[:, None] * weights[-1]
    slopes = [ACTIVATIONS[layer.activation] for layer in net.layers]
    linear = (y_scale[:, None] * net.linear_part()[:, :d]) / z_scale
    return _up(_norm(linear) + _chain(weights, slopes))


def _unbounded(net: CanonicalNet | ReducedCanonicalNet) -> str | None:
    """Why ``net`` has no finite global Lipschitz constant in its state, or ``None``."""
    reg = net.regressor if isinstance(net, ReducedCanonicalNet) else net
    if reg.cubic_reads_state():
        return "the slope 3 h² of its cubic branch is unbounded on the whole space"
    layers = list(reg.layers)
    if isinstance(net, ReducedCanonicalNet):
        layers += [*net.encoder, *net.decoder]
    names = sorted({x.activation for x in layers if not math.isfinite(ACTIVATIONS[x.activation])})
    if names:
        return f"the slope of its activation {', '.join(names)} is unbounded on the whole space"
    return None


def layer_norm_bound(system: LearnedSystem) -> Estimate:
    """The product-of-layer-norms upper bound of γ_f (module docstring): certified, loose; the
    trivial ``∞`` where the network has no finite global bound (a GRU, a cubic branch)."""
    t0 = time.perf_counter()
    net = system.network
    reg = system.regressor
    members = system.members if len(system.members) > 1 else ()
    why = (
        "a GRU regressor has no layer-norm bound"
        if any(m.recurrent for m in (reg, *members))
        else next((w for w in map(_unbounded, (net, *members)) if w is not None), None)
    )
    if why is not None:
        return Estimate(
            quantity="gamma_f",
            value=math.inf,
            kind="upper",
            sets={"X": system.X, "U": system.U},
            method=(
                "trivial: no layer-norm bound for a GRU regressor"
                if reg.recurrent
                else f"trivial: no finite global bound ({why})"
            ),
            window=reg.window,
            details={"unbounded": why},  # the reason alone, for a summary line
        )
    shift = 1.0 if reg.window >= 2 else 0.0
    if isinstance(net, ReducedCanonicalNet):
        inner = _regressor_z(reg, np.ones(reg.state_dim), np.ones(reg.n_y))
        encoder = _network(net.encoder, net.encoder_skip)
        decoder = _network(net.decoder, net.decoder_skip)
        middle = _up(math.sqrt(_up(shift + _up(inner * inner))))
        value = _up(_up(encoder * middle) * decoder)
        parts: dict[str, Any] = {"encoder": encoder, "regressor_z": inner, "decoder": decoder}
    else:
        # an ensemble's Ĥ is the mean of its members': its slope is at most the mean of theirs
        inners = [_regressor_z(m, m.z_std, m.y_std) for m in (members or (reg,))]
        inner = inners[0] if len(inners) == 1 else _up(_up(math.fsum(inners)) / len(inners))
        value = _up(math.sqrt(_up(shift + _up(inner * inner))))
        parts = {"regressor_z": inner, **({"members_regressor_z": inners} if members else {})}
    return Estimate(
        quantity="gamma_f",
        value=value,
        kind="upper",
        sets={"X": system.X, "U": system.U},
        method="certified, loose: product of layer norms (holds on the whole space)",
        window=reg.window,
        seconds=time.perf_counter() - t0,
        details={"shift_norm": shift, **parts},
    )


def layer_norm_words(layer_norms: Mapping[str, Any]) -> str:
    """How a summary line names the layer-norm bound (:meth:`Estimate.to_dict` of
    :func:`layer_norm_bound`): with the reason where it is infinite, else as loose."""
    why = layer_norms.get("details", {}).get("unbounded")
    return "product of layer norms" + (f": {why}" if why else ", loose")


@dataclass(frozen=True)
class LearnedGamma:
    """γ_f of a learned model on its training hull.

    Attributes:
        bracket: the sampled lower bound and the branch-and-bound upper bound.
        layer_norms: the product-of-layer-norms upper bound.
    """

    bracket: Bracket
    layer_norms: Estimate

    @property
    def upper(self) -> Estimate:
        """The smaller of the two certified upper bounds."""
        b = self.bracket.upper
        return b if b.value <= self.layer_norms.value else self.layer_norms

    def to_dict(self) -> dict[str, Any]:
        return {
            "lower": self.bracket.lower.to_dict(),
            "branch_and_bound": self.bracket.upper.to_dict(),
            "layer_norms": self.layer_norms.to_dict(),
            "best_upper": self.upper.value if math.isfinite(self.upper.value) else None,
        }


def learned_gamma(
    system: LearnedSystem,
    *,
    budget: Budget | None = None,
    tol: float = 0.05,
    seed: int = 0,
    progress: Progress | None = None,
) -> LearnedGamma:
    """γ_f of ``system`` on ``system.X × system.U``: sampled lower bound, certified
    branch-and-bound upper bound and the layer-norm bound (see the module docstring)."""
    # an MLP model: its layers give fast enclosures and its point Jacobians come from numpy
    enclosure = network_enclosure(system)
    rows = None if enclosure is None else (lambda x, u: system.linearise(x, u).f_x)
    bracket = lipschitz_bracket(
        system.f,
        system.X,
        system.U,
        window=system.regressor.window,
        tol=tol,
        budget=budget,
        seed=seed,
        where="the training hull X × U of the learned model",
        progress=progress,
        enclosure=enclosure,
        jacobian=rows,
    )
    return LearnedGamma(bracket=bracket, layer_norms=layer_norm_bound(system))
