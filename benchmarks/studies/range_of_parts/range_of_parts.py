"""How far each official test part goes beyond the training part's span, signal by signal.

What :data:`canonid.coverage.NOTED_BEYOND` rests on: the printed tables name a signal only where
it goes more than that share of its training span beyond it. A record drawn like the training data
leaves a finite span a little at its tails; a part made to extrapolate leaves it by much more.
Measured on every standard benchmark whose files are in ``--dir`` (the training part split as
``canonid benchmark`` splits it: the last 20 % validates), no model involved.

Usage: python range_of_parts.py [--dir ../../shared/data]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import DataError

ROOT = Path(__file__).resolve().parents[3]
SECTION = "Test parts outside the training range"


def _load(name: str, directory: Path) -> Dataset | None:
    """Benchmark ``name`` from ``directory`` in the package's layout or from a folder of its
    name; ``None`` where its files are not there."""
    from canonid.datagen.benchmarks import load_benchmark

    for where in (directory, directory / name):
        try:
            return load_benchmark(name, where)
        except DataError:
            continue
    return None


def table(directory: Path) -> list[str]:
    from canonid.coverage import NOTED_BEYOND, outside_training_range, training_ranges
    from canonid.datagen.benchmarks import BENCHMARKS
    from canonid.datagen.loaders import split_train_val

    rows = [
        "| benchmark | test part | signal | share of samples outside | largest distance / span "
        "| named in the tables |",
        "|---|---|---|---:|---:|---|",
    ]
    for name in BENCHMARKS:
        raw = _load(name, directory)
        if raw is None:
            continue
        data = split_train_val(raw, val_fraction=0.2, record_tails=True)
        spans = {"training_range": training_ranges(data.split("train"))}
        names = {"input_names": data.input_names, "output_names": data.output_names}
        for part in data.split("test"):
            found = outside_training_range(spans, [part], **names) or ()
            label = part.info.get("part", "")
            if not found:
                rows.append(f"| {name} | {label} | — | 0 | — | no |")
            for o in found:
                beyond = "—" if o.beyond is None else f"{o.beyond:.3f}"
                rows.append(
                    f"| {name} | {label} | {o.kind} {o.name} | {100 * o.share:.3g} % | "
                    f"{beyond} | {'yes' if o.noted else 'no'} |"
                )
    return [
        "Each official test part against the span of its benchmark's training part (the last 20 % "
        "validates, as `canonid benchmark` splits; `canonid.coverage.outside_training_range`). "
        f"The tables name a signal beyond {NOTED_BEYOND:g} of its span "
        "(`canonid.coverage.NOTED_BEYOND`), a threshold set from this table: between the "
        "largest excursion of the parts drawn like the training data and the smallest of the "
        "part made to extrapolate. It decides what is printed; no model or score depends on it.",
        "",
        *rows,
    ]


#: datasets whose validation part is measured against their training part (those found)
VALIDATION_DATA = (
    "runs/data/tank-s0",
    "runs/data/drone2d-small",
    "runs/data/masses-id",
    "runs/small-data/data/n1000",
    "runs/small-data/data/n3000",
    "runs/small-data/data/n10000",
    "runs/data/tanks-overflow",
    *(f"runs/data/tanks-overflow-s{seed}" for seed in range(1, 5)),
)


def validation_table(directory: Path) -> list[str]:
    """Each dataset's training part against its validation part's spans: what
    :data:`canonid.coverage.UNVALIDATED_SHARE` rests on."""
    from canonid.coverage import NOTED_BEYOND, UNVALIDATED_SHARE, unvalidated
    from canonid.datagen.loaders import split_train_val

    found: dict[str, Dataset] = {}
    raw = _load("silverbox", directory)
    if raw is not None:  # the official Silverbox split, as canonid benchmark makes it
        found["silverbox"] = split_train_val(raw, val_fraction=0.2, record_tails=True)
    for path in VALIDATION_DATA:
        if (ROOT / path / "dataset.npz").is_file():
            found[path.removeprefix("runs/")] = Dataset.load(ROOT / path / "dataset.npz")
    rows = [
        "| data | training / validation samples | signal | share of training samples outside "
        "| largest distance / validation span | named by `canonid train` |",
        "|---|---|---|---:|---:|---|",
    ]
    for name, data in found.items():
        train, val = data.split("train"), data.split("val")
        sizes = f"{sum(t.T for t in train):,} / {sum(t.T for t in val):,}"
        names = {"input_names": data.input_names, "output_names": data.output_names}
        outside = unvalidated(train, val, **names)
        if not outside:
            rows.append(f"| {name} | {sizes} | — | 0 | — | no |")
        for o in outside:
            beyond = "—" if o.beyond is None else f"{o.beyond:.3f}"
            named = o.noted and o.share >= UNVALIDATED_SHARE
            rows.append(
                f"| {name} | {sizes} | {o.kind} {o.name} | {100 * o.share:.3g} % | {beyond} "
                f"| {'yes' if named else 'no'} |"
            )
    return [
        "",
        "### Validation parts against their training parts",
        "",
        "Each dataset's training part against the spans of its validation part "
        "(`canonid.coverage.unvalidated`): levels the model trains on that no choice made on "
        "validation sees. `canonid train` names a signal whose training samples go beyond the "
        f"validation span by more than {NOTED_BEYOND:g} of it (as the scores' tables) on at "
        f"least {UNVALIDATED_SHARE:g} of them (`canonid.coverage.UNVALIDATED_SHARE`), a share "
        "set from this table: the handfuls of extreme training samples of the large datasets "
        "(Silverbox, the tank, the masses) do not make their validation parts "
        "unrepresentative; the levels that the small records' last fifths miss do, and so "
        "does the drone's position px, flown farther in training than in validation.",
        "",
        *rows,
    ]


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT / "benchmarks"))  # _results
    from _results import record

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, default=ROOT.parent / "shared" / "data")
    directory = parser.parse_args(argv).dir
    body = "\n".join([*table(directory), *validation_table(directory)])
    return record(SECTION, body)


if __name__ == "__main__":
    raise SystemExit(main())
