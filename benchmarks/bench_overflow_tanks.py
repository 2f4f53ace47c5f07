"""Cascaded tanks with overflow (``tanks-overflow``, a simulated analogue of the Cascaded Tanks
benchmark): canonid's defaults, the Classic GRU baseline, ARX and deepSI's SUBNET with its
defaults on the same small record, side by side.

Writes the section "Overflow tanks" of the records (benchmarks/records/).

* Data: ``canonid generate tanks-overflow --seed 0`` into ``runs/data/tanks-overflow``: one
  training record of 1,024 samples (Ts = 4 s) whose last 20 % (samples 819…1023) validate, one
  test record of 1,024 samples from another multisine realisation. The section counts how often
  each part reaches the upper tank's rim and the sensor's limit (noise-free state and output).
* Contestants, each in its own child process with one torch thread, CPU time of the child
  (user + system, from ``getrusage``) recorded:

  - ``canonid train DATA --max-window 50 --threads 1``: canonid's defaults (Ours (MLP), the
    quick profile, the window chosen on validation by the screen among those the scoring rule
    can feed, ℓ ≤ n_init = 50, as ``canonid benchmark`` caps it);
  - ``canonid train DATA --window 10 --threads 1``: the same at ℓ = 10, and at ℓ = 10 with
    ``--model classic-gru`` and ``--model arx``;
  - deepSI 0.4.4 with its defaults: ``deepSI.SUBNET(n_u, n_y, norm)`` (state dimension 10,
    encoder windows na = nb = 20, residual MLPs) trained by ``deepSI.fit`` (rollouts T = 50,
    batch 256, Adam at 1e-3, validation every 250 iterations by a simulation of the validation
    part, the best model kept) for ``--deepsi-iterations`` iterations; ``deepSI.fit`` has no
    default for that number, so the script gives it one chosen to cost about as much CPU as
    canonid's defaults (the table shows both CPU times). Torch's seed 0.

* Score, one code for all (:func:`canonid.learning.evaluate`): each model simulates the test
  record from its measured samples ``50 − w … 49`` (w its window: 10, or deepSI's 20) and the
  whole input; RMSE in V and fit % over samples 50…1023 (n_init = 50, the benchmark's rule in
  nonlinear_benchmarks 1.0.1), against the measured output and against the noise-free one. Nothing
  is chosen on the test record: every contestant runs with its defaults, each keeps its best
  model on the validation part.

* What the defaults lack, on validation only: Ours (MLP) at ℓ = 10 with one change each
  (:data:`VARIANTS`: ℓ = 20; hidden layers of 64): the best validation loss, its epoch and the
  training loss there, and both losses at the last epoch (training falling while validation
  does not: overfitting); the test score is read for the run the validation loss picks, after
  it picked it.

* How much of one comparison is chance (``--spread D S``): the defaults, the Classic GRU, ARX
  and deepSI again with training seed ``S`` (``canonid train --seed S``; torch's seed ``S`` for
  deepSI) on the data of ``canonid generate tanks-overflow --seed D`` (another realisation of
  both multisines), each cell in ``runs/overflow-tanks/spread/dD-sS``; the section's last table
  lists every cell trained, the main table's runs as cell (0, 0). Nothing is chosen from it.

The run folders, deepSI's scores and the CPU seconds stay in ``runs/overflow-tanks``;
``--record`` writes the section again from them without training; ``--only FOLDER`` trains that
canonid contestant alone and keeps the others' runs and CPU times.

Usage: python benchmarks/bench_overflow_tanks.py [--deepsi-iterations N] [--only FOLDER] [--record]
(about 16 CPU-minutes); python benchmarks/bench_overflow_tanks.py --spread D S (about 14 per cell)
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import resource
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import load_line, publish  # noqa: E402

from canonid.kernel.io import atomic_write_json  # noqa: E402

SECTION = "Overflow tanks"
DATA = ROOT / "runs" / "data" / "tanks-overflow"
RUNS = ROOT / "runs" / "overflow-tanks"
GENERATE = ["tanks-overflow", "--seed", "0"]
WINDOW, N_INIT = 10, 50
#: deepSI iterations (batch 256, rollouts of 50): about the CPU of canonid's defaults here
DEEPSI_ITERATIONS = 5000
#: the canonid contestants: table label → (run folder, extra ``canonid train`` arguments)
DEFAULTS_LABEL = "canonid defaults (Ours (MLP))"
FIXED_LABEL = "Ours (MLP), ℓ = 10"
CANONID = {
    DEFAULTS_LABEL: ("mlp-default", ["--max-window", str(N_INIT)]),
    FIXED_LABEL: ("mlp", ["--window", str(WINDOW)]),
    "Classic GRU": ("classic-gru", ["--window", str(WINDOW), "--model", "classic-gru"]),
    "ARX (linear)": ("arx", ["--window", str(WINDOW), "--model", "arx"]),
}
DEEPSI_LABEL = "deepSI SUBNET (its defaults)"
#: the diagnosis, read on validation only: canonid's defaults with one thing changed
VARIANTS = {
    "ℓ = 20": ("l20", ["--window", "20"]),
    "hidden 64 × 64 × 64": ("h64", ["--window", str(WINDOW), "--hidden", "64,64,64"]),
}
#: CPU seconds of every child and the load readings of the last full run
CPU_FILE = "cpu.json"
#: the contestants of a spread cell (``--spread D S``): folders of CANONID trained there
SPREAD_FOLDERS = ("mlp-default", "classic-gru", "arx")


@dataclass(frozen=True)
class Score:
    """One contestant's simulation scores on the test record (samples N_INIT…) and its cost."""

    label: str
    window: int
    rmse: float
    fit: float
    rmse_clean: float
    fit_clean: float
    cpu_s: float
    best_val: str


