"""The datasets the benchmarks train on (generated with ``canonid generate`` when missing) and the
systems the validation studies read."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "runs" / "data"

#: name → ``canonid generate`` arguments; the folder is ``runs/data/<name>``
DATASETS = {
    "tank-s0": ["tank"],
    "drone2d-small": ["drone2d", "--n-train", "40", "--n-val", "10", "--n-test", "10"],
    # the informative design at the same size (the same references, seed 0)
    "drone2d-id-small": ["drone2d-id", "--n-train", "40", "--n-val", "10", "--n-test", "10"],
}

#: system → (data source, the window ℓ the defaults chose there: the records) for the
#: validation studies (extrapolation_study.py, weight_decay_study.py); a source is a dataset
#: folder under the repository root, or "silverbox" (the benchmark, loaded from ``--dir``)
STUDY_SYSTEMS = {
    "silverbox": ("silverbox", 10),
    "tank": ("runs/data/tank-s0", 10),
    "drone2d": ("runs/data/drone2d-small", 10),
    "masses": ("runs/data/masses-id", 40),
    "silverbox-3k": ("runs/small-data/data/n3000", 10),
    "silverbox-10k": ("runs/small-data/data/n10000", 10),
    "silverbox-1k": ("runs/small-data/data/n1000", 10),
    "overflow-tanks": ("runs/data/tanks-overflow", 10),
}

__all__ = ["DATA", "DATASETS", "STUDY_SYSTEMS", "ensure_dataset"]


def ensure_dataset(name: str, path: Path | None = None) -> Path:
    """The folder of dataset ``name`` (default ``runs/data/<name>``), generated if it does not
    hold a ``dataset.npz`` yet."""
    folder = path or DATA / name
    if not (folder / "dataset.npz").is_file():
        cmd = [sys.executable, "-m", "canonid", "generate", *DATASETS[name]]
        subprocess.run([*cmd, "--no-progress", "--out", str(folder)], check=True, cwd=ROOT)
    return folder


#: the share of a cut training record that validates (its last samples)
VAL_FRACTION = 0.2


def cut(dataset: Any, samples: int) -> Any:
    """``dataset`` with its one training record cut to its first ``samples`` samples, then the
    validation tail (its last 20 %) split off as ``canonid benchmark`` does; the test parts are kept
    (the small-data study's and the development suite's Silverbox cuts)."""
    from canonid.datagen.loaders import split_train_val
    from canonid.kernel.dataset import Dataset

    (record,) = dataset.split("train")
    start = record.info["samples"][0]
    head = record.part(0, samples, samples=[start, start + samples])
    short = Dataset(
        splits={**dataset.splits, "train": (head,)},
        dt=dataset.dt,
        input_names=dataset.input_names,
        output_names=dataset.output_names,
        state_names=dataset.state_names,
        metadata={**dataset.metadata, "cut": f"first {samples} samples of the training part"},
    )
    return split_train_val(short, val_fraction=VAL_FRACTION, record_tails=True)
