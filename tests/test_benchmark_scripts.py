"""Every benchmark and study script starts: ``--help`` exits 0 (a moved script that lost an
import fails here, not when someone reruns its study)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(
    p
    for p in [*BENCHMARKS.glob("*.py"), *BENCHMARKS.glob("studies/*/*.py")]
    if not p.name.startswith("_")
)
#: scripts that need an optional peer package (the ``bench`` extra)
NEEDS = {"bench_deepsi.py": "deepSI", "drone_variants.py": "deepSI"}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.relative_to(BENCHMARKS).as_posix())
def test_each_script_starts(script: Path):
    needed = NEEDS.get(script.name)
    if needed is not None and importlib.util.find_spec(needed) is None:
        pytest.skip(f"needs {needed}")
    done = subprocess.run(
        [sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
