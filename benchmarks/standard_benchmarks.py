"""canonid's scores on the field's standard benchmarks → a section of its notes
(``benchmarks/records/``).

Runs ``canonid benchmark NAME ...`` (every argument after NAME is passed on), measures its wall
and CPU time and the load average, and writes the scores beside the published baselines::

    python benchmarks/standard_benchmarks.py silverbox --dir ../shared/data/silverbox

A run already made (timed outside, e.g. with ``/usr/bin/time``) is recorded with
``--record RUN --cpu-seconds S --wall-seconds S --load 'BEFORE / AFTER' --command '...'``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._results import write_section


def _load() -> str:
    return f"{os.getloadavg()[0]:.2f}"


def _screen_line(run: Path) -> str:
    """How the run's model was chosen (its search), or nothing when it was given."""
    from canonid.learning.search import SEARCH_FILE, Search

    if not (run / SEARCH_FILE).is_file():
        return ""
    return f"Model: {Search.read(run).line()}.\n\n"


def _cubic_line(run: Path) -> str:
    """The cubic branch is an axis of the search (:func:`_screen_line` says what it chose)."""
    return ""


def _body(run: Path, cpu: float, wall: float, load: str, earlier: str | None = None) -> str:
    report = json.loads((run / "benchmark.json").read_text())
    recipe = json.loads((run / "run.json").read_text())
    methods: list[str] = []
    for b in report["baselines"]:
        if b["method"] not in methods:
            methods.append(b["method"])
    # each published figure as its source prints it; * marks the lowest on the test part
    published = {
        (b["test"], b["method"]): b.get("figure", f"{b['rmse']:.3f}")
        + ("*" if b.get("best") else "")
        for b in report["baselines"]
    }
    units = report["scores"][0]["units"]
    head = ["test part", "n_init", f"canonid [{units}]", *methods]
    rows = [
        [
            s["test"],
            str(s["n_init"]),
            f"{s['rmse']:.3f}",
            *(published.get((s["test"], m), "") for m in methods),
        ]
        for s in report["scores"]
    ]
    table = "\n".join("| " + " | ".join(r) + " |" for r in [head, ["---"] * len(head), *rows])
    options = recipe["train_options"]
    sources = "; ".join(sorted({b["source"] for b in report["baselines"]})) or "none entered"
    return (
        _screen_line(run)
        + _cubic_line(run)
        + f"{report['title']}: {report['model']}, ℓ = {report['window']}, profile "
        f"{report['profile']} ({options['epochs']} epochs, rollouts up to {options['horizon']} "
        f"steps), seed {options['seed']}; validation: {report['validation']}. Score: simulation "
        f"RMSE of each official test part after its first n_init measured samples "
        f"({report['definition']}). Wall {wall / 60:.1f} min, CPU {cpu / 60:.1f} min (training, "
        f"canonid train's evaluation and the benchmark's scoring); load average before / after: "
        f"{load}.\n\n{table}\n\nPublished baselines: "
        f"{sources}. * the lowest published figure on the test part. Figures: "
        f"`RUN/benchmark-<part>.png`." + (f"\n\n{earlier}" if earlier else "")
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("name", nargs="?", help="benchmark NAME (runs canonid benchmark)")
    parser.add_argument("--record", type=Path, metavar="RUN", help="record a finished run")
    parser.add_argument("--cpu-seconds", type=float)
    parser.add_argument("--wall-seconds", type=float)
    parser.add_argument("--load", help="load average before / after, for --record")
    parser.add_argument("--command", help="the command that made the --record run")
    parser.add_argument("--earlier", help="a sentence on earlier runs, kept under the table")
    args, rest = parser.parse_known_args()
    if args.record is not None:
        if None in (args.cpu_seconds, args.wall_seconds, args.load, args.command):
            parser.error("--record needs --cpu-seconds, --wall-seconds, --load and --command")
        body = _body(args.record, args.cpu_seconds, args.wall_seconds, args.load, args.earlier)
        write_section("Standard benchmarks", body, command=args.command)
        return 0
    if args.name is None:
        parser.error("give a benchmark NAME or --record RUN")
    out = Path("runs") / f"bench-{args.name}"
    quiet = [] if "--no-progress" in rest else ["--no-progress"]
    cmd = ["canonid", "benchmark", args.name, "--out", str(out), *quiet, *rest]
    before, start = _load(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "canonid", *cmd[1:]], check=True)
    wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    load = f"{before} / {_load()}"
    body = _body(out, usage.ru_utime + usage.ru_stime, wall, load, args.earlier)
    write_section("Standard benchmarks", body, command=" ".join(cmd))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