def child_cpu(cmd: list[str]) -> float:
    """Run ``cmd`` to its end; the CPU seconds (user + system) it took."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, cwd=ROOT)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def episodes(mask: np.ndarray) -> int:
    """Runs of consecutive True samples."""
    return int(mask[0]) + int(np.sum(np.diff(mask.astype(int)) == 1))


def regimes(data: Path) -> list[str]:
    """Table rows: per part, samples (and episodes) at the rim and at the sensor's limit."""
    from canonid.kernel.dataset import Dataset
    from canonid.models import get_system

    ds, system = Dataset.load(data), get_system("tanks-overflow")
    rows = []
    for split, label in (("train", "training"), ("val", "validation"), ("test", "test")):
        (tr,) = ds.split(split)
        assert tr.x is not None and tr.y_clean is not None
        rim = tr.x[:, 0] >= system.top
        sensor = tr.y_clean[:, 0] >= system.y_max
        rows.append(
            f"| {label} | {tr.T} | {rim.sum()} ({episodes(rim)}) | "
            f"{sensor.sum()} ({episodes(sensor)}) | {tr.u.min():.2f} … {tr.u.max():.2f} |"
        )
    return rows


def score(label: str, model: Any, data: Path, cpu: float, best_val: str) -> Score:
    from canonid.kernel.dataset import Dataset
    from canonid.learning import evaluate

    ev = evaluate(model, Dataset.load(data).split("test"), n_init=N_INIT)
    assert ev.clean is not None
    return Score(
        label=label,
        window=model.window,
        rmse=ev.measured.rmse,
        fit=ev.measured.fit_percent,
        rmse_clean=ev.clean.rmse,
        fit_clean=ev.clean.fit_percent,
        cpu_s=cpu,
        best_val=best_val,
    )


def canonid_train(folder: str, extra: list[str], data: Path) -> float:
    """``canonid train DATA EXTRA`` into ``RUNS/folder``; its CPU seconds."""
    cmd = [sys.executable, "-m", "canonid", "train", str(data)]
    out = RUNS / folder
    return child_cpu([*cmd, *extra, "--threads", "1", "--no-progress", "--out", str(out)])


@dataclass(frozen=True)
class Validation:
    """What a ``canonid train`` run folder says about its validation (normalised losses): the
    best validation loss and its epoch, the training loss there, and both at the end."""

    best: float
    epoch: int
    train_at_best: float
    last: int
    val_last: float
    train_last: float


