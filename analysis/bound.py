"""Proposition 2 and its Monte-Carlo check.

Proposition 2 (paper §III-A). With ``x̂_{t−ℓ} ∈ argmin_{x∈X} ‖ȳ_{t−ℓ|t−1} − O_ℓ(x, ū)‖`` and
``x̂_t = F_ℓ(x̂_{t−ℓ}, ū_{t−ℓ|t−1})``,

    ‖x̂_t − x_t‖ ≤ 2 γ_f^ℓ α_ℓ^{−1} ‖w̄_{t−ℓ|t−1}‖,

where ``w̄_{t−ℓ|t−1} = (w_{t−ℓ}, …, w_{t−1}) ∈ R^{ℓ·n_y}`` is the stacked measurement noise of
the window and every norm is Euclidean. The proof: optimality gives ``‖ȳ − O(x̂)‖ ≤ ‖w̄‖``, so
``‖O(x̂) − O(x_{t−ℓ})‖ ≤ 2‖w̄‖`` and ``‖x̂_{t−ℓ} − x_{t−ℓ}‖ ≤ 2 α_ℓ^{−1}‖w̄‖``; ``F_ℓ`` is
``γ_f^ℓ``-Lipschitz (Lemma 1). Here γ_f must hold on a convex set containing every state reached
in ``ℓ − 1`` steps (:mod:`canonid.analysis.reach`), which is how the constants are computed.

Consequence used for learned models (paper §III-B): ``y_t = h(x̂_t, u_t) + ξ_t`` with
``‖ξ_t‖ ≤ ‖w_t‖ + γ_h ‖x̂_t − x_t‖ ≤ ‖w_t‖ + 2 γ_h γ_f^ℓ α_ℓ^{−1}‖w̄‖``. The paper writes this
level without the factor 2 of Proposition 2; the factor is kept here (it is what the proof gives
for a general argmin; for a linear system's least-squares estimate the factor 1 already holds).

Along recorded trajectories (:func:`bound_along`): the bound of every window of ℓ samples of a
recorded noise sequence, marked where the premises hold (the state at the window's start in X, the
window's inputs in U), and the reason when a constant makes it infinite.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from canonid.analysis.argmin import output_error_argmin
from canonid.analysis.estimate import Estimate
from canonid.analysis.maps import Horizon, batched, check_window
from canonid.analysis.observability import input_box
from canonid.kernel.errors import SetError, ShapeError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["BoundCheck", "BoundConstants", "TrajectoryBound", "bound_along", "check_bound"]

_QUANTILES = (0.5, 0.9, 0.99, 1.0)


@dataclass(frozen=True)
class BoundConstants:
    """The constants of Proposition 2 for one window.

    Attributes:
        window: ``ℓ``.
        gamma_f: γ_f — an upper bound makes the bound valid.
        alpha: α_ℓ — a lower bound makes the bound valid.
        gamma_h: γ_h (for the residual level of learned models), optional.
    """

    window: int
    gamma_f: Estimate
    alpha: Estimate
    gamma_h: Estimate | None = None

    def __post_init__(self) -> None:
        check_window(self.window)
        if self.gamma_f.quantity != "gamma_f" or self.alpha.quantity != "alpha":
            raise SetError(
                f"constants must be gamma_f and alpha estimates, got {self.gamma_f.quantity} "
                f"and {self.alpha.quantity}"
            )
        if self.gamma_h is not None and self.gamma_h.quantity != "gamma_h":
            raise SetError(f"gamma_h must be a gamma_h estimate, got {self.gamma_h.quantity}")

    @property
    def certified(self) -> bool:
        """True when γ_f (and γ_h) are upper bounds and α_ℓ a lower bound: the bound holds."""
        ok = self.gamma_f.kind == "upper" and self.alpha.kind == "lower"
        return ok and (self.gamma_h is None or self.gamma_h.kind == "upper")

    @property
    def factor(self) -> float:
        """``γ_f^ℓ / α_ℓ`` (``inf`` when ``α_ℓ = 0``: the proposition then says nothing)."""
        if self.alpha.value <= 0:
            return math.inf
        try:
            return float(self.gamma_f.value**self.window / self.alpha.value)
        except OverflowError:  # γ_f^ℓ beyond the float range: as good as no bound
            return math.inf

    def bound(self, noise_norm: np.ndarray | float) -> np.ndarray:
        """``2 γ_f^ℓ α_ℓ^{−1} ‖w̄‖`` for the given norms of the stacked window noise."""
        w = np.asarray(noise_norm, dtype=np.float64)
        if math.isinf(self.factor):
            return np.where(w > 0, np.inf, 0.0)
        return 2.0 * self.factor * w

    def why_infinite(self) -> str | None:
        """Why ``2 γ_f^ℓ α_ℓ^{−1}`` is infinite — which constant, and how it was obtained — or
        ``None`` when the factor is finite."""
        if self.alpha.value <= 0:
            # an exact 0 is structure (outputs that miss some state); any other 0 is a search
            # that certified nothing positive
            what = (
                "the window's outputs do not separate the states"
                if self.alpha.method.startswith("exact")
                else "no positive bound was certified"
            )
            return (
                f"α_{self.window} has the {self.alpha.kind} bound 0 ({self.alpha.method}): {what}"
            )
        if not math.isfinite(self.gamma_f.value):
            why = self.gamma_f.details.get("why")
            return f"γ_f has no finite {self.gamma_f.kind} bound ({self.gamma_f.method})" + (
                f": {why}" if why else ""
            )
        if math.isinf(self.factor):
            return f"γ_f^{self.window} = {self.gamma_f.value:.4g}^{self.window} overflows float64"
        return None

    def residual_level(self, w_now: np.ndarray, w_window: np.ndarray) -> np.ndarray:
        """``‖w_t‖ + 2 γ_h γ_f^ℓ α_ℓ^{−1}‖w̄_{t−ℓ|t−1}‖`` (needs ``gamma_h``)."""
        if self.gamma_h is None:
            raise SetError("the residual level needs gamma_h in the constants")
        return np.asarray(w_now) + self.gamma_h.value * self.bound(w_window)

    def to_dict(self) -> dict[str, Any]:
        out = {
            "window": self.window,
            "gamma_f": self.gamma_f.to_dict(),
            "alpha": self.alpha.to_dict(),
            "factor": self.factor if math.isfinite(self.factor) else None,
            "certified": self.certified,
        }
        if self.gamma_h is not None:
            out["gamma_h"] = self.gamma_h.to_dict()
        return out


def _quantiles(values: np.ndarray) -> dict[str, float | None]:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return {f"q{int(q * 100)}": None for q in _QUANTILES}
    return {f"q{int(q * 100)}": float(np.quantile(finite, q)) for q in _QUANTILES}


@dataclass(frozen=True)
class BoundCheck:
    """Result of the Monte-Carlo check of Proposition 2 for one window.

    Attributes:
        window: ``ℓ``.
        trials: number of trials.
        violations: trials (solver failures excluded) whose error exceeds the bound.
        solver_failures: trials whose found objective exceeds the objective at the true state.
        max_ratio: largest error / bound over the trials that are not solver failures
            (``None`` when the bound is infinite).
        ratio_quantiles: quantiles of error / bound (``q50``, ``q90``, ``q99``, ``q100``).
        max_error, median_error: of ``‖x̂_t − x_t‖``.
        worst_case_bound: the bound at the largest ``‖w̄‖`` over ``W^ℓ``
            (``2 γ_f^ℓ α_ℓ^{−1} √ℓ · max_{w∈W}‖w‖``), ``None`` when infinite.
        constants: the constants used (:meth:`BoundConstants.to_dict`).
        max_ratio_estimated: the largest error / bound with the *estimated* constants (sampled
            γ_f, sampled α_ℓ) when given — a bound that is not proved, shown for comparison.
        seconds: wall time.
        errors, bounds, failed: per-trial arrays (not written to JSON).
    """

    window: int
    trials: int
    violations: int
    solver_failures: int
    max_ratio: float | None
    ratio_quantiles: Mapping[str, float | None]
    max_error: float
    median_error: float
    worst_case_bound: float | None
    constants: Mapping[str, Any]
    max_ratio_estimated: float | None = None
    seconds: float = 0.0
    settings: Mapping[str, Any] = field(default_factory=dict)
    errors: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    bounds: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    failed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {
            "window": self.window,
            "trials": self.trials,
            "violations": self.violations,
            "solver_failures": self.solver_failures,
            "max_ratio": self.max_ratio,
            "ratio_quantiles": dict(self.ratio_quantiles),
            "max_error": self.max_error,
            "median_error": self.median_error,
            "worst_case_bound": self.worst_case_bound,
            "max_ratio_estimated": self.max_ratio_estimated,
            "constants": dict(self.constants),
            "seconds": round(self.seconds, 6),
            "settings": dict(self.settings),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BoundCheck:
        """The check of a :meth:`to_dict` record (without the per-trial arrays)."""
        return cls(
            window=int(data["window"]),
            trials=int(data["trials"]),
            violations=int(data["violations"]),
            solver_failures=int(data["solver_failures"]),
            max_ratio=data["max_ratio"],
            ratio_quantiles=dict(data["ratio_quantiles"]),
            max_error=float(data["max_error"]),
            median_error=float(data["median_error"]),
            worst_case_bound=data["worst_case_bound"],
            constants=dict(data["constants"]),
            max_ratio_estimated=data.get("max_ratio_estimated"),
            seconds=float(data.get("seconds", 0.0)),
            settings=dict(data.get("settings", {})),
        )


@dataclass(frozen=True)
class TrajectoryBound:
    """Proposition 2's bound along recorded trajectories (:func:`bound_along`).

    One entry per window start ``j`` of each trajectory, in order (trajectory by trajectory):
    the window holds the samples ``j … j+ℓ−1`` and the bound is on the error of the estimate of
    the state at sample ``j+ℓ``.

    Attributes:
        constants: the constants used.
        trajectory: the index of the trajectory of each window.
        start: ``j`` within its trajectory.
        noise_norms: ``‖w̄_{j|j+ℓ−1}‖`` (Euclidean norm of the stacked noise of the window).
        bounds: ``2 γ_f^ℓ α_ℓ^{−1}‖w̄‖`` (``inf`` where the factor is infinite and ``w̄ ≠ 0``).
        applies: where the premises hold — ``x_j ∈ X`` (the argmin is over X) and
            ``u_j … u_{j+ℓ−1} ∈ U`` — when states and inputs were given; ``True`` otherwise.
    """

    constants: BoundConstants
    trajectory: np.ndarray
    start: np.ndarray
    noise_norms: np.ndarray
    bounds: np.ndarray
    applies: np.ndarray

    @property
    def infinite(self) -> str | None:
        """Why the bound is infinite (:meth:`BoundConstants.why_infinite`), or ``None``."""
        return self.constants.why_infinite()

    def summary(self) -> dict[str, Any]:
        """Median and largest bound and ``‖w̄‖`` over the windows where the premises hold
        (bounds ``None`` when infinite, with the reason in ``infinite``); JSON-ready."""
        ok = self.applies
        b, w = self.bounds[ok], self.noise_norms[ok]
        finite = b.size > 0 and bool(np.all(np.isfinite(b)))
        return {
            "window": self.constants.window,
            "windows": int(self.applies.size),
            "windows_applied": int(np.count_nonzero(ok)),
            "certified": self.constants.certified,
            "factor": self.constants.factor if math.isfinite(self.constants.factor) else None,
            "infinite": self.infinite,
            "bound_median": float(np.median(b)) if finite else None,
            "bound_max": float(np.max(b)) if finite else None,
            "noise_norm_median": float(np.median(w)) if w.size else None,
            "noise_norm_max": float(np.max(w)) if w.size else None,
            "constants": self.constants.to_dict(),
        }


def bound_along(
    constants: BoundConstants,
    noise: Sequence[np.ndarray],
    *,
    states: Sequence[np.ndarray] | None = None,
    inputs: Sequence[np.ndarray] | None = None,
    X: Box | None = None,
    U: Box | None = None,
) -> TrajectoryBound:
    """Proposition 2's bound ``2 γ_f^ℓ α_ℓ^{−1}‖w̄_{j|j+ℓ−1}‖`` along recorded trajectories.

    Args:
        constants: the constants (certified ones make a bound: :attr:`BoundConstants.certified`).
        noise: per trajectory, the measurement noise ``w_k`` of its samples, ``(T, n_y)``
            (``y_k = h(x_k, u_k) + w_k``); the windows are ``w_j … w_{j+ℓ−1}`` for
            ``j = 0 … T−ℓ`` (none when ``T < ℓ``).
        states, inputs: per trajectory, the true states ``x_k`` and the inputs ``u_k`` of the
            same samples (at least ``T`` rows from sample 0).
        X, U: the sets of the constants, given with ``states`` and ``inputs``: a window applies
            where ``x_j ∈ X`` and ``u_j … u_{j+ℓ−1} ∈ U`` (the proposition's premises). Without
            them every window applies.
    """
    ell = constants.window
    if (states is None) != (X is None) or (inputs is None) != (U is None):
        raise ShapeError("give states with X and inputs with U (or neither of a pair)")
    for name, given in (("states", states), ("inputs", inputs)):
        if given is not None and len(given) != len(noise):
            raise ShapeError(f"{name}: {len(given)} trajectories for {len(noise)} of noise")
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("traj", "start", "norm", "ok")}
    for i, w in enumerate(noise):
        w = np.asarray(w, dtype=np.float64)
        if w.ndim != 2:
            raise ShapeError(f"noise of trajectory {i} must be (T, n_y), got {w.shape}")
        starts = np.arange(max(w.shape[0] - ell + 1, 0))
        # window j stacks the rows j … j+ℓ−1: its norm is √(Σ of the rows' squared norms)
        squares = np.sum(w**2, axis=1)
        norms = np.sqrt(np.array([squares[j : j + ell].sum() for j in starts]))
        ok = np.ones(starts.size, dtype=bool)
        if states is not None and X is not None:
            x = np.asarray(states[i], dtype=np.float64)
            if x.ndim != 2 or x.shape[0] < w.shape[0] or x.shape[1] != X.dim:
                raise ShapeError(
                    f"states of trajectory {i} must be (>= {w.shape[0]}, {X.dim}), got {x.shape}"
                )
            ok &= X.contains_rows(x[starts])
        if inputs is not None and U is not None:
            u = np.asarray(inputs[i], dtype=np.float64)
            if u.ndim != 2 or u.shape[0] < w.shape[0] or u.shape[1] != U.dim:
                raise ShapeError(
                    f"inputs of trajectory {i} must be (>= {w.shape[0]}, {U.dim}), got {u.shape}"
                )
            inside = U.contains_rows(u)
            ok &= np.array([bool(inside[j : j + ell].all()) for j in starts], dtype=bool)
        parts["traj"].append(np.full(starts.size, i))
        parts["start"].append(starts)
        parts["norm"].append(norms)
        parts["ok"].append(ok)
    norms = np.concatenate(parts["norm"]) if parts["norm"] else np.zeros(0)
    return TrajectoryBound(
        constants=constants,
        trajectory=np.concatenate(parts["traj"]) if parts["traj"] else np.zeros(0, dtype=int),
        start=np.concatenate(parts["start"]) if parts["start"] else np.zeros(0, dtype=int),
        noise_norms=norms,
        bounds=constants.bound(norms),
        applies=np.concatenate(parts["ok"]) if parts["ok"] else np.zeros(0, dtype=bool),
    )


def check_bound(
    system: System,
    constants: BoundConstants,
    *,
    trials: int,
    X: Box | None = None,
    U: Box | None = None,
    W: Box | None = None,
    states: np.ndarray | None = None,
    noise: str = "uniform",
    starts: int = 8,
    seed: int = 0,
    estimated: BoundConstants | None = None,
) -> BoundCheck:
    """Monte-Carlo check of Proposition 2 for window ``constants.window``.

    Each trial draws ``x_{t−ℓ}`` uniformly in X (or from ``states``, rows of an ``(M, n_x)``
    array, e.g. states of recorded trajectories; rows outside X are refused), inputs
    ``u_{t−ℓ}, …, u_{t−1}`` uniformly in U and noise ``w_{t−ℓ}, …, w_{t−1}`` in W
    (``noise="uniform"``, or ``"vertices"``: each component at ±its bound, the largest norms);
    measures ``ȳ = O_ℓ(x_{t−ℓ}, ū) + w̄``; solves the argmin over X
    (:func:`canonid.analysis.argmin.output_error_argmin`, ``starts`` random starts); and compares
    ``‖F_ℓ(x̂_{t−ℓ}, ū) − F_ℓ(x_{t−ℓ}, ū)‖`` with ``2 γ_f^ℓ α_ℓ^{−1} ‖w̄‖``.

    A trial whose objective at ``x̂`` exceeds the objective at ``x_{t−ℓ}`` is a solver failure,
    counted apart (the proposition speaks of a true minimiser). With certified constants a
    violation is a bug, never a statistic.
    """
    ell = constants.window
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
        raise ShapeError(f"trials must be an integer >= 1, got {trials!r}")
    if noise not in ("uniform", "vertices"):
        raise ShapeError(f"noise must be 'uniform' or 'vertices', got {noise!r}")
    X, U, W = X or system.X, U or system.U, W or system.W
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    hz = Horizon(system, ell)
    ubox = input_box(U, ell)
    if states is None:
        x0 = rng.uniform(X.lo, X.hi, size=(trials, system.n_x))
    else:
        pool = np.asarray(states, dtype=np.float64)
        if pool.ndim != 2 or pool.shape[1] != system.n_x or pool.shape[0] == 0:
            raise ShapeError(f"states must have shape (M, {system.n_x}), got {pool.shape}")
        outside = ~X.contains_rows(pool)
        if outside.any():
            raise SetError(
                f"{int(outside.sum())} of {pool.shape[0]} given states lie outside X = {X}; "
                "the bound holds for x in X only (filter them first)"
            )
        x0 = pool[rng.integers(0, pool.shape[0], size=trials)]
    ubar = rng.uniform(ubox.lo, ubox.hi, size=(trials, ubox.dim))
    wbox = Box(np.tile(W.lo, ell), np.tile(W.hi, ell))
    if noise == "uniform":
        wbar = rng.uniform(wbox.lo, wbox.hi, size=(trials, wbox.dim))
    else:
        wbar = np.where(rng.random((trials, wbox.dim)) < 0.5, wbox.lo, wbox.hi)
    (clean,) = batched(hz.O, x0, ubar)
    ybar = clean + wbar
    sol = output_error_argmin(hz, ybar, ubar, X, starts=starts, rng=rng)
    obj_true = 0.5 * np.sum((ybar - clean) ** 2, axis=1)
    failed = sol.objective > obj_true
    (xt_true,) = batched(hz.F, x0, ubar)
    (xt_hat,) = batched(hz.F, sol.x, ubar)
    errors = np.linalg.norm(xt_hat - xt_true, axis=1)
    wnorm = np.linalg.norm(wbar, axis=1)
    bounds = constants.bound(wnorm)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bounds > 0, errors / bounds, np.where(errors > 0, np.inf, 0.0))
    ok = ~failed
    finite_bound = bool(np.all(np.isfinite(bounds)))
    violations = int(np.count_nonzero(ok & (errors > bounds)))
    max_ratio = float(ratio[ok].max()) if finite_bound and ok.any() else None
    est_ratio = None
    if estimated is not None and math.isfinite(estimated.factor):
        est_bounds = estimated.bound(wnorm)
        with np.errstate(divide="ignore", invalid="ignore"):
            est = np.where(est_bounds > 0, errors / est_bounds, 0.0)
        est_ratio = float(est[ok].max()) if ok.any() else None
    worst_noise = math.sqrt(ell) * W.radius
    worst = float(constants.bound(worst_noise)) if math.isfinite(constants.factor) else None
    return BoundCheck(
        window=ell,
        trials=trials,
        violations=violations,
        solver_failures=int(np.count_nonzero(failed)),
        max_ratio=max_ratio,
        ratio_quantiles=_quantiles(ratio[ok]) if finite_bound else _quantiles(np.zeros(0)),
        max_error=float(errors.max()),
        median_error=float(np.median(errors)),
        worst_case_bound=worst,
        constants=constants.to_dict(),
        max_ratio_estimated=est_ratio,
        seconds=time.perf_counter() - t0,
        settings={"noise": noise, "starts": starts, "seed": seed, "iterations": sol.iterations},
        errors=errors,
        bounds=bounds,
        failed=failed,
    )
