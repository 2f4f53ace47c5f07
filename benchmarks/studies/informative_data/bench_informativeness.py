"""How informative closed-loop drone data are: ``drone2d`` (the paper's design) against
``drone2d-id`` (the same plus a random-phase multisine on the rotors), at the same size and seed.

For each scenario: generate the training flights serially, then report the failed solves, the
regenerated flights, the flights whose true state leaves the system's box X (and how many of
those are loose flights), the 99th percentile of |θ|, and the informativeness measures of
:func:`canonid.datagen.informativeness.dataset_informativeness` at window ℓ = 10 (the learned
drone model's window). Writes the "Informative drone data" section of its notes
(``benchmarks/records/``).
"""

from __future__ import annotations

import argparse
import itertools
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

from _results import write_section

from canonid.datagen.generate import GenerationConfig, generate_dataset, is_loose
from canonid.datagen.informativeness import Informativeness, dataset_informativeness
from canonid.datagen.scenarios import get_scenario
from canonid.kernel.dataset import Dataset
from canonid.models.registry import get_system

SCENARIOS = ("drone2d", "drone2d-id")
WINDOW = 10
SIZES = {"quick": 10, "full": 40}


@dataclass(frozen=True)
class Row:
    """One scenario's generation counts, box exits and informativeness."""

    failures: int
    replaced: int
    left: int
    loose: int
    theta99: float
    info: Informativeness


def measure(name: str, flights: int, seed: int, folder: Path) -> Row:
    """One scenario's row: generation counts, box exits and the informativeness."""
    result = generate_dataset(
        GenerationConfig(system=name, counts={"train": flights, "val": 0, "test": 0}, seed=seed),
        folder / name,
    )
    data = Dataset.load(folder / name)
    scenario = get_scenario(name)
    box = get_system(scenario.system).X
    trajectories = data.split("train")
    left = [
        i
        for i, tr in enumerate(trajectories)
        if not (np.all(tr.x >= box.lo) and np.all(tr.x <= box.hi))
    ]
    loose = [i for i in left if is_loose("train", i, scenario.loose_fraction)]
    theta = np.concatenate([tr.x[:, 2] for tr in trajectories])
    return Row(
        failures=result.solver_failures,
        replaced=result.replaced,
        left=len(left),
        loose=len(loose),
        theta99=float(np.percentile(np.abs(theta), 99)),
        info=dataset_informativeness(data, window=WINDOW),
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=tuple(SIZES), default="full")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    flights = SIZES[args.size]
    with tempfile.TemporaryDirectory() as tmp:
        rows = {name: measure(name, flights, args.seed, Path(tmp)) for name in SCENARIOS}
    edges = rows[SCENARIOS[0]].info.band_edges_hz
    bands = " / ".join(f"{lo:.2g}–{hi:.2g} Hz" for lo, hi in itertools.pairwise(edges))
    lines = [
        "| data | failed solves | regenerated flights | flights that left X (loose of them) | "
        "\\|θ\\| 99th pct [rad] | smallest eigenvalue of the regressor covariance | condition "
        f"number | smallest eigenvalue, inputs given outputs | first input's variance per band "
        f"({bands}) |",
        "|---|---:|---:|---|---:|---:|---:|---:|---|",
    ]
    for name, row in rows.items():
        first = next(iter(row.info.band_shares.values()))
        shares = " / ".join(f"{100 * share:.0f} %" for share in first)
        lines.append(
            f"| {name} | {row.failures} | {row.replaced} | {row.left} ({row.loose}) | "
            f"{row.theta99:.2f} | {row.info.smallest:.3g} | {row.info.condition_number:.2g} | "
            f"{row.info.input_given_outputs:.2g} | {shares} |"
        )
    body = (
        f"`drone2d` (the paper's design) against `drone2d-id` (the same plus a random-phase "
        f"multisine on each rotor; see `canonid.datagen.scenarios`), {flights} training flights "
        f"each, seed {args.seed}, generated serially; measures by "
        f'`dataset_informativeness(dataset, window={WINDOW})`. "Left X" counts flights whose '
        "true state leaves the system's box X (the generator does not reject them); loose flights "
        "carry random rotor kicks by design.\n\n" + "\n".join(lines) + "\n\n"
        "Reading: at ℓ = 10 the output lags of the 6-state drone are nearly dependent, so the "
        "smallest eigenvalue of the whole window regressor sits near the measurement-noise floor "
        "for both designs and does not separate them; the part of the inputs that the outputs "
        "do not determine (inputs given outputs) and where the inputs' variance lies in "
        "frequency do. Whether these data close the NMPC loop on the learned drone is a "
        "separate measurement (`benchmarks/studies/learned_mpc/learned_mpc.py`)."
    )
    write_section("Informative drone data", body)
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
