"""``canonid generate`` — closed-loop datasets (tank PID, planar-drone NMPC).

Flights run serially, on a local Dask cluster (``--workers N``) or on an existing one
(``--scheduler ADDRESS``) through :func:`canonid.runner.run_jobs`; the same seed gives the same
bytes whichever is used. See :mod:`canonid.datagen.generate` for seeds, parts and resuming.
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path
from typing import Any

from canonid.commands import _options, _paths
from canonid.datagen.generate import (
    FLIGHTS_PER_TASK,
    FlightResult,
    GenerationConfig,
    generate_dataset,
)
from canonid.datagen.scenarios import get_scenario, scenario_names
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import ShapeError
from canonid.models.registry import get_system
from canonid.runner import run_jobs


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "generate",
        description="Generate a closed-loop identification dataset: random spline references "
        "tracked by the system's controller, bounded measurement noise, train/val/test splits. "
        "Writes DIR/dataset.npz and DIR/dataset.json.",
    )
    p.add_argument("system", help=f"the system ({', '.join(scenario_names())})")
    p.add_argument(
        "--out",
        type=_paths.folder,
        metavar="DIR",
        help="output folder (default runs/data/SYSTEM-sSEED)",
    )
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    for split in ("train", "val", "test"):
        p.add_argument(
            f"--n-{split}",
            type=int,
            dest=f"n_{split}",
            metavar="N",
            help=f"number of {split} flights (default: the system's)",
        )
    p.add_argument(
        "--noise",
        metavar="LEVEL",
        help="measurement-noise half-width, one number or one per output separated by commas "
        "(default: the system's W; a level outside W is refused)",
    )
    p.add_argument("--horizon", type=int, metavar="N", help="MPC horizon (MPC systems only)")
    p.add_argument(
        "--steps", type=int, metavar="T", help="samples per flight (default: the system's)"
    )
    _options.add_where(p, jobs="simulate the flights", sees="--out")
    p.add_argument(
        "--resume", action="store_true", help="keep finished flights of an interrupted run"
    )
    p.add_argument(
        "--plot", action="store_true", help="plot a few flights against their references"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def _noise(text: str | None) -> float | tuple[float, ...] | None:
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ShapeError(
            f"--noise must be a number or numbers separated by commas, got {text!r}"
        ) from None
    return values[0] if len(values) == 1 else values


def _tally(result: FlightResult) -> int:
    return result.solver_failures


def run(args: argparse.Namespace) -> int:
    get_scenario(args.system)  # unknown system: one-line error before anything else
    counts = {
        split: n
        for split in ("train", "val", "test")
        if (n := getattr(args, f"n_{split}")) is not None
    }
    options = {} if args.horizon is None else {"horizon": args.horizon}
    config = GenerationConfig(
        system=args.system,
        seed=args.seed,
        counts=counts,
        noise=_noise(args.noise),
        controller_options=options,
        T=args.steps,
    )
    if args.workers < 0:
        raise ShapeError(f"--workers must be >= 0, got {args.workers}")
    out = _paths.check_folder(args.out or Path("runs") / "data" / f"{args.system}-s{args.seed}")
    runner = functools.partial(
        run_jobs,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
        description=f"{args.system} flights",
        tally=_tally,
        tally_name="solver failures",
        batch=FLIGHTS_PER_TASK,
    )
    result = generate_dataset(config, out, run_jobs=runner, resume=args.resume)
    counts_text = ", ".join(f"{k} {v}" for k, v in result.counts.items())
    print(f"dataset written to {result.path.resolve()} ({counts_text} flights)")
    if result.chunks is not None:
        chunks_text = ", ".join(f"{k} {v}" for k, v in result.chunks.items())
        length = get_scenario(args.system).chunk_length
        print(f"  flights cut into {length}-sample chunks: {chunks_text} chunks")
    stand_in = get_system(args.system).simulated_stand_in_for
    if stand_in:
        print(f"  SIMULATED data: {args.system} is a simulated stand-in for {stand_in}")
    print(
        f"  generated {result.generated}, resumed {result.resumed}; solver failures (fell back) "
        f"{result.solver_failures}; flights regenerated with a new seed {result.replaced}"
    )
    if args.plot:
        figure = plot_flights(Dataset.load(result.path), out / "flights.png")
        print(f"  figure: {figure.resolve()}")
    return 0


def plot_flights(dataset: Dataset, path: Path, *, n: int = 3) -> Path:
    """Outputs against their references for the first ``n`` test (or train) flights."""
    from matplotlib.figure import Figure  # matplotlib only when a figure is asked for

    flights = (dataset.split("test") or dataset.split("train"))[:n]
    ref_names = dataset.metadata.get("scenario", {}).get("reference_names", [])
    fig = Figure(figsize=(4 * len(flights), 2.2 * dataset.n_y))
    axes = fig.subplots(dataset.n_y, len(flights), squeeze=False)
    for j, flight in enumerate(flights):
        t = [i * dataset.dt for i in range(flight.T)]
        for i, name in enumerate(dataset.output_names):
            ax = axes[i, j]
            ax.plot(t, flight.y[:, i], lw=0.8, label=f"{name} (measured)")
            target = f"{name}_ref"
            if flight.reference is not None:
                if target in ref_names:
                    col = ref_names.index(target)
                    ax.plot(t, flight.reference[:, col], "k--", lw=0.8, label="reference")
            if j == 0:
                ax.set_ylabel(name)
            if i == dataset.n_y - 1:
                ax.set_xlabel("time [s]")
        axes[0, j].set_title(f"flight {flight.info.get('split', '')} {flight.info.get('index', j)}")
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
