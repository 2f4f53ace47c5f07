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
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SECTION = "Test parts outside the training range"


def table(directory: Path) -> list[str]:
    from canonid.coverage import NOTED_BEYOND, outside_training_range, training_ranges
    from canonid.datagen.benchmarks import BENCHMARKS, load_benchmark
    from canonid.datagen.loaders import split_train_val
    from canonid.kernel.errors import DataError

    rows = [
        "| benchmark | test part | signal | share of samples outside | largest distance / span "
        "| named in the tables |",
        "|---|---|---|---:|---:|---|",
    ]
    for name in BENCHMARKS:
        raw = None
        for where in (directory, directory / name):  # the package's layout, or a folder each
            try:
                raw = load_benchmark(name, where)
                break
            except DataError:
                continue
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


def main(argv: list[str] | None = None) -> int:
    from _results import write_section

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, default=ROOT.parent / "shared" / "data")
    body = "\n".join(table(parser.parse_args(argv).dir))
    write_section(SECTION, body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
