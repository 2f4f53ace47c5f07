"""How informative a dataset is, read before training: the window regressor's conditioning and the
inputs' spread over frequency bands.

**Regressor.** With every input and output channel standardised over the flights (mean 0,
standard deviation 1; a constant channel is only centred), the canonical states
``z_t = (u_{t−ℓ}, y_{t−ℓ}, …, u_{t−1}, y_{t−1})`` of all flights (:func:`canonid.kernel.canonical.
cut_windows`) are centred and their covariance ``C = Zᵀ Z / N`` (``ℓ·(n_u+n_y)`` square) is
decomposed. Its smallest eigenvalue ``λ_min`` (= smallest singular value: ``C`` is symmetric
positive semi-definite) says how well the data pin down the direction of ``z`` they excite least:
a model is free to do anything along a direction with ``λ_min ≈ 0``. On a linear system of order
``n`` with ``ℓ = n`` the covariance is of full rank exactly when the input is persistently
exciting of order ``2n`` (Willems et al.'s fundamental lemma); otherwise ``λ_min`` sits at the
noise floor, about ``σ_w² / σ_y²`` (the measurement noise's variance relative to the output's).
The condition number ``λ_max / λ_min`` is reported beside it.

**Inputs given outputs.** In closed loop a good controller makes the inputs a function of the
outputs, and then the data cannot tell the input-to-output response from the controller. The
smallest eigenvalue of the Schur complement ``C_uu − C_uy C_yy⁻¹ C_yu`` of the output lags in
``C`` (the covariance of the input lags left after the best linear prediction from the output
lags, in standardised units: 1 for white inputs independent of the outputs, 0 for inputs that the
outputs fix) measures what the inputs do on their own.

**Bands.** For each input, the share of its variance (flight means removed, periodogram summed
over flights) in the octave bands ``[0, f_N/16), [f_N/16, f_N/8), …, [f_N/2, f_N]`` below the
Nyquist frequency ``f_N = 1 / (2 dt)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.canonical import cut_windows
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import ShapeError

__all__ = ["Informativeness", "dataset_informativeness", "measure_informativeness"]

#: octave bands below Nyquist: edges f_N · 2^-k for k = OCTAVES-1 … 0, and 0
OCTAVES = 5


@dataclass(frozen=True)
class Informativeness:
    """The measures of the module docstring.

    Attributes:
        window: ℓ of the canonical states.
        samples: number of canonical states ``N`` in the covariance.
        eigenvalues: the covariance's eigenvalues, largest first.
        input_given_outputs: the smallest eigenvalue of the input lags' covariance left after
            the output lags (module docstring).
        band_edges_hz: the octave bands' edges, ``OCTAVES + 1`` numbers.
        band_shares: per input, its variance's share in each band (sums to 1).
    """

    window: int
    samples: int
    eigenvalues: tuple[float, ...]
    input_given_outputs: float
    band_edges_hz: tuple[float, ...]
    band_shares: dict[str, tuple[float, ...]]

    @property
    def smallest(self) -> float:
        """The smallest eigenvalue (= singular value) of the regressor covariance."""
        return self.eigenvalues[-1]

    @property
    def condition_number(self) -> float:
        return self.eigenvalues[0] / self.smallest if self.smallest > 0 else math.inf

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (the dataset metadata's ``informativeness``)."""
        return {
            "window": self.window,
            "samples": self.samples,
            "regressor": "z_t = (u_{t-l}, y_{t-l}, ..., u_{t-1}, y_{t-1}), channels standardised",
            "smallest_eigenvalue": self.smallest,
            "largest_eigenvalue": self.eigenvalues[0],
            "condition_number": self.condition_number
            if math.isfinite(self.condition_number)
            else None,
            "eigenvalues": list(self.eigenvalues),
            "input_given_outputs_smallest_eigenvalue": self.input_given_outputs,
            "band_edges_hz": list(self.band_edges_hz),
            "input_variance_share_per_band": {k: list(v) for k, v in self.band_shares.items()},
        }


def measure_informativeness(
    flights: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    window: int,
    dt: float,
    input_names: Sequence[str] | None = None,
) -> Informativeness:
    """The measures of flights ``(u (T, n_u), y (T, n_y))`` (module docstring)."""
    if not flights:
        raise ShapeError("informativeness needs at least one flight")
    pairs = [
        (np.atleast_2d(np.asarray(u, float).T).T, np.atleast_2d(np.asarray(y, float).T).T)
        for u, y in flights
    ]
    n_u = pairs[0][0].shape[1]
    signals = np.concatenate([np.concatenate(p, axis=1) for p in pairs], axis=0)
    mean, std = signals.mean(axis=0), signals.std(axis=0)
    std = np.where(std > 0, std, 1.0)  # a constant channel is centred only: it adds zeros
    Z = np.concatenate(
        [
            cut_windows((u - mean[:n_u]) / std[:n_u], (y - mean[n_u:]) / std[n_u:], window)[:-1]
            for u, y in pairs
            if u.shape[0] > window
        ]
    )  # the last row of each flight (z_T) has no output to predict: left out as in training
    Z = Z - Z.mean(axis=0)
    C = Z.T @ Z / Z.shape[0]
    eigenvalues = np.clip(np.linalg.eigvalsh(C)[::-1], 0.0, None)
    p = signals.shape[1]
    inputs = [k * p + j for k in range(window) for j in range(n_u)]
    outputs = [k * p + j for k in range(window) for j in range(n_u, p)]
    C_yy = C[np.ix_(outputs, outputs)]
    C_uy = C[np.ix_(inputs, outputs)]
    # pinv: output lags that are (nearly) collinear must not blow the complement up
    left = C[np.ix_(inputs, inputs)] - C_uy @ np.linalg.pinv(C_yy, rcond=1e-10) @ C_uy.T
    input_given_outputs = max(0.0, float(np.linalg.eigvalsh(left)[0]))
    nyquist = 0.5 / dt
    edges = (0.0, *(nyquist * 2.0**-k for k in range(OCTAVES - 1, -1, -1)))
    shares = {}
    names = list(input_names) if input_names is not None else [f"u{j}" for j in range(n_u)]
    for j, name in enumerate(names):
        total = np.zeros(len(edges) - 1)
        for u, _ in pairs:
            x = u[:, j] - u[:, j].mean()
            spectrum = np.abs(np.fft.rfft(x)) ** 2
            freqs = np.fft.rfftfreq(x.size, dt)
            band = np.clip(np.searchsorted(edges, freqs, side="right") - 1, 0, len(edges) - 2)
            total += np.bincount(band, weights=spectrum, minlength=len(edges) - 1)
        shares[name] = tuple(float(v) for v in (total / total.sum() if total.sum() > 0 else total))
    return Informativeness(
        window=int(window),
        samples=int(Z.shape[0]),
        eigenvalues=tuple(float(v) for v in eigenvalues),
        input_given_outputs=input_given_outputs,
        band_edges_hz=tuple(float(v) for v in edges),
        band_shares=shares,
    )


def dataset_informativeness(
    dataset: Dataset, *, window: int, split: str = "train"
) -> Informativeness:
    """The measures of one split of ``dataset`` (measured outputs ``y``, applied inputs ``u``)."""
    flights = [(tr.u, tr.y) for tr in dataset.split(split)]
    if not flights:
        raise ShapeError(f"the dataset has no {split} flights to measure")
    return measure_informativeness(
        flights, window=window, dt=dataset.dt, input_names=dataset.input_names
    )
