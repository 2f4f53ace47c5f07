"""Two regularisers for small records, judged on validation only: a weight average, narrow seeds.

The defaults overfit records of about a thousand samples early (sections "Small data" and
"Overflow tanks"). Two cheap candidates against one network of the default widths, each trained as
stacked candidates (:func:`canonid.learning.batched.fit_batched`, the quick profile, the
defaults' window on that record, the plain network: stacks have no cubic branch):

* ``wide``: 3 × 256 (the default widths), seeds 0 and 1;
* ``wide-average``: the same with an exponential moving average of the weights (decay 0.999 per
  optimiser step, about 67 epochs), validated and kept in place of the weights;
* ``narrow``: 3 × 64, seeds 0 … 7 (eight cost about as much as one wide network on a core,
  section "Batched candidates").

Only the training and validation parts are read; test parts are never loaded.

Usage: python small_record_variants.py run SYSTEM VARIANT --out DIR
       python small_record_variants.py record DIR     (writes the study file and the section)
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _data import STUDY_SYSTEMS  # noqa: E402

STUDY_FILE = ROOT / "benchmarks" / "studies" / "small_record_variants.json"
SECTION = "Weight average and narrow networks on small records"
#: system → (dataset folder, the defaults' window there)
SYSTEMS = {
    "overflow-tanks": (STUDY_SYSTEMS["overflow-tanks"][0], 20),
    "silverbox-1k": STUDY_SYSTEMS["silverbox-1k"],
}
#: variant → (hidden widths, seeds, weight-average decay)
VARIANTS: dict[str, tuple[tuple[int, ...], tuple[int, ...], float | None]] = {
    "wide": ((256, 256, 256), (0, 1), None),
    "wide-average": ((256, 256, 256), (0, 1), 0.999),
    "narrow": ((64, 64, 64), tuple(range(8)), None),
}


def run(system: str, variant: str, out: Path) -> dict:
    """Train one variant's stack on one system; write and return its summary."""
    import torch

    from canonid.kernel.dataset import Dataset
    from canonid.kernel.io import atomic_write_text
    from canonid.learning.batched import candidate_grid, fit_batched
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    source, window = SYSTEMS[system]
    hidden, seeds, decay = VARIANTS[variant]
    data = Dataset.load(ROOT / source / "dataset.npz")
    folder = out / f"{system}-{variant}"
    folder.mkdir(parents=True, exist_ok=True)
    cpu0 = time.process_time()
    result = fit_batched(
        data.split("train"),
        data.split("val"),
        candidate_grid(hidden=[hidden], seed=list(seeds)),
        window=window,
        options=train_options("quick", device="cpu", ema_decay=decay),
        run_dir=folder,
    )
    summary = {
        "system": system,
        "variant": variant,
        "window": window,
        "hidden": list(hidden),
        "ema_decay": decay,
        "cpu_seconds": time.process_time() - cpu0,
        "ensemble": result.ensemble,
        "ensemble_val_loss": result.ensemble_val_loss,
        "candidates": [
            {"seed": seed, **_best(r.history)} for seed, r in zip(seeds, result.runs, strict=True)
        ],
    }
    atomic_write_text(folder / "summary.json", json.dumps(summary, indent=1))
    return summary


def _best(history: list[dict]) -> dict:
    """The best validation loss, its epoch and the last epoch trained."""
    loss, epoch = min((h["val_loss"], h["epoch"]) for h in history if h.get("val_loss") is not None)
    return {"best_val_loss": loss, "best_epoch": epoch, "last_epoch": history[-1]["epoch"]}


