"""Peak memory of dataset generation and of training, each case in a fresh child process.

Writes the section "Memory" of the records (benchmarks/records/).

Every case is one ``canonid`` command run in a child process (``python bench_memory.py --child
ARGS...`` → ``canonid.cli.main(ARGS)``), which reports its own peak resident set size
(``resource.getrusage``, ``ru_maxrss``) and that of its largest finished child process. While it
runs, this script samples the resident memory of the child's whole process tree every 50 ms with
psutil; the peak of that sum is what a multi-process run (a local Dask cluster) holds at once.

Cases (``quick`` / ``full``):

* Generation of the planar-drone dataset, flights run serially in the child process, at two
  sizes: 18 and 54 flights (quick) or 54 and the paper's 540 flights (full), 600 steps each. The
  difference of the peaks divided by the difference of the flights is the memory each extra
  flight costs; compare it with the bytes a flight adds to the dataset.
* The larger size again on a local Dask cluster of 2 worker processes (``--workers 2``).
* Training Ours (MLP) with the ``paper`` profile (batch 32, rollout 100, validation from every
  start, final evaluation on the test split), ℓ = 10, one thread, on the larger drone dataset
  and on the tank dataset, for 1 and for 3 epochs (memory does not depend on the epoch count).

Usage: python benchmarks/bench_memory.py [--size quick|full]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import write_section  # noqa: E402

MIB = 2**20


@dataclass(frozen=True)
class Peak:
    """Peak memory of one case, in MiB, and its wall time in seconds."""

    self_mib: float
    child_mib: float
    tree_mib: float
    seconds: float


def child(argv: list[str], report: Path) -> int:
    """Run ``canonid ARGS`` in this process, then write its peak RSS to ``report`` (JSON)."""
    from canonid.cli import main as canonid_main

    try:
        rc = canonid_main(argv)
    finally:
        # ru_maxrss is in KiB on Linux
        report.write_text(
            json.dumps(
                {
                    "self_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                    "children_kib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
                }
            )
        )
    return rc


def tree_rss(proc: psutil.Process) -> int:
    total = 0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            total += p.memory_info().rss
        except psutil.Error:  # gone between listing and reading
            pass
    return total


def measure(args: list[str]) -> Peak:
    """Run ``canonid ARGS`` in a child process; its peaks (see the module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "peak.json"
        cmd = [sys.executable, __file__, "--child", str(report), "--", *args]
        t0 = time.perf_counter()
        proc = psutil.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        peak = 0
        while proc.poll() is None:
            try:
                peak = max(peak, tree_rss(proc))
            except psutil.Error:
                pass
            time.sleep(0.05)
        seconds = time.perf_counter() - t0
        err = proc.stderr.read().decode() if proc.stderr else ""
        if proc.returncode != 0 or not report.is_file():
            raise RuntimeError(f"`canonid {' '.join(args)}` failed ({proc.returncode}): {err}")
        got = json.loads(report.read_text())
    return Peak(got["self_kib"] / 1024, got["children_kib"] / 1024, peak / MIB, seconds)


def split(n: int) -> list[str]:
    """Train/val/test counts for ``n`` flights in the paper's proportions (500/20/20)."""
    held = max(1, round(n * 20 / 540))
    return ["--n-train", str(n - 2 * held), "--n-val", str(held), "--n-test", str(held)]


def flight_bytes(path: Path) -> float:
    """Bytes of float64 arrays per flight in the dataset at ``path``."""
    with np.load(path / "dataset.npz") as z:  # keys are "split/index/array"
        total = sum(z[k].nbytes for k in z.files)
        flights = len({k.rsplit("/", 1)[0] for k in z.files})
    return total / max(flights, 1)


def main() -> int:
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        return child(sys.argv[4:], Path(sys.argv[2]))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    args = parser.parse_args()
    small, large = (18, 54) if args.size == "quick" else (54, 540)
    rows = [
        "| case | wall s | peak RSS, process MiB | largest child MiB | peak RSS, tree MiB |",
        "|---|---:|---:|---:|---:|",
    ]

    def add(label: str, p: Peak) -> Peak:
        rows.append(
            f"| {label} | {p.seconds:.0f} | {p.self_mib:.0f} | {p.child_mib:.0f} | "
            f"{p.tree_mib:.0f} |"
        )
        return p

    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        data = {n: Path(tmp) / f"drone-{n}" for n in (small, large)}
        gen = {}
        for n, out in data.items():
            gen[n] = add(
                f"generate drone2d, {n} flights × 600, serial",
                measure(["generate", "drone2d", *split(n), "--out", str(out), "--no-progress"]),
            )
        add(
            f"generate drone2d, {large} flights × 600, 2 Dask workers",
            measure(
                [
                    *("generate", "drone2d", *split(large), "--workers", "2", "--no-progress"),
                    *("--out", str(Path(tmp) / "drone-dask")),
                ]
            ),
        )
        per_flight = (gen[large].self_mib - gen[small].self_mib) / (large - small)
        dataset_kib = flight_bytes(data[large]) / 1024
        paper_mib = gen[small].self_mib + per_flight * (540 - small)
        tank = Path(tmp) / "tank"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "canonid",
                "generate",
                "tank",
                "--no-progress",
                "--out",
                str(tank),
            ],
            check=True,
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
        )
        for name, path in ((f"drone2d ({large} flights)", data[large]), ("tank", tank)):
            for epochs in (1, 3):
                train = ["train", str(path), "--model", "mlp", "--window", "10"]
                opts = ["--profile", "paper", "--epochs", str(epochs), "--threads", "1"]
                out = ["--out", str(Path(tmp) / f"run-{path.name}-{epochs}"), "--no-progress"]
                add(
                    f"train Ours (MLP), paper profile, {epochs} epoch(s), {name}",
                    measure([*train, *opts, *out]),
                )
    load1 = os.getloadavg()[0]
    body = "\n\n".join(
        [
            f"Size `{args.size}`; each case in a fresh child process (see the script's "
            f"docstring). Load average {load0:.1f} before, {load1:.1f} after, on 2 cores shared "
            "with other jobs (wall times are not the point here).",
            "\n".join(rows),
            f"Serial generation: each extra flight costs {per_flight * 1024:.0f} KiB of peak RSS "
            f"(({gen[large].self_mib:.0f} − {gen[small].self_mib:.0f}) MiB / "
            f"({large} − {small}) flights), {per_flight * 1024 / dataset_kib:.1f}× the "
            f"{dataset_kib:.0f} KiB of arrays a flight adds to the dataset (the dataset is held "
            "in memory and serialised to bytes in memory before its atomic write). At that "
            f"rate the paper's 540 flights need {paper_mib:.0f} MiB (a linear extrapolation "
            "unless the size is `full`).",
        ]
    )
    write_section("Memory", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
