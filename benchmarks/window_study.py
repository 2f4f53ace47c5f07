"""The window chosen on validation by the screen (``canonid train`` without ``--window``),
against ℓ = 10, on four systems.

Each step appends one JSON row to ``benchmarks/studies/window_study.jsonl``; ``table`` writes
the section "Window on validation" of ``benchmarks/RESULTS.md``::

    python benchmarks/window_study.py screen masses --fraction 0.1
    python benchmarks/window_study.py full masses --window 40
    python benchmarks/window_study.py score masses --window 40
    python benchmarks/window_study.py table

``screen``: :func:`canonid.learning.screen.screen_windows` over the ladder the data allow
(Silverbox: ℓ ≤ n_init = 50, as ``canonid benchmark`` caps it), the table and the choice.
``full``: the full ``quick`` run at one window (its best validation loss, CPU time; the model is
saved under ``runs/window_study``). ``score``: the test score of a saved model, asked for once
the window has been chosen on validation. Everything trains Ours (MLP) with canonid's defaults,
seed 0, one torch thread, on the CPU.

Systems: ``tank`` (``runs/data/tank-s0``) and ``drone2d`` (``runs/data/drone2d-small``), generated
when missing (``benchmarks/_data.py``) and scored by 100-step test rollouts against ``y_clean``;
``silverbox`` (``bench_silverbox.train_val``; multisine-test simulation RMSE after n_init = 50,
mV); ``masses`` (``canonid generate masses-id --n-train 10 --n-val 3 --n-test 3 --seed 1`` in
``runs/data/masses-id``; the lowest test fit % over the outputs, simulation after
max(ℓ, 50) samples). The ℓ = 10 rows are the measured ones of the same recipe:
``benchmarks/studies/defaults_study.jsonl`` (column "feedthrough auto (now)", seed 0) and
RESULTS.md "Chain of masses".
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _data import DATA, ensure_dataset  # noqa: E402
from _results import append_row, read_rows, write_section  # noqa: E402

from canonid.learning.screen import (  # noqa: E402
    SCREEN_FRACTION,
    SCREEN_TOLERANCE,
    SCREEN_WINDOWS,
    choose_window,
)

ROWS = ROOT / "benchmarks" / "studies" / "window_study.jsonl"
DEFAULTS_ROWS = ROOT / "benchmarks" / "studies" / "defaults_study.jsonl"
MODELS = ROOT / "runs" / "window_study"
SECTION = "Window on validation"
SYSTEMS = ("tank", "drone2d", "silverbox", "masses")
MASSES = ["masses-id", "--n-train", "10", "--n-val", "3", "--n-test", "3", "--seed", "1"]
#: the chain of masses at ℓ = 10 (RESULTS.md "Chain of masses", 2026-11-27; same recipe)
MASSES_L10 = {"best_val": 0.000207, "cpu_s": 408.0, "score": 97.9}
SCORE_NAMES = {
    "tank": "test 100-step MSE vs y_clean",
    "drone2d": "test 100-step MSE vs y_clean",
    "silverbox": "multisine test RMSE [mV]",
    "masses": "lowest test fit % over a1, a2, a3",
}


def splits(system: str) -> tuple[list[Any], list[Any], Any]:
    """Training and validation records of ``system``, and what ``score`` needs of its test."""
    from canonid.kernel.dataset import Dataset

    if system == "silverbox":
        import bench_silverbox as sb

        data = sb.load(sb.DEFAULT_CSV)
        train, val = sb.train_val(data)
        return [train], [val], data[sb.MULTISINE][sb.N_TRAIN_VAL :]
    if system == "masses":
        folder = DATA / "masses-id"
        if not (folder / "dataset.npz").is_file():
            cmd = [sys.executable, "-m", "canonid", "generate", *MASSES, "--no-progress"]
            subprocess.run([*cmd, "--out", str(folder)], check=True, cwd=ROOT)
    else:
        folder = ensure_dataset({"tank": "tank-s0", "drone2d": "drone2d-small"}[system])
    ds = Dataset.load(folder / "dataset.npz")
    return list(ds.split("train")), list(ds.split("val")), ds.split("test")


def options(seed: int) -> Any:
    from canonid.profiles import stage_train_options

    return stage_train_options("quick", {"seed": seed, "device": "cpu", "checkpoint_every": 10**6})


def candidates(system: str, train: list[Any], val: list[Any], opts: Any) -> list[int]:
    from canonid.learning.screen import SCREEN_WINDOWS, fitting_windows

    windows = fitting_windows(train, val, SCREEN_WINDOWS, opts)
    return [w for w in windows if w <= 50] if system == "silverbox" else windows


def base_row(kind: str, system: str, seed: int) -> dict[str, Any]:
    return {"kind": kind, "system": system, "seed": seed, "threads": torch.get_num_threads()}


def screen(system: str, seed: int, fraction: float) -> None:
    from canonid.learning.screen import screen_windows

    train, val, _ = splits(system)
    opts = options(seed)
    windows = candidates(system, train, val, opts)
    start = time.process_time()
    result = screen_windows(train, val, windows=windows, options=opts, fraction=fraction)
    row = base_row("screen", system, seed) | {
        "fraction": fraction,
        "epochs": result.epochs,
        "chosen": result.chosen,
        "candidates": [c.__dict__ for c in result.candidates],
        "cpu_s": time.process_time() - start,
        "load": os.getloadavg()[0],
    }
    append_row(ROWS, row)


def full(system: str, seed: int, window: int) -> None:
    from canonid.learning import fit

    train, val, _ = splits(system)
    folder = MODELS / f"{system}-s{seed}-l{window}"
    start = time.process_time()
    result = fit(train, val, model="mlp", window=window, options=options(seed), run_dir=folder)
    row = base_row("full", system, seed) | {
        "window": window,
        "best_val": result.best_val_loss,
        "best_epoch": result.best_epoch,
        "epochs": result.epochs_run,
        "cpu_s": time.process_time() - start,
        "load": os.getloadavg()[0],
        "model": str(folder.relative_to(ROOT)),
    }
    append_row(ROWS, row)


def score(system: str, seed: int, window: int) -> None:
    import numpy as np

    from canonid.learning import Model, evaluate

    _, _, test = splits(system)
    model = Model.load(MODELS / f"{system}-s{seed}-l{window}")
    if system == "silverbox":
        import bench_silverbox as sb

        u, y = test[:, 0:1], test[:, 1:2]
        sim = model.simulate(u[sb.N_INIT - window :], y[sb.N_INIT - window : sb.N_INIT])
        value = 1000 * float(np.sqrt(np.mean((sim - y[sb.N_INIT :]) ** 2)))
    elif system == "masses":
        value = min(evaluate(model, test, horizon=100).measured.fit_percent_per_output)
    else:
        value = evaluate(model, test, horizon=100).clean.rollout_mse
    append_row(
        ROWS,
        base_row("test", system, seed)
        | {"window": window, "score": value, "score_name": SCORE_NAMES[system]},
    )


def reference(system: str, seed: int) -> dict[str, Any] | None:
    """The measured ℓ = 10 run of the same recipe (see the module docstring)."""
    if system == "masses":
        return {**MASSES_L10, "source": 'RESULTS.md "Chain of masses"'} if seed == 0 else None
    for r in read_rows(DEFAULTS_ROWS):
        if (r["system"], r["seed"], r["label"]) == (system, seed, "feedthrough auto (now)"):
            return {**r, "source": "defaults_study.jsonl"}
    return None


def _g(x: float | None) -> str:
    return "-" if x is None else (f"{x:.4g}" if abs(x) >= 0.01 else f"{x:.3e}")


def _choice(screen_row: dict, tolerance: float = SCREEN_TOLERANCE, ladder: bool = True) -> int:
    """The window a screen's row gives under ``tolerance`` (its recorded losses), among
    canonid's ladder (:data:`SCREEN_WINDOWS`) or, without ``ladder``, every window screened."""
    losses = {
        c["window"]: c["best_val_loss"]
        for c in screen_row["candidates"]
        if c["best_val_loss"] is not None and (not ladder or c["window"] in SCREEN_WINDOWS)
    }
    return choose_window(losses, tolerance)


