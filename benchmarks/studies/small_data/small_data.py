"""Small data: Silverbox's official training part cut to its first 1,000 / 3,000 / 10,000
samples, canonid's defaults beside deepSI's SUBNET with its defaults, scored by the official
Silverbox rule on the official test parts.

Writes the section "Small data" of the records (benchmarks/records/) (issue 27, "Must show:
Small data").

* Data: ``canonid.datagen.benchmarks.load_benchmark("silverbox", DIR)``; its training part
  ("multisine-train", samples 40,650 … 105,711 of the record) is cut to its first N samples
  (:func:`cut`) and split as ``canonid benchmark`` splits it
  (``split_train_val(..., val_fraction=0.2, record_tails=True)``: the last 20 % of the cut
  validates); the official test parts are kept. Saved to ``runs/small-data/data/nN``.
* Contestants, each in its own child process with one torch thread, CPU time of the child
  (user + system, from ``getrusage``) recorded:

  - ``canonid train DATA --threads 1``: canonid's defaults (Ours (MLP), the quick profile, the
    window chosen by the screen on validation); the run also scores the test parts itself
    (``metrics.json``), inside the CPU time;
  - deepSI 0.4.4's SUBNET with its defaults (``benchmarks/_deepsi.py``) for
    bench_overflow_tanks.py's ``DEEPSI_ITERATIONS`` iterations (5,000), and in extra jobs
    (``deepsi-long-nN``, not run by default) for :data:`DEEPSI_LONG`, about canonid's CPU time.

* Score: the official rule, :func:`canonid.benchmark.score_parts` for both (deepSI's SUBNET
  behind the same ``predict``): simulation of each test part from its whole input after
  n_init = 50 measured outputs, RMSE over samples 50… in mV. Nothing is chosen on test.
* What the defaults lack at 1,000 samples, on validation only: Ours (MLP) at ℓ = 10 and with one
  change each (:data:`VARIANTS`); the test score is read only for the run the validation loss
  picks, after it picked it.

Every job writes its CPU time (and the load before and after it) to ``runs/small-data/cpu``;
``--record`` writes the section again from the runs without training; ``--only JOB,...`` trains
those jobs alone (a size, e.g. ``1000``, stands for canonid's and deepSI's run on it,
``diagnosis`` for the variants, any other name is one job's: ``n1000``, ``deepsi-long-n3000``,
``diag-l20``, …) and keeps the others' runs; two such processes may run side by side.

Usage: python benchmarks/studies/small_data/small_data.py [--only JOB,...] [--record] [--dir
SILVERBOX_DIR]
(without ``--only``: every job but the deepsi-long ones, one after the other, about 55
CPU-minutes; the deepsi-long ones add about 19)
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _data import VAL_FRACTION, cut  # noqa: E402
from _results import load_line, publish  # noqa: E402
from bench_overflow_tanks import DEEPSI_ITERATIONS, Validation, child_cpu, validation  # noqa: E402

from canonid.kernel.io import atomic_write_json  # noqa: E402

SECTION = "Small data"
BENCHMARK = "silverbox"
DEFAULT_DIR = ROOT.parent / "shared" / "data" / "silverbox"
RUNS = ROOT / "runs" / "small-data"
SIZES = (1000, 3000, 10000)
#: the issue's targets: multisine test RMSE [mV] per size
TARGETS = {1000: 0.80, 3000: 0.45, 10000: 0.35}
TESTS = ("multisine", "arrow-no-extrapolation", "arrow-full")
#: the diagnosis, read on validation only: Ours (MLP) at ℓ = 10 with one change each
DIAGNOSIS_SIZE = 1000
VARIANTS = {
    "ℓ = 10": ("l10", ["--window", "10"]),
    "ℓ = 20": ("l20", ["--window", "20"]),
    "hidden 64 × 64 × 64": ("h64", ["--window", "10", "--hidden", "64,64,64"]),
    "learning rate 1e-3": ("lr1e-3", ["--window", "10", "--lr", "1e-3"]),
}
#: deepSI's iterations at about the CPU time of canonid's defaults (an extra job: the runs of
#: DEEPSI_ITERATIONS found their best model at or near their last validation on 10,000 samples)
DEEPSI_LONG = 12500


def data_path(samples: int) -> Path:
    return RUNS / "data" / f"n{samples}" / "dataset.npz"


def prepare(samples: int, directory: Path) -> Path:
    """The cut dataset of ``samples`` samples (written once)."""
    from canonid.datagen.benchmarks import load_benchmark

    path = data_path(samples)
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        cut(load_benchmark(BENCHMARK, directory), samples).save(path)
    return path


# ---------------------------------------------------------------------------------- jobs
@dataclass(frozen=True)
class Job:
    """One training: ``kind`` "canonid" (``canonid train`` with ``extra`` arguments) or
    "deepsi" (``iterations`` of ``deepSI.fit``), on the cut of ``samples`` samples."""

    kind: str
    samples: int
    extra: tuple[str, ...] = ()
    iterations: int = 0


def jobs() -> dict[str, Job]:
    """Every job by name (its run folder's or score file's name)."""
    found: dict[str, Job] = {}
    for n in SIZES:
        found[f"n{n}"] = Job("canonid", n)
        found[f"deepsi-n{n}"] = Job("deepsi", n, iterations=DEEPSI_ITERATIONS)
        found[f"deepsi-long-n{n}"] = Job("deepsi", n, iterations=DEEPSI_LONG)
    for folder, extra in VARIANTS.values():
        found[f"diag-{folder}"] = Job("canonid", DIAGNOSIS_SIZE, tuple(extra))
    return found


def expand(names: str) -> list[str]:
    """``--only``'s list: a size stands for its two contestants (canonid's and deepSI's
    defaults), ``diagnosis`` for the variants; any other name is a job's."""
    known, out = jobs(), []
    for name in names.split(","):
        if name.isdigit() and int(name) in SIZES:
            out += [f"n{name}", f"deepsi-n{name}"]
        elif name == "diagnosis":
            out += [f"diag-{folder}" for folder, _ in VARIANTS.values()]
        elif name in known:
            out.append(name)
        else:
            allowed = ", ".join([*map(str, SIZES), "diagnosis", *known])
            raise SystemExit(f"unknown job {name!r}: one of {allowed}")
    return out


