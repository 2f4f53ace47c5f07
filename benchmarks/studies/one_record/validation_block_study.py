"""Where one record's validation part should lie: its tail, or a block that reaches the levels.

On the overflow tanks' single record the last fifth often misses the spill and the sensor's limit
(section "Overflow tanks": the spread table's last column), so no choice made on it sees how a
model treats them. This study moves the validation block (the same 205 samples, 20 % of the
1,024) to where the training part and the block cover each other's levels best, and asks
whether the defaults then choose models that simulate the system better — judged on records
that neither variant saw: the other draws' training records (`canonid generate tanks-overflow
--seed D`, samples 0 … 1,023, simulation after n_init = 50). Test records are never read.

1. ``prepare``: for each draw D = 0 … 4 the block start among 0, 103, …, 721 and 819 (the tail)
   with the smallest larger share of output samples outside the other part's span (training
   outside the block, block outside the training part; the latest on a tie), and its dataset in
   ``runs/valblock/data/dD`` (the training part: the pieces before and after the block of at
   least 130 samples; no test split).
2. ``train D``: ``canonid train runs/valblock/data/dD --max-window 50 --seed 0 --threads 1`` (the
   overflow benchmark's defaults) into ``runs/valblock/dD``; a draw whose block is the tail
   keeps the defaults' run of the spread.
3. ``judge``: both models of every draw on the other draws' records; writes the section.

Usage: python validation_block_study.py prepare | train D | judge
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
RUNS = ROOT / "runs" / "valblock"
SECTION = "Validation block on one record (overflow tanks)"
DRAWS = range(5)
BLOCK = 205
STEP = 103
MIN_PIECE = 130
N_INIT = 50


def data_folder(draw: int) -> Path:
    name = "tanks-overflow" if draw == 0 else f"tanks-overflow-s{draw}"
    return ROOT / "runs" / "data" / name


def defaults_run(draw: int) -> Path:
    """The overflow benchmark's run of canonid's defaults on draw ``draw``, training seed 0."""
    cell = "mlp-default" if draw == 0 else f"spread/d{draw}-s0/mlp-default"
    return ROOT / "runs" / "overflow-tanks" / cell


def whole_record(draw: int) -> tuple[object, object]:
    """The draw's dataset and its training record whole (training part, then validation)."""
    from canonid.kernel.dataset import Dataset, Trajectory

    data = Dataset.load(data_folder(draw) / "dataset.npz")
    (train,), (val,) = data.split("train"), data.split("val")
    y_clean = None if train.y_clean is None else np.concatenate([train.y_clean, val.y_clean])
    whole = Trajectory(
        u=np.concatenate([train.u, val.u]), y=np.concatenate([train.y, val.y]), y_clean=y_clean
    )
    return data, whole


def cut(whole, start: int) -> tuple[list, object]:
    """The training pieces around the block at ``start``, and the block."""
    from canonid.kernel.dataset import Trajectory

    def piece(i: int, j: int) -> Trajectory:
        clean = None if whole.y_clean is None else whole.y_clean[i:j]
        return Trajectory(u=whole.u[i:j], y=whole.y[i:j], y_clean=clean)

    spans = ((0, start), (start + BLOCK, whole.T))
    return [piece(i, j) for i, j in spans if j - i >= MIN_PIECE], piece(start, start + BLOCK)


def shares(data, whole) -> dict[int, tuple[float, float]]:
    """Per block start: the share of training output samples outside the block's span, and of
    block output samples outside the training part's."""
    from canonid.coverage import unvalidated

    names = {"input_names": data.input_names, "output_names": data.output_names}
    found = {}
    for start in [*range(0, whole.T - BLOCK, STEP), whole.T - BLOCK]:
        train, val = cut(whole, start)
        a = sum(o.share for o in unvalidated(train, [val], **names) if o.kind == "output")
        b = sum(o.share for o in unvalidated([val], train, **names) if o.kind == "output")
        found[start] = (a, b)
    return found


def chosen(found: dict[int, tuple[float, float]]) -> int:
    best = min(max(v) for v in found.values())
    return max(start for start, v in found.items() if max(v) == best)


