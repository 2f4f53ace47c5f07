"""What ``canonid evaluate --residuals`` asks for: a data-only check of a trained model's input
response, the k-step-ahead residuals against the excitation (Ljung, ch. 13 and 16.6).

:func:`check_residuals` reads the model of a run folder and its data as ``canonid evaluate`` does
(:func:`canonid.scoring.scoring_data`), computes the k-step residuals of the split's records
(:func:`canonid.learning.evaluate.kstep_residuals`, rows ``t = ℓ + H − 1 … T − 1`` for every
``k``, ``H`` the largest) and correlates them at lags ``1 … k`` with an instrument
(:func:`residual_tests`, :func:`canonid.analysis.residuals.correlation_test`):

* for a dataset of ``canonid generate`` whose flights carry an excitation, the excitation
  ``e + d`` added to every command, regenerated from the flights' seeds
  (:func:`canonid.datagen.generate.dataset_excitation`);
* otherwise the recorded inputs, which in a loop closed on measured outputs carry the noise, so
  that the test can flag a correct model (:data:`INPUTS_NOTE`).

Either is prewhitened by AR(:data:`PREWHITEN`) per channel; the band is :data:`CONFIDENCE` per
correlation and admits residual autocorrelation over ``M = k + ℓ − 1 + p`` lags (a window-ℓ
predictor's k-step residuals share window noise over ``k + ℓ − 1`` lags, the order-``p`` filter
adds ``p``). These settings are those of ``benchmarks/studies/excitation/excitation_check.py``,
fixed before its
numbers were seen. Every number is an estimate (:class:`CorrelationTest`).

The module imports no torch; the check loads it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from canonid.analysis.residuals import CorrelationTest, correlation_test
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError, OptionError, OutputError
from canonid.kernel.io import atomic_write_json
from canonid.scoring import EvaluateRequest, scoring_data

__all__ = [
    "CONFIDENCE",
    "DEFAULT_HORIZONS",
    "DEFAULT_K",
    "INPUTS_NOTE",
    "JSON_HELP",
    "PREWHITEN",
    "RESIDUALS_HELP",
    "CheckedRecords",
    "ResidualCheck",
    "ResidualRequest",
    "check_residuals",
    "generated_excitation",
    "residual_horizons",
    "residual_tests",
]

#: two-sided confidence of the band per correlation
CONFIDENCE = 0.99
#: AR order of the prewhitening filter fitted to each instrument channel
PREWHITEN = 10
#: the horizons checked by default; a K asked for joins them
DEFAULT_HORIZONS = (1, 10)
#: the K of ``--residuals`` without one
DEFAULT_K = 10
#: what the check prints when the instrument is the inputs
INPUTS_NOTE = (
    "note: no recorded excitation in these data, so the instrument is the inputs (prewhitened); "
    "in closed loop they carry the noise and this test can flag a correct model: the excitation "
    "you added to the commands, recorded, is the instrument to use (docs: Identifying for "
    "control, the Python route)"
)

#: ``canonid evaluate --residuals [K]``'s help
RESIDUALS_HELP = (
    "instead of scoring, check the input response: the model's k-step-ahead residuals on the "
    "split, correlated at lags 1 ... k with the excitation that canonid generate added to the "
    "commands (regenerated from the flights' seeds), else with the inputs, both prewhitened by "
    f"AR({PREWHITEN}), {CONFIDENCE * 100:.0f}%% band per correlation; one line per k = "
    + ", ".join(map(str, DEFAULT_HORIZONS))
    + f" and K (default {DEFAULT_K}; e.g. your controller's horizon): correlations outside the "
    "band, the null's share, the largest |r|/band, the count per output; on the validation "
    "split unless --split names another. Estimates; writes nothing to RUN"
)
#: ``canonid evaluate --json FILE``'s help
JSON_HELP = "with --residuals: also write its result to FILE, a new file (default: none written)"
#: the scoring options that the check does not take: request field → flag, default
_SCORING_ONLY = {
    "horizon": ("--eval-horizon", None),
    "stride": ("--stride", 1),
    "n_init": ("--n-init", None),
    "figure_format": ("--figure-format", "png"),
}


def residual_horizons(k: int) -> tuple[int, ...]:
    """The horizons checked: :data:`DEFAULT_HORIZONS` and ``k`` (an integer >= 1)."""
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise OptionError(f"--residuals K must be an integer >= 1, got {k!r}")
    return tuple(sorted({*DEFAULT_HORIZONS, k}))


def residual_tests(
    residuals: Mapping[int, Sequence[np.ndarray]],
    instrument: Sequence[np.ndarray],
    window: int,
    *,
    prewhiten: int = PREWHITEN,
    confidence: float = CONFIDENCE,
    what: str,
    instrument_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
) -> dict[int, CorrelationTest]:
    """The test of each horizon ``k`` of ``residuals`` (``k`` → one array per record, the last
    rows of each, as :func:`canonid.learning.evaluate.kstep_residuals` gives them) against
    ``instrument`` (one ``(T, n_s)`` array per record): the instrument's last rows, lags
    ``1 … k``, prewhitened by AR(``prewhiten``), the band admitting
    ``k + window − 1 + prewhiten`` lags of residual autocorrelation (names: as
    :func:`canonid.analysis.residuals.correlation_test`)."""
    out: dict[int, CorrelationTest] = {}
    for k, eps in residuals.items():
        out[k] = correlation_test(
            eps,
            [s[s.shape[0] - e.shape[0] :] for e, s in zip(eps, instrument, strict=True)],
            lags=range(1, k + 1),
            confidence=confidence,
            prewhiten=prewhiten,
            null_lags=k + window - 1 + prewhiten,
            what=what,
            instrument_names=instrument_names,
            output_names=output_names,
        )
    return out


def generated_excitation(dataset: Dataset, split: str) -> list[np.ndarray] | None:
    """The excitation ``e + d`` of every record of ``split``, regenerated from the seeds of a
    ``canonid generate`` dataset; ``None`` for data from elsewhere or flights with none."""
    from canonid.datagen.generate import dataset_excitation

    if dataset.metadata.get("source") != "canonid generate":
        return None
    signals = [flight.total for flight in dataset_excitation(dataset, split)]
    return signals if any(np.any(s != 0.0) for s in signals) else None


@dataclass(frozen=True)
class CheckedRecords:
    """The records a check reads and the instrument their residuals are correlated with, read
    once for any number of models (:meth:`tests`).

    Attributes:
        data: the data's path. split: the split's name. records: its records.
        instrument: ``"excitation"`` (regenerated) or ``"inputs"``; signals: one array per
        record. input_names, output_names: the signals' names.
    """

    data: str
    split: str
    records: Sequence[Any]
    instrument: Literal["excitation", "inputs"]
    signals: Sequence[np.ndarray]
    input_names: Sequence[str]
    output_names: Sequence[str]

    @classmethod
    def of(cls, dataset: Dataset, split: str | None, *, where: str) -> CheckedRecords:
        """The split ``split`` of ``dataset`` (read from ``where``) and its instrument."""
        from canonid.runfolder import pick_split

        name, records = pick_split(dataset, split, where=where)
        excitation = generated_excitation(dataset, name)
        return cls(
            data=str(where),
            split=name,
            records=records,
            instrument="excitation" if excitation is not None else "inputs",
            signals=excitation if excitation is not None else [tr.u for tr in records],
            input_names=dataset.input_names,
            output_names=dataset.output_names,
        )

    def tests(self, model: Any, horizons: Sequence[int]) -> tuple[int, dict[int, CorrelationTest]]:
        """``model``'s k-step residuals on the records tested for every k of ``horizons``:
        ``(first row, {k: test})``; a :class:`DataError` where the records are too short."""
        from canonid.learning.evaluate import kstep_residuals

        ell, top = model.window, max(horizons)
        first = ell + top - 1
        needed = first + PREWHITEN + top + 1  # rows past the filter's start at the longest lag
        longest = max((tr.T for tr in self.records), default=0)  # 0: an empty split
        if longest < needed:
            raise DataError(
                f"{self.data} [{self.split}]: records of at most {longest} samples; "
                f"the check at k = {top} needs one of {needed} or more (ℓ + k − 1 skipped, "
                f"AR({PREWHITEN}) prewhitening, lags up to k); give a smaller K"
            )
        eps = kstep_residuals(model, self.records, horizons)
        return first, residual_tests(
            eps,
            self.signals,
            ell,
            what=self.instrument,
            instrument_names=self.input_names,
            output_names=self.output_names,
        )


@dataclass(frozen=True, kw_only=True)
class ResidualRequest(EvaluateRequest):
    """The check asked for: the run and data of :class:`canonid.scoring.EvaluateRequest`, whose
    scoring options (``horizon``, ``stride``, ``n_init``, ``figure_format``) the check refuses
    when they are not their defaults.

    Attributes:
        residuals: the ``K`` added to :data:`DEFAULT_HORIZONS` (``None``: not asked for, which
            ``canonid evaluate`` refuses with ``--json``).
        json: a new file to write the result into (:meth:`ResidualCheck.to_dict`).
    """

    residuals: int | None = DEFAULT_K
    json: Path | None = None


@dataclass(frozen=True)
class ResidualCheck:
    """What :func:`check_residuals` found: one :class:`CorrelationTest` per horizon.

    Attributes:
        run, data, split: what was checked. model, window: the model's name and ``ℓ``.
        records: records of the split. first_row: the first row ``ℓ + H − 1`` of every record.
        instrument: ``"excitation"`` (regenerated) or ``"inputs"``.
        tests: horizon ``k`` → its test (lags ``1 … k``).
        kind: always ``"estimate"``.
    """

    run: str
    data: str
    split: str
    model: str
    window: int
    records: int
    first_row: int
    instrument: Literal["excitation", "inputs"]
    tests: Mapping[int, CorrelationTest]
    kind: Literal["estimate"] = "estimate"

    def lines(self) -> list[str]:
        """What ``canonid evaluate --residuals`` prints: a head, the note of the inputs'
        fallback, one line per horizon, and what the numbers are."""
        any_test = next(iter(self.tests.values()))
        source = (
            "the excitation e + d regenerated from the flights' seeds"
            if self.instrument == "excitation"
            else "the recorded inputs"
        )
        out = [
            f"residual check of {self.run} ({self.model}, ℓ = {self.window}) on {self.data} "
            f"[{self.split}], {self.records} record{'' if self.records == 1 else 's'}: "
            f"k-step-ahead residuals on rows t = {self.first_row} … T − 1 against {source}, "
            "prewhitened by "
            f"AR({any_test.prewhitening}), at lags 1 … k"
        ]
        if self.instrument == "inputs":
            out.append(INPUTS_NOTE)
        width = len(str(max(self.tests)))
        for k, test in self.tests.items():
            value, channel, output, lag = test.worst
            per_output = test.outside.sum(axis=(0, 2))
            total = test.outside.shape[0] * test.outside.shape[2]
            outputs = ", ".join(
                f"{name} {int(n)}/{total}" for name, n in zip(test.output_names, per_output)
            )
            out.append(
                f"k = {k:>{width}}: {int(test.outside.sum())} / {test.outside.size} outside "
                f"the band ({test.outside_fraction:.1%}, null about {test.expected_fraction:.0%});"
                f" largest |r|/band {value:.1f} ({channel} -> {output}, lag {lag}); "
                f"per output {outputs}"
            )
        out.append(
            f"estimates: sample correlations against an asymptotic {any_test.confidence:.0%} "
            "band per correlation (residual autocorrelation admitted over M = k + ℓ − 1 + "
            f"{any_test.prewhitening} lags; N = {any_test.samples}); well above the null's "
            "share, the model's input response is not the data's"
        )
        return out

    def summary(self) -> str:
        """:meth:`lines`, one string."""
        return "\n".join(self.lines())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields; ``tests`` by horizon (:meth:`CorrelationTest.to_dict`)."""
        return {
            "kind": self.kind,
            "run": self.run,
            "data": self.data,
            "split": self.split,
            "model": self.model,
            "window": self.window,
            "records": self.records,
            "first_row": self.first_row,
            "instrument": self.instrument,
            "tests": {str(k): test.to_dict() for k, test in self.tests.items()},
        }


