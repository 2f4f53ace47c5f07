"""Training rollout length H on validation: the defaults at H = 50 against H = 10, full runs.

On the planar drone's informative data the defaults (open-loop rollouts of up to 50 samples)
learn a model that moves px the wrong way after a rotor difference, while rollouts of 10 samples
get it right (benchmarks/RESULTS.md, "NMPC on a learned model: informative drone data"). This
study asks whether validation would choose H = 10 there, and what it would choose elsewhere:
each system is trained with ``canonid train`` as a user types it, once with the profile's H = 50
and once with ``--train-horizon 10``, and the best validation loss of each run is compared (the
validation rollouts have the profile's 100 samples in both, so the losses compare). ``short``
adds the same comparison after the window screen's share of the epochs (what a cheap test per
run would see). The runs score their test parts as ``canonid train`` does; the study reads and
records only validation.

Usage (from the repository root; one job per process, one torch thread each)::

    python benchmarks/horizon_study.py prepare [--dir DIR]  # the datasets under runs/data
    python benchmarks/horizon_study.py run SYSTEM H        # one full run → runs/horizon-study
    python benchmarks/horizon_study.py ramp SYSTEM C       # H = 50 reached over C epochs
    python benchmarks/horizon_study.py short SYSTEM H,...  # short runs (screen share) → JSON line
    python benchmarks/horizon_study.py record [--short FILE] [--loop FILE ...]

``ramp`` trains the defaults (plain network, the feedthrough test's choice) with the curriculum
stretched from the profile's 50 epochs to C, by the library (no command has that option).
``--loop FILE`` adds, for the informative drone data, what each candidate's validation says
beside what NMPC on it does (``benchmarks/learned_mpc.py --json FILE``): the validation loss of
its training, its validation MSE over the NMPC's horizon (``canonid evaluate RUN --split val
--eval-horizon 20 --stride 5``), the learned / true tracking RMSE and the px response.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this checkout's packages
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import write_section  # noqa: E402

from canonid.kernel.io import atomic_write_json  # noqa: E402

OUT = ROOT / "runs" / "horizon-study"
SECTION = "Training horizon on validation"
HORIZONS = (50, 10)
#: system → (dataset under runs/data, the window argument: the defaults' choice or the screen)
SYSTEMS = {
    "drone2d-id": ("drone2d-id-small", "10"),
    "drone2d": ("drone2d-small", "10"),
    "tank": ("tank-s0", "10"),
    "silverbox": ("silverbox-tv", "auto"),
    "masses": ("masses-id", "40"),
}


def prepare(directory: Path) -> None:
    """The study's datasets: the generated ones as the other benchmarks make them, and
    Silverbox's training record split as ``canonid benchmark`` splits it (its last 20 %
    validates), without the official test parts."""
    from _data import ensure_dataset

    from canonid.datagen.benchmarks import load_benchmark
    from canonid.datagen.loaders import split_train_val
    from canonid.kernel.dataset import Dataset

    for name in ("tank-s0", "drone2d-small", "drone2d-id-small"):
        ensure_dataset(name)
    masses = ROOT / "runs" / "data" / "masses-id"
    if not (masses / "dataset.npz").is_file():
        from bench_masses import GENERATE  # the chain of masses as its benchmark makes it

        subprocess.run(
            [sys.executable, "-m", "canonid", "generate", *GENERATE, "--no-progress",
             "--out", str(masses)], check=True, cwd=ROOT,
        )  # fmt: skip
    full = split_train_val(
        load_benchmark("silverbox", directory), val_fraction=0.2, record_tails=True
    )
    kept = Dataset(
        splits={part: full.split(part) for part in ("train", "val")},
        dt=full.dt,
        input_names=full.input_names,
        output_names=full.output_names,
        metadata={"study": "Silverbox's training record as canonid benchmark splits it"},
    )
    kept.save(ROOT / "runs" / "data" / "silverbox-tv" / "dataset.npz")


def command(system: str, horizon: int) -> list[str]:
    data, window = SYSTEMS[system]
    return [
        "canonid", "train", f"runs/data/{data}", "--window", window,
        "--train-horizon", str(horizon), "--threads", "1", "--device", "cpu", "--no-progress",
        "--out", str((OUT / f"{system}-h{horizon}").relative_to(ROOT)),
    ]  # fmt: skip


def run(system: str, horizon: int) -> None:
    """One full run; its CPU seconds (the child's user + system time) beside its folder."""
    OUT.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = command(system, horizon)
    subprocess.run([sys.executable, "-m", "canonid", *cmd[1:]], check=True, cwd=ROOT, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    atomic_write_json(OUT / f"{system}-h{horizon}.json", {"cpu_seconds": cpu})


def _defaults_net(train, val, window: int) -> dict:
    """The defaults' network options for a plain network, the feedthrough decided as they do."""
    from canonid.learning.data import Normalisation
    from canonid.learning.linear import feedthrough_test
    from canonid.learning.presets import net_options

    options = net_options("mlp", {"cubic": 0})
    options["feedthrough"] = feedthrough_test(
        train, val, Normalisation.fit(train), window=window
    ).feedthrough
    return options


def ramp(system: str, curriculum: int) -> None:
    """A full run whose training rollouts reach H = 50 over ``curriculum`` epochs, written to
    ``runs/horizon-study/SYSTEM-ramp{curriculum}`` with its CPU seconds."""
    import dataclasses

    import torch

    from canonid.kernel.dataset import Dataset
    from canonid.learning.training import fit
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    data_name, window_arg = SYSTEMS[system]
    window = 10 if window_arg == "auto" else int(window_arg)
    data = Dataset.load(ROOT / "runs" / "data" / data_name / "dataset.npz")
    train, val = data.split("train"), data.split("val")
    options = dataclasses.replace(
        train_options("quick", device="cpu"), curriculum_epochs=curriculum
    )
    out = OUT / f"{system}-ramp{curriculum}"
    if out.exists():  # a recorded run is not trained over
        sys.exit(f"horizon_study.py ramp: {out} exists; move it away to train it again")
    cpu0 = time.process_time()
    fit(train, val, model="mlp", window=window, options=options,
        net_options=_defaults_net(train, val, window), run_dir=out)  # fmt: skip
    atomic_write_json(
        OUT / f"{system}-ramp{curriculum}.json", {"cpu_seconds": time.process_time() - cpu0}
    )


def short(system: str, horizons: list[int]) -> None:
    """The comparison after the window screen's share of the epochs (its compressed schedule),
    at the window of ``SYSTEMS`` (10 where the screen chooses); one JSON line per H."""
    import dataclasses

    import torch

    from canonid.kernel.dataset import Dataset
    from canonid.learning.training import fit
    from canonid.learning.window_screen import SCREEN_FRACTION, screen_options
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    data_name, window_arg = SYSTEMS[system]
    window = 10 if window_arg == "auto" else int(window_arg)
    data = Dataset.load(ROOT / "runs" / "data" / data_name / "dataset.npz")
    train, val = data.split("train"), data.split("val")
    options = _defaults_net(train, val, window)
    base = train_options("quick", device="cpu")
    for h in horizons:
        opts = screen_options(dataclasses.replace(base, horizon=h), SCREEN_FRACTION)
        cpu0 = time.process_time()
        result = fit(train, val, model="mlp", window=window, options=opts, net_options=options)
        row = {
            "system": system,
            "horizon": h,
            "epochs": opts.epochs,
            "best_val_loss": result.best_val_loss,
            "best_epoch": result.best_epoch,
            "cpu_seconds": round(time.process_time() - cpu0, 1),
        }
        print(json.dumps(row), flush=True)


def full_row(system: str, horizon: int | str) -> dict | None:
    """The recorded run ``SYSTEM-hH`` (``horizon`` an int) or ``SYSTEM-NAME`` (a str)."""
    name = f"{system}-h{horizon}" if isinstance(horizon, int) else f"{system}-{horizon}"
    folder = OUT / name
    if not (folder / "config.json").is_file():
        return None
    info = json.loads((folder / "config.json").read_text())["info"]
    cpu_file = OUT / f"{name}.json"
    cpu = json.loads(cpu_file.read_text())["cpu_seconds"] if cpu_file.is_file() else None
    return {
        "best_val_loss": info["training"]["best_val_loss"],
        "best_epoch": info["training"]["best_epoch"],
        "window": info["training"].get("window") or _window(folder),
        "cubic": (info.get("cubic_test") or {}).get("units"),
        "cpu_seconds": cpu,
    }


def _window(folder: Path) -> int | None:
    run = folder / "run.json"
    return json.loads(run.read_text())["window"] if run.is_file() else None


def _val20(folder: Path) -> float | None:
    """The validation MSE over 20-sample rollouts that ``canonid evaluate`` wrote, if any."""
    found = sorted(folder.glob("evaluations/*-val-h20-stride5/metrics.json"))
    return json.loads(found[0].read_text())["rollout_mse"] if found else None


def _training(info: dict, recipe: dict) -> str:
    """The candidate in words: the model, and for a network its rollouts and their ramp."""
    if recipe.get("model") == "arx":
        return "ARX (least squares)"
    opts = info.get("training", {}).get("options", {})
    linear = recipe.get("net_options", {}).get("linear")
    start = ", linear path from ARX" if linear == "arx" else ""
    return (
        f"Ours (MLP), H = {opts.get('horizon')} reached over {opts.get('curriculum_epochs')} "
        f"epochs{start}"
    )


def loop_rows(loops: list[Path]) -> list[str]:
    """The informative drone data's candidates: validation beside the NMPC loop."""
    lines = [
        "",
        "On the informative drone data (`drone2d-id`), what validation says about each candidate "
        "beside what NMPC on it does (`benchmarks/learned_mpc.py`, the 10 test references of "
        'the section "NMPC on a learned model: informative drone data"): the best validation '
        "loss of its training (100-sample rollouts, normalised), its validation MSE over the "
        "NMPC's horizon (20-sample rollouts, physical units, `canonid evaluate RUN --split val "
        "--eval-horizon 20 --stride 5`), the learned / true tracking RMSE and the learned / true "
        "change of px 20 samples after a rotor-difference step from rest (negative: the wrong "
        "way).",
        "",
        "| candidate | run | best validation loss (100 samples) | validation MSE, 20 samples | "
        "learned / true tracking RMSE | learned loops that left X | px change, learned / true |",
        "|---|---|---:|---:|---:|---|---:|",
    ]
    for path in loops:
        for res in json.loads(path.read_text()).values():
            if res.get("data") != "drone2d-id":
                continue
            folder = ROOT / res["run"]
            info = json.loads((folder / "config.json").read_text())["info"]
            recipe = json.loads((folder / "run.json").read_text())
            best = info.get("training", {}).get("best_val_loss")
            ratio, left, loops_run, px = loop_figures(res)
            val20 = _val20(folder)
            lines.append(
                f"| {_training(info, recipe)} | `{res['run']}` | "
                f"{'-' if best is None else f'{best:.4g}'} | "
                f"{'-' if val20 is None else f'{val20:.3g}'} | {ratio:.2f} | {left} of "
                f"{loops_run} | {px:.3g} |"
            )
    return lines


def loop_figures(res: dict) -> tuple[float, int, int, float]:
    """What one drone entry of ``learned_mpc.py --json`` measured: the learned / true tracking
    RMSE, the learned loops that left X, the loops run, and the learned / true px change after
    the first judged step (the rotor difference) from rest."""
    rows = res["rows"]
    ratio = rows["learned model"]["rmse"] / rows["true model"]["rmse"]
    left = len(rows["learned model"]["left_X"])
    px = next(iter(res["responses"].values()))["rest"]["ratios"][0]
    return ratio, left, len(rows["learned model"]["rmses"]), px


def record(short_files: list[Path], loops: list[Path], write: bool) -> int:
    lines = [
        "Full runs of `canonid train` as a user types it (the quick profile's 600 epochs, one "
        "torch thread, two or more runs at a time on the 2-core machine), once with the "
        "profile's training rollouts of H = 50 samples and once with `--train-horizon 10`; "
        "command per row: `canonid train runs/data/DATA --window W --train-horizon H --threads 1 "
        "--device cpu --no-progress --out runs/horizon-study/SYSTEM-hH` (`python "
        "benchmarks/horizon_study.py run SYSTEM H`). Best validation loss (normalised, on "
        "100-sample rollouts of the validation part in both); the runs score their test parts as "
        "`canonid train` does, the study reads only validation. CPU: "
        "the whole command (for Silverbox the window screen and the cubic test included).",
        "",
        "| system | data | ℓ | best validation loss, H = 50 (epoch) | H = 10 (epoch) | "
        "H = 10 / H = 50 | CPU s, H = 50 | CPU s, H = 10 |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    found = 0
    for system, (data, _) in SYSTEMS.items():
        rows = {h: full_row(system, h) for h in HORIZONS}
        if any(r is None for r in rows.values()):
            continue
        found += 1
        r50, r10 = rows[50], rows[10]
        assert r50 is not None and r10 is not None

        def cpu(r: dict) -> str:
            return "-" if r["cpu_seconds"] is None else f"{r['cpu_seconds']:.0f}"

        lines.append(
            f"| {system} | `{data}` | {r10['window']} | {r50['best_val_loss']:.4g} "
            f"({r50['best_epoch']}) | {r10['best_val_loss']:.4g} ({r10['best_epoch']}) | "
            f"{r10['best_val_loss'] / r50['best_val_loss']:.2f} | {cpu(r50)} | {cpu(r10)} |"
        )
    linked = sorted(
        f"`{p.relative_to(ROOT)}` → `{p.resolve().relative_to(ROOT)}`"
        for p in OUT.iterdir()
        if p.is_symlink() and p.is_dir()
    )
    if linked:
        lines += [
            "",
            "Run folders trained under another `--out` (the same command otherwise) and linked "
            "here: " + ", ".join(linked) + ".",
        ]
    ramps = [
        (system, name.removeprefix(f"{system}-"))
        for system in SYSTEMS
        for name in sorted(p.name for p in OUT.glob(f"{system}-ramp*") if p.is_dir())
    ]
    if ramps:
        lines += [
            "",
            "The defaults with the curriculum stretched: the training rollouts grow to H = 50 over "
            "C epochs instead of the profile's 50 (`python benchmarks/horizon_study.py ramp "
            "SYSTEM C`; plain network, the feedthrough test's choice):",
            "",
            "| system | C | best validation loss (epoch) | / H = 50 | CPU s |",
            "|---|---:|---:|---:|---:|",
        ]
        for system, name in ramps:
            r, r50 = full_row(system, name), full_row(system, 50)
            if r is None or r50 is None:
                continue
            cpu = "-" if r["cpu_seconds"] is None else f"{r['cpu_seconds']:.0f}"
            lines.append(
                f"| {system} | {name.removeprefix('ramp')} | {r['best_val_loss']:.4g} "
                f"({r['best_epoch']}) | {r['best_val_loss'] / r50['best_val_loss']:.2f} | {cpu} |"
            )
    short_rows = [json.loads(line) for f in short_files for line in f.read_text().splitlines()]
    if short_rows:
        lines += [
            "",
            "The same comparison after the window screen's share of the epochs "
            "(`python benchmarks/horizon_study.py short SYSTEM 10,50`: 60 epochs, the "
            "curriculum and patience scaled alike, ℓ = 10, plain network):",
            "",
            "| system | H | epochs | best validation loss (epoch) | CPU s |",
            "|---|---:|---:|---:|---:|",
        ]
        for r in short_rows:
            lines.append(
                f"| {r['system']} | {r['horizon']} | {r['epochs']} | "
                f"{r['best_val_loss']:.4g} ({r['best_epoch']}) | {r['cpu_seconds']:.0f} |"
            )
    lines += loop_rows(loops) if loops else []
    if not found:
        print("no pair of full runs recorded under", OUT, file=sys.stderr)
        return 1
    text = "\n".join(lines)
    print(text)
    if write:
        write_section(SECTION, text)
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("--dir", type=Path, default=ROOT.parent / "shared" / "data" / "silverbox")
    p = sub.add_parser("run")
    p.add_argument("system", choices=SYSTEMS)
    p.add_argument("horizon", type=int)
    p = sub.add_parser("ramp")
    p.add_argument("system", choices=SYSTEMS)
    p.add_argument("curriculum", type=int)
    p = sub.add_parser("short")
    p.add_argument("system", choices=SYSTEMS)
    p.add_argument("horizons")
    p = sub.add_parser("record")
    p.add_argument("--short", type=Path, action="append", default=[])
    p.add_argument("--loop", type=Path, action="append", default=[])
    p.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    if args.cmd == "prepare":
        prepare(args.dir)
        return 0
    if args.cmd == "run":
        run(args.system, args.horizon)
        return 0
    if args.cmd == "short":
        short(args.system, [int(h) for h in args.horizons.split(",")])
        return 0
    if args.cmd == "ramp":
        ramp(args.system, args.curriculum)
        return 0
    return record(args.short, args.loop, not args.no_write)


if __name__ == "__main__":
    sys.exit(main())
