"""How the ``quick`` ``train`` profile was chosen: Ours (MLP) on the tank, ℓ = 10, variants of it.

    python benchmarks/studies/quick_profile/train_variants.py runs/data/tank [--only KEY ...] \
        [--seeds 0 1]
    python benchmarks/studies/quick_profile/train_variants.py runs/data/tank --only KEY ... \
        --test   # afterwards

Each variant is the ``quick`` ``train`` stage as it was before the first study (``BASE``: 600
epochs, batch 16, 4 windows per trajectory, rollout length 50) with a few options changed, and
the MLP's constructor options (``VARIANTS``); the second study's variants (the ``h100-…`` keys
after ``clip``) start from the stage the first one chose (``h100-e600``) and change one training
option or the MLP's activation. Every model is ``--model mlp --window 10 --residual
--no-feedthrough``, trained on one torch thread on the CPU. The script prints one Markdown row
per variant and seed: the **validation** split's 100-step rollout MSE (the paper metric, every
start time, physical units) against the noise-free ``y_clean`` and against the measured ``y``,
the best epoch and the CPU time of the training (user + system of this process). Variants are
compared on validation only; ``--test`` scores the models already trained (saved under
``--out``) on the test split, for the variants chosen. Each row is also appended to
``OUT/results.jsonl``. Not a speed benchmark (``run_all.py`` skips it): a variant is a few CPU
minutes.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))

WINDOW = 10
NET = {"residual": True, "feedthrough": False}

#: the ``quick`` ``train`` stage before this study (explicit, so the table does not move when the
#: profile does): every variant starts from it
BASE: dict[str, Any] = {
    "epochs": 600,
    "batch_size": 16,
    "lr": 3e-3,
    "lr_final": 1e-5,
    "horizon": 50,
    "curriculum_epochs": 50,
    "windows_per_epoch": 4 * 60,
    "alpha_first": 10.0,
}

#: key → (description, overrides of ``BASE``, MLP constructor options)
VARIANTS: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {
    "quick": ("BASE: 600 epochs, batch 16, 4 windows/traj, H 50, 3 × 256", {}, {}),
    "w3x64-b64": (
        "3 × 64, batch 64, 16 windows/traj (4× the data per epoch, same steps)",
        {"batch_size": 64, "windows_per_epoch": 16 * 60},
        {"hidden": [64, 64, 64]},
    ),
    "w3x64-b64-h100": (
        "3 × 64, batch 64, 16 windows/traj, H 100 (curriculum 100 epochs)",
        {"batch_size": 64, "windows_per_epoch": 16 * 60, "horizon": 100, "curriculum_epochs": 100},
        {"hidden": [64, 64, 64]},
    ),
    "h100-e300": ("H 100 (curriculum 50), 300 epochs", {"horizon": 100, "epochs": 300}, {}),
    "h100-e450": ("H 100 (curriculum 50), 450 epochs", {"horizon": 100, "epochs": 450}, {}),
    "h100-e600": (
        "H 100 (curriculum 50), 600 epochs: the quick profile now",
        {"horizon": 100, "epochs": 600},
        {},
    ),
    "h100-e300-alpha1": (
        "H 100 (curriculum 50), 300 epochs, α = 1",
        {"horizon": 100, "epochs": 300, "alpha_first": 1.0},
        {},
    ),
    "clip": ("gradient clipping at norm 1", {"grad_clip": 1.0}, {}),
    # second study, from the quick profile of the first (H 100, 600 epochs): regularisation
    "h100-wd1e-4": (
        "h100-e600 with Adam weight decay 1e-4",
        {"horizon": 100, "epochs": 600, "weight_decay": 1e-4},
        {},
    ),
    "h100-w8-b32": (
        "h100-e600 with 8 windows/traj and batch 32 (2× the data per epoch, same steps)",
        {"horizon": 100, "epochs": 600, "windows_per_epoch": 8 * 60, "batch_size": 32},
        {},
    ),
    "h100-ema": (
        "h100-e600, validating and keeping the weight average (ema_decay 0.999)",
        {"horizon": 100, "epochs": 600, "ema_decay": 0.999},
        {},
    ),
    "h100-silu": (
        "h100-e600 with SiLU activations",
        {"horizon": 100, "epochs": 600},
        {"activation": "silu"},
    ),
    "h100-silu-lr1e-3": (
        "h100-silu with Adam at 1e-3",
        {"horizon": 100, "epochs": 600, "lr": 1e-3},
        {"activation": "silu"},
    ),
    "h100-silu-lr5e-3": (
        "h100-silu with Adam at 5e-3",
        {"horizon": 100, "epochs": 600, "lr": 5e-3},
        {"activation": "silu"},
    ),
    "h100-silu-e900": (
        "h100-silu over 900 epochs (cosine over the 900)",
        {"horizon": 100, "epochs": 900},
        {"activation": "silu"},
    ),
    "h100-silu-3x512": (
        "h100-silu with a 3 × 512 MLP",
        {"horizon": 100, "epochs": 600},
        {"activation": "silu", "hidden": [512, 512, 512]},
    ),
    "h100-tanh": (
        "h100-e600 with tanh activations",
        {"horizon": 100, "epochs": 600},
        {"activation": "tanh"},
    ),
}


def train_variant(train: Any, val: Any, key: str, *, seed: int, run: Path) -> Any:
    """Train variant ``key`` with ``seed`` on the CPU; the model is saved in ``run``."""
    from canonid.learning import fit
    from canonid.profiles import train_options

    _, overrides, net_opts = VARIANTS[key]
    opts = train_options("quick", **{**BASE, **overrides}, seed=seed, device="cpu")
    net = {**NET, **net_opts}
    return fit(train, val, model="mlp", window=WINDOW, options=opts, net_options=net, run_dir=run)


def main() -> int:
    import torch

    from canonid.learning import Model, evaluate
    from canonid.runfolder import load

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="the tank dataset (canonid generate tank)")
    parser.add_argument("--only", nargs="*", metavar="KEY", help=f"variants: {list(VARIANTS)}")
    parser.add_argument("--seeds", nargs="*", type=int, default=[0], help="seeds (default 0)")
    parser.add_argument(
        "--out",
        type=Path,
        default=ROOT / "runs" / "train-variants",
        help="where the models are kept (default runs/train-variants)",
    )
    parser.add_argument(
        "--test", action="store_true", help="score the saved models on the test split"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    keys = list(VARIANTS) if args.only is None else args.only
    unknown = sorted(set(keys) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variant(s) {unknown}; known: {sorted(VARIANTS)}")

    dataset = load(args.data, {})
    train, val = list(dataset.split("train")), list(dataset.split("val"))
    split = "test" if args.test else "val"
    scored = list(dataset.split(split))
    print(f"| variant | seed | {split} MSE vs y_clean | vs y | best epoch | CPU s |")
    print("|---|---:|---:|---:|---:|---:|")
    for key in keys:
        description = VARIANTS[key][0]
        for seed in args.seeds:
            run_dir = args.out / f"{key}-s{seed}"
            cpu = None
            if args.test:
                model = Model.load(run_dir)
                best = model.info["training"]["best_epoch"]
            else:
                t0 = time.process_time()
                res = train_variant(train, val, key, seed=seed, run=run_dir)
                cpu = time.process_time() - t0
                model, best = res.model, res.best_epoch
            ev = evaluate(model, scored, horizon=100)
            assert ev.clean is not None
            row = {
                "variant": key,
                "description": description,
                "seed": seed,
                "split": split,
                "clean_rollout_mse": ev.clean.rollout_mse,
                "rollout_mse": ev.measured.rollout_mse,
                "best_epoch": best,
                "cpu_seconds": cpu,
            }
            with open(args.out / "results.jsonl", "a", encoding="utf-8") as fh:
                fh.write(json.dumps(row) + "\n")
            print(
                f"| {key}: {description} | {seed} | {ev.clean.rollout_mse:.3e} | "
                f"{ev.measured.rollout_mse:.3e} | {best} | "
                f"{'-' if cpu is None else f'{cpu:.0f}'} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