def validation(run: Path) -> Validation:
    """Read ``history.csv`` (one row per epoch, the validation loss every few; epoch 0 is the
    untrained model, ARX's least squares, and has no training loss)."""
    with (run / "history.csv").open() as f:
        rows = list(csv.DictReader(f))

    def train(row: dict[str, str]) -> float:
        return float(row["train_loss"]) if row["train_loss"] else math.nan

    scored = [r for r in rows if r["val_loss"]]
    best = min(scored, key=lambda r: float(r["val_loss"]))
    return Validation(
        best=float(best["val_loss"]),
        epoch=int(best["epoch"]),
        train_at_best=train(best),
        last=int(rows[-1]["epoch"]),
        val_last=float(scored[-1]["val_loss"]),
        train_last=train(rows[-1]),
    )


def canonid_score(label: str, run: Path, data: Path, cpu: float) -> Score:
    from canonid.learning import Model

    v = validation(run)
    best = f"epoch {v.epoch} of {v.last}" if v.last > 0 else "least squares"
    return score(label, Model.load(run), data, cpu, best)


def deepsi_child(data: Path, iterations: int, out: Path, seed: int = 0) -> int:
    """Train deepSI's SUBNET with its defaults (this process: one torch thread, torch's seed
    ``seed``) and write its scores to ``out`` as JSON."""
    from _deepsi import fit_subnet

    from canonid.kernel.dataset import Dataset

    ds = Dataset.load(data)
    found = fit_subnet(ds.split("train"), ds.split("val"), iterations, seed=seed)
    best_val = f"iteration {found.at} of {iterations}"
    result = score(DEEPSI_LABEL, found.model, data, 0.0, best_val)
    out.write_text(json.dumps(asdict(result)))
    return 0


def deepsi_train(data: Path, iterations: int, runs: Path = RUNS, seed: int = 0) -> float:
    """deepSI in a child process (its scores land in ``runs/deepsi.json``); its CPU seconds."""
    runs.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, __file__, "--deepsi-child", str(runs / "deepsi.json")]
    extra = ["--deepsi-data", str(data), "--deepsi-seed", str(seed)]
    return child_cpu([*cmd, "--deepsi-iterations", str(iterations), *extra])


def spread_data(data_seed: int) -> Path:
    """The dataset of ``canonid generate tanks-overflow --seed D`` (generated when missing)."""
    if data_seed == 0:
        data = DATA
    else:
        data = DATA.with_name(f"{DATA.name}-s{data_seed}")
    if not (data / "dataset.npz").is_file():
        cmd = [sys.executable, "-m", "canonid", "generate", "tanks-overflow"]
        child_cpu([*cmd, "--seed", str(data_seed), "--out", str(data)])
    return data


def spread_cell(data_seed: int, seed: int) -> Path:
    return RUNS / "spread" / f"d{data_seed}-s{seed}"