def prepare() -> dict[int, dict]:
    from canonid.kernel.dataset import Dataset
    from canonid.kernel.io import atomic_write_text

    plan = {}
    for draw in DRAWS:
        data, whole = whole_record(draw)
        found = shares(data, whole)
        start = chosen(found)
        train, val = cut(whole, start)
        Dataset(
            splits={"train": train, "val": [val]},
            dt=data.dt,
            input_names=data.input_names,
            output_names=data.output_names,
            metadata={"source": f"valblock of draw {draw}, block at {start}"},
        ).save(RUNS / "data" / f"d{draw}" / "dataset.npz")
        plan[draw] = {"start": start, "shares": {str(k): v for k, v in found.items()}}
        print(f"draw {draw}: block at {start}")
    atomic_write_text(RUNS / "plan.json", json.dumps(plan, indent=1))
    return plan


def train(draw: int) -> int:
    """Train the block's run of ``draw``; none where the block is the tail (the defaults' run)."""
    start = json.loads((RUNS / "plan.json").read_text())[str(draw)]["start"]
    if start == whole_record(draw)[1].T - BLOCK:
        print(f"draw {draw}: the block is the tail; the defaults' run {defaults_run(draw)} stands")
        return 0
    cmd = [sys.executable, "-m", "canonid", "train", str(RUNS / "data" / f"d{draw}")]
    cmd += ["--max-window", "50", "--seed", "0", "--threads", "1", "--no-progress"]
    return subprocess.run([*cmd, "--out", str(RUNS / f"d{draw}")], check=False).returncode


def rmse_on_others(model, draw: int, records: dict) -> float:
    """The RMSE of ``model``'s simulations of every draw's record but ``draw``'s (``records``:
    draw → whole record), after n_init = N_INIT measured samples."""
    from canonid.learning.evaluate import simulate_records

    judges = [records[k] for k in DRAWS if k != draw]
    sims = simulate_records(model, judges, N_INIT)
    err = np.concatenate([s - r.y[N_INIT:] for s, r in zip(sims, judges, strict=True)])
    return float(np.sqrt(np.mean(err**2)))


def geomean(values: list[float]) -> float:
    return math.exp(sum(map(math.log, values)) / len(values))


def judge() -> int:
    from _results import record

    from canonid.learning import Model

    plan = {int(k): v for k, v in json.loads((RUNS / "plan.json").read_text()).items()}
    records = {draw: whole_record(draw)[1] for draw in DRAWS}
    lines = [
        __doc__.split("\n\n")[1].replace("\n", " "),
        "",
        "Block start per draw (the tail is 819) and the shares it balances (training output "
        "samples outside the block's span / block samples outside the training part's): the "
        "tail's, then the chosen block's. RMSE [V] of each model's simulations of the other "
        "four draws' records after n_init = 50.",
        "",
        "| draw | block at | tail: shares | block: shares | window: tail / block | "
        "RMSE, tail's model | RMSE, block's model | block / tail |",
        "|---:|---:|---|---|---|---:|---:|---:|",
    ]
    ratios = []
    for draw in DRAWS:
        start = plan[draw]["start"]
        runs = {"tail": defaults_run(draw)}
        runs["block"] = runs["tail"] if start == records[draw].T - BLOCK else RUNS / f"d{draw}"
        rmse, windows = {}, {}
        for name, run in runs.items():
            model = Model.load(run)
            rmse[name], windows[name] = rmse_on_others(model, draw, records), model.window
        ratios.append(rmse["block"] / rmse["tail"])
        tail = plan[draw]["shares"][str(records[draw].T - BLOCK)]
        block = plan[draw]["shares"][str(start)]
        lines.append(
            f"| {draw} | {start} | {tail[0]:.3f} / {tail[1]:.3f} | {block[0]:.3f} / "
            f"{block[1]:.3f} | {windows['tail']} / {windows['block']} | {rmse['tail']:.4f} | "
            f"{rmse['block']:.4f} | {ratios[-1]:.2f} |"
        )
    mean = geomean(ratios)
    lines += [
        "",
        f"Block over tail: geometric mean {mean:.2f} over {len(ratios)} draws; lower in "
        f"{sum(r < 1 for r in ratios)}, higher in {sum(r > 1 for r in ratios)}.",
    ]
    return record(SECTION, "\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    sub.add_parser("prepare")
    sub.add_parser("train").add_argument("draw", type=int, choices=list(DRAWS))
    sub.add_parser("judge")
    args = parser.parse_args(argv)
    if args.step == "prepare":
        prepare()
        return 0
    if args.step == "train":
        return train(args.draw)
    return judge()


if __name__ == "__main__":
    raise SystemExit(main())
