"""``canonid generate`` — closed-loop datasets (tank PID, planar-drone NMPC):
:func:`canonid.generation.generate`."""

from __future__ import annotations

import argparse

from canonid.commands import _options
from canonid.generation import GenerateRequest, generate, scenario_names

SPLITS = ("train", "val", "test")


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Generate a closed-loop identification dataset: random spline references "
        "tracked by the system's controller, bounded measurement noise, train/val/test splits. "
        "Writes DIR/dataset.npz and DIR/dataset.json."
    )
    p.add_argument(
        "system",
        help=f"the scenario: a system or a named design ({', '.join(scenario_names())})",
    )
    _options.add_out(p, "runs/data/SYSTEM-sSEED")
    p.add_argument("--seed", type=int, default=0, help="root seed")
    for split in SPLITS:
        p.add_argument(
            f"--n-{split}",
            type=int,
            dest=f"n_{split}",
            metavar="N",
            help=f"number of {split} flights (default: the system's)",
        )
    p.add_argument(
        "--noise",
        metavar="W,...",
        help="measurement-noise half-width, one number or one per output separated by commas "
        "(default: the system's W; a level outside W is refused)",
    )
    p.add_argument(
        "--mpc-horizon",
        dest="horizon",
        type=int,
        metavar="N",
        help="prediction horizon of the NMPC controller (MPC scenarios only; default 20)",
    )
    _options.add_former(p, "--horizon", "--mpc-horizon")
    p.add_argument(
        "--steps", type=int, metavar="T", help="samples per flight (default: the system's)"
    )
    design = p.add_argument_group("experiment design (docs: Data generation, Experiment design)")
    design.add_argument(
        "--excitation",
        choices=("multisine", "prbs"),
        help="add a signal to the controller's command (the applied input, clipped to U, is "
        "recorded): a random-phase multisine or a PRBS (default: none, the controller's command "
        "alone)",
    )
    design.add_argument(
        "--amplitude",
        metavar="RMS,...",
        help="its RMS per input, one number or one per input (required with --excitation)",
    )
    design.add_argument(
        "--band", metavar="LOW,HIGH", help="multisine band in Hz (required with multisine)"
    )
    design.add_argument(
        "--lines", type=int, metavar="N", help="multisine lines per input (required with multisine)"
    )
    design.add_argument(
        "--clock", type=int, metavar="N", help="samples each PRBS level holds (required with prbs)"
    )
    design.add_argument(
        "--references",
        metavar="FAMILY",
        help="another reference family (drone2d: steps; default: random splines)",
    )
    _options.add_where(p, jobs="simulate the flights", sees="--out")
    _options.add_resume(p, what="generation (finished flights are kept)")
    p.add_argument(
        "--plot", action="store_true", help="plot a few flights against their references"
    )
    _options.add_figure_format(p)
    _options.add_no_progress(p)


def run(args: argparse.Namespace) -> int:
    counts = {k: n for k in SPLITS if (n := getattr(args, f"n_{k}")) is not None}
    print(generate(_options.request(GenerateRequest, args, counts=counts)))
    return 0