def run_job(name: str, directory: Path) -> None:
    """Train job ``name``; its CPU seconds, wall seconds and the load before and after it go
    to ``RUNS/cpu/NAME.json``."""
    job = jobs()[name]
    data = prepare(job.samples, directory)
    load0, start = os.getloadavg()[0], time.perf_counter()
    if job.kind == "canonid":
        out = RUNS / name
        cmd = [sys.executable, "-m", "canonid", "train", str(data), *job.extra]
        cpu = child_cpu([*cmd, "--threads", "1", "--no-progress", "--out", str(out)])
    else:
        me = [sys.executable, __file__, "--deepsi-child", name]
        cpu = child_cpu([*me, "--deepsi-iterations", str(job.iterations)])
    wall = time.perf_counter() - start
    atomic_write_json(
        RUNS / "cpu" / f"{name}.json",
        {"cpu_s": cpu, "wall_s": wall, "load": [load0, os.getloadavg()[0]]},
    )


@dataclass(frozen=True)
class Scores:
    """Official RMSE [mV] per test part, the window and where the model was best."""

    rmse: dict[str, float]
    window: int
    best: str


def official(model: Any, samples: int) -> dict[str, float]:
    """The official Silverbox scores of ``model`` on the cut dataset's test parts."""
    from canonid.benchmark import score_parts
    from canonid.datagen.benchmarks import benchmark
    from canonid.kernel.dataset import Dataset

    parts, _ = score_parts(model, Dataset.load(data_path(samples)), benchmark(BENCHMARK))
    return {p.test: p.rmse for p in parts}


def deepsi_child(name: str, iterations: int) -> int:
    """Train deepSI's SUBNET of job ``name`` (this process) and write its scores."""
    from _deepsi import fit_subnet

    from canonid.kernel.dataset import Dataset

    samples = jobs()[name].samples
    ds = Dataset.load(data_path(samples))
    found = fit_subnet(ds.split("train"), ds.split("val"), iterations)
    best = f"iteration {found.at} of {iterations}"
    result = Scores(official(found.model, samples), found.model.window, best)
    atomic_write_json(RUNS / "scores" / f"{name}.json", asdict(result))
    return 0


def canonid_scores(name: str) -> Scores:
    """The official scores of canonid job ``name``'s model (computed once per training, then
    read from ``RUNS/scores``; a run trained again after its scores were kept is scored again)."""
    from canonid.learning import Model

    path = RUNS / "scores" / f"{name}.json"
    weights = RUNS / name / "weights.pt"
    if not path.is_file() or weights.stat().st_mtime > path.stat().st_mtime:
        run, samples = RUNS / name, jobs()[name].samples
        model, v = Model.load(run), validation(run)
        found = Scores(official(model, samples), model.window, f"{v.epoch} of {v.last}")
        atomic_write_json(path, asdict(found))
    return Scores(**json.loads(path.read_text()))


