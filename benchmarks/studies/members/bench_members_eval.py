"""CPU time of simulating a mean of K members (``canonid train --members K``) block by block
against the same weights multiplied densely, and against the K members one after another.

Writes the section "Members: simulation cost" of the records (benchmarks/records/).

A mean of K Ours (MLP) members (:func:`canonid.learning.members.average_members`) stores its
hidden layers dense and block-diagonal; it applies them block by block (``OursMLP(groups=K)``).
On one thread, with the network of the defaults (ℓ = 10, one input and one output, 3 × 256 SiLU
units, 16 cubic units, feedthrough, the linear skip) and members of random weights, the process
CPU time (best of ``--repeats``) of the two kinds of work a trained model does most:

* evaluation: ``--batch`` rollouts of ``--horizon`` steps at once (a chunk of ``canonid
  train``'s stride-1 score of the test split, and of the validation losses ``--members``
  compares);
* simulation: one record of ``--steps`` steps (the official score of a benchmark's test part);

for the mean as it runs (block by block), for the same mean with ``groups`` set to 1 (the dense
product of the stored weights, which is how a mean ran before), and for its K members one after
another. Only the arithmetic differs: the three give the same outputs up to rounding.

Usage: python benchmarks/studies/members/bench_members_eval.py [--members 1,2,3,4] [--batch 256]
[--horizon 100]
[--steps 5000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _results import load_line, write_section  # noqa: E402

from canonid.learning import Model, Normalisation, build_net  # noqa: E402
from canonid.learning.members import average_members  # noqa: E402

CONFIG = {
    "window": 10,
    "n_u": 1,
    "n_y": 1,
    "hidden": [256, 256, 256],
    "activation": "silu",
    "cubic": 16,
    "feedthrough": True,
    "residual": True,
    "linear": "skip",
}


def member(seed: int, norm: Normalisation) -> Model:
    torch.manual_seed(seed)
    net = build_net("mlp", **CONFIG)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(0.05 * torch.randn_like(p))
    return Model(net.eval(), norm)


def best_cpu(work: Callable[[], object], repeats: int) -> float:
    """The lowest process CPU seconds of ``repeats`` calls of ``work`` (after one warm-up)."""
    work()
    times = []
    for _ in range(repeats):
        start = time.process_time()
        work()
        times.append(time.process_time() - start)
    return min(times)


def rollouts(nets: list[torch.nn.Module], batch: int, steps: int) -> Callable[[], object]:
    """``batch`` rollouts of ``steps`` steps through each of ``nets`` (no gradient)."""
    g = torch.Generator().manual_seed(0)
    ell = CONFIG["window"]
    u_past = torch.randn(batch, ell, 1, generator=g)
    y_past = torch.randn(batch, ell, 1, generator=g)
    u_future = 0.5 * torch.randn(batch, steps, 1, generator=g)

    def work() -> object:
        with torch.no_grad():
            return [net.rollout(u_past, y_past, u_future) for net in nets]

    return work


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", default="1,2,3,4", help="the K to measure")
    parser.add_argument("--batch", type=int, default=256, help="evaluation: rollouts at once")
    parser.add_argument("--horizon", type=int, default=100, help="evaluation: steps per rollout")
    parser.add_argument("--steps", type=int, default=5000, help="simulation: steps of one record")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--no-write", action="store_true", help="print, do not write the record's notes"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    unit = {"u_mean": [0.0], "u_std": [1.0], "y_mean": [0.0], "y_std": [1.0], "dy_std": [1.0]}
    norm = Normalisation.from_dict(unit)
    loads = [os.getloadavg()[0]]
    rows = []
    for k in (int(x) for x in args.members.split(",")):
        members = [member(seed, norm) for seed in range(k)]
        mean = average_members(members).net
        dense = build_net("mlp", **{**mean.config(), "groups": 1})
        dense.load_state_dict(mean.state_dict())
        dense.eval()
        check = rollouts([mean, dense], 8, 20)()
        gap = float((check[0] - check[1]).abs().max())  # type: ignore[index]
        row = {"K": k, "gap": gap}
        for what, batch, steps in (
            ("evaluation", args.batch, args.horizon),
            ("simulation", 1, args.steps),
        ):
            for name, nets in (
                ("blocks", [mean]),
                ("dense", [dense]),
                ("members", [m.net for m in members]),
            ):
                row[f"{what}/{name}"] = best_cpu(rollouts(nets, batch, steps), args.repeats)
        rows.append(row)
        loads.append(os.getloadavg()[0])
        print(row, flush=True)
    own = [1] * len(loads)  # this benchmark's one busy process
    sentence, _ = load_line(loads, "CPU times of one thread are less affected than wall times", own)
    body = table(rows, args) + "\n\n" + sentence + "\n"
    if args.no_write:
        print(body)
    else:
        write_section("Members: simulation cost", body, command=" ".join(["python", *sys.argv]))
    return 0


def table(rows: list[dict], args: argparse.Namespace) -> str:
    head = (
        f"One thread, process CPU seconds (best of {args.repeats}); the network of the defaults "
        "(ℓ = 10, 3 × 256 SiLU units, 16 cubic units, feedthrough, the linear skip), members of "
        f"random weights. Evaluation: {args.batch} rollouts of {args.horizon} steps at once; "
        f"simulation: one record of {args.steps} steps. 'blocks': the mean of K members as it "
        "runs (`OursMLP(groups=K)`); 'dense': the same stored weights multiplied as one dense "
        "network (how a mean ran before); 'members': the K members one after another (each on "
        "its own predictions: not the mean's computation, the arithmetic of its K networks, for "
        "scale). Largest "
        "difference between the blocks' and the dense outputs (8 rollouts of 20 steps): the "
        "column 'gap'.\n\n"
        "| K | evaluation: blocks [s] | dense [s] | members [s] | dense / blocks | "
        "simulation: blocks [s] | dense [s] | members [s] | dense / blocks | gap |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    lines = []
    for r in rows:
        cells = [str(r["K"])]
        for what in ("evaluation", "simulation"):
            blocks, dense, members = (r[f"{what}/{n}"] for n in ("blocks", "dense", "members"))
            cells += [f"{blocks:.2f}", f"{dense:.2f}", f"{members:.2f}", f"{dense / blocks:.2f}×"]
        cells.append(f"{r['gap']:.1e}")
        lines.append("| " + " | ".join(cells) + " |")
    last = rows[-1]
    reading = (
        f"\n\nAt K = {last['K']} the blocks take "
        f"{last['evaluation/dense'] / last['evaluation/blocks']:.1f}× less CPU than the dense "
        f"product in evaluation and {last['simulation/dense'] / last['simulation/blocks']:.1f}× "
        "less in simulation, where one row per step leaves the per-operation overhead to "
        "dominate."
    )
    return head + "\n".join(lines) + reading


if __name__ == "__main__":
    raise SystemExit(main())
