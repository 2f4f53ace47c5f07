"""Run every benchmark script (``benchmarks/bench_*.py``) in turn; each writes its own section
of its notes (``benchmarks/records/``). ``--size quick`` (default) or ``--size full`` (paper
sizes)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _data import DATASETS, ensure_dataset  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    args = parser.parse_args()
    scripts = sorted(HERE.glob("bench_*.py"))
    if not scripts:
        print("no benchmark scripts found in", HERE)
        return 0
    for name in DATASETS:  # the training benchmarks need them
        ensure_dataset(name)
    failed = []
    for script in scripts:
        print(f"== {script.name} ({args.size})", flush=True)
        rc = subprocess.call([sys.executable, str(script), "--size", args.size])
        if rc != 0:
            failed.append(script.name)
    if failed:
        print("failed:", ", ".join(failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
