"""Input designs: excitation signals with a chosen spectrum and amplitude, added to a controller's
command during data generation.

A closed loop flown by a good controller is a poor experiment: the controller cancels what the
identification needs to see, so the inputs follow the outputs and the data do not determine the
input-to-output response (docs: Data generation, "Experiment design"). An
:class:`InputDesign` adds a known signal ``d[t]`` to the command, ``u[t] = clip(c[t] + e[t] +
d[t], U)`` (see :mod:`canonid.datagen.simulate`); the controller still closes the loop, so the
flight stays in its box.

* :class:`Multisine`: a random-phase multisine, ``lines`` cosines per input on frequencies of the
  flight's grid ``k / (T·dt)`` inside ``band`` (whole periods per flight, so its spectrum has no
  leakage). The inputs get interleaved lines (input ``j`` takes every ``n_u``-th of the chosen
  frequencies), so within a flight the inputs are uncorrelated.
* :class:`RandomBinary`: a pseudo-random binary sequence, ``±amplitude`` held for ``clock``
  samples, independent per input; the hold is a low-pass filter (power mostly below
  ``1 / (clock·dt)`` Hz, the first zero of its sinc² spectrum).

``amplitude`` is the root mean square of the signal per input (input units): one number for all
inputs or one per input. Both signals are drawn from a generator, so a flight's signal is fixed by
its seed (:mod:`canonid.datagen.generate` gives the design its own child seed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from canonid.kernel.errors import OptionError

__all__ = [
    "InputDesign",
    "Multisine",
    "RandomBinary",
    "design_from_description",
    "design_from_options",
]


def _amplitudes(amplitude: float | Sequence[float]) -> tuple[float, ...]:
    values = (amplitude,) if isinstance(amplitude, (int, float)) else tuple(amplitude)
    out = tuple(float(v) for v in values)
    if not out or not all(math.isfinite(v) and v > 0 for v in out):
        raise OptionError(f"excitation amplitude must be one or more numbers > 0, got {amplitude}")
    return out


def _per_input(amplitudes: tuple[float, ...], n_u: int) -> np.ndarray:
    if len(amplitudes) == 1:
        return np.full(n_u, amplitudes[0])
    if len(amplitudes) != n_u:
        raise OptionError(
            f"excitation amplitude: give one number or {n_u} (one per input), got {len(amplitudes)}"
        )
    return np.asarray(amplitudes)


@dataclass(frozen=True)
class Multisine:
    """Random-phase multisine (module docstring).

    Attributes:
        band: ``(low, high)`` frequency band in Hz, ``0 <= low < high``.
        lines: cosines per input.
        amplitude: RMS per input (input units), one number or one per input.
    """

    band: tuple[float, float]
    lines: int
    amplitude: float | tuple[float, ...]

    def __post_init__(self) -> None:
        band = tuple(float(v) for v in self.band)
        if len(band) != 2 or not (0.0 <= band[0] < band[1] < math.inf):
            raise OptionError(
                f"multisine band must be (low, high) Hz with 0 <= low < high, got {self.band}"
            )
        if isinstance(self.lines, bool) or not isinstance(self.lines, int) or self.lines < 1:
            raise OptionError(f"multisine lines must be an integer >= 1, got {self.lines!r}")
        amplitudes = _amplitudes(self.amplitude)
        object.__setattr__(self, "band", band)
        object.__setattr__(self, "amplitude", amplitudes[0] if len(amplitudes) == 1 else amplitudes)

    def frequencies(self, T: int, dt: float, n_u: int) -> np.ndarray:
        """Grid indices ``k`` (frequency ``k / (T·dt)``), shape ``(n_u, lines)``; raises when the
        band holds fewer than ``n_u · lines`` grid frequencies strictly between 0 and Nyquist."""
        period = T * dt
        first = max(1, math.ceil(self.band[0] * period - 1e-9))
        last = min((T - 1) // 2, math.floor(self.band[1] * period + 1e-9))
        wanted = n_u * self.lines
        if last - first + 1 < wanted:
            raise OptionError(
                f"multisine band {self.band[0]:g}-{self.band[1]:g} Hz holds "
                f"{max(0, last - first + 1)} frequencies of a {T}-sample flight (spacing "
                f"{1 / period:.3g} Hz, below Nyquist {0.5 / dt:g} Hz); {n_u} inputs x "
                f"{self.lines} lines need {wanted}"
            )
        chosen = np.round(np.linspace(first, last, wanted)).astype(int)
        return chosen.reshape(self.lines, n_u).T  # input j: every n_u-th chosen frequency

    def signal(self, rng: np.random.Generator, T: int, dt: float, n_u: int) -> np.ndarray:
        """The ``(T, n_u)`` signal of one flight; phases uniform in [0, 2π) from ``rng``."""
        k = self.frequencies(T, dt, n_u)
        phases = rng.uniform(0.0, 2.0 * np.pi, size=k.shape)
        t = np.arange(T, dtype=np.float64)
        waves = np.cos(2.0 * np.pi * k[:, :, None] * t / T + phases[:, :, None])  # (n_u, lines, T)
        # each cosine has mean square 1/2 over whole periods: scale the sum to the RMS asked for
        scale = _per_input(_amplitudes(self.amplitude), n_u) * math.sqrt(2.0 / self.lines)
        return np.ascontiguousarray((waves.sum(axis=1) * scale[:, None]).T)

    def describe(self) -> dict[str, Any]:
        return {
            "kind": "multisine",
            "band_hz": list(self.band),
            "lines_per_input": self.lines,
            "rms": self.amplitude if isinstance(self.amplitude, float) else list(self.amplitude),
            "phases": "uniform in [0, 2pi), drawn per flight",
            "frequencies": "grid k/(T dt) inside the band, interleaved between the inputs",
        }


@dataclass(frozen=True)
class RandomBinary:
    """Pseudo-random binary sequence held for ``clock`` samples (module docstring).

    Attributes:
        clock: samples each level is held (the clock period, in samples).
        amplitude: the level ``±amplitude`` (also its RMS), one number or one per input.
    """

    clock: int
    amplitude: float | tuple[float, ...]

    def __post_init__(self) -> None:
        if isinstance(self.clock, bool) or not isinstance(self.clock, int) or self.clock < 1:
            raise OptionError(f"PRBS clock must be an integer >= 1 (samples), got {self.clock!r}")
        amplitudes = _amplitudes(self.amplitude)
        object.__setattr__(self, "amplitude", amplitudes[0] if len(amplitudes) == 1 else amplitudes)

    def signal(self, rng: np.random.Generator, T: int, dt: float, n_u: int) -> np.ndarray:
        """The ``(T, n_u)`` signal of one flight; levels drawn from ``rng``."""
        levels = 2.0 * rng.integers(0, 2, size=(-(-T // self.clock), n_u)) - 1.0
        held = np.repeat(levels, self.clock, axis=0)[:T]
        return np.ascontiguousarray(held * _per_input(_amplitudes(self.amplitude), n_u))

    def describe(self) -> dict[str, Any]:
        return {
            "kind": "prbs",
            "clock_samples": self.clock,
            "rms": self.amplitude if isinstance(self.amplitude, float) else list(self.amplitude),
            "levels": "+-rms, drawn per flight and input, held for clock samples",
        }


#: the designs :mod:`canonid.datagen.generate` accepts
InputDesign = Multisine | RandomBinary

EXCITATION_KINDS = ("multisine", "prbs")


def design_from_options(
    kind: str,
    *,
    amplitude: float | Sequence[float] | None,
    band: tuple[float, float] | None = None,
    lines: int | None = None,
    clock: int | None = None,
) -> InputDesign:
    """The design that ``canonid generate --excitation KIND ...`` names; the options that do not
    belong to ``kind`` are refused rather than ignored."""
    if kind not in EXCITATION_KINDS:
        raise OptionError(
            f"--excitation must be one of {', '.join(EXCITATION_KINDS)}, got {kind!r}"
        )
    if amplitude is None:
        raise OptionError(f"--excitation {kind} needs --amplitude (RMS per input, input units)")
    if kind == "multisine":
        if clock is not None:
            raise OptionError("--clock belongs to --excitation prbs, not multisine")
        if band is None or lines is None:
            raise OptionError("--excitation multisine needs --band LOW,HIGH (Hz) and --lines N")
        return Multisine(band=band, lines=lines, amplitude=tuple(_amplitudes(amplitude)))
    if band is not None or lines is not None:
        raise OptionError("--band and --lines belong to --excitation multisine, not prbs")
    if clock is None:
        raise OptionError("--excitation prbs needs --clock N (samples each level is held)")
    return RandomBinary(clock=clock, amplitude=tuple(_amplitudes(amplitude)))


def design_from_description(description: Any) -> InputDesign:
    """The design whose ``describe()`` is ``description`` (as a dataset's
    ``metadata["generation"]["design"]`` records it); refuses anything else."""
    if not isinstance(description, dict):
        raise OptionError(f"a design description must be an object, got {description!r:.60}")
    kind = description.get("kind")
    if kind not in EXCITATION_KINDS:
        raise OptionError(f"design kind must be one of {', '.join(EXCITATION_KINDS)}, got {kind!r}")
    try:
        rms = description["rms"]
        amplitude: float | tuple[float, ...] = tuple(rms) if isinstance(rms, list) else rms
        if kind == "multisine":
            low, high = description["band_hz"]
            return Multisine(
                band=(low, high), lines=description["lines_per_input"], amplitude=amplitude
            )
        return RandomBinary(clock=description["clock_samples"], amplitude=amplitude)
    except (KeyError, TypeError, ValueError) as exc:
        raise OptionError(f"design description {description} is incomplete: {exc}") from None