def spread_train(data_seed: int, seed: int, iterations: int) -> int:
    """Train one cell of the spread: every contestant of SPREAD_FOLDERS and deepSI, training
    seed ``seed``, on the data of generation seed ``data_seed``; CPU seconds in its cpu.json."""
    data, cell = spread_data(data_seed), spread_cell(data_seed, seed)
    cpu: dict[str, float] = {}
    for folder in SPREAD_FOLDERS:
        cmd = [sys.executable, "-m", "canonid", "train", str(data), *_extra(folder)]
        out = ["--seed", str(seed), "--threads", "1", "--no-progress", "--out", str(cell / folder)]
        cpu[folder] = child_cpu([*cmd, *out])
    cpu["deepsi"] = deepsi_train(data, iterations, cell, seed)
    atomic_write_json(cell / CPU_FILE, cpu)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--deepsi-iterations", type=int, default=DEEPSI_ITERATIONS)
    parser.add_argument(
        "--size", choices=("quick", "full"), help="read for run_all.py: there is one size"
    )
    parser.add_argument(
        "--record",
        action="store_true",
        help=f"write the section from the runs in {RUNS.relative_to(ROOT)} (no training)",
    )
    parser.add_argument(
        "--only",
        choices=[folder for folder, _ in [*CANONID.values(), *VARIANTS.values()]],
        help="train this canonid contestant alone; the others' runs and CPU times are kept",
    )
    parser.add_argument(
        "--spread",
        nargs=2,
        type=int,
        metavar=("D", "S"),
        help="train the defaults, the Classic GRU, ARX and deepSI with training seed S on the "
        "data of generation seed D (one cell of the section's last table; --record writes it)",
    )
    parser.add_argument("--deepsi-child", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--deepsi-data", type=Path, default=DATA, help=argparse.SUPPRESS)
    parser.add_argument("--deepsi-seed", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.deepsi_child is not None:
        return deepsi_child(
            args.deepsi_data, args.deepsi_iterations, args.deepsi_child, args.deepsi_seed
        )
    needs_runs = args.only is not None or args.record or args.spread is not None
    if needs_runs and not (RUNS / CPU_FILE).is_file():
        # checked before training: --only merges into the full run's records, --record reads them
        parser.error(
            f"{RUNS / CPU_FILE} not found: --only, --spread and --record need the runs of a full "
            "`python bench_overflow_tanks.py` in that folder"
        )
    if args.spread is not None:
        # the section is written by --record: cells may train side by side
        data_seed, seed = args.spread
        return spread_train(data_seed, seed, args.deepsi_iterations)
    if args.only is not None:
        seconds = canonid_train(args.only, _extra(args.only), DATA)
        # read after training: another --only may have written its time meanwhile
        cpu = json.loads((RUNS / CPU_FILE).read_text())
        cpu[args.only] = seconds
        atomic_write_json(RUNS / CPU_FILE, cpu)
        return record(rewritten=True)
    if not args.record:
        start = time.perf_counter()
        load = [os.getloadavg()[0]]
        if not (DATA / "dataset.npz").is_file():
            child_cpu([sys.executable, "-m", "canonid", "generate", *GENERATE, "--out", str(DATA)])
        cpu: dict[str, Any] = {}
        for folder, extra in [*CANONID.values(), *VARIANTS.values()]:
            cpu[folder] = canonid_train(folder, extra, DATA)
            load.append(os.getloadavg()[0])
        cpu["deepsi"] = deepsi_train(DATA, args.deepsi_iterations)
        load.append(os.getloadavg()[0])
        cpu.update(load=load, minutes=(time.perf_counter() - start) / 60)
        atomic_write_json(RUNS / CPU_FILE, cpu)
    return record(rewritten=args.record)


def _extra(folder: str) -> list[str]:
    """The ``canonid train`` arguments of the contestant or variant trained into ``folder``."""
    return next(extra for f, extra in [*CANONID.values(), *VARIANTS.values()] if f == folder)


def record(*, rewritten: bool = False) -> int:
    """Write the section from the run folders and ``cpu.json`` of the last full run."""
    cpu = json.loads((RUNS / CPU_FILE).read_text())
    scores = [
        canonid_score(label, RUNS / folder, DATA, cpu[folder])
        for label, (folder, _) in CANONID.items()
    ]
    found = json.loads((RUNS / "deepsi.json").read_text())
    scores.append(Score(**{**found, "cpu_s": cpu["deepsi"]}))
    sentence, _ = load_line(
        cpu["load"], "CPU times of one thread are less affected than wall times"
    )
    lines = [*report(scores, regimes(DATA), sentence), "", screen_lines(RUNS / "mlp-default")]
    if rewritten:
        lines += [
            "",
            "(Section written from the runs, CPU times and load readings of the last full run, "
            "`python bench_overflow_tanks.py`; a contestant added later was trained alone by "
            "`--only FOLDER` and its CPU time merged.)",
        ]
    return publish(SECTION, [*lines, "", *diagnosis(cpu), *spread_lines(scores)], cpu["minutes"])


def spread_lines(main: list[Score]) -> list[str]:
    """The spread table: the main table's runs as cell (0, 0), then every cell trained by
    ``--spread D S``; RMSE on each cell's own test record, nothing chosen from it."""
    from canonid.coverage import NOTED_BEYOND, UNVALIDATED_SHARE

    cells = sorted(
        (int(d), int(s), path)
        for path in (RUNS / "spread").glob("d*-s*/")
        if (path / CPU_FILE).is_file()
        for d, s in [path.name[1:].split("-s")]
    )
    if not cells:
        return []
    labels = dict(zip(SPREAD_FOLDERS, (DEFAULTS_LABEL, "Classic GRU", "ARX (linear)")))
    table = {(0, 0): {s.label: s for s in main}}
    for d, seed, path in cells:
        cpu = json.loads((path / CPU_FILE).read_text())
        data = spread_data(d)
        found = {
            labels[f]: canonid_score(labels[f], path / f, data, cpu[f]) for f in SPREAD_FOLDERS
        }
        deepsi = json.loads((path / "deepsi.json").read_text())
        found[DEEPSI_LABEL] = Score(**{**deepsi, "cpu_s": cpu["deepsi"]})
        table[(d, seed)] = found
    order = (DEFAULTS_LABEL, "Classic GRU", "ARX (linear)", DEEPSI_LABEL)
    rows = []
    for (d, seed), found in sorted(table.items()):
        ours = found[DEFAULTS_LABEL]
        cells_text = " | ".join(f"{found[k].rmse:.4f}" for k in order)
        rows.append(
            f"| {d} | {seed} | {ours.window} | {cells_text} | "
            f"{found[DEEPSI_LABEL].rmse / ours.rmse:.2f} | "
            f"{found['Classic GRU'].rmse / ours.rmse:.2f} | "
            f"{ours.cpu_s:.0f} | {found[DEEPSI_LABEL].cpu_s:.0f} | {_levels_unseen(d)} |"
        )
    below = sum(f[DEEPSI_LABEL].rmse > f[DEFAULTS_LABEL].rmse for f in table.values())
    target = sum(
        f[DEEPSI_LABEL].rmse > f[DEFAULTS_LABEL].rmse
        and min(f["Classic GRU"].rmse, f["ARX (linear)"].rmse) >= 1.5 * f[DEFAULTS_LABEL].rmse
        for f in table.values()
    )
    ratio = [f[DEEPSI_LABEL].rmse / f[DEFAULTS_LABEL].rmse for f in table.values()]
    return [
        "",
        "### Seeds and data: how much of one comparison is chance",
        "",
        "The same contestants with another training seed (`canonid train --seed S`; torch's "
        "seed S for deepSI) or on another realisation of the data (`canonid generate "
        "tanks-overflow --seed D`: both records' multisines drawn again), each cell trained by "
        "`python bench_overflow_tanks.py --spread D S`; cell (0, 0) is the table above. Test RMSE "
        "[V] on each cell's own test record, after n_init = 50; every model kept on its "
        "validation part; nothing is chosen here.",
        "",
        "| data seed D | training seed S | canonid's window | canonid defaults | Classic GRU "
        "| ARX | deepSI (its defaults) | deepSI / canonid | GRU / canonid | canonid CPU s "
        "| deepSI CPU s | validation span of the level; training samples outside it |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        *rows,
        "",
        f"canonid's defaults below deepSI's in {below} of {len(table)} cells (deepSI / canonid "
        f"from {min(ratio):.2f} to {max(ratio):.2f}, geometric mean "
        f"{math.exp(sum(map(math.log, ratio)) / len(ratio)):.2f}); the issue's whole target "
        f"(also 1.5× below the Classic GRU and ARX) in {target} of {len(table)}. The last "
        "column: the span of the level over the validation part, and the share of the training "
        "samples outside it (`canonid.coverage.unvalidated`; `canonid train` names the level "
        f"where that share is {100 * UNVALIDATED_SHARE:g} % or more and the samples go more "
        f"than {100 * NOTED_BEYOND:g} % of the span beyond): levels the choices made on "
        "validation cannot judge.",
    ]


def _levels_unseen(data_seed: int) -> str:
    """The validation part's span of the level and the share of training samples outside it."""
    from canonid.coverage import training_ranges, unvalidated
    from canonid.kernel.dataset import Dataset

    data = Dataset.load(spread_data(data_seed) / "dataset.npz")
    train, val = data.split("train"), data.split("val")
    ((low, high),) = training_ranges(val)["outputs"]
    names = {"input_names": data.input_names, "output_names": data.output_names}
    share = sum(o.share for o in unvalidated(train, val, **names) if o.kind == "output")
    return f"{low:.2f} to {high:.2f} V; {100 * share:.0f} %"


def screen_lines(run: Path) -> str:
    """What canonid's defaults chose on validation: the search's losses and its choice."""
    from canonid.learning.search import Search

    return f"canonid's defaults, on validation only: {Search.read(run).line()}."


def diagnosis(cpu: dict[str, Any]) -> list[str]:
    """The validation-only look at what the defaults lack (the test score is read only for the
    run the validation loss picks, after it picked it)."""
    runs = {FIXED_LABEL: "mlp", **{k: folder for k, (folder, _) in VARIANTS.items()}}
    found = {label: validation(RUNS / folder) for label, folder in runs.items()}
    rows = [
        f"| {label} | {v.best:.4f} | {v.epoch} | {v.train_at_best:.5f} | {v.last} | "
        f"{v.val_last:.4f} | {v.train_last:.5f} | {cpu[runs[label]]:.0f} |"
        for label, v in found.items()
    ]
    chosen = min(found, key=lambda k: found[k].best)
    picked = canonid_score(chosen, RUNS / runs[chosen], DATA, cpu[runs[chosen]])
    return [
        "### What the defaults lack: validation only",
        "",
        "Ours (MLP) at ℓ = 10 and the same with one change (`canonid train DATA --window 10 "
        "--threads 1` plus the change, or `--window 20`). Losses are canonid's validation loss "
        "(100-step rollouts on the validation part) and the training loss (the epoch's "
        "rollouts of up to 50 steps), both normalised by the training output variance; each "
        "run stops 200 epochs after its best validation loss and keeps that epoch's model. "
        "The validation part holds no sample at the sensor's limit (table above): it cannot "
        "judge how a model treats it.",
        "",
        "| run | best validation loss | at epoch | training loss there | last epoch | validation "
        "loss, last | training loss, last | CPU s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        f"Chosen on validation: **{chosen}**; its test RMSE, read once after the choice: "
        f"{picked.rmse:.4f} V (fit {picked.fit:.1f} %).",
    ]


def report(scores: list[Score], regime_rows: list[str], load: str) -> list[str]:
    from canonid.datagen.scenarios import TANKS_OVERFLOW_DESIGN as design
    from canonid.datagen.scenarios import TANKS_OVERFLOW_OFFSET

    by = {s.label: s for s in scores}
    ours = by["canonid defaults (Ours (MLP))"]
    rows = [
        f"| {s.label} | {s.window} | {s.rmse:.4f} | {s.fit:.1f} | {s.rmse_clean:.4f} | "
        f"{s.fit_clean:.1f} | {s.best_val} | {s.cpu_s:.0f} |"
        for s in scores
    ]
    ratios = [
        f"{label}: {by[label].rmse / ours.rmse:.2f}×"
        for label in ("Classic GRU", "ARX (linear)", DEEPSI_LABEL)
    ]
    holds = (
        by["Classic GRU"].rmse >= 1.5 * ours.rmse
        and by["ARX (linear)"].rmse >= 1.5 * ours.rmse
        and by[DEEPSI_LABEL].rmse > ours.rmse
    )
    return [
        f"Data: `canonid generate {' '.join(GENERATE)}` (one training record of 1,024 samples at "
        "Ts = 4 s, validation its last 20 %, one test record of 1,024 samples; a random-phase "
        f"multisine up to {design.band[1]:g} Hz, RMS {design.amplitude:g} V, around "
        f"{TANKS_OVERFLOW_OFFSET:g} V). Samples at the upper tank's rim and at the sensor's 10-V "
        "limit (noise-free), with the number of episodes:",
        "",
        "| part | samples | at the rim (episodes) | at the sensor limit (episodes) | u range [V] |",
        "|---|---:|---:|---:|---|",
        *regime_rows,
        "",
        "Simulation of the test record after n_init = 50 measured samples (samples 50…1023), "
        "scored by `canonid.learning.evaluate` for all; RMSE in V. Every contestant runs with its "
        "defaults and keeps its best model on the validation part; nothing is chosen on test. "
        "CPU: the whole child process (loading, training, validation, saving), one torch thread.",
        "",
        "| model | window | RMSE [V] | fit % | RMSE, noise-free [V] | fit %, noise-free "
        "| best on validation at | CPU s |",
        "|---|---:|---:|---:|---:|---:|---|---:|",
        *rows,
        "",
        f"RMSE of each against canonid's defaults: {'; '.join(ratios)}. Target (canonid's "
        "defaults at least 1.5× below Classic GRU and ARX, and below deepSI's defaults): "
        f"**{'holds' if holds else 'does not hold'}**.",
        "",
        load,
    ]


if __name__ == "__main__":
    raise SystemExit(main())
