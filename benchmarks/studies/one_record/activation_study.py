"""The hidden units' activation on one record of a saturating system: SiLU (the defaults) or tanh.

On the overflow tanks the level is bounded twice, by the upper tank's rim and the sensor's 10-V
limit; SiLU units grow linearly beyond the levels they were trained on, tanh units saturate.
deepSI's SUBNET, which beats the defaults on some draws, uses tanh. This study trains the
overflow benchmark's defaults with ``--activation tanh`` on each of five draws of the data
(`canonid generate tanks-overflow --seed D`) and judges both models of a draw on records that
neither saw: the other draws' training records (samples 0 … 1,023, simulation after
n_init = 50), as the validation-block study does. The verdict never reads a test record
(``canonid train`` scores its test split when it ends, as it always does; those scores chose
nothing).

1. ``train D``: ``canonid train DATA --max-window 50 --seed 0 --threads 1 --activation tanh`` into
   ``runs/activation/tanh-dD``; the SiLU model is the defaults' run of the overflow benchmark.
2. ``judge``: both models of every draw: the window, the best validation loss, the RMSE on the
   other four draws' records; writes the section.

Usage: python activation_study.py train D | judge
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from validation_block_study import (
    DRAWS,
    N_INIT,
    ROOT,
    data_folder,
    defaults_run,
    geomean,
    rmse_on_others,
    whole_record,
)

RUNS = ROOT / "runs" / "activation"
SECTION = "Activation on one record (overflow tanks)"


def tanh_run(draw: int) -> Path:
    return RUNS / f"tanh-d{draw}"


def train(draw: int) -> int:
    cmd = [sys.executable, "-m", "canonid", "train", str(data_folder(draw))]
    cmd += ["--max-window", str(N_INIT), "--seed", "0", "--threads", "1", "--no-progress"]
    cmd += ["--activation", "tanh", "--out", str(tanh_run(draw))]
    return subprocess.run(cmd, check=False).returncode


def judge() -> int:
    from _results import record

    from canonid.learning import Model

    records = {draw: whole_record(draw)[1] for draw in DRAWS}
    lines = [
        __doc__.split("\n\n")[1].replace("\n", " "),
        "",
        "Per draw: the window each run chose, its best validation loss (normalised, the "
        "loss `canonid train` reports) and the RMSE [V] of its simulations of the other four "
        "draws' records after n_init = 50.",
        "",
        "| draw | window: SiLU / tanh | validation loss, SiLU | validation loss, tanh | "
        "RMSE, SiLU | RMSE, tanh | tanh / SiLU: validation | tanh / SiLU: other records |",
        "|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    by_val, by_judges = [], []
    for draw in DRAWS:
        found = {}
        for name, run in (("silu", defaults_run(draw)), ("tanh", tanh_run(draw))):
            model = Model.load(run)
            loss = model.info["training"]["best_val_loss"]
            found[name] = (model.window, loss, rmse_on_others(model, draw, records))
        (w_s, v_s, r_s), (w_t, v_t, r_t) = found["silu"], found["tanh"]
        by_val.append(v_t / v_s)
        by_judges.append(r_t / r_s)
        lines.append(
            f"| {draw} | {w_s} / {w_t} | {v_s:.4g} | {v_t:.4g} | {r_s:.4f} | {r_t:.4f} | "
            f"{by_val[-1]:.2f} | {by_judges[-1]:.2f} |"
        )

    lines += [
        "",
        f"tanh over SiLU, geometric mean over {len(by_judges)} draws: validation loss "
        f"{geomean(by_val):.2f} (lower in {sum(r < 1 for r in by_val)}), RMSE on the other "
        f"draws' records {geomean(by_judges):.2f} (lower in {sum(r < 1 for r in by_judges)}).",
    ]
    return record(SECTION, "\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    sub.add_parser("train").add_argument("draw", type=int, choices=list(DRAWS))
    sub.add_parser("judge")
    args = parser.parse_args(argv)
    return train(args.draw) if args.step == "train" else judge()


if __name__ == "__main__":
    raise SystemExit(main())