# ---------------------------------------------------------------------------------- report
def done(name: str) -> bool:
    return (RUNS / "cpu" / f"{name}.json").is_file()


def cpu_of(name: str) -> dict[str, Any]:
    return json.loads((RUNS / "cpu" / f"{name}.json").read_text())


def screen(name: str) -> str:
    """What the search chose for run ``name``, with its validation losses."""
    from canonid.learning.search import Search

    return Search.read(RUNS / name).line()


def mv(value: float | None) -> str:
    return "–" if value is None or math.isnan(value) else f"{value:.3f}"


def deepsi_scores(name: str) -> Scores | None:
    """deepSI job ``name``'s scores, None when it has not run."""
    if not done(name):
        return None
    return Scores(**json.loads((RUNS / "scores" / f"{name}.json").read_text()))


def size_label(n: int) -> str:
    """``N (training / validation)`` as :func:`cut` splits it."""
    n_train = int((1 - VAL_FRACTION) * n)
    return f"{n:,} ({n_train:,} / {n - n_train:,})"


def three(found: Scores) -> str:
    """The three official scores as table cells, multisine first."""
    return " | ".join(mv(found.rmse[t]) for t in TESTS)


def size_row(n: int) -> str:
    """One size's row: canonid's defaults, deepSI's defaults, the target."""
    ours, theirs = canonid_scores(f"n{n}") if done(f"n{n}") else None, deepsi_scores(f"deepsi-n{n}")
    cells = [size_label(n)]
    if ours is None:
        cells += ["not run", "", "", "", "", ""]
    else:
        cpu = cpu_of(f"n{n}")["cpu_s"]
        cells += [str(ours.window), ours.best, three(ours), f"{cpu:.0f}"]
    if theirs is None:
        cells += ["not run", "", "", "", ""]
    else:
        cpu = cpu_of(f"deepsi-n{n}")["cpu_s"]
        cells += [three(theirs), theirs.best, f"{cpu:.0f}"]
    target = TARGETS[n]
    if ours is None:
        cells.append(f"≤ {target:.2f}")
    else:
        holds = ours.rmse["multisine"] <= target
        cells.append(f"≤ {target:.2f}: {'**holds**' if holds else 'does not hold'}")
    return "| " + " | ".join(cells) + " |"


def long_rows() -> list[str]:
    """deepSI with about canonid's CPU time, per size that ran."""
    rows = []
    for n in SIZES:
        found = deepsi_scores(f"deepsi-long-n{n}")
        if found is not None:
            cpu = cpu_of(f"deepsi-long-n{n}")["cpu_s"]
            rows.append(f"| {size_label(n)} | {three(found)} | {found.best} | {cpu:.0f} |")
    if not rows:
        return []
    ats = [
        int(found.best.split()[1])
        for n in SIZES
        if (found := deepsi_scores(f"deepsi-n{n}")) is not None
    ]
    return [
        f"deepSI given about canonid's CPU time ({DEEPSI_LONG:,} iterations, otherwise the same; "
        f"an extra table, not deepSI's defaults: its runs of {DEEPSI_ITERATIONS:,} iterations "
        f"kept models of iterations {min(ats):,} … {max(ats):,}, still improving):",
        "",
        "| size (training / validation) | multisine [mV] | arrow no-extrap. [mV] | arrow full "
        "[mV] | best at | CPU s |",
        "|---|---:|---:|---:|---|---:|",
        *rows,
        "",
    ]


def ratios() -> list[str]:
    """deepSI's multisine RMSE over canonid's, per size where both ran."""
    found = []
    for n in SIZES:
        theirs = deepsi_scores(f"deepsi-n{n}")
        if done(f"n{n}") and theirs is not None:
            ratio = theirs.rmse["multisine"] / canonid_scores(f"n{n}").rmse["multisine"]
            found.append(f"{n:,}: {ratio:.2f}×")
    if not found:
        return []
    return [f"deepSI's multisine RMSE over canonid's: {'; '.join(found)}.", ""]


