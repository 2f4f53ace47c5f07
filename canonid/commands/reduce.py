"""``canonid reduce`` — compress the state of a trained canonical model with an auto-encoder:
one reduction or the compression study (:func:`canonid.reduction.reduce_runs`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from canonid.commands import _options
from canonid.kernel.catalog import COMPRESSION_RATES, help_value


def _rate(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), got {text!r}") from None


def register(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Reduce the state z of the canonical model (Ours MLP/GRU) trained in RUN: an "
        "auto-encoder (E, D) gives the reduced model x̄⁺ = E(Ā D(x̄) + B̄ u + S̄ Ĥ(D(x̄), u)), "
        "ȳ = Ĥ(D(x̄), u) with n̄ = ⌊dim z (1 − r)⌋ + 1 states. --compression R trains one "
        "reduced model and writes a run folder that `canonid evaluate` reads; --sweep "
        "trains one per (RUN, rate, seed) and draws the reconstruction heat-map and the "
        "reduced model's 100-step MSE against n̄."
    )
    p.add_argument(
        "runs", nargs="+", type=Path, metavar="RUN", help="run folder(s) of canonid train"
    )
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument(
        "--compression", type=_rate, metavar="R", help="compression rate in (0, 1), e.g. 0.6"
    )
    mode.add_argument("--sweep", action="store_true", help="the compression study")
    _options.add_profile(p, what="budget")
    _options.add_out(p, "RUN-r<rate> beside RUN; runs/compression-sweep")
    _options.add_from_profile(p, "--epochs", "auto-encoder epochs", "reduce", type=int, metavar="N")
    skip = "E and D with an affine path started from the principal components of the training "
    skip += "windows; off: the paper's plain MLPs"
    kind = argparse.BooleanOptionalAction
    _options.add_from_profile(p, "--linear-skip", skip, "reduce", action=kind, default=None)
    p.add_argument("--seed", type=int, default=0, help="seed (--sweep: the first of --seeds)")
    _options.add_device(p, what="torch device")
    _options.add_threads(p, per=" per job", default="torch's, one per core; 1 with --sweep")
    _options.add_resume(p, what="reduction")
    _options.add_figure_format(p)
    g = p.add_argument_group("compression study (--sweep)")
    g.add_argument(
        "--rates",
        type=_options.comma_list(_rate, "R"),
        nargs="+",
        action=_options.Items,
        metavar="R,...",
        help=f"rates, e.g. 0.3,0.6 (default {help_value(COMPRESSION_RATES)})",
    )
    g.add_argument("--seeds", type=int, default=3, metavar="N", help="seeds per rate")
    _options.add_where(g, jobs="run the reductions", sees="RUN and --out")
    _options.add_no_progress(p)


def run(args: argparse.Namespace) -> int:
    from canonid.reduction import ReduceRequest, reduce_runs  # torch, matplotlib

    print(reduce_runs(_options.request(ReduceRequest, args)).summary())
    return 0
