"""Residual tests against an instrument on a linear closed loop whose correct model is known.

The plant ``x[t+1] = a x[t] + b u[t]``, ``y[t] = x[t] + w[t]`` runs under output feedback on the
*measured* output, ``u[t] = −K y[t] + d[t]``, so the inputs carry the noise (a true closed loop)
and only the excitation ``d`` is independent of it. The correct model's k-step predictor from a
window of ℓ = 1 sample propagates ``y[t−k]`` under the recorded inputs; its residual is exactly
``w[t] − a^k w[t−k]``: independent of ``d``, correlated with itself at lag k (so ``M = k``), and
correlated with the inputs at lag k through the feedback.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from canonid.analysis.residuals import correlation_test, prewhitening_filter
from canonid.datagen.excitation import Multisine
from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import DataError, ShapeError
from canonid.learning.evaluate import kstep_residuals


class LinearModel:
    """The k-step predictor of ``x[t+1] = a x[t] + b u[t]``, ``y = x``, window ℓ = 1 (the
    duck type of :class:`canonid.learning.model.Model` that ``kstep_residuals`` calls)."""

    name, n_u, n_y, window = "linear", 1, 1, 1

    def __init__(self, a: float, b: float) -> None:
        self.a, self.b = a, b

    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        x = y_burn_in[:, -1, :].copy()
        out = np.empty((u.shape[0], u.shape[1] - 1, 1))
        for j in range(u.shape[1] - 1):
            x = self.a * x + self.b * u[:, j, :]
            out[:, j] = x
        return out


def closed_loop(rng, *, a=0.9, b=0.5, K=0.8, noise=0.5, flights=5, T=600, multisine=False):
    """Flights of the module's loop and their excitations ``d`` (white or a multisine)."""
    records, excitations = [], []
    for _ in range(flights):
        if multisine:
            d = Multisine(band=(0.1, 5.0), lines=20, amplitude=1.0).signal(rng, T, 0.02, 1)
        else:
            d = rng.standard_normal((T, 1))
        w = noise * rng.standard_normal((T, 1))
        # x[t+1] = (a − bK) x[t] + b d[t] − bK w[t], from x[0] = 0
        x = lfilter([0.0, 1.0], [1.0, -(a - b * K)], b * d[:, 0] - b * K * w[:, 0])[:, None]
        records.append(Trajectory(u=-K * (x + w) + d, y=x + w, y_clean=x))
        excitations.append(d)
    return records, excitations


def test_kstep_residuals_of_the_correct_model_are_the_noise_terms(rng):
    """``ε_k[t] = w[t] − a^k w[t−k]`` on rows ``t = ℓ+H−1 … T−1`` for every k."""
    records, _ = closed_loop(rng, flights=2, T=80)
    model, horizons = LinearModel(0.9, 0.5), (1, 4, 7)
    residuals = kstep_residuals(model, records, horizons)
    first = model.window + max(horizons) - 1
    for k in horizons:
        for tr, eps in zip(records, residuals[k]):
            w = tr.y - tr.y_clean
            t = np.arange(first, tr.T)
            np.testing.assert_allclose(eps, w[t] - 0.9**k * w[t - k], atol=1e-12)


def test_kstep_residuals_give_empty_rows_for_a_short_record(rng):
    records, _ = closed_loop(rng, flights=1, T=8)
    assert kstep_residuals(LinearModel(0.9, 0.5), records, [8])[8][0].shape == (0, 1)
    with pytest.raises(ShapeError, match="horizons must be integers >= 1"):
        kstep_residuals(LinearModel(0.9, 0.5), records, [0])


@pytest.mark.parametrize("multisine", [False, True], ids=["white d", "multisine d"])
def test_the_correct_model_stays_inside_the_band_at_the_stated_rate(multisine):
    """Over 40 independent data sets of 5 flights, the share of the 5 lags' correlations
    outside the 95 % band is 5 % up to sampling error (about ±1.3 % for 200 independent
    tests, more because neighbouring lags move together)."""
    rng = np.random.default_rng(11)
    k, shares = 5, []
    for _ in range(40):
        records, d = closed_loop(rng, multisine=multisine)
        eps = kstep_residuals(LinearModel(0.9, 0.5), records, [k])[k]
        test = correlation_test(
            eps, [x[k:] for x in d], lags=range(1, k + 1), confidence=0.95, null_lags=k
        )
        shares.append(test.outside_fraction)
    assert 0.02 <= np.mean(shares) <= 0.09


def test_a_flipped_input_gain_is_flagged_and_the_inputs_flag_even_the_correct_model(rng):
    """The flipped model's residuals follow the excitation of the k samples it predicted
    through; against the inputs (prewhitened), the classical open-loop test, the *correct*
    model is flagged too: in closed loop the inputs carry the noise (u[t−k] holds −K w[t−k])."""
    k = 5
    records, d = closed_loop(rng)
    instrument = [x[k:] for x in d]
    inputs = [tr.u[k:] for tr in records]
    right = kstep_residuals(LinearModel(0.9, 0.5), records, [k])[k]
    flipped = kstep_residuals(LinearModel(0.9, -0.5), records, [k])[k]
    lags = range(1, k + 1)
    wrong = correlation_test(flipped, instrument, lags=lags, null_lags=k, what="excitation")
    assert wrong.outside[0, 0, :2].all() and wrong.worst[0] > 5  # the nearest lags the most
    assert "largest |r|/band" in wrong.summary() and "(s1 -> y1, lag 1)" in wrong.summary()
    assert correlation_test(right, instrument, lags=lags, null_lags=k).worst[0] < 1.5
    on_inputs = correlation_test(right, inputs, lags=lags, prewhiten=3, null_lags=k + 3)
    assert on_inputs.outside[0, 0, k - 1]  # lag k: the fed-back noise


