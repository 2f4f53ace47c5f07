"""Choose or average? Validation RMSE of trained runs and of the average of their simulations.

Each run folder's model simulates every record of the data's validation split from its measured
samples ``n_init − ℓ … n_init − 1`` and the whole input
(:func:`canonid.learning.evaluate.simulate_records`); the script prints the RMSE over samples
``n_init …`` of each model and of the mean of their outputs. Only the validation split is read.

Usage: python benchmarks/studies/window/average_runs.py DATA N_INIT RUN [RUN ...]
(the figures of benchmarks/studies/window/window_study_notes.md, "Averaging instead of choosing")
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", type=Path, help="a canonid dataset with a val split")
    parser.add_argument("n_init", type=int, help="measured samples before the simulation")
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN", help="run folders")
    args = parser.parse_args()

    from canonid.kernel.dataset import Dataset
    from canonid.learning import Model
    from canonid.learning.evaluate import simulate_records

    val = list(Dataset.load(args.data).split("val"))
    measured = [t.y[args.n_init :] for t in val]

    def rmse(sims: list[np.ndarray]) -> float:
        err = np.concatenate([s - y for s, y in zip(sims, measured, strict=True)])
        return float(np.sqrt(np.mean(err**2)))

    sims = {run: simulate_records(Model.load(run), val, args.n_init) for run in args.runs}
    for run, sim in sims.items():
        print(f"{run}: validation RMSE {rmse(sim):.4g}")
    mean = [np.mean([sim[i] for sim in sims.values()], axis=0) for i in range(len(val))]
    print(f"average of the {len(sims)} runs: validation RMSE {rmse(mean):.4g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