def check_residuals(request: ResidualRequest) -> ResidualCheck:
    """The residual check of ``request.run`` on its data's split (module docstring)."""
    from canonid.runfolder import load_run_model

    if request.residuals is None:
        raise OptionError("--json FILE writes the residual check: give --residuals [K] too")
    given = [
        flag for name, (flag, default) in _SCORING_ONLY.items() if getattr(request, name) != default
    ]
    if given:
        raise OptionError(f"{', '.join(given)} set the scores; --residuals takes none of them")
    horizons = residual_horizons(request.residuals)
    if request.json is not None:
        _new_file(request.json)  # before the work, not after it
    model = load_run_model(request.run)
    dataset, data_path, split = scoring_data(
        request.run, request.data, request.data_options, split=request.split, model=model.info
    )
    # a check that chooses a model reads validation data by default, never the test part unasked
    # (for the run's own data scoring_data names the split that scores them: test)
    if request.split is None and dataset.splits.get("val"):
        split = "val"
    checked = CheckedRecords.of(dataset, split, where=data_path)
    first, tests = checked.tests(model, horizons)
    check = ResidualCheck(
        run=str(request.run),
        data=str(data_path),
        split=checked.split,
        model=model.name,
        window=model.window,
        records=len(checked.records),
        first_row=first,
        instrument=checked.instrument,
        tests=tests,
    )
    if request.json is not None:
        atomic_write_json(_new_file(request.json), check.to_dict())
    return check


def _new_file(path: Path) -> Path:
    """``path`` if nothing is there yet and its folder exists; else :class:`OutputError`."""
    if path.exists() or path.is_symlink():
        raise OutputError(f"--json {path} exists; remove it or give another file name")
    if not path.parent.is_dir():
        raise OutputError(f"--json {path}: the folder {path.parent} does not exist")
    return path
