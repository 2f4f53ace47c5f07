"""Start-up benchmark: wall and CPU time of ``canonid --help``, ``canonid train --help``,
``canonid systems``, ``canonid generate --help``, ``import canonid`` and reading a 1,000-row CSV
with ``canonid.load_data``, each in a fresh interpreter beside the interpreter alone, and which
of torch, CasADi, scipy and matplotlib it loaded. Targets: ``train --help`` ≤ 0.3 s of CPU,
loading the CSV ≤ 0.2 s, ``import canonid`` ≤ 0.05 s more than the interpreter alone.

A tree of today's layout (a ``kernel/`` folder) runs from links shaped like the installed
package (``docs/hooks/api_reference.py::source_tree``); an older tree, whose folders were
top-level packages, from its root.

``--baseline REF`` measures the tree of git revision ``REF`` too (exported to a temporary
folder and run with the same interpreter), the two trees taking turns run by run, so both see
the same machine load. Each tree's modules are compiled to bytecode first, as an installed
wheel's are. Reports the median and minimum wall time and the median CPU time (user +
system, which depends little on the load) of ``--repeats`` runs, and the load average before
and after. Writes the "Start-up" section of its notes (``benchmarks/records/``).
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
sys.path.insert(0, str(ROOT / "docs" / "hooks"))

from _results import write_section  # noqa: E402
from api_reference import source_tree  # noqa: E402

#: the CSV the load case reads (written into the temporary folder)
CSV_ROWS = 1000
CSV_NAME = "startup.csv"


def cases(csv: Path) -> dict[str, list[str]]:
    """label → arguments of the interpreter."""
    load = f"import canonid; canonid.load_data({str(csv)!r}, inputs=['u'], outputs=['y'], dt=0.1)"
    return {
        "python -c pass": ["-c", "pass"],  # the interpreter alone: the floor on this machine
        "canonid --help": ["-m", "canonid", "--help"],
        "canonid train --help": ["-m", "canonid", "train", "--help"],
        "canonid systems": ["-m", "canonid", "systems"],
        "canonid generate --help": ["-m", "canonid", "generate", "--help"],
        "import canonid": ["-c", "import canonid"],
        f"canonid.load_data (CSV, {CSV_ROWS} rows)": ["-c", load],
    }


HEAVY = ("torch", "casadi", "scipy", "matplotlib")


def export_tree(ref: str, into: Path) -> Path:
    """The files of git revision ``ref`` under ``into``."""
    archive = subprocess.run(["git", "archive", ref], cwd=ROOT, capture_output=True, check=True)
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into


#: tree → the folder on PYTHONPATH that makes ``import canonid`` read that tree
_PATHS: dict[Path, Path] = {}


def importable_tree(tree: Path, scratch: Path) -> Path:
    """The folder to put first on ``sys.path`` for ``tree``."""
    if not (tree / "kernel").is_dir():
        return tree  # the old layout: the folders were top-level packages
    return source_tree(tree, scratch / f"links-{len(_PATHS)}")


#: the folders of a tree that hold the package's modules (both layouts)
PACKAGE_FOLDERS = ("canonid", "kernel", "models", "datagen", "learning", "analysis")


def _compile(tree: Path) -> None:
    """Write the bytecode of ``tree``'s modules, as installing a wheel does: an interpreter
    that may not write it (``PYTHONDONTWRITEBYTECODE``) would otherwise compile every module
    it imports on every run, and a fresh export never has any."""
    folders = [str(tree / f) for f in PACKAGE_FOLDERS if (tree / f).is_dir()]
    subprocess.run([sys.executable, "-m", "compileall", "-q", *folders], check=True)


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(_PATHS[tree])}


def _seconds(tree: Path, args: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of one run; CPU hardly depends on the load."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], cwd=_PATHS[tree], env=_env(tree), capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _heavy_modules(tree: Path, args: list[str]) -> list[str]:
    """The modules of :data:`HEAVY` that the command imports (``-X importtime``)."""
    res = subprocess.run(
        [sys.executable, "-X", "importtime", *args],
        cwd=_PATHS[tree],
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
        scratch = Path(tmp)
        csv = scratch / CSV_NAME
        rows = "".join(f"{0.1 * t:.1f},{t % 7},{(t * 13) % 11}\n" for t in range(CSV_ROWS))
        csv.write_text("time,u,y\n" + rows, encoding="utf-8")
        commands = cases(csv)
        trees = {"this tree": ROOT}
        if args.baseline:
            old = export_tree(args.baseline, scratch / "baseline")
            trees = {f"`{args.baseline}`": old, **trees}
        for tree in trees.values():
            _PATHS[tree] = importable_tree(tree, scratch)
            _compile(tree)
        load_before = _load()
        for tree in trees.values():  # warm the file cache once
            for case in commands.values():
                _seconds(tree, case)
        times: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for _ in range(repeats):
            for label, tree in trees.items():
                for case, cmd in commands.items():
                    times.setdefault((label, case), []).append(_seconds(tree, cmd))
        heavy = {
            (label, case): _heavy_modules(tree, cmd)
            for label, tree in trees.items()
            for case, cmd in commands.items()
        }
        load_after = _load()
    rows = [
        "| command | tree | median wall (s) | min wall (s) | median CPU (s) | CPU over the "
        "interpreter (s) | loads (of torch, CasADi, scipy, matplotlib) |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    cpu = {key: statistics.median(c for _, c in runs) for key, runs in times.items()}
    for case in commands:
        for label in trees:
            wall = [w for w, _ in times[(label, case)]]
            extra = cpu[(label, case)] - cpu[(label, "python -c pass")]
            loads = ", ".join(heavy[(label, case)]) or "none"
            rows.append(
                f"| `{case}` | {label} | {statistics.median(wall):.2f} | {min(wall):.2f} | "
                f"{cpu[(label, case)]:.3f} | {extra:.3f} | {loads} |"
            )
    here = {case: cpu[("this tree", case)] for case in commands}
    floor = here["python -c pass"]
    load_case = next(c for c in commands if c.startswith("canonid.load_data"))
    targets = [
        ("`canonid train --help` ≤ 0.3 s of CPU", here["canonid train --help"], 0.3),
        (f"`{load_case}` ≤ 0.2 s of CPU", here[load_case], 0.2),
        (
            "`import canonid` ≤ 0.05 s of CPU over the interpreter",
            here["import canonid"] - floor,
            0.05,
        ),
    ]
    rows += ["", "Targets (this tree, median CPU):"]
    rows += [
        f"- {what}: {value:.3f} s — {'met' if value <= bound else 'NOT met'}"
        for what, value, bound in targets
    ]
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
