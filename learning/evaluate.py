"""Scores of a trained model on test trajectories, in physical units.

Two families, both against the measured outputs ``y`` and, when the trajectories carry them,
also against the noise-free ``y_clean`` (the burn-in always uses the measured ``y``: it is what
a model sees in use).

**Paper metric** (Table 1), :attr:`Evaluation.rollout_mse`: from every start ``s = 0, stride,
2·stride, …`` with ``s + ℓ + H ≤ T`` of every test trajectory, burn in on the measured samples
``s … s+ℓ−1`` and predict samples ``s+ℓ … s+ℓ+H−1`` in open loop; the mean squared error over all
those rollouts, their ``H`` steps and the outputs (per output too, and per test record: the mean
over that record's rollouts, ``None`` for a record too short for one, so that a few records
that dominate the mean can be found). The same rollouts give the
**k-step NRMSE**: for ``k = 1 … H``, the RMSE of the k-th predicted step over all rollouts divided
by the standard deviation of the target over all samples of the test trajectories.

**Simulation scores** (the ``nonlinear_benchmarks`` rule): each test record is simulated in open
loop once, from a burn-in on the measured samples ``n_init−ℓ … n_init−1`` to its end; the scores
use samples ``n_init … T−1`` of every record (concatenated), which the model never saw measured.
Per output: ``RMSE``, ``NRMSE = RMSE / std(target)`` and ``fit% = 100 (1 − ‖e‖ / ‖target −
mean(target)‖)`` over those samples; overall: ``rmse`` = square root of the mean over outputs of
the per-output MSE, ``nrmse`` and ``fit_percent`` = means of the per-output values.
``n_init`` defaults to :func:`default_n_init`, the one rule of the library and of ``canonid
evaluate``: ``max(ℓ, min(50, T_max − 1))`` for records of at most ``T_max`` samples (50, less on
short records so that the longest keeps a scored sample, never less than ℓ), or ``max(ℓ, n)``
for data that name their own ``n`` (a benchmark's official rule, ``metadata["n_init"]``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import ShapeError
from canonid.kernel.io import jsonable
from canonid.learning.model import Model

__all__ = [
    "Evaluation",
    "Scores",
    "default_n_init",
    "evaluate",
    "kstep_residuals",
    "score_rows",
    "simulate_records",
]

#: samples of initialisation of the simulation scores when the records are long enough
N_INIT = 50


def default_n_init(window: int, lengths: Sequence[int], data_n_init: int | None = None) -> int:
    """The samples reserved for initialisation when none are asked for: ``max(ℓ, data_n_init)``
    when the data name their own (a benchmark's rule), else ``max(ℓ, min(50, T_max − 1))`` with
    ``T_max`` the longest of ``lengths``."""
    if data_n_init is not None:
        return max(int(data_n_init), window)
    return max(window, min(N_INIT, max(lengths, default=0) - 1))


@dataclass(frozen=True)
class Scores:
    """The metrics against one target (``y`` or ``y_clean``); lists are per output."""

    rollout_mse: float
    rollout_mse_per_output: list[float]
    rollout_mse_per_record: list[float | None]
    kstep_nrmse: list[float]
    kstep_nrmse_per_output: list[list[float]]
    rmse: float
    rmse_per_output: list[float]
    nrmse: float
    nrmse_per_output: list[float]
    fit_percent: float
    fit_percent_per_output: list[float]

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def __str__(self) -> str:
        """A short table: the scores over all outputs, then (several outputs) each one's."""
        names = [f"y[{i}]" for i in range(len(self.rmse_per_output))]
        return "\n".join(score_rows({**self.to_dict(), "output_names": names}, clean=False))

    def __repr__(self) -> str:
        main = ", ".join(f"{k}={_number(getattr(self, k), s)}" for k, s in _TABLE_SCORES)
        return f"Scores({main}, outputs={len(self.rmse_per_output)})"


@dataclass(frozen=True)
class Evaluation:
    """All scores of one model on one set of test trajectories.

    Attributes:
        measured: scores against the measured outputs ``y``.
        clean: scores against ``y_clean`` (``None`` when the data do not carry it).
        rollout_horizon, rollout_stride, n_rollouts: the paper metric's rollouts.
        n_init, n_records, n_scored_samples: the simulation scores' records and samples.
        output_names: names of the outputs (order of the per-output lists).
    """

    measured: Scores
    clean: Scores | None
    rollout_horizon: int
    rollout_stride: int
    n_rollouts: int
    n_init: int
    n_records: int
    n_scored_samples: int
    window: int
    model: str
    output_names: list[str]

    @property
    def finite(self) -> bool:
        """Whether every score is a finite number (a simulation that blew up scores inf or
        NaN)."""
        parts = [self.measured] + ([self.clean] if self.clean else [])
        return all(
            v is None or math.isfinite(v)
            for scores in parts
            for v in _numbers(scores.to_dict().values())
        )

    def __str__(self) -> str:
        """A short table of the main scores (measured and, if any, noise-free targets)."""
        head = (
            f"{self.model} (ℓ = {self.window}) on {self.n_records} records: {self.n_rollouts} "
            f"rollouts of {self.rollout_horizon} steps; simulation scores after n_init = "
            f"{self.n_init}"
        )
        return "\n".join([head, *score_rows(self.to_json())])

    def __repr__(self) -> str:
        main = ", ".join(f"{k}={_number(getattr(self.measured, k), s)}" for k, s in _TABLE_SCORES)
        return (
            f"Evaluation(model={self.model!r}, window={self.window}, {main}, "
            f"n_records={self.n_records}, clean={self.clean is not None})"
        )

    def to_json(self) -> dict[str, Any]:
        """The ``metrics.json`` body: top-level scores are against the measured ``y``; the
        same keys against ``y_clean`` sit under ``"clean"`` (``null`` without it). JSON has no
        inf or NaN: a score that is not finite is written ``null`` and ``finite`` says so."""
        return jsonable(
            {
                "model": self.model,
                "window": self.window,
                "targets": {
                    "top_level": "y (measured outputs, with noise)",
                    "clean": "y_clean (noise-free outputs)" if self.clean else None,
                },
                **self.measured.to_dict(),
                "clean": self.clean.to_dict() if self.clean else None,
                "rollout_horizon": self.rollout_horizon,
                "rollout_stride": self.rollout_stride,
                "n_rollouts": self.n_rollouts,
                "n_init": self.n_init,
                "n_records": self.n_records,
                "n_scored_samples": self.n_scored_samples,
                "output_names": self.output_names,
                "units": "physical (the data's units); rollout_mse in units², rmse in units",
                "finite": self.finite,
            }
        )


#: the scores of the short tables (``print(evaluation)``, ``canonid evaluate``) and their format
_TABLE_SCORES = (("rollout_mse", ".4g"), ("rmse", ".4g"), ("nrmse", ".4g"), ("fit_percent", ".2f"))


def score_rows(metrics: Mapping[str, Any], *, clean: bool = True) -> list[str]:
    """The rows of a short text table of the main scores of a ``metrics.json`` body
    (:meth:`Evaluation.to_json`): measured and (``clean``, where present) noise-free targets;
    with several outputs each target's row (over all outputs) is followed by one per output."""
    rows: list[tuple[str, ...]] = [("target", "rollout_mse", "rmse", "nrmse", "fit %")]
    names = metrics.get("output_names") or []
    targets = [("y (measured)", metrics), ("y_clean", metrics.get("clean") if clean else None)]
    for label, scores in targets:
        if scores:
            rows.append((label, *_row(scores, "")))
            if len(names) > 1:  # a MIMO model: each output's own scores
                for i, name in enumerate(names):
                    rows.append((f"  {name}", *_row(scores, "_per_output", i)))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    return ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]