def _screens(rows: list[dict], system: str) -> list[dict]:
    """The screens of ``system`` at canonid's fraction, in the order they ran."""
    return [
        r
        for r in rows
        if r["kind"] == "screen" and r["system"] == system and r["fraction"] == SCREEN_FRACTION
    ]


def _screen_cpu(screen_row: dict) -> float:
    """CPU seconds of the screen's candidates on canonid's ladder."""
    return sum(c["cpu_seconds"] for c in screen_row["candidates"] if c["window"] in SCREEN_WINDOWS)


def table() -> str:
    rows = read_rows(ROWS)
    lines = [
        "Ours (MLP), canonid's defaults (`quick` profile, feedthrough decided on validation), "
        "seed 0, one torch thread, CPU. **Screen**: each candidate window trained for a fraction "
        "of the profile's 600 epochs (the schedule compressed: curriculum and patience scaled "
        "alike); the rule keeps the shortest window of the ladder "
        f"{', '.join(map(str, SCREEN_WINDOWS))} whose best validation loss (normalised) is "
        f"within {SCREEN_TOLERANCE:g}× of the lowest (the column 'lowest' takes the lowest of "
        "every window screened). "
        "**Full**: the full `quick` run at a window. The test score is read only for the "
        "window chosen on validation, after the choice.",
        "",
        "### Screens",
        "",
        "| system | fraction (epochs) | ℓ: best validation loss of the screen | lowest | "
        f"the rule (×{SCREEN_TOLERANCE:g}) | CPU s |",
        "|---|---|---|---:|---:|---:|",
    ]
    for r in (r for r in rows if r["kind"] == "screen"):
        cells = ", ".join(f"{c['window']}: {_g(c['best_val_loss'])}" for c in r["candidates"])
        lines.append(
            f"| {r['system']} | {r['fraction']} ({r['epochs']}) | {cells} | "
            f"{_choice(r, 1.0, ladder=False)} | **{_choice(r)}** | {r['cpu_s']:.0f} |"
        )
    lines += [
        "",
        "### Full runs: the chosen window against ℓ = 10",
        "",
        "| system | ℓ | best validation loss (normalised) | CPU s | source |",
        "|---|---:|---:|---:|---|",
    ]
    for system in SYSTEMS:
        ref = reference(system, 0)
        if ref is not None:
            lines.append(
                f"| {system} | 10 | {_g(ref['best_val'])} | {ref['cpu_s']:.0f} | "
                f"{ref['source']} (same recipe, not re-run) |"
            )
        for r in (r for r in rows if r["kind"] == "full" and r["system"] == system):
            lines.append(
                f"| {system} | {r['window']} | {_g(r['best_val'])} | {r['cpu_s']:.0f} | "
                "this study |"
            )
    lines += [
        "",
        "### The rule judged by the full runs (validation only)",
        "",
        "| system | the screen's lowest: ℓ, full-run validation loss | the rule: ℓ, full-run "
        "validation loss | ℓ = 10 | the rule / ℓ = 10 |",
        "|---|---|---|---:|---:|",
    ]
    for system in SYSTEMS:
        screens = _screens(rows, system)
        ref = reference(system, 0)
        if not screens or ref is None:
            continue
        full = {
            r["window"]: r["best_val"]
            for r in rows
            if r["kind"] == "full" and r["system"] == system
        }
        full.setdefault(10, ref["best_val"])
        low, rule = _choice(screens[-1], 1.0, ladder=False), _choice(screens[-1])
        ratio = f"{full[rule] / full[10]:.2f}" if rule in full else "-"
        lines.append(
            f"| {system} | {low}: {_g(full.get(low))} | {rule}: {_g(full.get(rule))} | "
            f"{_g(full[10])} | {ratio} |"
        )
    lines += [
        "",
        "Cost of the default (the screen at canonid's fraction, then the full run):",
    ]
    for system in SYSTEMS:
        screens = _screens(rows, system)
        fulls = [
            r
            for r in rows
            if screens
            and r["kind"] == "full"
            and r["system"] == system
            and r["window"] == _choice(screens[-1])
        ]
        ref = reference(system, 0) if screens and _choice(screens[-1]) == 10 else None
        fulls = fulls or ([{**ref, "window": 10}] if ref is not None else [])
        if fulls:
            cpu = _screen_cpu(screens[-1]) + fulls[-1]["cpu_s"]
            lines.append(
                f"{system}: ℓ = {fulls[-1]['window']}, {_screen_cpu(screens[-1]):.0f} + "
                f"{fulls[-1]['cpu_s']:.0f} = {cpu:.0f} CPU s ({cpu / 60:.1f} min)."
            )
    tests = [r for r in rows if r["kind"] == "test"]
    if tests:
        lines += [
            "",
            "### Test, read once after the choice",
            "",
            "| system | ℓ | score | ℓ = 10 (same score, earlier run) |",
            "|---|---:|---|---|",
        ]
        for r in tests:
            ref = reference(r["system"], r["seed"])
            lines.append(
                f"| {r['system']} | {r['window']} | {_g(r['score'])} ({r['score_name']}) | "
                f"{'-' if ref is None else _g(ref['score'])} |"
            )
    loads = [r["load"] for r in rows if r.get("load") is not None]
    if loads:
        lines.append(
            f"\nLoad average (1 min) at the end of each step: {min(loads):.1f}–{max(loads):.1f} "
            f"on {os.cpu_count()} cores (other jobs shared the machine; CPU times are this "
            "process's)."
        )
    notes = ROWS.with_name("window_study_notes.md")
    if notes.is_file():
        lines += ["", notes.read_text(encoding="utf-8").strip()]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("step", choices=["screen", "full", "score", "table"])
    parser.add_argument("system", nargs="?", choices=SYSTEMS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fraction", type=float, default=0.1)
    parser.add_argument("--window", type=int)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if args.step == "table":
        write_section(SECTION, table(), command="python benchmarks/window_study.py table")
        return 0
    if args.system is None:
        parser.error(f"{args.step} needs a SYSTEM")
    if args.step == "screen":
        screen(args.system, args.seed, args.fraction)
    elif args.window is None:
        parser.error(f"{args.step} needs --window")
    elif args.step == "full":
        full(args.system, args.seed, args.window)
    else:
        score(args.system, args.seed, args.window)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
