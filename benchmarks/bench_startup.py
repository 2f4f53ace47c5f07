"""Start-up benchmark: wall and CPU time of ``canonid --help``, ``canonid systems``, ``canonid
generate --help`` (what ``generate`` loads before its first flight) and ``import canonid``, each
in a fresh interpreter beside the interpreter alone, and whether it loaded torch or CasADi.

``--baseline REF`` measures the tree of git revision ``REF`` too (exported to a temporary
folder and run with the same interpreter), the two trees taking turns run by run, so both see
the same machine load. Reports the median and minimum wall time and the median CPU time (user +
system, which depends little on the load) of ``--repeats`` runs, and the load average before
and after. Writes the "Start-up" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import io
import os
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import write_section  # noqa: E402

#: label → arguments of the interpreter (run in the tree's root, so its packages come first)
CASES = {
    "python -c pass": ["-c", "pass"],  # the interpreter alone: the floor on this machine
    "canonid --help": ["-m", "canonid", "--help"],
    "canonid systems": ["-m", "canonid", "systems"],
    "canonid generate --help": ["-m", "canonid", "generate", "--help"],
    "import canonid": ["-c", "import canonid"],
}
HEAVY = ("torch", "casadi")


def _export(ref: str, into: Path) -> Path:
    """The files of git revision ``ref`` under ``into``."""
    archive = subprocess.run(["git", "archive", ref], cwd=ROOT, capture_output=True, check=True)
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree)}


def _seconds(tree: Path, args: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of one run; CPU hardly depends on the load."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], cwd=tree, env=_env(tree), capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _heavy_modules(tree: Path, args: list[str]) -> list[str]:
    """The modules of :data:`HEAVY` that the command imports (``-X importtime``)."""
    res = subprocess.run(
        [sys.executable, "-X", "importtime", *args],
        cwd=tree,
        env=_env(tree),
        capture_output=True,
        text=True,
    )
    loaded = {line.rsplit("|", 1)[-1].strip() for line in res.stderr.splitlines()}
    return [m for m in HEAVY if m in loaded]


def _load() -> str:
    return " / ".join(Path("/proc/loadavg").read_text().split()[:3])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--repeats", type=int, help="runs per command (quick 5, full 15)")
    parser.add_argument("--baseline", metavar="REF", help="also measure git revision REF")
    args = parser.parse_args()
    repeats = args.repeats or (5 if args.size == "quick" else 15)
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this tree": ROOT}
        if args.baseline:
            trees = {f"`{args.baseline}`": _export(args.baseline, Path(tmp)), **trees}
        load_before = _load()
        for tree in trees.values():  # warm the file cache once
            for case in CASES.values():
                _seconds(tree, case)
        times: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for _ in range(repeats):
            for label, tree in trees.items():
                for case, cmd in CASES.items():
                    times.setdefault((label, case), []).append(_seconds(tree, cmd))
        heavy = {
            (label, case): _heavy_modules(tree, cmd)
            for label, tree in trees.items()
            for case, cmd in CASES.items()
        }
        load_after = _load()
    rows = [
        "| command | tree | median wall (s) | min wall (s) | median CPU (s) | loads |",
        "|---|---|---:|---:|---:|---|",
    ]
    for case in CASES:
        for label in trees:
            wall = [w for w, _ in times[(label, case)]]
            cpu = statistics.median(c for _, c in times[(label, case)])
            loads = ", ".join(heavy[(label, case)]) or "neither torch nor CasADi"
            rows.append(
                f"| `{case}` | {label} | {statistics.median(wall):.2f} | {min(wall):.2f} | "
                f"{cpu:.2f} | {loads} |"
            )
    body = (
        f"Wall and CPU (user + system) time of a fresh interpreter "
        f"(`{Path(sys.executable).name}`), {repeats} runs each after one warm-up, the trees "
        "taking turns; load average (1/5/15 min) "
        f"{load_before} before, {load_after} after.\n\n" + "\n".join(rows)
    )
    write_section("Start-up", body)
    print(body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