def record() -> int:
    """Write the section from the runs that finished."""
    from canonid.datagen.benchmarks import benchmark

    bench = benchmark(BENCHMARK)
    ran = [name for name in jobs() if done(name)]
    missing = [
        name for name in jobs() if not done(name) and not name.startswith(("diag-", "deepsi-long"))
    ]
    screens = [f"{n:,} samples: ℓ = {screen(f'n{n}')}" for n in SIZES if done(f"n{n}")]
    published = [
        f"{b.method} {b.figure} mV"
        for b in sorted(bench.baselines, key=lambda b: b.rmse)
        if b.test == "multisine"
    ][:3]
    flat = [v for name in ran for v in cpu_of(name)["load"]]
    sentence, _ = load_line(
        flat or [os.getloadavg()[0]],
        "other sessions' jobs ran beside these; CPU times of one thread are less affected than "
        "wall times, but see the row ℓ = 10 below",
        own=[2] * len(flat) if flat else None,
    )
    lines = [
        'Silverbox\'s official training part (`load_benchmark("silverbox", DIR)`, '
        '"multisine-train", samples 40,650 … 105,711 of the record) cut to its first N '
        "samples; the last 20 % of the cut validates (`split_train_val(..., val_fraction=0.2, "
        "record_tails=True)`, as `canonid benchmark` splits); the official test parts are "
        "kept. Scores: the official rule (`canonid.benchmark.score_parts` for both; simulation "
        f"of the whole test part after n_init = {bench.n_init} measured outputs, RMSE over "
        "samples 50… in mV). Every contestant runs with its defaults in its own child process "
        "with one torch thread and keeps its best model on the validation part; nothing is "
        "chosen on test. CPU: the whole child process (user + system; canonid's includes its "
        "window screen and its own evaluation of the test parts).",
        "",
        "canonid: `python -m canonid train DATA --threads 1 --no-progress` (no `--window`: "
        "the screen chooses it). deepSI 0.4.4: `SUBNET(n_u, n_y, norm)` with its defaults "
        f"(na = nb = 20), `deepSI.fit` for {DEEPSI_ITERATIONS:,} iterations (the number "
        "bench_overflow_tanks.py gives it; `fit` has no default), torch seed 0.",
        "",
        "| size (training / validation) | canonid: window | best epoch of last | multisine "
        "[mV] | arrow no-extrap. [mV] | arrow full [mV] | CPU s | deepSI: multisine [mV] | "
        "deepSI: arrow no-extrap. [mV] | deepSI: arrow full [mV] | best at | CPU s | "
        "issue's target (canonid, multisine) |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---|",
        *[size_row(n) for n in SIZES],
        "",
        *ratios(),
        "Best published on the multisine test part, trained on the whole training part "
        f"(`canonid.datagen.benchmarks` baselines): {'; '.join(published)}.",
        "",
        *long_rows(),
        "The window screen's choice and its best validation loss per window (normalised): "
        + ("; ".join(screens) if screens else "none yet")
        + ".",
        "",
        cubic_line(),
        "",
        sentence,
    ]
    if missing:
        lines += ["", f"Not run (yet): {', '.join(missing)}."]
    lines += ["", *diagnosis()]
    ran = [j for j in jobs() if done(j)]
    lines += [
        "",
        f"{len(ran)} jobs, two at a time (`--only`, two processes), some trained again later; "
        "the time below is the sum of the jobs' wall times.",
    ]
    return publish(SECTION, lines, sum(cpu_of(j)["wall_s"] for j in ran) / 60)


def cubic_line() -> str:
    """The cubic branch is an axis of the search: what it chose on each cut."""
    from canonid.learning.search import Search

    told = [
        f"{n:,} samples: {Search.read(RUNS / f'n{n}').chosen}"
        for n in SIZES
        if (RUNS / f"n{n}" / "search.json").is_file()
    ]
    return "; ".join(told)


def losses(run: Path) -> list[tuple[str, str, str]]:
    """(epoch, training loss, validation loss) of every row of ``run``'s history."""
    with (run / "history.csv").open() as f:
        return [(r["epoch"], r["train_loss"], r["val_loss"]) for r in csv.DictReader(f)]


def same_training(ran: dict[str, str]) -> str:
    """When the defaults chose ℓ = 10 at the diagnosis size, the row ℓ = 10 is their training
    again (the same seed): a sentence saying so and what the load did to its CPU time."""
    name, fixed = f"n{DIAGNOSIS_SIZE}", ran.get("ℓ = 10")
    if fixed is None or not done(name):
        return ""
    screened = json.loads((RUNS / name / "window-screen.json").read_text())
    if screened["chosen"] != 10 or losses(RUNS / name) != losses(RUNS / fixed):
        return ""
    screen_cpu = sum(c["cpu_seconds"] for c in screened["candidates"])
    after, here = cpu_of(name), cpu_of(fixed)
    return (
        f" The defaults chose ℓ = 10 at {DIAGNOSIS_SIZE:,} samples: the row ℓ = 10 is their "
        "training again (the same seed, the same losses at every epoch). Its CPU time shows what "
        f"the load does to the same work: {after['cpu_s'] - screen_cpu:.0f} s in the defaults' "
        f"run after its {screen_cpu:.0f}-s screen (load {after['load'][0]:.2f} at its start), "
        f"{here['cpu_s']:.0f} s here (load {here['load'][0]:.2f})."
    )


