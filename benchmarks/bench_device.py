"""Candidates per second of Ours (MLP) trained as one stack, on a GPU against one CPU core, and
the work per rollout step at which the GPU starts to pay off (the rule of ``--device auto``).

Two steps, because the GPU machine is not the one that keeps the results:

1. ``python bench_device.py measure --out device.json`` (on a machine with CUDA; without it the
   GPU part is skipped) trains stacks of ``K`` candidates (seeds 0…K−1) by
   :func:`canonid.learning.batched.fit_batched` on the generated tank, ℓ = 10, the quick
   profile's options with ``--epochs`` epochs and no curriculum, for the widths 3 × 256 (the
   default) and 3 × 64: on one CPU thread (``device="cpu"``, ``torch.set_num_threads(1)``) and
   on the GPU (``device="cuda"``). It writes every job to the JSON as it ends.
2. ``python bench_device.py render device.json`` writes the section "Device" of
   benchmarks/RESULTS.md from it, with the card and the CPU named, and the threshold that
   :data:`canonid.learning.training.AUTO_CUDA_WORK_PER_THREAD` should hold.

Work per rollout step is ``K × batch × Σ fan_in × fan_out`` (multiply-adds of the stack's layers
for one step of every rollout in a batch). A GPU's time per step hardly grows with it until the
card fills, while a core's grows in proportion; the threshold is the smallest measured work at
which the GPU's epoch is shorter than one core's at the same ``K`` and widths.

Usage: python bench_device.py measure --out FILE [--epochs N] [--data DIR] [--ks 1,8,…]
       python bench_device.py render FILE
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

WINDOW = 10
WIDTHS = ((256, 256, 256), (64, 64, 64))
#: the stacks each device trains (one CPU thread stops at the largest it can do in minutes)
GPU_KS = (1, 8, 32, 128, 512)
CPU_KS = {(256, 256, 256): (1, 8, 32), (64, 64, 64): (1, 8, 32, 128)}


def work_per_step(k: int, batch: int, n_u: int, n_y: int, hidden: tuple[int, ...]) -> int:
    """Multiply-adds of one rollout step of a stack (what ``device="auto"`` weighs)."""
    from canonid.learning.nets import build_net
    from canonid.learning.training import network_work

    net = build_net("mlp", window=WINDOW, n_u=n_u, n_y=n_y, hidden=list(hidden))
    return network_work(net, batch, k)


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def measure(args: argparse.Namespace) -> int:
    import torch
    from _data import ensure_dataset

    from canonid.kernel.dataset import Dataset
    from canonid.learning.batched import candidate_grid, fit_batched
    from canonid.profiles import train_options

    folder = args.data or ensure_dataset("tank-s0")
    ds = Dataset.load(folder / "dataset.npz")
    train, val = ds.splits["train"], ds.splits["val"]
    n_u, n_y = train[0].u.shape[1], train[0].y.shape[1]
    cuda = torch.cuda.is_available()
    record: dict = {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "card": torch.cuda.get_device_name(0) if cuda else None,
        "torch": torch.__version__,
        "python": platform.python_version(),
        "epochs": args.epochs,
        "window": WINDOW,
        "records": [len(train), len(val), train[0].T],
        "jobs": [],
    }
    out = Path(args.out)

    def save() -> None:
        tmp = out.with_suffix(".tmp")
        tmp.write_text(json.dumps(record, indent=1))
        tmp.replace(out)

    torch.set_num_threads(args.threads)
    record["threads"] = args.threads
    devices = [d for d in ("cpu", *(["cuda"] if cuda else [])) if d in args.devices]
    for device in devices:
        opts = train_options("quick", epochs=args.epochs, curriculum_epochs=0, device=device)
        record["batch"], record["horizon"] = opts.batch_size, opts.horizon
        record["windows_per_epoch"] = opts.windows_per_epoch
        # warm-up: the first run on a device pays one-time costs (CUDA context, cuBLAS handles)
        warm = train_options("quick", epochs=1, curriculum_epochs=0, device=device)
        fit_batched(train, val, candidate_grid(seed=[0, 1]), window=WINDOW, options=warm)
        for hidden in WIDTHS:
            ks = GPU_KS if device == "cuda" else CPU_KS[hidden]
            for k in ks if args.ks is None else args.ks:
                if device == "cuda":
                    torch.cuda.synchronize()
                start_wall, start_cpu = time.perf_counter(), time.process_time()
                try:
                    result = fit_batched(
                        train,
                        val,
                        candidate_grid(seed=list(range(k))),
                        window=WINDOW,
                        options=opts,
                        net_options={"hidden": list(hidden)},
                        ensemble=0,
                    )
                    if device == "cuda":
                        torch.cuda.synchronize()
                    error = None
                except Exception as exc:  # a job that fails is recorded, the others go on
                    result, error = None, f"{type(exc).__name__}: {exc}"
                wall, cpu = time.perf_counter() - start_wall, time.process_time() - start_cpu
                job = {
                    "device": device,
                    "hidden": list(hidden),
                    "k": k,
                    "work": work_per_step(k, opts.batch_size, n_u, n_y, hidden),
                    "wall_s": wall,
                    "cpu_s": cpu,
                    "candidate_epochs_per_s": k * args.epochs / wall,
                    "best_val_first": None if result is None else result.runs[0].best_val_loss,
                    "error": error,
                }
                record["jobs"].append(job)
                save()
                print(json.dumps(job), flush=True)
    return 0


def threshold(jobs: list[dict]) -> tuple[int | None, int | None]:
    """``(lowest, highest)``: the smallest measured work per step at which the GPU beat one
    CPU thread at the same K and widths, and the largest at which it lost."""
    cpu = {
        (tuple(j["hidden"]), j["k"]): j["wall_s"]
        for j in jobs
        if j["device"] == "cpu" and j.get("threads", 1) == 1 and not j["error"]
    }
    won, lost = [], []
    for j in jobs:
        key = (tuple(j["hidden"]), j["k"])
        if j["device"] == "cuda" and not j["error"] and key in cpu:
            (won if j["wall_s"] < cpu[key] else lost).append(j["work"])
    return (min(won) if won else None, max(lost) if lost else None)


def render(path: Path) -> int:
    from _results import write_section

    record = json.loads(path.read_text())
    jobs = [j for j in record["jobs"] if not j["error"]]
    failed = [j for j in record["jobs"] if j["error"]]
    threads = sorted({j.get("threads", 1) for j in jobs if j["device"] == "cpu"})
    seconds = {
        (tuple(j["hidden"]), j["k"], j["device"], j.get("threads")): j["wall_s"] for j in jobs
    }
    gpu = {(tuple(j["hidden"]), j["k"]): j for j in jobs if j["device"] == "cuda"}
    core = [j for j in jobs if j["device"] == "cpu" and j.get("threads", 1) == 1]
    one = {tuple(j["hidden"]): j for j in core if j["k"] == 1}
    core_best = {}  # one thread's best rate per widths, over the stacks it trained
    for j in core:
        h = tuple(j["hidden"])
        if (
            h not in core_best
            or j["candidate_epochs_per_s"] > core_best[h]["candidate_epochs_per_s"]
        ):
            core_best[h] = j
    keys = sorted({(tuple(j["hidden"]), j["k"]) for j in jobs}, key=lambda t: (-t[0][0], t[1]))
    rows, verdicts = [], []
    for hidden, k in keys:
        cpu_cells = [seconds.get((hidden, k, "cpu", t)) for t in threads]
        g = gpu.get((hidden, k))
        measured = [(s, f"CPU {t}") for s, t in zip(cpu_cells, threads, strict=True) if s]
        if g:
            measured.append((g["wall_s"], "GPU"))
        fastest = min(measured)[1] if len(measured) > 1 else "—"
        work = next(j["work"] for j in jobs if (tuple(j["hidden"]), j["k"]) == (hidden, k))
        if g and len(measured) > 1:
            verdicts.append((work, "GPU" if fastest == "GPU" else "CPU"))
        versus = (
            f"{g['candidate_epochs_per_s'] / one[hidden]['candidate_epochs_per_s']:.0f}×"
            if g and hidden in one
            else "—"
        )
        gpu_cells = (
            ["—", "—"] if not g else [f"{g['wall_s']:.2f}", f"{g['candidate_epochs_per_s']:.1f}"]
        )
        cells = ["—" if c is None else f"{c:.2f}" for c in cpu_cells] + gpu_cells
        rows.append(
            f"| {' × '.join(map(str, hidden))} | {k} | {work / 1e6:.1f} M | "
            + " | ".join(cells)
            + f" | {versus} | {fastest} |"
        )
    won, lost = threshold(jobs)
    head = " | ".join(f"CPU {t} thread{'s' if t > 1 else ''} (s)" for t in threads)
    lines = [
        f"Measured on one {record['card'] or 'no GPU'} beside {record['cpu']} "
        f"({record['cores']} cores), torch {record['torch']}, Python {record['python']}, from "
        f"the run recorded in `benchmarks/device/{path.name}` (its commands are listed there); "
        "this section is rendered from that file.",
        "",
        f"Ours (MLP) stacks of K candidates (seeds 0…K−1) by `fit_batched` on the generated tank "
        f"({record['records'][0]} training, {record['records'][1]} validation records of "
        f"{record['records'][2]} samples), ℓ = {record['window']}, the quick profile's options "
        f"with {record['epochs']} epochs and no curriculum (batch {record['batch']}, horizon "
        f"{record['horizon']}, {record['windows_per_epoch']} windows per epoch), validation at "
        "the last epoch: wall seconds of the whole call after a warm-up run on each device. "
        "Work: multiply-adds of one rollout step of the stack (K × batch × the entries of the "
        "weight matrices, `canonid.learning.training.network_work`).",
        "",
        f"| widths | K | work per step | {head} | GPU (s) | GPU candidate-epochs per s | "
        "GPU × one thread at K = 1 | fastest |",
        "|---|---|---|" + "---|" * len(threads) + "---|---|---|---|",
        *rows,
        "",
    ]
    if failed:
        lines += [f"Failed: {j['device']} K = {j['k']}: {j['error']}" for j in failed] + [""]
    for h in sorted({key[0] for key in gpu}, reverse=True):
        top = max((j for key, j in gpu.items() if key[0] == h), key=lambda j: j["k"])
        rate, width = top["candidate_epochs_per_s"], " × ".join(map(str, h))
        if h in one and h in core_best:
            lines.append(
                f"- Widths {width}: the GPU trains {rate:.0f} candidate-epochs per second at "
                f"K = {top['k']}, **{rate / one[h]['candidate_epochs_per_s']:.0f}×** one CPU "
                "thread training one candidate and "
                f"**{rate / core_best[h]['candidate_epochs_per_s']:.0f}×** one thread's best "
                f"stack (K = {core_best[h]['k']}); target ≥ 20×."
            )
    lines.append("")
    # does the threshold split the rows the same way against the fastest CPU column?
    fastest_gpu = [(work, fastest == "GPU") for work, fastest in verdicts]
    agrees = won is not None and all((w >= won) == is_gpu for w, is_gpu in fastest_gpu)
    if won is not None and lost is not None:
        lines.append(
            f"The GPU beat one CPU thread from **{won / 1e6:.1f} M** multiply-adds per rollout "
            f"step and lost at {lost / 1e6:.1f} M and below. "
            + (
                "Against the fastest of the measured thread counts the same work splits the rows "
                "the same way (column 'fastest'), so `device=\"auto\"` picks CUDA from that work "
                "whatever the thread count (`canonid.learning.training.AUTO_CUDA_WORK`)."
                if agrees
                else "Against the fastest of the measured thread counts it does not split the "
                "rows the same way (column 'fastest'): the rule needs the thread count."
            )
        )
    write_section(
        "Device", "\n".join(lines), command=f"python bench_device.py render device/{path.name}"
    )
    print("\n".join(lines))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="step", required=True)
    m = sub.add_parser("measure")
    m.add_argument("--out", required=True)
    m.add_argument("--epochs", type=int, default=2)
    m.add_argument("--data", type=Path, default=None)
    m.add_argument("--ks", type=lambda s: [int(v) for v in s.split(",")], default=None)
    m.add_argument("--threads", type=int, default=1, help="CPU threads (default 1)")
    m.add_argument("--devices", default="cpu,cuda", help="which sides to run (default cpu,cuda)")
    r = sub.add_parser("render")
    r.add_argument("path", type=Path)
    args = parser.parse_args()
    return measure(args) if args.step == "measure" else render(args.path)


if __name__ == "__main__":
    raise SystemExit(main())
