"""Peak memory and time of loading a large CSV file with ``canonid.datagen.loaders.load_csv``.

Writes a CSV file of ``--rows`` rows (columns ``t, u, y``: a time stamp and two random signals,
each written as the shortest decimal that reads back to its double, like ``repr``) in a
temporary folder, then loads it in a fresh interpreter per run, which reports its own peak
resident set size (``resource.getrusage(RUSAGE_SELF).ru_maxrss``) after the imports (the
interpreter, numpy and canonid alone: the floor) and after the load, and the seconds the load
took. ``--baseline REF`` loads the same file with git revision ``REF`` too (exported to a
temporary folder, laid out as the installed package), the two trees taking turns run by run so
both see the same machine load. Writes the "CSV memory" section of its notes
(``benchmarks/records/``).

Usage: python benchmarks/bench_csv_memory.py [--size quick|full] [--rows N] [--repeats R]
[--baseline REF] (quick: 200,000 rows; full: 2 million)
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import load_line, write_section  # noqa: E402

MIB = 2**20
#: the layers' folders and where the installed package has them (pyproject.toml, package-dir)
LAYERS = ("kernel", "models", "datagen", "learning", "analysis")

CHILD = """
import json, resource, sys, time
from canonid.datagen import loaders
imports = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
data = loaders.load_csv(sys.argv[1], inputs=["u"], outputs=["y"], dt=0.01)
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
rows = sum(t.T for t in data.split("train"))
print(json.dumps({"imports_kib": imports, "peak_kib": peak, "seconds": seconds, "rows": rows,
                  "module": loaders.__file__}))
"""


def write_csv(path: Path, rows: int, seed: int = 0) -> None:
    """``rows`` rows of ``t, u, y`` (sampled at 100 Hz), written a block at a time."""
    rng = np.random.default_rng(seed)
    with path.open("w", newline="") as f:
        f.write("t,u,y\n")
        for start in range(0, rows, 100_000):
            u, y = rng.normal(size=(2, min(100_000, rows - start))).tolist()
            f.writelines(
                f"{(start + k) / 100!r},{a!r},{b!r}\n" for k, (a, b) in enumerate(zip(u, y))
            )


def export(ref: str, into: Path) -> Path:
    """The files of git revision ``ref`` under ``into``, with each layer linked into
    ``canonid/`` where the installed package has it, so ``PYTHONPATH=into`` imports them."""
    archive = subprocess.run(["git", "archive", ref], cwd=ROOT, capture_output=True, check=True)
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(into, filter="data")
    for layer in LAYERS:
        (into / "canonid" / layer).symlink_to(into / layer, target_is_directory=True)
    return into


def load_once(tree: Path | None, csv_path: Path) -> dict:
    """One load in a fresh interpreter: this tree (the installed package) or an exported one."""
    env = dict(os.environ)
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
    res = subprocess.run(
        [sys.executable, "-c", CHILD, str(csv_path)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tree or ROOT,
        check=True,
    )
    report = json.loads(res.stdout)
    expected = ROOT / "datagen" if tree is None else tree / "canonid" / "datagen"
    if Path(report["module"]).parent != expected:  # the tree measured is the one named
        raise RuntimeError(f"loaded {report['module']}, expected a module of {expected}")
    return report


def _load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--rows", type=int, help="rows of the file (quick 200,000, full 2 M)")
    parser.add_argument("--repeats", type=int, default=2, help="loads per tree")
    parser.add_argument("--baseline", metavar="REF", help="also measure git revision REF")
    args = parser.parse_args()
    args.rows = args.rows or (200_000 if args.size == "quick" else 2_000_000)
    with tempfile.TemporaryDirectory() as tmp:
        csv_path = Path(tmp) / "big.csv"
        write_csv(csv_path, args.rows)
        size = csv_path.stat().st_size
        trees: dict[str, Path | None] = {"this tree": None}
        if args.baseline:
            tree = export(args.baseline, Path(tmp) / "baseline")
            trees = {f"`{args.baseline}`": tree, **trees}
        load_before = _load()
        runs: dict[str, list[dict]] = {label: [] for label in trees}
        for _ in range(args.repeats):
            for label, tree in trees.items():
                runs[label].append(load_once(tree, csv_path))
        load_after = _load()
    rows = [
        "| tree | peak RSS (MiB) | imports alone (MiB) | peak / file size | "
        "(peak − imports) / file size | load time (s), median of runs |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for label, reports in runs.items():
        assert all(r["rows"] == args.rows for r in reports)
        peak = max(r["peak_kib"] for r in reports) * 1024
        imports = max(r["imports_kib"] for r in reports) * 1024
        seconds = statistics.median(r["seconds"] for r in reports)
        rows.append(
            f"| {label} | {peak / MIB:.0f} | {imports / MIB:.0f} | {peak / size:.2f} | "
            f"{(peak - imports) / size:.2f} | {seconds:.2f} |"
        )
    load, _ = load_line(
        [load_before, load_after], "the seconds are rough; the memory does not depend on the load"
    )
    body = (
        f"Loading a CSV file of {args.rows:,} rows × 3 columns (`t, u, y`, reading `u` and `y`; "
        f"{size / MIB:.0f} MiB; the arrays loaded hold {args.rows * 2 * 8 / MIB:.0f} MiB) with "
        f"`load_csv`, in a fresh interpreter (`{Path(sys.executable).name}`) per run, "
        f"{args.repeats} runs per tree, the trees taking turns; peak RSS is the largest of the "
        "runs (`ru_maxrss`), *imports alone* the peak before the load (interpreter, numpy, "
        f"canonid). {load}\n\n" + "\n".join(rows)
    )
    write_section("CSV memory", body)
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