def weight_decay_of(run: Path) -> float:
    """The Adam weight decay a run trained with (recorded in its ``config.json``)."""
    config = json.loads((run / "config.json").read_text())
    return float(config["info"]["training"]["options"]["weight_decay"])


def other_weight_decay(ran: dict[str, str]) -> str:
    """A sentence when these runs trained with another weight decay than the defaults' run at
    the diagnosis size (they predate the default they would get now)."""
    name = f"n{DIAGNOSIS_SIZE}"
    if not done(name):
        return ""
    now = weight_decay_of(RUNS / name)
    then = sorted({weight_decay_of(RUNS / r) for r in ran.values()} - {now})
    if not then:
        return ""
    return (
        f" These runs trained with Adam weight decay {', '.join(f'{w:g}' for w in then)}, "
        f"before the defaults' run above, which used {now:g} (section \"Weight decay on small "
        'records"); they compare the changes with one another, not with that run.'
    )


def diagnosis() -> list[str]:
    """The validation-only look at 1,000 samples (the test score is read only for the run the
    validation loss picks, after it picked it)."""
    names = {label: f"diag-{folder}" for label, (folder, _) in VARIANTS.items()}
    ran = {label: name for label, name in names.items() if done(name)}
    if not ran:
        return ["### What the defaults lack at 1,000 samples: validation only", "", "Not run."]
    found: dict[str, Validation] = {label: validation(RUNS / name) for label, name in ran.items()}
    rows = [
        f"| {label} | {v.best:.3e} | {v.epoch} | {v.train_at_best:.3e} | {v.last} | "
        f"{v.val_last:.3e} | {v.train_last:.3e} | {cpu_of(ran[label])['cpu_s']:.0f} |"
        for label, v in found.items()
    ]
    lines = [
        "### What the defaults lack at 1,000 samples: validation only",
        "",
        "Ours (MLP) at ℓ = 10 and the same with one change (`canonid train DATA --window 10 "
        "--threads 1` plus the change, or `--window 20`), on the 1,000-sample cut. Losses are "
        "canonid's validation loss (100-step rollouts on the 200 validation samples) and the "
        "training loss (the epoch's rollouts), both normalised by the training output variance; "
        "each run keeps its best epoch on validation. (`canonid train` also writes its own test "
        "metrics into every run folder and its log; this script does not read them.)"
        + same_training(ran)
        + other_weight_decay(ran),
        "",
        "| run | best validation loss | at epoch | training loss there | last epoch | validation "
        "loss, last | training loss, last | CPU s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
        *rows,
    ]
    missing = [label for label in names if label not in ran]
    if missing:
        lines += ["", f"Not run (yet): {', '.join(missing)}; no choice is made without them."]
        return lines
    base = found.get("ℓ = 10")
    if base is not None:
        ratios = [f"{k} {v.best / base.best:.2f}×" for k, v in found.items() if k != "ℓ = 10"]
        lines += ["", f"Best validation loss against ℓ = 10's: {'; '.join(ratios)}."]
    chosen = min(found, key=lambda k: found[k].best)
    picked = canonid_scores(ran[chosen])
    return [
        *lines,
        "",
        f"Chosen on validation: **{chosen}**; its official test RMSE, read once after the "
        f"choice: multisine {mv(picked.rmse['multisine'])} mV, arrow no-extrapolation "
        f"{mv(picked.rmse['arrow-no-extrapolation'])} mV, arrow full "
        f"{mv(picked.rmse['arrow-full'])} mV.",
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dir", type=Path, default=DEFAULT_DIR, help="Silverbox's files")
    parser.add_argument("--deepsi-iterations", type=int, help=argparse.SUPPRESS)
    parser.add_argument(
        "--record",
        action="store_true",
        help=f"write the section from the runs in {RUNS.relative_to(ROOT)} (no training)",
    )
    parser.add_argument(
        "--only",
        help="train these jobs alone (comma-separated: a size, 'diagnosis' or a job's name); "
        "the others' runs are kept",
    )
    parser.add_argument("--deepsi-child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.deepsi_child is not None:
        return deepsi_child(args.deepsi_child, args.deepsi_iterations)
    if not args.record:
        every = [name for name in jobs() if not name.startswith("deepsi-long")]
        for name in expand(args.only) if args.only else every:
            run_job(name, args.dir)
        if args.only:  # a few jobs: the section keeps the others' rows until --record is asked
            print("trained; `python small_data.py --record` writes the section from every job")
            return 0
    return record()


if __name__ == "__main__":
    raise SystemExit(main())
