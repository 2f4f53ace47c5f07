"""Residual tests: are a model's prediction errors correlated with a signal they must not follow?

A model whose response to the input is right leaves prediction residuals ``ε[t]`` that carry no
trace of the input's independent part. In closed loop the only part of the input known to be
independent of the noise is the external excitation ``d[t]`` added to the controller's command
(Ljung, *System Identification*, ch. 13): for a correct model the k-step-ahead residuals are
uncorrelated with ``d`` at every lag, and a model with a wrong input response leaves residuals
correlated with ``d[t − τ]``, ``τ = 1 … k`` (the inputs the predictor had to answer without
seeing the outputs). Without a recorded excitation the classical test correlates the residuals
with the inputs themselves (Ljung, ch. 16.6), after both are prewhitened.

:func:`correlation_test` estimates, for every instrument channel ``j``, output ``i`` and lag
``τ``, the normalised cross-correlation

``r_ij(τ) = (1 / N_τ) Σ ε_i[t] s_j[t − τ] / (σ̂_εi σ̂_sj)``

pooled over records (sums over the ``N_τ`` pairs ``(t, t − τ)`` inside each record, each signal
centred per record, ``σ̂`` the pooled standard deviations), where ``s`` is the instrument after
an optional prewhitening: an AR(p) filter ``A_j(q) = 1 − a_1 q⁻¹ − … − a_p q⁻ᵖ`` fitted to
channel ``j`` by least squares (pooled over records) and applied to both ``s_j`` and the
residuals, so that ``A_j(q) s_j`` is close to white.

**The null band.** If ``ε`` is stationary, independent of ``s`` and its autocorrelation vanishes
beyond ``M`` lags, ``sqrt(N) r_ij(τ)`` is asymptotically normal with variance ``P_ij = Σ_{|m| ≤ M}
ρ_εi(m) ρ_sj(m)`` (Ljung, eq. 16.62; ``ρ`` the autocorrelations), whatever ``s`` is, a
deterministic multisine included. The band at confidence ``c`` is ``± z_c sqrt(P̂_ij / N_τ)``
with ``P̂`` from the sample autocorrelations and ``N_τ`` the pairs at lag ``τ``. ``M = 0`` gives
the classical band ``± z_c / sqrt(N)``, which assumes one of the two signals white. k-step
residuals of a correct window-ℓ predictor are correlated over ``k + ℓ − 1`` lags (each shares
noise samples of the window with its neighbours), so ``M`` is the caller's statement of how far
the null's residual correlation reaches. Every number here is an estimate: the correlations are
sample estimates, the band is asymptotic and uses estimated autocorrelations, and the lags are
not independent tests (neighbouring lags of a smooth instrument move together), so the share of
correlations outside the band is compared with ``1 − c`` as a rate, not as a calibrated test.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from statistics import NormalDist
from typing import Any, Literal

import numpy as np

from canonid.kernel.errors import DataError, ShapeError

__all__ = ["BAND_ASSUMES", "CorrelationTest", "correlation_test", "prewhitening_filter"]

#: what the band of :class:`CorrelationTest` assumes, in one sentence (kept in every result)
BAND_ASSUMES = (
    "residuals stationary and independent of the instrument, their autocorrelation zero beyond "
    "null_lags lags; the band is asymptotic (normal) and uses sample autocorrelations"
)


@dataclass(frozen=True)
class CorrelationTest:
    """Cross-correlations of residuals with an instrument and their null band (module docs).

    Every number is an **estimate** (``kind``): sample correlations, and a band that holds under
    the assumptions in ``assumes`` only asymptotically.

    Attributes:
        lags: the lags ``τ`` (``(L,)``, the instrument ``τ`` samples before the residual).
        correlation: ``r_ij(τ)``, shape ``(n_s, n_y, L)`` (instrument channel, output, lag).
        band: half-width of the null band, same shape.
        confidence: the band's two-sided confidence ``c`` per correlation.
        variance_factor: ``P̂_ij`` of the band, ``(n_s, n_y)`` (1 for white signals).
        samples: residual samples used (after prewhitening), over all records.
        prewhitening: the AR order ``p`` of the prewhitening filter, 0 for none.
        null_lags: ``M``, the residual autocorrelation lags the band admits.
        instrument: what the instrument is, in words (``"excitation"``, ``"inputs"``, ...).
        instrument_names, output_names: labels of the channels and outputs.
        kind: always ``"estimate"``.
        assumes: what the band assumes (:data:`BAND_ASSUMES`).
    """

    lags: np.ndarray
    correlation: np.ndarray
    band: np.ndarray
    confidence: float
    variance_factor: np.ndarray
    samples: int
    prewhitening: int
    null_lags: int
    instrument: str
    instrument_names: tuple[str, ...]
    output_names: tuple[str, ...]
    kind: Literal["estimate"] = "estimate"
    assumes: str = field(default=BAND_ASSUMES)

    @property
    def ratio(self) -> np.ndarray:
        """``|r| / band`` per correlation (``> 1``: outside the band)."""
        return np.abs(self.correlation) / self.band

    @property
    def outside(self) -> np.ndarray:
        """Which correlations lie outside the band, ``(n_s, n_y, L)`` booleans."""
        return self.ratio > 1.0

    @property
    def outside_fraction(self) -> float:
        """Share of all correlations outside the band (the null expects about ``1 − c``)."""
        return float(self.outside.mean())

    @property
    def expected_fraction(self) -> float:
        """``1 − c``: the share outside the band that the null expects."""
        return 1.0 - self.confidence

    @property
    def worst(self) -> tuple[float, str, str, int]:
        """The largest ``|r| / band``: its value, instrument channel, output and lag."""
        j, i, k = np.unravel_index(int(np.argmax(self.ratio)), self.ratio.shape)
        return (
            float(self.ratio[j, i, k]),
            self.instrument_names[j],
            self.output_names[i],
            int(self.lags[k]),
        )

    def summary(self) -> str:
        """One line: the share outside the band against the null's, and the worst correlation."""
        value, channel, output, lag = self.worst
        white = f", prewhitened AR({self.prewhitening})" if self.prewhitening else ""
        return (
            f"residuals vs {self.instrument}{white}: {int(self.outside.sum())} of "
            f"{self.outside.size} correlations outside the {self.confidence:.0%} band "
            f"({self.outside_fraction:.1%}, null {self.expected_fraction:.1%}); largest "
            f"|r|/band {value:.2f} ({channel} -> {output}, lag {lag}); estimates, N = "
            f"{self.samples}"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        value, channel, output, lag = self.worst
        return {
            "kind": self.kind,
            "instrument": self.instrument,
            "lags": self.lags.tolist(),
            "correlation": self.correlation.tolist(),
            "band": self.band.tolist(),
            "confidence": self.confidence,
            "variance_factor": self.variance_factor.tolist(),
            "samples": self.samples,
            "prewhitening": self.prewhitening,
            "null_lags": self.null_lags,
            "outside": int(self.outside.sum()),
            "outside_fraction": self.outside_fraction,
            "expected_fraction": self.expected_fraction,
            "worst": {"ratio": value, "instrument": channel, "output": output, "lag": lag},
            "instrument_names": list(self.instrument_names),
            "output_names": list(self.output_names),
            "assumes": self.assumes,
        }


def _records(values: Any, name: str) -> list[np.ndarray]:
    """One ``(T, n)`` float64 array, or a sequence of them, as a list of finite 2-D arrays."""
    if isinstance(values, np.ndarray):
        values = [values]
    out = []
    for i, value in enumerate(values):
        arr = np.asarray(value, dtype=np.float64)
        arr = arr[:, None] if arr.ndim == 1 else arr
        if arr.ndim != 2 or not np.all(np.isfinite(arr)):
            raise ShapeError(f"{name}, record {i}: must be a finite (T, n) array, got {arr.shape}")
        out.append(arr)
    if not out:
        raise ShapeError(f"{name}: no records")
    return out


def prewhitening_filter(signals: Sequence[np.ndarray], order: int) -> np.ndarray:
    """The AR(``order``) coefficients ``a`` of each channel, ``(n, order)``, fitted by least
    squares over all records: ``s[t] ≈ a_1 s[t−1] + … + a_p s[t−p]`` on each record's centred
    rows ``t = p … T−1``."""
    n = signals[0].shape[1]
    coefficients = np.zeros((n, order))
    for j in range(n):
        rows, targets = [], []
        for s in signals:
            x = s[:, j] - s[:, j].mean()
            if x.size <= order:
                continue
            rows.append(np.stack([x[order - i : x.size - i] for i in range(1, order + 1)], axis=1))
            targets.append(x[order:])
        if not rows:
            raise ShapeError(f"no record is longer than the prewhitening order {order}")
        coefficients[j] = np.linalg.lstsq(np.concatenate(rows), np.concatenate(targets))[0]
    return coefficients


def _whiten(x: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``A(q) x`` on rows ``p … T−1`` (``x`` ``(T, n)``, ``a`` the ``p`` AR coefficients)."""
    p = a.size
    out = x[p:].copy()
    for i in range(1, p + 1):
        out -= a[i - 1] * x[p - i : x.shape[0] - i]
    return out


def _lagged_sum(a: list[np.ndarray], b: list[np.ndarray], lag: int) -> tuple[np.ndarray, int]:
    """``Σ_records Σ_t a[t] ⊗ b[t − lag]`` (``a`` ``(T, n_a)``, ``b`` ``(T, n_b)`` →
    ``(n_a, n_b)``) and the number of pairs."""
    total = np.zeros((a[0].shape[1], b[0].shape[1]))
    pairs = 0
    for x, y in zip(a, b, strict=True):
        if x.shape[0] <= lag:
            continue
        total += x[lag:].T @ y[: y.shape[0] - lag]
        pairs += x.shape[0] - lag
    return total, pairs


def correlation_test(
    residuals: Any,
    instrument: Any,
    *,
    lags: Sequence[int],
    confidence: float = 0.99,
    prewhiten: int = 0,
    null_lags: int = 0,
    what: str = "instrument",
    instrument_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
) -> CorrelationTest:
    """Cross-correlate ``residuals`` with ``instrument`` at ``lags`` (module docstring).

    Args:
        residuals: ``(T, n_y)``, or a sequence of records ``(T_r, n_y)``.
        instrument: the same records' instrument ``(T_r, n_s)``; row ``t`` of both is the same
            sample time.
        lags: lags ``τ >= 0`` (the instrument ``τ`` samples before the residual).
        confidence: two-sided confidence of the band per correlation, in (0, 1).
        prewhiten: AR order of the prewhitening filter fitted to each instrument channel and
            applied to it and to the residuals; 0: none.
        null_lags: ``M``, the lags over which the null admits residual autocorrelation (0: the
            classical band ``± z / sqrt(N)``).
        what: the instrument in words, for the summary.
        instrument_names, output_names: labels (default ``s1, …`` and ``y1, …``).

    Raises:
        ShapeError: mismatched records, a negative lag, an order or ``M`` out of range.
        DataError: an instrument or residual channel with no variance left (after prewhitening:
            a signal its AR filter predicts exactly), or a variance factor ``P̂ <= 0``.
    """
    eps = _records(residuals, "residuals")
    sig = _records(instrument, "instrument")
    if len(eps) != len(sig) or any(e.shape[0] != s.shape[0] for e, s in zip(eps, sig)):
        raise ShapeError(
            f"residuals and instrument must be the same records of the same lengths, got "
            f"{[e.shape[0] for e in eps]} and {[s.shape[0] for s in sig]}"
        )
    n_y, n_s = eps[0].shape[1], sig[0].shape[1]
    if any(e.shape[1] != n_y for e in eps) or any(s.shape[1] != n_s for s in sig):
        raise ShapeError("every record must have the same numbers of outputs and channels")
    lag_arr = np.asarray(list(lags), dtype=np.int64)
    if lag_arr.size == 0 or np.any(lag_arr < 0):
        raise ShapeError(f"lags must be one or more integers >= 0, got {list(lags)}")
    if not 0.0 < confidence < 1.0:
        raise ShapeError(f"confidence must be in (0, 1), got {confidence}")
    for name, value in (("prewhiten", prewhiten), ("null_lags", null_lags)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ShapeError(f"{name} must be an integer >= 0, got {value!r}")
    for names, count, label in (
        (instrument_names, n_s, "instrument_names"),
        (output_names, n_y, "output_names"),
    ):
        if names is not None and len(names) != count:
            raise ShapeError(f"{label}: {count} names needed, got {len(names)}")
    z = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    coefficients = prewhitening_filter(sig, prewhiten) if prewhiten else np.zeros((n_s, 0))

    correlation = np.empty((n_s, n_y, lag_arr.size))
    band = np.empty_like(correlation)
    factor = np.empty((n_s, n_y))
    # records too short for the filter drop out
    kept = [(e, s) for e, s in zip(eps, sig) if e.shape[0] > prewhiten]
    samples = sum(e.shape[0] - prewhiten for e, _ in kept)
    for j in range(n_s):
        # channel j's filter applied to its instrument and to every residual output
        ew = [_whiten(e, coefficients[j]) for e, _ in kept]
        sw = [_whiten(s[:, j : j + 1], coefficients[j]) for _, s in kept]
        ew = [e - e.mean(axis=0) for e in ew]
        sw = [s - s.mean(axis=0) for s in sw]
        rows = samples
        e_var = sum((e**2).sum(axis=0) for e in ew) / rows
        s_var = float(sum((s**2).sum() for s in sw)) / rows
        raw = np.concatenate([s[:, j] - s[:, j].mean() for _, s in kept])
        scale = float(raw @ raw) / raw.size
        if s_var <= 1e-12 * scale or np.any(e_var <= 0):
            raise DataError(
                f"{what} channel {j}: no variance left to correlate (after prewhitening by "
                f"AR({prewhiten}), {s_var:.3g} of {scale:.3g}); lower the order or check the data"
            )
        p_hat = np.ones(n_y)
        for m in range(1, null_lags + 1):
            e_auto = np.diag(_lagged_sum(ew, ew, m)[0])
            s_auto = float(_lagged_sum(sw, sw, m)[0][0, 0])
            p_hat = p_hat + 2.0 * (e_auto / (rows * e_var)) * (s_auto / (rows * s_var))
        if np.any(p_hat <= 0):
            raise DataError(
                f"{what} channel {j}: the estimated variance factor is {p_hat.min():.3g} <= 0 "
                f"over null_lags = {null_lags}; use fewer lags"
            )
        factor[j] = p_hat
        for k, lag in enumerate(lag_arr):
            cross, pairs = _lagged_sum(ew, sw, int(lag))
            if pairs == 0:
                raise ShapeError(f"lag {int(lag)} is longer than every record")
            correlation[j, :, k] = cross[:, 0] / (pairs * np.sqrt(e_var * s_var))
            band[j, :, k] = z * np.sqrt(p_hat / pairs)
    return CorrelationTest(
        lags=lag_arr,
        correlation=correlation,
        band=band,
        confidence=float(confidence),
        variance_factor=factor,
        samples=samples,
        prewhitening=prewhiten,
        null_lags=null_lags,
        instrument=what,
        instrument_names=tuple(instrument_names or (f"s{j + 1}" for j in range(n_s))),
        output_names=tuple(output_names or (f"y{i + 1}" for i in range(n_y))),
    )