def _row(scores: Mapping[str, Any], suffix: str, index: int | None = None) -> tuple[str, ...]:
    """The table's four scores of ``scores`` (``suffix`` ``"_per_output"``: output ``index``)."""
    values = [scores[key + suffix] for key, _ in _TABLE_SCORES]
    if index is not None:
        values = [None if v is None else v[index] for v in values]
    return tuple(_number(v, spec) for v, (_, spec) in zip(values, _TABLE_SCORES, strict=True))


def _number(value: float | None, spec: str) -> str:
    """``value`` formatted, or ``not finite`` for a score that is none (written ``null``)."""
    return "not finite" if value is None or not math.isfinite(value) else format(value, spec)


def _numbers(values: Any) -> list[float | None]:
    """The floats in ``values``, nested lists flattened."""
    out: list[float | None] = []
    for v in values:
        if isinstance(v, (list, tuple)):
            out.extend(_numbers(v))
        else:
            out.append(None if v is None else float(v))
    return out


def _rollouts(
    model: Model, records: Sequence[Trajectory], horizon: int, stride: int
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    ell = model.window
    span = ell + horizon
    starts = [(i, s) for i, tr in enumerate(records) for s in range(0, tr.T - span + 1, stride)]
    if not starts:
        raise ShapeError(
            f"no test trajectory holds window ℓ = {ell} plus horizon {horizon} = {span} samples "
            f"(longest has {max(tr.T for tr in records)}); lower the horizon"
        )
    u = np.stack([records[i].u[s : s + span] for i, s in starts])
    y0 = np.stack([records[i].y[s : s + ell] for i, s in starts])
    return model.predict(u, y0), starts


def simulate_records(model: Model, records: Sequence[Trajectory], n_init: int) -> list[np.ndarray]:
    """Open-loop simulation of each record from its samples ``n_init−ℓ … n_init−1``; returns the
    predictions of samples ``n_init … T−1`` per record (empty for records of ≤ n_init samples).

    Records run as one batch per group, the longest first: a group takes every record at least
    half as long as its longest, the shorter ones padded at their end with their last input. The
    models are causal, so padding never reaches a prediction that is kept, and it at most doubles
    a group's work (one sequential pass over the longest record instead of one per length).
    """
    ell = model.window
    out: list[np.ndarray] = [np.zeros((0, model.n_y)) for _ in records]
    todo = sorted((i for i, tr in enumerate(records) if tr.T > n_init), key=lambda i: -records[i].T)
    while todo:
        T = records[todo[0]].T
        group = [i for i in todo if 2 * records[i].T >= T]
        todo = [i for i in todo if 2 * records[i].T < T]
        pad = [((0, T - records[i].T), (0, 0)) for i in group]
        u = np.stack(
            [np.pad(records[i].u[n_init - ell :], p, mode="edge") for i, p in zip(group, pad)]
        )
        y0 = np.stack([records[i].y[n_init - ell : n_init] for i in group])
        pred = model.predict(u, y0)
        for j, i in enumerate(group):
            out[i] = pred[j, : records[i].T - n_init]
    return out


def kstep_residuals(
    model: Model, records: Sequence[Trajectory], horizons: Sequence[int]
) -> dict[int, list[np.ndarray]]:
    """The k-step-ahead prediction residuals ``ε_k[t] = y[t] − ŷ(t | y up to t−k, u)`` of each
    record, for every ``k`` in ``horizons``.

    ``ŷ(t | t−k)`` is the model's open-loop rollout burnt in on the measured samples
    ``t−k−ℓ+1 … t−k`` and run under the recorded inputs to sample ``t`` (its k-th predicted
    step). With ``H = max(horizons)`` every record gives the rows ``t = ℓ+H−1 … T−1`` for every
    ``k`` (the same rows, so the horizons line up; the first ``ℓ+H−1`` samples are skipped),
    an array ``(T − ℓ − H + 1, n_y)`` per record; a record of ``T ≤ ℓ+H−1`` samples gives an
    empty one. One batch of rollouts of ``H`` steps, one from every start, gives all the
    horizons (the inputs are padded past the record's end with its last row: the models are
    causal, so the padding reaches no prediction that is kept).
    """
    records = as_trajectories(records, what="records")
    ks = sorted({int(k) for k in horizons})
    if not ks or ks[0] < 1:
        raise ShapeError(f"horizons must be integers >= 1, got {list(horizons)}")
    ell, H = model.window, ks[-1]
    out: dict[int, list[np.ndarray]] = {k: [] for k in ks}
    for tr in records:
        first = ell + H - 1  # the first row every horizon has
        if tr.T <= first:
            for k in ks:
                out[k].append(np.zeros((0, tr.n_y)))
            continue
        starts = range(tr.T - ell)  # window s … s+ℓ−1 predicts samples s+ℓ … s+ℓ+H−1
        u = np.pad(tr.u, ((0, H - 1), (0, 0)), mode="edge")
        pred = model.predict(
            np.stack([u[s : s + ell + H] for s in starts]),
            np.stack([tr.y[s : s + ell] for s in starts]),
        )  # (T − ℓ, H, n_y): pred[s, j] is the (j+1)-step prediction of sample s + ℓ + j
        t = np.arange(first, tr.T)
        for k in ks:
            out[k].append(tr.y[t] - pred[t - ell - k + 1, k - 1])
    return out


def _scores(
    pred_roll: np.ndarray,
    starts: list[tuple[int, int]],
    sims: list[np.ndarray],
    targets: Sequence[np.ndarray],
    ell: int,
    n_init: int,
) -> Scores:
    horizon = pred_roll.shape[1]
    true_roll = np.stack([targets[i][s + ell : s + ell + horizon] for i, s in starts])
    err2 = (pred_roll - true_roll) ** 2  # (N, H, n_y)
    mse_out = err2.mean(axis=(0, 1))
    owner = np.array([i for i, _ in starts])
    sums = np.bincount(owner, weights=err2.mean(axis=(1, 2)), minlength=len(targets))
    counts = np.bincount(owner, minlength=len(targets))
    per_record: list[float | None] = [
        float(total / n) if n else None for total, n in zip(sums, counts, strict=True)
    ]
    sd_all = np.concatenate(list(targets)).std(axis=0)
    sd_all = np.where(sd_all > 0, sd_all, 1.0)
    kstep = np.sqrt(err2.mean(axis=0)) / sd_all  # (H, n_y)
    scored = np.concatenate([targets[i][n_init:] for i in range(len(targets))])
    sim = np.concatenate(sims)
    e = sim - scored
    rmse_out = np.sqrt((e**2).mean(axis=0))
    sd = scored.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    centred = np.linalg.norm(scored - scored.mean(axis=0), axis=0)
    centred = np.where(centred > 0, centred, 1.0)
    fit_out = 100.0 * (1.0 - np.linalg.norm(e, axis=0) / centred)
    return Scores(
        rollout_mse=float(mse_out.mean()),
        rollout_mse_per_output=mse_out.tolist(),
        rollout_mse_per_record=per_record,
        kstep_nrmse=kstep.mean(axis=1).tolist(),
        kstep_nrmse_per_output=kstep.T.tolist(),
        rmse=float(np.sqrt((rmse_out**2).mean())),
        rmse_per_output=rmse_out.tolist(),
        nrmse=float((rmse_out / sd).mean()),
        nrmse_per_output=(rmse_out / sd).tolist(),
        fit_percent=float(fit_out.mean()),
        fit_percent_per_output=fit_out.tolist(),
    )


def evaluate(
    model: Model,
    data: Sequence[Trajectory],
    *,
    horizon: int = 100,
    stride: int = 1,
    n_init: int | None = None,
    output_names: Sequence[str] | None = None,
) -> Evaluation:
    """Score ``model`` on the trajectories ``data`` (see the module docstring).

    Args:
        model: a trained :class:`canonid.learning.model.Model`.
        data: test trajectories (:class:`~canonid.kernel.dataset.Trajectory`, or any objects
            with ``.u``, ``.y`` and optionally ``.y_clean``, converted once by
            :func:`~canonid.kernel.dataset.as_trajectories`).
        horizon: ``H`` of the paper metric (paper: 100).
        stride: stride of the rollout start times.
        n_init: samples reserved for initialisation in the simulation scores (default
            :func:`default_n_init`; must be ≥ ℓ).
        output_names: labels for the per-output lists (default ``y1, y2, …``).
    """
    test = as_trajectories(data, what="test data")
    ell = model.window
    if (test[0].n_u, test[0].n_y) != (model.n_u, model.n_y):
        raise ShapeError(
            f"test data have n_u={test[0].n_u}, n_y={test[0].n_y}; the model "
            f"has n_u={model.n_u}, n_y={model.n_y}"
        )
    if isinstance(horizon, bool) or horizon < 1 or stride < 1:
        raise ShapeError(f"horizon and stride must be >= 1, got {horizon} and {stride}")
    n_init = default_n_init(ell, [tr.T for tr in test]) if n_init is None else int(n_init)
    if n_init < ell:
        raise ShapeError(f"n_init = {n_init} must be at least the window ℓ = {ell}")
    records = [tr for tr in test if tr.T > n_init]
    if not records:
        raise ShapeError(
            f"no test trajectory is longer than n_init = {n_init} samples "
            f"(longest has {max(tr.T for tr in test)}); lower n_init"
        )
    pred_roll, starts = _rollouts(model, test, horizon, stride)
    sims = simulate_records(model, test, n_init)
    measured = _scores(pred_roll, starts, sims, [tr.y for tr in test], ell, n_init)
    clean = None
    if all(tr.y_clean is not None for tr in test):
        targets = [tr.y_clean for tr in test if tr.y_clean is not None]
        clean = _scores(pred_roll, starts, sims, targets, ell, n_init)
    return Evaluation(
        measured=measured,
        clean=clean,
        rollout_horizon=horizon,
        rollout_stride=stride,
        n_rollouts=len(starts),
        n_init=n_init,
        n_records=len(records),
        n_scored_samples=sum(tr.T - n_init for tr in records),
        window=ell,
        model=model.name,
        output_names=list(output_names or (f"y{i + 1}" for i in range(model.n_y))),
    )
