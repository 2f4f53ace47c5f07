"""Settings of Ours (MLP) on the planar drone, compared on the validation split.

    python benchmarks/studies/drone_settings/drone_variants.py [--budget 300] [--only KEY ...] \
        [--drone DIR]

Each variant is the ``quick`` ``train`` profile (ℓ = 10) with a few training or network options
changed (``VARIANTS``), trained as ``bench_deepsi.py`` trains Ours (MLP): seed 0, one torch
thread, a budget of training CPU time of its own thread with the validation passes excluded,
stopping at the first validation past the budget or when its epochs are done. The number
compared is the one both contestants of ``bench_deepsi.py`` are kept on, the normalised MSE of
100-step rollouts from every 5th start of the validation flights; the test split is not read.
Prints, and writes to the section "Ours (MLP) on the planar drone: settings" of
the records (benchmarks/records/) (``--add``: beside the rows of an earlier run with the same
data and
budget), one row per variant: the best validation MSE after a third, two thirds
and all of the budget, how it stopped and its training CPU time. Not a speed benchmark
(``run_all.py`` skips it): each variant takes up to the budget in CPU seconds.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _data import ensure_dataset  # noqa: E402
from _results import read_section, write_section  # noqa: E402
from bench_deepsi import WARM_UP, Curve, run_turns, train_ours  # noqa: E402

from canonid.kernel.dataset import Dataset  # noqa: E402
from canonid.profiles import train_options  # noqa: E402

RES = {"residual": True, "feedthrough": False}

#: key → (description, overrides of the quick ``train`` stage, network options)
VARIANTS: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {
    "quick": ("quick profile, network defaults (as in bench_deepsi.py)", {}, {}),
    "residual": ("`--residual`", {}, {"residual": True}),
    "res-noft": ("`--residual --no-feedthrough` (the tank's options)", {}, RES),
    "res-noft-w12": (
        "`--residual --no-feedthrough`, 12 windows per flight and epoch",
        {"windows_per_epoch": 12 * 40},
        RES,
    ),
    "res-noft-b64": (
        "`--residual --no-feedthrough`, batch 64, 16 windows per flight and epoch",
        {"batch_size": 64, "windows_per_epoch": 16 * 40},
        RES,
    ),
    "res-noft-lr1e-3": ("`--residual --no-feedthrough`, Adam 1e-3", {"lr": 1e-3}, RES),
    "res-noft-lr1e-3-b64": (
        "`--residual --no-feedthrough`, Adam 1e-3, batch 64, 16 windows per flight and epoch",
        {"lr": 1e-3, "batch_size": 64, "windows_per_epoch": 16 * 40},
        RES,
    ),
}
SECTION = "Ours (MLP) on the planar drone: settings"


def earlier(intro: str) -> tuple[str, list[str]]:
    """The command and the variant rows of this script's section, if it was written for the
    same data and budget (``intro``); else ``("", [])``."""
    text = read_section(SECTION)
    found = re.search(rf"<!-- BEGIN {re.escape(SECTION)} -->(.*?)<!-- END", text, re.S)
    if found is None or intro not in found.group(1):
        return "", []
    command = re.search(r"Command: `([^`]*)`", found.group(1))
    rows = [line for line in found.group(1).splitlines() if line.split(" | ")[0][2:] in VARIANTS]
    return (command.group(1) if command else ""), rows


def best_by(curve: Curve, seconds: float) -> str:
    """The lowest validation MSE at training CPU time ``seconds`` or before."""
    best = min((v for s, v in zip(curve.seconds, curve.val) if s <= seconds), default=None)
    return "—" if best is None else f"{best:.3g}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=float, default=300.0, help="CPU seconds per variant")
    parser.add_argument(
        "--drone", type=Path, help="planar-drone dataset (default runs/data/drone2d-small)"
    )
    parser.add_argument(
        "--only", nargs="*", metavar="KEY", help=f"variants (default all): {list(VARIANTS)}"
    )
    parser.add_argument(
        "--add",
        action="store_true",
        help="keep the rows of an earlier run with the same data and budget in the records",
    )
    args = parser.parse_args()
    unknown = sorted(set(args.only or ()) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variant(s) {unknown}; known: {sorted(VARIANTS)}")
    torch.set_num_threads(1)
    ds = Dataset.load(ensure_dataset("drone2d-small", args.drone))
    budget = args.budget

    def train(key: str, seconds: float) -> Curve:
        _, overrides, net_options = VARIANTS[key]
        _, curves = run_turns(
            {
                "ours": lambda turns, curve: train_ours(
                    ds, turns, seconds, curve, net_options=net_options, overrides=overrides
                )
            },
            slice_s=3600.0,
        )
        return curves["ours"]

    keys = args.only or list(VARIANTS)
    train(keys[0], WARM_UP)  # untimed, as in bench_deepsi.py
    marks = [budget / 3, 2 * budget / 3]
    rows = [
        "| variant | options | "
        + " | ".join(f"best val MSE by {m:.0f} s" for m in marks)
        + " | best val MSE | stopped | training CPU s | validation CPU s |",
        "|---|---|---:|---:|---:|---|---:|---:|",
    ]
    train_split = ds.split("train")
    quick = train_options("quick")  # the stage every variant starts from (described as it is now)
    intro = (
        f"Ours (MLP), ℓ = 10, seed 0, on `runs/data/drone2d-small` ({len(train_split)} "
        f"training and {len(ds.split('val'))} validation flights × "
        f"{train_split[0].u.shape[0]} samples); budget {budget:.0f} s of training CPU per "
        "variant, clocked as in `bench_deepsi.py`. Validation MSE: 100-step rollouts from "
        "every 5th start of the validation flights, normalised by the training output "
        "variance (the test split is not read). Each variant is the quick profile "
        f"({quick.epochs} epochs of {quick.windows_per_epoch} windows in "
        f"batches of {quick.batch_size}, Adam {quick.lr:g} cosine-decayed to "
        f"{quick.lr_final:g}, rollout length 1 → {quick.horizon} over "
        f"{quick.curriculum_epochs} epochs) with the options listed changed."
    )
    command = "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])
    if args.add:
        before, kept = earlier(intro)
        rows += [row for row in kept if row.split(" | ")[0][2:] not in keys]
        command = f"{before}; {command}" if before else command
    for key in keys:  # the section is rewritten after each variant, so none is lost
        curve = train(key, budget)
        rows.append(
            f"| {key} | {VARIANTS[key][0]} | "
            + " | ".join(best_by(curve, m) for m in marks)
            + f" | {curve.best:.3g} | {curve.stopped} | {curve.seconds[-1]:.0f} | "
            f"{curve.clock.val_cpu:.0f} |"
        )
        print(rows[-1], flush=True)
        write_section(SECTION, intro + "\n\n" + "\n".join(rows), command=command)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