def test_the_band_needs_the_autocorrelations_when_neither_signal_is_white():
    """Residuals summed over 21 samples against a slow multisine: the classical band (M = 0)
    assumes one of them white and rejects far more than 5 %; M = 20 carries both signals'
    autocorrelations into the band (Ljung's P) and comes near the stated rate (the sample
    autocorrelations of such smooth signals are biased low, so it stays a little narrow)."""
    rng = np.random.default_rng(3)
    q, shares = 20, {0: [], 20: []}
    for _ in range(60):
        eps, sig = [], []
        for _ in range(5):
            eps.append(np.convolve(rng.standard_normal(600 + q), np.ones(q + 1), "valid"))
            sig.append(
                Multisine(band=(0.05, 1.0), lines=10, amplitude=1.0).signal(rng, 600, 0.02, 1)
            )
        for M in shares:
            test = correlation_test(eps, sig, lags=range(1, 21), confidence=0.95, null_lags=M)
            shares[M].append(test.outside_fraction)
    assert np.mean(shares[0]) > 0.3
    assert np.mean(shares[20]) < 0.15


def test_prewhitening_recovers_the_coefficients_of_an_ar_process(rng):
    records = [
        lfilter([1.0], [1.0, -1.5, 0.7], rng.standard_normal(2000))[:, None] for _ in range(3)
    ]
    np.testing.assert_allclose(prewhitening_filter(records, 2)[0], [1.5, -0.7], atol=0.03)


@settings(max_examples=25, deadline=None)
@given(
    scale=st.floats(1e-3, 1e3) | st.floats(-1e3, -1e-3),
    offset=st.floats(-10.0, 10.0),
    seed=st.integers(0, 2**16),
)
def test_correlations_do_not_depend_on_units_or_offsets(scale, offset, seed):
    """Each record is centred and the correlation normalised: rescaling the instrument (or
    shifting it) changes at most the sign, and the band not at all."""
    rng = np.random.default_rng(seed)
    eps = [rng.standard_normal((300, 2)) for _ in range(2)]
    sig = [rng.standard_normal((300, 1)) for _ in range(2)]
    base = correlation_test(eps, sig, lags=[0, 1, 4], prewhiten=2, null_lags=3)
    moved = correlation_test(
        eps, [scale * s + offset for s in sig], lags=[0, 1, 4], prewhiten=2, null_lags=3
    )
    np.testing.assert_allclose(moved.correlation, np.sign(scale) * base.correlation, atol=1e-9)
    np.testing.assert_allclose(moved.band, base.band, rtol=1e-9)


@settings(max_examples=15, deadline=None)
@given(
    a=st.floats(-0.9, 0.9),
    b=st.floats(0.2, 2.0),
    pole=st.floats(-0.8, 0.8),
    seed=st.integers(0, 2**16),
)
def test_a_flipped_gain_is_flagged_on_any_stable_loop(a, b, pole, seed):
    """Whatever the plant and the (stabilising) feedback, the model with the input gain's sign
    flipped leaves 3-step residuals outside the 99 % band against the excitation."""
    records, d = closed_loop(np.random.default_rng(seed), a=a, b=b, K=(a - pole) / b, noise=0.1)
    eps = kstep_residuals(LinearModel(a, -b), records, [3])[3]
    assert correlation_test(eps, [x[3:] for x in d], lags=[1, 2, 3], null_lags=3).outside.any()


def test_bad_arguments_are_refused_by_name(rng):
    eps, sig = rng.standard_normal((100, 1)), rng.standard_normal((100, 1))
    with pytest.raises(ShapeError, match="same records of the same lengths"):
        correlation_test(eps, sig[:90], lags=[1])
    with pytest.raises(ShapeError, match="lags must be one or more integers >= 0"):
        correlation_test(eps, sig, lags=[-1])
    with pytest.raises(ShapeError, match="output_names: 1 names needed"):
        correlation_test(eps, sig, lags=[1], output_names=["a", "b"])
    sine = np.sin(2 * np.pi * 5 * np.arange(100) / 100)[:, None]  # AR(2) predicts it exactly
    with pytest.raises(DataError, match="no variance left"):
        correlation_test(eps, sine, lags=[1], prewhiten=2)


def test_the_result_says_it_is_an_estimate_and_what_the_band_assumes(rng):
    test = correlation_test(rng.standard_normal((200, 1)), rng.standard_normal((200, 1)), lags=[1])
    record = test.to_dict()
    assert record["kind"] == "estimate" and "independent of the instrument" in record["assumes"]
    assert "estimates, N = 200" in test.summary()
