"""Residuals against the excitation: a data-only check of a learned model's input response.

On the informative drone data (`drone2d-id`) the models whose NMPC loops fail move px the wrong
way after a rotor difference, and validation losses do not rank them for control (the records,
"Training horizon on validation"). Closed-loop identification theory (Ljung, ch. 13) offers a
check that needs no true system: the only part of the input known to be independent of the noise
is the external excitation added to the controller's command, ``u = clip(c + e + d, U)``; the
k-step-ahead residuals of a correct model are uncorrelated with it at every lag, and a model
with a wrong input response leaves residuals correlated with the excitation of the k samples it
predicted through.

For each run folder, on the **validation** flights only: the k-step residuals
(:func:`canonid.learning.evaluate.kstep_residuals`, ``k`` = 1, 10 and 20, the NMPC's horizon;
rows ``t = ℓ + 19 … T − 1`` for all three) and :func:`canonid.analysis.residuals.correlation_test`
at lags 1 … k, 99 % band, against

* the excitation ``e + d`` (the Gaussian ``e`` and the multisine ``d``), which the dataset does
  not store: it is regenerated from the flights' seeds
  (:func:`canonid.datagen.generate.dataset_excitation`), and the script first re-flies the first
  validation flight from its seed and checks that it reproduces the recorded inputs;
  prewhitened by AR(10) (fitted per rotor), and also raw (the band then carries the
  autocorrelations of both signals, Ljung's eq. 16.62);
* the recorded inputs, prewhitened by AR(10): the classical test, for data without a recorded
  excitation.

The band admits residual autocorrelation over ``M = k + ℓ − 1 + p`` lags (a correct window-ℓ
predictor's k-step residuals share window noise over ``k + ℓ − 1`` lags, the order-``p`` filter
adds ``p``). A reference row gives the measurement noise ``y − y_clean`` itself, which is what a
correct model fed the true state leaves (it uses the true outputs: not data-only).

Usage (from the repository root)::

    python benchmarks/studies/excitation/excitation_check.py [--data DIR] [--run RUN ...] \
        [--loop FILE ...]
                                          [--json FILE] [--no-write]

``--loop`` takes ``benchmarks/studies/learned_mpc/learned_mpc.py --json`` files, to set each
run's loop beside it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))  # this checkout's packages
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

import numpy as np  # noqa: E402
from _results import write_section  # noqa: E402

from canonid.analysis.residuals import CorrelationTest  # noqa: E402
from canonid.kernel.dataset import Dataset  # noqa: E402
from canonid.kernel.io import atomic_write_json  # noqa: E402
from canonid.residual_check import (  # noqa: E402
    CONFIDENCE,
    PREWHITEN,
    generated_excitation,
    residual_tests,
)

SECTION = "Residuals against the excitation"
DATA = "runs/data/drone2d-id-small"
RUNS = (
    "runs/drone2d/id-def",
    "runs/hz/drone-id-c300",
    "runs/drone2d/id-arx",
    "runs/drone2d/id-h10",
    "runs/drone2d/arx-l10-drone2d-id",
)
LOOPS = (
    "runs/learned_mpc_id.json",
    "runs/horizon-study/loop-c300.json",
    "runs/horizon-study/loop-linear-arx.json",
)
HORIZONS = (1, 10, 20)
ORDER = PREWHITEN  # AR order of the prewhitening filters (canonid evaluate --residuals's)
#: the instruments of the table: label → (signal name, prewhitening order)
INSTRUMENTS = {
    "excitation e + d, AR(10)": ("excitation", ORDER),
    "excitation e + d, raw": ("excitation", 0),
    "inputs u, AR(10)": ("inputs", ORDER),
}


def loop_figures(res: dict) -> tuple[float, int, int, float]:
    """What one drone entry of ``learned_mpc.py --json`` measured: the learned / true tracking
    RMSE, the learned loops that left X, the loops run, and the learned / true px change after
    the first judged step (the rotor difference) from rest."""
    rows = res["rows"]
    ratio = rows["learned model"]["rmse"] / rows["true model"]["rmse"]
    left = len(rows["learned model"]["left_X"])
    px = next(iter(res["responses"].values()))["rest"]["ratios"][0]
    return ratio, left, len(rows["learned model"]["rmses"]), px


def replay_check(data: Dataset) -> str:
    """Re-fly validation flight 0 from its seed: does it reproduce the recorded inputs bytewise?"""
    from canonid.datagen.generate import FlightJob, GenerationConfig, run_flight

    config = GenerationConfig.from_json(data.metadata["generation"])
    recorded = data.split("val")[0]
    flown = run_flight(FlightJob(config, "val", int(recorded.info["index"]))).trajectory
    same = np.array_equal(flown.u, recorded.u)
    gap = float(np.max(np.abs(flown.u - recorded.u)))
    return "identical" if same else f"NOT identical (largest difference {gap:.3g} rad/s)"


def tests_for(
    residuals: dict[int, list[np.ndarray]],
    signals: dict[str, list[np.ndarray]],
    window: int,
    names: dict[str, tuple[str, ...]],
    output_names: tuple[str, ...],
) -> dict[int, dict[str, CorrelationTest]]:
    """Every (horizon, instrument) test of one model's residuals (the settings of ``canonid
    evaluate --residuals``: :func:`canonid.residual_check.residual_tests`)."""
    by_label = {
        label: residual_tests(
            residuals,
            signals[signal],
            window,
            prewhiten=order,
            confidence=CONFIDENCE,
            what=signal,
            instrument_names=names[signal],
            output_names=output_names,
        )
        for label, (signal, order) in INSTRUMENTS.items()
    }
    return {k: {label: by_label[label][k] for label in INSTRUMENTS} for k in residuals}


def cell(test: CorrelationTest) -> str:
    """``outside / total (worst |r|/band)``."""
    return f"{int(test.outside.sum())} / {test.outside.size} ({test.worst[0]:.1f})"


def loops_by_run(files: list[Path]) -> dict[str, tuple[float, int, int, float]]:
    """Each drone2d-id run's loop figures from ``learned_mpc.py --json`` files."""
    found: dict[str, tuple[float, int, int, float]] = {}
    for path in files:
        if not path.is_file():
            continue
        for res in json.loads(path.read_text()).values():
            if res.get("data") == "drone2d-id":
                found[res["run"]] = loop_figures(res)
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=DATA, help=f"the dataset folder (default {DATA})")
    parser.add_argument("--run", action="append", help="a run folder (repeat; default: five)")
    parser.add_argument("--loop", action="append", type=Path, help="a learned_mpc.py --json file")
    parser.add_argument("--json", type=Path, help="also write every test here")
    parser.add_argument("--no-write", action="store_true", help="do not touch the record's notes")
    args = parser.parse_args()

    import torch

    from canonid.datagen.generate import GenerationConfig
    from canonid.learning.evaluate import kstep_residuals
    from canonid.learning.model import Model

    torch.set_num_threads(1)
    started = time.perf_counter()
    data = Dataset.load(ROOT / args.data)
    val = data.split("val")
    replay = replay_check(data)
    excitation = generated_excitation(data, "val")
    if excitation is None:
        raise SystemExit(f"{args.data}: no excitation to regenerate (not canonid generate data)")
    config = GenerationConfig.from_json(data.metadata["generation"])
    box = config.true_system.U
    applied = np.concatenate([tr.u for tr in val])
    clipped = float(np.mean(np.any((applied <= box.lo) | (applied >= box.hi), axis=1)))
    names = {"excitation": data.input_names, "inputs": data.input_names}
    first_row = max(HORIZONS) - 1  # plus ℓ: the rows every horizon has

    results: dict[str, Any] = {}
    rows_main, rows_out = [], []
    loops = loops_by_run([ROOT / p for p in (args.loop or LOOPS)])
    runs = args.run or list(RUNS)
    noise_done = False
    for run in runs:
        model = Model.load(ROOT / run)
        ell = model.window
        first = ell + first_row
        residuals = kstep_residuals(model, val, HORIZONS)
        signals = {"excitation": excitation, "inputs": [tr.u for tr in val]}
        tests = tests_for(residuals, signals, ell, names, data.output_names)
        if not noise_done:  # the reference row: the noise on the same rows
            noise = {k: [tr.y[first:] - tr.y_clean[first:] for tr in val] for k in HORIZONS}
            noise_tests = tests_for(noise, signals, ell, names, data.output_names)
            results["noise y - y_clean"] = {
                k: {lab: t.to_dict() for lab, t in v.items()} for k, v in noise_tests.items()
            }
            for k in HORIZONS:
                rows_main.append(
                    f"| noise y − y_clean (reference: uses the true outputs) | - | - | {k} | "
                    + " | ".join(cell(noise_tests[k][lab]) for lab in INSTRUMENTS)
                    + " |"
                )
            noise_done = True
        results[run] = {k: {lab: t.to_dict() for lab, t in v.items()} for k, v in tests.items()}
        loop = loops.get(run)
        ratio = "-" if loop is None else f"{loop[0]:.3g}"
        px = "-" if loop is None else f"{loop[3]:.3g}"
        for k in HORIZONS:
            rows_main.append(
                f"| `{run}` | {ratio} | {px} | {k} | "
                + " | ".join(cell(tests[k][lab]) for lab in INSTRUMENTS)
                + " |"
            )
        main = tests[max(HORIZONS)][next(iter(INSTRUMENTS))]
        per_output = main.outside.sum(axis=(0, 2))
        worst_by_output = main.ratio.max(axis=(0, 2))
        rows_out.append(
            f"| `{run}` | "
            + " | ".join(
                f"{int(n)} / {main.outside.shape[0] * main.outside.shape[2]} ({w:.1f})"
                for n, w in zip(per_output, worst_by_output)
            )
            + " |"
        )
        print(run, "k=20:", main.summary(), flush=True)
    wall = time.perf_counter() - started

    n_flights, T = len(val), val[0].T
    labels = " | ".join(INSTRUMENTS)
    body = "\n".join(
        [
            f"Data: `{args.data}` (`{config.system}`), the {n_flights} **validation** flights "
            f"of {T} samples. Per run: the k-step-ahead residuals ε_k[t] = y[t] − ŷ(t | y up to "
            "t−k, "
            "recorded u) of canonid's own rollout (`canonid.learning.evaluate.kstep_residuals`; "
            f"rows t = ℓ + {first_row} … T − 1 for every k), correlated with an instrument at "
            f"lags 1 … k (`canonid.analysis.residuals.correlation_test`, {CONFIDENCE:.0%} band "
            "per correlation, residual autocorrelation admitted over M = k + ℓ − 1 + p lags, p "
            "the prewhitening order). Instruments: the excitation e + d that the data engine "
            "added to each command (Gaussian e, σ = 1 rad/s, and the multisine d, RMS 5 rad/s), "
            "not stored in the dataset and regenerated from the flights' seeds "
            "(`canonid.datagen.generate.dataset_excitation`; validation flight 0 re-flown from "
            f"its seed reproduces the recorded inputs: {replay}), prewhitened by AR({ORDER}) "
            f"per rotor or raw ({clipped:.1%} of the validation samples have a rotor clipped "
            "to U, where the applied input is not c + e + d); and the recorded inputs u "
            "prewhitened by AR("
            f"{ORDER}) (the classical test). Each cell: correlations outside the band / all "
            "(2 rotors × 3 outputs × k lags), and the largest |r| / band in brackets. The null "
            f"expects about {1 - CONFIDENCE:.0%} outside. Loop figures (learned / true tracking "
            "RMSE of NMPC on the model, px change after a rotor difference learned / true) from "
            'the section "NMPC on a learned model: informative drone data" and "Training horizon '
            'on validation".',
            "",
            f"| run | loop RMSE ratio | px learned / true | k | {labels} |",
            "|---|---:|---:|---:|---:|---:|---:|",
            *rows_main,
            "",
            f"The k = {max(HORIZONS)} test against the excitation (AR({ORDER})) per output: "
            "outside / all (2 rotors × k lags), largest |r| / band:",
            "",
            "| run | " + " | ".join(data.output_names) + " |",
            "|---|" + "---:|" * len(data.output_names),
            *rows_out,
            "",
            f"Wall time {wall:.0f} s.",
        ]
    )
    if args.json:
        atomic_write_json(args.json, results)
    print(body)
    if not args.no_write:
        write_section(SECTION, body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
