"""Learned models against the theory, through plain numpy callables (no torch here).

The identification layer exports a regressor ``H(z, u) -> y``: ``z`` of shape
``(N, ℓ(n_u+n_y))`` in the :mod:`canonid.kernel.canonical` ordering, ``u`` ``(N, n_u)``, ``y``
``(N, n_y)``, physical units. Trajectories are the kernel's
:class:`~canonid.kernel.dataset.Trajectory` (``u`` ``(T, n_u)``, ``y`` ``(T, n_y)`` and, where
available, ``y_clean`` (noise-free outputs) and ``x`` (true states), following the dataset time
convention: sample ``t`` holds ``x[t]``, ``u[t]``, ``y[t]``); other objects with ``.u`` and
``.y`` are converted once (:func:`~canonid.kernel.dataset.as_trajectories`).

Rows. For window ``ℓ`` a trajectory of ``T`` samples gives rows ``t = ℓ, …, T−1``:
``z_t`` holds samples ``t−ℓ … t−1``, the target is ``y_t``, the true state ``x_t``, the state at
the start of the window ``x_{t−ℓ}``, the noise ``w_t = y_t − y_clean_t`` and the window noise
``w̄_{t−ℓ|t−1}``.

* :func:`residual_check` — the one-step residual ``‖y_t − Ĥ(z_t, u_t)‖`` against the
  noise-induced level ``‖w_t‖ + 2 γ_h γ_f^ℓ α_ℓ^{−1}‖w̄_{t−ℓ|t−1}‖`` (see
  :mod:`canonid.analysis.bound` for the factor 2): the residual an ideal regressor — ``h`` of the
  output-error estimate — cannot exceed.
* :func:`state_probe` — a least-squares probe (affine or quadratic features) from ``z_t``, or
  from a reduced state ``x̄_t`` given as arrays, to the true ``x_t``; its error on test data is
  set beside the Proposition 2 bound ``2 γ_f^ℓ α_ℓ^{−1}‖w̄‖`` of the same rows.

Rows whose window starts outside X (``x_{t−ℓ} ∉ X``) are outside the theory and are counted
apart in both checks.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.analysis.bound import BoundConstants
from canonid.analysis.maps import check_window
from canonid.kernel.canonical import cut_windows
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import DataError, ShapeError
from canonid.models.sets import Box

__all__ = [
    "ProbeResult",
    "Regressor",
    "ResidualCheck",
    "WindowRows",
    "residual_check",
    "state_probe",
    "window_rows",
]

Regressor = Callable[[np.ndarray, np.ndarray], np.ndarray]
_QUANTILES = (0.5, 0.9, 0.99, 1.0)


@dataclass(frozen=True)
class WindowRows:
    """All rows ``t = ℓ … T−1`` of a set of trajectories (see the module docstring)."""

    window: int
    z: np.ndarray
    u_now: np.ndarray
    y_now: np.ndarray
    x_now: np.ndarray | None
    x_start: np.ndarray | None
    w_now: np.ndarray | None
    w_window: np.ndarray | None
    trajectory: np.ndarray

    @property
    def count(self) -> int:
        return int(self.z.shape[0])


def window_rows(trajectories: Sequence[Trajectory], window: int) -> WindowRows:
    """Cut every trajectory into the rows of the module docstring and stack them."""
    ell = check_window(window)
    trajectories = as_trajectories(trajectories, what="trajectories")
    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ("z", "u", "y", "x", "x0", "wn", "ww", "id")
    }
    has_x = all(tr.x is not None for tr in trajectories)
    has_w = all(tr.y_clean is not None for tr in trajectories)
    for i, tr in enumerate(trajectories):
        u, y, steps = tr.u, tr.y, tr.T
        if steps <= ell:
            raise ShapeError(f"trajectory {i} has {steps} samples, window ℓ = {ell} needs more")
        parts["z"].append(cut_windows(u, y, ell)[:-1])  # rows t = ℓ … T−1
        parts["u"].append(u[ell:])
        parts["y"].append(y[ell:])
        parts["id"].append(np.full(steps - ell, i))
        if has_x:
            assert tr.x is not None
            parts["x"].append(tr.x[ell:])
            parts["x0"].append(tr.x[: steps - ell])
        if has_w:
            assert tr.y_clean is not None
            w = y - tr.y_clean
            sq = np.concatenate([[0.0], np.cumsum(np.sum(w**2, axis=1))])
            parts["wn"].append(np.linalg.norm(w[ell:], axis=1))
            window_sq = sq[ell:steps] - sq[: steps - ell]  # Σ_{k=t−ℓ}^{t−1} ‖w_k‖²
            parts["ww"].append(np.sqrt(np.maximum(window_sq, 0.0)))
    stack = {k: np.concatenate(v) if v else None for k, v in parts.items()}
    return WindowRows(
        window=ell,
        z=stack["z"],  # type: ignore[arg-type]
        u_now=stack["u"],  # type: ignore[arg-type]
        y_now=stack["y"],  # type: ignore[arg-type]
        x_now=stack["x"],
        x_start=stack["x0"],
        w_now=stack["wn"],
        w_window=stack["ww"],
        trajectory=stack["id"],  # type: ignore[arg-type]
    )


def _quantiles(values: np.ndarray) -> dict[str, float | None]:
    if values.size == 0:
        return {f"q{int(q * 100)}": None for q in _QUANTILES}
    return {f"q{int(q * 100)}": float(np.quantile(values, q)) for q in _QUANTILES}


def _in_set(points: np.ndarray | None, box: Box | None, count: int) -> np.ndarray:
    if points is None or box is None:
        return np.ones(count, dtype=bool)
    return box.contains_rows(points)


@dataclass(frozen=True)
class ResidualCheck:
    """One-step residuals of a regressor against the noise-induced level.

    Attributes:
        window: ``ℓ``.
        rows: rows compared (window starting in X).
        excluded: rows left out because ``x_{t−ℓ} ∉ X``.
        within: rows with residual ≤ level.
        max_ratio: largest residual / level.
        residual, level, ratio: quantiles (``q50``, ``q90``, ``q99``, ``q100``).
        constants: the constants used.
    """

    window: int
    rows: int
    excluded: int
    within: int
    max_ratio: float | None
    residual: Mapping[str, float | None]
    level: Mapping[str, float | None]
    ratio: Mapping[str, float | None]
    constants: Mapping[str, Any]

    @property
    def fraction_within(self) -> float:
        return self.within / self.rows if self.rows else float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {
            "window": self.window,
            "rows": self.rows,
            "excluded": self.excluded,
            "within": self.within,
            "fraction_within": self.fraction_within if self.rows else None,
            "max_ratio": self.max_ratio,
            "residual": dict(self.residual),
            "level": dict(self.level),
            "ratio": dict(self.ratio),
            "constants": dict(self.constants),
        }


def _call_regressor(regressor: Regressor, z: np.ndarray, u: np.ndarray, n_y: int) -> np.ndarray:
    out = np.asarray(regressor(z, u), dtype=np.float64)
    if out.ndim == 1 and n_y == 1:
        out = out[:, None]
    if out.shape != (z.shape[0], n_y):
        raise ShapeError(
            f"the regressor returned shape {out.shape}, expected ({z.shape[0]}, {n_y})"
        )
    if not np.all(np.isfinite(out)):
        raise ShapeError("the regressor returned NaN or Inf")
    return out


def residual_check(
    regressor: Regressor,
    trajectories: Sequence[Trajectory],
    constants: BoundConstants,
    *,
    X: Box | None = None,
) -> ResidualCheck:
    """Residual ``‖y_t − Ĥ(z_t, u_t)‖`` versus ``‖w_t‖ + 2 γ_h γ_f^ℓ α_ℓ^{−1}‖w̄‖`` per row.

    Args:
        regressor: ``H(z, u) -> y`` (batched numpy callable, physical units).
        trajectories: test trajectories with ``u``, ``y`` and ``y_clean`` (for ``w``); with
            ``x`` the rows whose window starts outside ``X`` are excluded.
        constants: γ_f, α_ℓ and γ_h for ``ℓ = constants.window``.
        X: the set the constants hold on (``None``: no exclusion).
    """
    rows = window_rows(trajectories, constants.window)
    if rows.w_now is None or rows.w_window is None:
        raise DataError("the residual check needs y_clean in every trajectory (to know w_t)")
    inside = _in_set(rows.x_start, X, rows.count)
    pred = _call_regressor(regressor, rows.z[inside], rows.u_now[inside], rows.y_now.shape[1])
    residual = np.linalg.norm(rows.y_now[inside] - pred, axis=1)
    level = constants.residual_level(rows.w_now[inside], rows.w_window[inside])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(level > 0, residual / level, np.where(residual > 0, np.inf, 0.0))
    finite = ratio[np.isfinite(ratio)]
    return ResidualCheck(
        window=constants.window,
        rows=int(inside.sum()),
        excluded=int((~inside).sum()),
        within=int(np.count_nonzero(residual <= level)),
        max_ratio=float(ratio.max()) if ratio.size and np.isfinite(ratio.max()) else None,
        residual=_quantiles(residual),
        level=_quantiles(level[np.isfinite(level)]),
        ratio=_quantiles(finite),
        constants=constants.to_dict(),
    )


@dataclass(frozen=True)
class ProbeResult:
    """A least-squares probe to the true state and its test error beside Proposition 2.

    Attributes:
        window: ``ℓ``.
        features: ``"z"`` (canonical state) or ``"reduced"`` (given arrays).
        kind: ``"affine"`` or ``"quadratic"`` feature map.
        train_rows, test_rows: rows used.
        rmse: root mean square of ``‖x̂_t − x_t‖`` on test rows.
        error: quantiles of ``‖x̂_t − x_t‖`` on test rows.
        bound: quantiles of ``2 γ_f^ℓ α_ℓ^{−1}‖w̄‖`` on the test rows whose window starts in X
            (empty without constants).
        within: test rows (window in X) whose probe error is ≤ the bound.
        bound_rows: test rows that have a bound (window in X).
    """

    window: int
    features: str
    kind: str
    train_rows: int
    test_rows: int
    rmse: float
    error: Mapping[str, float | None]
    bound: Mapping[str, float | None]
    within: int
    bound_rows: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "window": self.window,
            "features": self.features,
            "kind": self.kind,
            "train_rows": self.train_rows,
            "test_rows": self.test_rows,
            "rmse": self.rmse,
            "error": dict(self.error),
            "bound": dict(self.bound),
            "within": self.within,
            "bound_rows": self.bound_rows,
        }


def _design(features: np.ndarray, kind: str) -> np.ndarray:
    ones = np.ones((features.shape[0], 1))
    if kind == "affine":
        return np.hstack([ones, features])
    if kind == "quadratic":
        i, j = np.triu_indices(features.shape[1])
        return np.hstack([ones, features, features[:, i] * features[:, j]])
    raise ShapeError(f"probe kind must be 'affine' or 'quadratic', got {kind!r}")


def _features(rows: WindowRows, reduced: Sequence[np.ndarray] | None, name: str) -> np.ndarray:
    if reduced is None:
        return rows.z
    arr = np.concatenate([np.asarray(r, dtype=np.float64).reshape(len(r), -1) for r in reduced])
    if arr.shape[0] != rows.count:
        raise ShapeError(
            f"{name}: {arr.shape[0]} reduced states given, the trajectories have {rows.count} "
            f"rows t = ℓ … T−1 (one per row, aligned with them)"
        )
    return arr


def state_probe(
    train: Sequence[Trajectory],
    test: Sequence[Trajectory],
    *,
    window: int,
    constants: BoundConstants | None = None,
    X: Box | None = None,
    reduced_train: Sequence[np.ndarray] | None = None,
    reduced_test: Sequence[np.ndarray] | None = None,
    kind: str = "affine",
    ridge: float = 1e-9,
) -> ProbeResult:
    """Fit ``x_t ≈ P φ(features_t)`` on ``train`` by ridge least squares, evaluate on ``test``.

    Args:
        train, test: trajectories with ``u``, ``y``, ``x`` (and ``y_clean`` on ``test`` for the
            bound).
        window: ``ℓ``.
        constants: Proposition 2 constants for the bound column (optional).
        X: the set of the constants (rows whose window starts outside are not given a bound).
        reduced_train, reduced_test: per trajectory, reduced states ``x̄_t`` for rows
            ``t = ℓ … T−1`` (shape ``(T−ℓ, n̄)``) used as features instead of ``z_t``.
        kind: ``"affine"`` or ``"quadratic"`` features.
        ridge: Tikhonov weight (relative to the mean squared feature).
    """
    ell = check_window(window)
    tr_rows = window_rows(train, ell)
    te_rows = window_rows(test, ell)
    if tr_rows.x_now is None or te_rows.x_now is None:
        raise DataError("the state probe needs the true states x in every trajectory")
    features = "z" if reduced_train is None else "reduced"
    if (reduced_train is None) != (reduced_test is None):
        raise ShapeError("give both reduced_train and reduced_test, or neither")
    phi_train = _design(_features(tr_rows, reduced_train, "reduced_train"), kind)
    phi_test = _design(_features(te_rows, reduced_test, "reduced_test"), kind)
    scale = float(np.mean(phi_train**2)) or 1.0
    gram = phi_train.T @ phi_train + ridge * scale * phi_train.shape[0] * np.eye(phi_train.shape[1])
    coef = np.linalg.solve(gram, phi_train.T @ tr_rows.x_now)
    err = np.linalg.norm(phi_test @ coef - te_rows.x_now, axis=1)
    bound_q: Mapping[str, float | None] = _quantiles(np.zeros(0))
    within = bound_rows = 0
    if constants is not None:
        if constants.window != ell:
            raise ShapeError(f"constants are for ℓ = {constants.window}, the probe uses ℓ = {ell}")
        if te_rows.w_window is None:
            raise DataError("the bound column needs y_clean in every test trajectory")
        inside = _in_set(te_rows.x_start, X, te_rows.count)
        bounds = constants.bound(te_rows.w_window[inside])
        bound_rows = int(inside.sum())
        within = int(np.count_nonzero(err[inside] <= bounds))
        bound_q = _quantiles(bounds[np.isfinite(bounds)])
    return ProbeResult(
        window=ell,
        features=features,
        kind=kind,
        train_rows=tr_rows.count,
        test_rows=te_rows.count,
        rmse=float(np.sqrt(np.mean(err**2))),
        error=_quantiles(err),
        bound=bound_q,
        within=within,
        bound_rows=bound_rows,
    )