def render(study: dict) -> str:
    """The section: the variants' validation losses per system, and what they say."""
    rows = {(s["system"], s["variant"]): s for s in study["summaries"]}
    lines = [
        "Two cheap regularisers for records of about a thousand samples, against one network of "
        f"the default widths (`wide`: {_shape('wide')}), judged on validation only "
        "(`benchmarks/small_record_variants.py`; every number is in "
        "`benchmarks/studies/small_record_variants.json`): `wide-average`, the same with an "
        f"exponential moving average of the weights (decay {VARIANTS['wide-average'][2]} per "
        "optimiser step) validated and kept in place of the weights; `narrow`, "
        f"{_shape('narrow')}. Each variant trains as one stack of candidates "
        "(`canonid.learning.batched.fit_batched`: the quick profile, the defaults' window on "
        "that record, the plain network — stacks have no cubic branch), `python "
        "small_record_variants.py run SYSTEM VARIANT --out runs/srv`, one after another on one "
        "thread beside two or three other jobs; `record runs/srv` wrote this section. Test "
        "parts were never loaded.",
        "",
        "Best validation loss (normalised rollout MSE on the validation part) per seed, the "
        "lowest and the median of the variant's seeds; CPU: the stack's training on one thread.",
        "",
        "| system | ℓ | variant | seeds | lowest | median | per seed | CPU s |",
        "|---|---:|---|---:|---:|---:|---|---:|",
    ]
    for system in SYSTEMS:
        for variant in VARIANTS:
            s = rows.get((system, variant))
            if s is None:
                continue
            losses = [c["best_val_loss"] for c in s["candidates"]]
            per = ", ".join(f"{v:.3g}" for v in losses)
            lines.append(
                f"| {system} | {s['window']} | {variant} | {len(losses)} | {min(losses):.3g} | "
                f"{statistics.median(losses):.3g} | {per} | {s['cpu_seconds']:.0f} |"
            )
    lines += ["", _reading(rows)]
    return "\n".join(lines)


def _shape(variant: str) -> str:
    """``3 × 256, seeds 0 … 1``: a variant's widths and seeds."""
    hidden, seeds, _ = VARIANTS[variant]
    return f"{len(hidden)} × {hidden[0]}, seeds {seeds[0]} … {seeds[-1]}"


def _reading(rows: dict) -> str:
    """What the table says of each variant against ``wide``, system by system, and whether it
    lowers both the lowest and the median loss on every system (what adoption would ask)."""
    said, verdicts = [], []
    for variant in ("wide-average", "narrow"):
        lowered = []
        for system in SYSTEMS:
            base, s = rows.get((system, "wide")), rows.get((system, variant))
            if base is None or s is None:
                continue
            wide = [c["best_val_loss"] for c in base["candidates"]]
            mine = [c["best_val_loss"] for c in s["candidates"]]
            low, mid = min(mine) / min(wide), statistics.median(mine) / statistics.median(wide)
            said.append(f"{system}, {variant} / wide: lowest {low:.2f}×, median {mid:.2f}×")
            lowered.append(low < 1 and mid < 1)
        if lowered:
            verdicts.append(
                f"`{variant}` lowers both on {sum(lowered)} of {len(lowered)} records"
                + (": a candidate for the defaults" if all(lowered) else ": not adopted")
            )
    return (
        "Against `wide` (below 1: a lower validation loss): "
        + "; ".join(said)
        + ". "
        + "; ".join(verdicts)
        + "."
    )


def record(directory: Path) -> int:
    from _results import record as write_and_print

    from canonid.kernel.io import atomic_write_text

    summaries = [json.loads(p.read_text()) for p in sorted(directory.glob("*/summary.json"))]
    study = {"summaries": summaries}
    atomic_write_text(STUDY_FILE, json.dumps(study, indent=1) + "\n")
    return write_and_print(SECTION, render(study))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    p = sub.add_parser("run")
    p.add_argument("system", choices=list(SYSTEMS))
    p.add_argument("variant", choices=list(VARIANTS))
    p.add_argument("--out", type=Path, required=True)
    p = sub.add_parser("record")
    p.add_argument("directory", type=Path)
    args = parser.parse_args(argv)
    if args.step == "run":
        print(json.dumps(run(args.system, args.variant, args.out), indent=1))
        return 0
    return record(args.directory)


if __name__ == "__main__":
    raise SystemExit(main())
