"""How often the cubic test decides the same way when only the seed changes, and which rule
makes its decision stable — on validation data only.

``canonid.learning.extrapolation.cubic_test`` trains the plain network and the one with a cubic
branch on the training part's held-out peaks for the window screen's share of the epochs, and
keeps the branch when its best held-out loss is at most ``CUBIC_GAIN`` × the plain one's. On
Silverbox one pair of such trainings gave ratios from 0.35 to 1.03 over four seeds
(RESULTS.md, "Extrapolation"), around the 0.8 threshold. This study trains each *arm* (plain,
cubic) of the test separately for many seeds, on each study system's usual training part at the
window the defaults chose there, exactly as the test does (same split, options and feedthrough
decision), and records each arm's best held-out loss. Rules that pool k seeds per arm are then
scored offline from those numbers: for every k and every way of choosing k of the seeds, the
decision the rule takes; a rule is stable when that decision hardly depends on which seeds it saw.

The held-out peaks come from the training part; the validation and test parts play no part.

Usage: python cubic_seeds.py run --out FILE [--jobs N] [--deadline S] [--plan NAME]
       python cubic_seeds.py record FILE [FILE ...]

``run`` writes one JSON line per finished arm to FILE (appended as each ends, so a deadline keeps
what finished); it reads the study data of ``extrapolation_study.py prepare``. ``record`` merges
the files into :data:`STUDY_FILE` and writes the section of RESULTS.md.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _data import STUDY_SYSTEMS  # noqa: E402

STUDY_FILE = ROOT / "benchmarks" / "studies" / "cubic_seeds.json"
SECTION = "Cubic test across seeds"
#: plan → [(system, seeds, screen fraction)]: the arms ``run`` trains, in this order
PLANS: dict[str, list[tuple[str, range, float | None]]] = {
    "device": [
        ("silverbox", range(16), None),
        ("tank", range(8), None),
        ("masses", range(8), None),
        ("silverbox-3k", range(8), None),
        ("silverbox-10k", range(8), None),
        ("drone2d", range(8), None),
        ("silverbox", range(8), 0.2),
    ],
    "smoke": [("silverbox-3k", range(1), None)],
}
#: the arms' cubic units: the plain network and the test's branch
ARMS = (0, 16)


def arm(system: str, seed: int, units: int, fraction: float | None) -> dict[str, Any]:
    """One arm of the cubic test on ``system`` with ``seed``: the same split, options and
    feedthrough decision as ``cubic_test`` inside ``canonid train`` (``fraction`` replaces the
    window screen's share of the epochs when given)."""
    import torch
    from extrapolation_study import usual_setup

    from canonid.learning.extrapolation import held_out_peaks
    from canonid.learning.training import fit
    from canonid.learning.window_screen import SCREEN_FRACTION, screen_options
    from canonid.profiles import train_options

    torch.set_num_threads(1)
    train, _, window, nets = usual_setup(system)
    share = SCREEN_FRACTION if fraction is None else fraction
    opts = screen_options(train_options("quick", device="cpu", seed=seed), share)
    longest = max(opts.horizon, opts.rollout_horizon)
    split = held_out_peaks(train, window=window, horizon=longest, val_horizon=opts.rollout_horizon)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    result = fit(
        split.train,
        split.val,
        model="mlp",
        window=window,
        options=opts,
        net_options={**nets, "cubic": units},
    )
    loss = result.best_val_loss
    return {
        "system": system,
        "seed": seed,
        "units": units,
        "fraction": share,
        "epochs": opts.epochs,
        "best_val_loss": loss if math.isfinite(loss) else None,
        "best_epoch": result.best_epoch,
        "val_history": [
            [h["epoch"], h["val_loss"]] for h in result.history if h.get("val_loss") is not None
        ],
        "cpu_s": time.process_time() - cpu0,
        "wall_s": time.perf_counter() - wall0,
    }


def run(out: Path, jobs: int, deadline: float, plan: str) -> None:
    """Train every arm of ``plan`` in ``jobs`` processes of one thread each; launch none after
    ``deadline`` seconds and stop those still running at 1.2 × ``deadline``."""
    todo = [
        (system, seed, units, fraction)
        for system, seeds, fraction in PLANS[plan]
        for seed in seeds
        for units in ARMS
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("a") as f:
        f.write(json.dumps({"meta": _machine(), "plan": plan, "jobs": jobs}) + "\n")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    start, running = time.monotonic(), []
    while todo or running:
        running = [p for p in running if p.poll() is None]
        elapsed = time.monotonic() - start
        if elapsed > 1.2 * deadline:
            for p in running:
                p.kill()
            print(f"stopped {len(running)} arm(s) at the deadline; {len(todo)} not started")
            return
        while todo and len(running) < jobs and elapsed < deadline:
            system, seed, units, fraction = todo.pop(0)
            cmd = [sys.executable, __file__, "arm", system, str(seed), str(units), str(out)]
            if fraction is not None:
                cmd += ["--fraction", str(fraction)]
            running.append(subprocess.Popen(cmd, env=env))
        if elapsed >= deadline and not running:
            break
        time.sleep(0.5)
    print(f"{len(todo)} arm(s) not started", flush=True)


def _machine() -> dict[str, Any]:
    import torch

    cpu = platform.processor()
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            cpu = line.split(":", 1)[1].strip()
            break
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "torch": torch.__version__,
        "python": platform.python_version(),
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }


# ------------------------------------------------------------------------------ the rules
def load(files: list[Path]) -> tuple[list[dict], list[dict]]:
    """The arms and the machine lines of ``files`` (a later arm of the same system, seed,
    units and fraction replaces an earlier one)."""
    arms: dict[tuple, dict] = {}
    machines = []
    for file in files:
        for line in file.read_text().splitlines():
            row = json.loads(line)
            if "meta" in row:
                machines.append(row)
            else:
                arms[(row["system"], row["seed"], row["units"], row["fraction"])] = row
    return list(arms.values()), machines


def pairs(arms: list[dict], system: str, fraction: float) -> dict[int, tuple[float, float]]:
    """seed → (plain, cubic) best held-out losses where both arms finished with a finite loss."""
    by = {
        (a["seed"], a["units"]): a["best_val_loss"]
        for a in arms
        if a["system"] == system and a["fraction"] == fraction
    }
    return {
        seed: (by[(seed, 0)], by[(seed, ARMS[1])])
        for seed in sorted({s for s, _ in by})
        if by.get((seed, 0)) is not None and by.get((seed, ARMS[1])) is not None
    }


def keeps(chosen: list[tuple[float, float]], gain: float, pool: str) -> bool:
    """The decision of a rule that pools the seeds ``chosen`` per arm: ``mean`` compares the
    arms' geometric mean losses, ``min`` their best losses."""
    plain = np.array([p for p, _ in chosen])
    cubic = np.array([c for _, c in chosen])
    if pool == "min":
        return bool(cubic.min() <= gain * plain.min())
    return bool(np.exp(np.log(cubic).mean()) <= gain * np.exp(np.log(plain).mean()))


def agreement(found: dict[int, tuple[float, float]], k: int, gain: float, pool: str) -> float:
    """The share of the k-subsets of the seeds on which the rule keeps the branch."""
    subsets = list(itertools.combinations(sorted(found), k))
    return sum(keeps([found[s] for s in sub], gain, pool) for sub in subsets) / len(subsets)


#: the rules ``record`` compares: (pool, seeds per arm); ("min", 1) is the test before this study
RULES = (("min", 1), ("min", 2), ("min", 3), ("mean", 3), ("mean", 4))
#: the systems in the order of the section's tables
ORDER = ("silverbox", "silverbox-10k", "silverbox-3k", "masses", "tank", "drone2d")


def full_run_verdicts() -> dict[str, bool]:
    """system → whether the cubic branch ended below the plain network on the held-out peaks in
    the full runs of ``extrapolation_study.py`` (by the last epoch both reached)."""
    study = json.loads((ROOT / "benchmarks" / "studies" / "extrapolation_study.json").read_text())
    out = {}
    for system in {r["system"] for r in study["records"]}:
        runs = {r["variant"]: r["history"] for r in study["records"] if r["system"] == system}
        if not system.endswith("-x") or not {"default", "cubic16"} <= set(runs):
            continue
        last = min(runs[v][-1][0] for v in ("default", "cubic16"))
        best = [min(h[1] for h in runs[v] if h[0] <= last) for v in ("default", "cubic16")]
        out[system.removesuffix("-x")] = best[1] < best[0]
    return out


def render(arms: list[dict], machines: list[dict]) -> str:
    from canonid.learning.extrapolation import CUBIC_GAIN, CUBIC_MARGIN, CUBIC_SEEDS, CUBIC_UNITS

    verdicts = full_run_verdicts()
    screen = min(a["fraction"] for a in arms)
    where = "; ".join(
        f"{m['meta']['cpu']} ({m['meta']['cores']} cores, torch {m['meta']['torch']}, "
        f"{m['jobs']} arms at a time, one thread each, {m['meta']['date']})"
        for m in machines
    )
    lines = [
        "Whether canonid's cubic test (`canonid.learning.extrapolation.cubic_test`: the plain "
        f"network against one with {CUBIC_UNITS} cubic units, each trained briefly on the "
        "training part's held-out peaks) decides the same way when only the seed changes "
        "(`benchmarks/cubic_seeds.py`; every number is in `benchmarks/studies/cubic_seeds.json`). "
        "Each arm of the test was trained on its own from seeds 0, 1, … exactly as `canonid "
        "train` runs it (the quick profile compressed to the window screen's share, "
        f"{screen:g} of the epochs; the window and the feedthrough decision of the defaults on "
        "each system's usual training part). Only the training part was read: the held-out "
        "peaks are its largest excursions; validation and test parts played no part. "
        f"Machine: {where}; there `python cubic_seeds.py run --out FILE --jobs 16 --deadline "
        "380` (plan `device`: the arms of the table below in its order, then Silverbox at twice "
        "the share, until the deadline).",
        "",
        "Each seed's ratio, cubic branch / plain network, of the best held-out loss (the "
        f"branch is kept at {CUBIC_GAIN:g} or below). The full runs' verdict: which of the two "
        "ended lower on the same held-out peaks when trained for the whole budget (section "
        '"Extrapolation", read by the last epoch both reached).',
        "",
        "| system | seeds | ratio per seed | median | full runs' verdict | CPU s per arm |",
        "|---|---:|---|---:|---|---:|",
    ]
    found = {system: pairs(arms, system, screen) for system in ORDER}
    for system in ORDER:
        got = found[system]
        ratios = [c / p for p, c in got.values()]
        cpu = [a["cpu_s"] for a in arms if a["system"] == system and a["fraction"] == screen]
        verdict = {True: "branch", False: "plain network", None: "-"}[verdicts.get(system)]
        lines.append(
            f"| {system} | {len(got)} | {' '.join(f'{r:.2f}' for r in ratios)} | "
            f"{float(np.median(ratios)):.2f} | {verdict} | {float(np.mean(cpu)):.0f} |"
        )
    lines += [
        "",
        "How often a rule keeps the branch, over every choice of k of the seeds above (k seeds "
        "per arm, the same seeds for both arms): `min` compares the arms' best losses, `mean` "
        f"their geometric means; the threshold is {CUBIC_GAIN:g} throughout. A stable rule "
        "gives 0 or 1; the cost is k times that of one pair of short trainings.",
        "",
        "| system | full runs' verdict | " + " | ".join(f"{p}, k = {k}" for p, k in RULES) + " |",
        "|---|---|" + "---:|" * len(RULES),
    ]
    worst = dict.fromkeys(RULES, 1.0)
    for system in ORDER:
        verdict = verdicts.get(system)
        shares = [agreement(found[system], k, CUBIC_GAIN, pool) for pool, k in RULES]
        for rule, share in zip(RULES, shares, strict=True):
            if verdict is not None:
                worst[rule] = min(worst[rule], share if verdict else 1 - share)
        label = {True: "branch", False: "plain network", None: "-"}[verdict]
        lines.append(f"| {system} | {label} | " + " | ".join(f"{v:.2f}" for v in shares) + " |")
    lines.append(
        "| **agreeing with the verdict, worst system** | | "
        + " | ".join(f"**{worst[r]:.2f}**" for r in RULES)
        + " |"
    )
    longer = [a for a in arms if a["fraction"] != screen]
    if longer:
        got = {f: pairs(arms, "silverbox", f) for f in sorted({a["fraction"] for a in longer})}
        lines += [
            "",
            "Longer short trainings instead of more seeds (Silverbox, the same arms at another "
            "share of the epochs; the deadline stopped the rest): "
            + "; ".join(
                f"{f:g} of the epochs, seed(s) {', '.join(map(str, g))}: ratio "
                + ", ".join(f"{c / p:.2f}" for p, c in g.values())
                for f, g in got.items()
            )
            + ".",
        ]
    lines += [
        "",
        f"The first pair deciding alone when it is far from the threshold (canonid's rule: up to "
        f"{CUBIC_SEEDS} seeds, in order; a first ratio at or beyond margin × {CUBIC_GAIN:g}, or "
        f"{CUBIC_GAIN:g} / margin, decides at once): share of ordered seed choices that keep the "
        "branch, and pairs of short trainings per test.",
        "",
        "| system | full runs' verdict | "
        + " | ".join("never" if m is None else f"margin {m:g}" for m in MARGINS)
        + " |",
        "|---|---|" + "---:|" * len(MARGINS),
    ]
    # per margin, the systems on which it agrees with the verdict less often than "never" does
    behind: dict[float | None, list[str]] = {m: [] for m in MARGINS}
    for system in ORDER:
        verdict = verdicts.get(system)
        cells = []
        results = {m: sequential(found[system], m, CUBIC_GAIN, CUBIC_SEEDS) for m in MARGINS}
        for m, (share, cost) in results.items():
            if verdict is not None and (share if verdict else 1 - share) < (
                results[None][0] if verdict else 1 - results[None][0]
            ):
                behind[m].append(system)
            cells.append(f"{share:.2f} ({cost:.2f} pairs)")
        label = {True: "branch", False: "plain network", None: "-"}[verdict]
        lines.append(f"| {system} | {label} | " + " | ".join(cells) + " |")
    lines.append(
        "| **agreeing less often than the best of three** | | "
        + " | ".join(", ".join(behind[m]) or "none" for m in MARGINS)
        + " |"
    )
    chosen = ("min", CUBIC_SEEDS)
    lines += [
        "",
        f"Chosen (on these held-out peaks, validation only): each arm trains from up to "
        f"{CUBIC_SEEDS} seeds (the run's and the next ones) and keeps its best loss; the branch "
        f"stays when its best is at most {CUBIC_GAIN:g} × the plain network's best "
        "(`canonid.learning.extrapolation.CUBIC_SEEDS`). The best of three agrees with the full "
        f"runs' verdict on every system in at least {worst[chosen]:.0%} of the seed triples, "
        f"against {worst[('min', 1)]:.0%} for one seed; the cheapest number of seeds that agrees "
        "at least 90 % of the time on every system. A first pair whose ratio is "
        f"{CUBIC_MARGIN:g}× beyond the threshold on either side decides alone "
        "(`CUBIC_MARGIN`): the smallest margin of the last table that agrees with the verdict "
        "on every system as often as the best of three does (agreeing less often at margin "
        f"{CUBIC_MARGIN:g}: {', '.join(behind[CUBIC_MARGIN]) or 'none'}); it spares the tank's "
        "clear case two pairs. (The table of the test's own decisions in "
        '"Extrapolation" was made with one seed per arm, before this study.)',
    ]
    return "\n".join(lines)


def record(files: list[Path]) -> int:
    """Merge ``files`` into :data:`STUDY_FILE` and write the section."""
    from _results import write_section

    from canonid.kernel.io import atomic_write_text

    arms, machines = load(files)
    atomic_write_text(STUDY_FILE, json.dumps({"machines": machines, "arms": arms}, indent=1) + "\n")
    write_section(SECTION, render(arms, machines))
    return 0


def sequential(
    found: dict[int, tuple[float, float]], margin: float | None, gain: float, seeds: int
) -> tuple[float, float]:
    """canonid's rule over every ordered choice of ``seeds`` of the seeds: the first pair
    decides alone when its ratio is ``margin`` × ``gain`` or more, or ``gain`` / ``margin`` or
    less (``None``: never), else the arms' best losses over all of them decide. Returns the
    share of choices that keep the branch and the mean number of pairs trained."""
    kept = pairs_trained = 0
    orders = list(itertools.permutations(sorted(found), seeds))
    for order in orders:
        plain, cubic = found[order[0]]
        if margin is not None and not gain / margin < cubic / plain < gain * margin:
            kept += cubic / plain <= gain
            pairs_trained += 1
        else:
            kept += keeps([found[s] for s in order], gain, "min")
            pairs_trained += seeds
    return kept / len(orders), pairs_trained / len(orders)


#: the margins ``record`` compares for the first pair deciding alone (``None``: it never does)
MARGINS = (None, 2.0, 2.5, 3.0, 4.0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--deadline", type=float, default=3600.0)
    p.add_argument("--plan", choices=list(PLANS), default="device")
    p = sub.add_parser("arm")
    p.add_argument("system", choices=list(STUDY_SYSTEMS))
    p.add_argument("seed", type=int)
    p.add_argument("units", type=int)
    p.add_argument("out", type=Path)
    p.add_argument("--fraction", type=float)
    p = sub.add_parser("record")
    p.add_argument("files", type=Path, nargs="+")
    args = parser.parse_args(argv)
    if args.command == "run":
        run(args.out, args.jobs, args.deadline, args.plan)
    elif args.command == "arm":
        row = arm(args.system, args.seed, args.units, args.fraction)
        with args.out.open("a") as f:  # one short line per write: appends do not interleave
            f.write(json.dumps(row) + "\n")
        print(
            f"{args.system} seed {args.seed} units {args.units}: {row['best_val_loss']}", flush=True
        )
    else:
        return record(args.files)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
