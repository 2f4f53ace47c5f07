"""Every measured figure the README and the docs quote, checked against the record that measured it.

A quoted figure carries a marker right after it, invisible once rendered::

    7.52e-5<!-- figure: defaults/tank/0 -->

:data:`FIGURES` says where each key's value comes from: a cell of a table in a section of
``benchmarks/RESULTS.md`` (the file the benchmark scripts write), a number a section states only
in its text (found by a regular expression) or a value of the code itself (``canonid.profiles``).
A number agrees with its source when it is the source rounded to the digits quoted (7.52e-5
quotes 7.520165e-05); any other text must be the source's text exactly. :func:`check` lists every
disagreement, and so every marker whose key is unknown; ``tests/test_figures.py`` runs it over
README.md and docs/, and as a MkDocs hook it turns a disagreement into a warning, which fails
the strict build. Run this file to print them all.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from decimal import Decimal, InvalidOperation
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "RESULTS.md"
MARKER = re.compile(r"<!-- figure: (?P<key>[\w./-]+) -->")

log = logging.getLogger("mkdocs.plugins.figures")


def _catalog() -> Any:
    """The plain-data defaults (``weight_decay="auto"``'s threshold and value)."""
    from canonid.kernel import catalog

    return catalog


def _jobs() -> Any:
    """The job layer (the worker pool's threshold)."""
    from canonid import jobs

    return jobs


class Cell(NamedTuple):
    """The first number (with ``pick``, the number at that place; with ``whole``, the whole text)
    of one cell of a RESULTS.md table: the ``nth`` table of ``section`` that has ``column`` (0:
    the first), the row whose cells match ``row``."""

    section: str
    row: tuple[tuple[str, str], ...]
    column: str
    whole: bool = False
    nth: int = 0
    pick: int = 0

    def value(self) -> str:
        tables = [(h, rows) for h, rows in _tables(self.section) if self.column in h]
        for header, rows in tables[self.nth : self.nth + 1]:
            for cells in rows:
                record = dict(zip(header, cells))
                if all(record.get(k) == v for k, v in self.row):
                    # bold and the mark of the lowest published figure are not part of it
                    text = record[self.column].replace("**", "").strip().rstrip("*")
                    if self.whole:
                        return text
                    if self.pick == 0:
                        return text.split()[0]
                    # "0.014 / 0.073 m", "0.04527 (0.1376; 243 s)": the numbers among the words
                    words = (w.strip("();") for w in text.split())
                    return [w for w in words if _number(w) is not None][self.pick]
        raise KeyError(
            f"{RESULTS.name}, section {self.section!r}: no row {dict(self.row)} "
            f"with a column {self.column!r}"
        )


class Prose(NamedTuple):
    """A number a RESULTS.md section states in its text rather than in a table: group ``group``
    of the first match of the regular expression ``pattern`` in ``section``."""

    section: str
    pattern: str
    group: int = 1

    def value(self) -> str:
        body = _sections().get(self.section)
        if body is None:
            raise KeyError(f"{RESULTS.name} has no section {self.section!r}")
        found = re.search(self.pattern, body)
        if found is None:
            raise KeyError(
                f"{RESULTS.name}, section {self.section!r}: no text matching {self.pattern!r}"
            )
        return found[self.group]


class Code(NamedTuple):
    """A value the code itself holds (a profile's budget): ``get()`` returns it."""

    get: Callable[[], Any]

    def value(self) -> str:
        return str(self.get())


#: the section of the cubic test across seeds (benchmarks/cubic_seeds.py)
SEEDS_SECTION = "Cubic test across seeds"


def _row(**cells: str) -> tuple[tuple[str, str], ...]:
    return tuple(cells.items())


def _grid(
    prefix: str,
    section: str,
    row_column: str,
    rows: tuple[tuple[str, str], ...],
    columns: tuple[tuple[str, str], ...],
    *,
    whole: tuple[str, ...] = (),
) -> dict[str, Cell]:
    """The cells ``prefix/slug/what`` of one table of ``section``: for each ``(slug, text)`` of
    ``rows`` the row whose ``row_column`` is ``text``, for each ``(what, column)`` that column
    (the whole cell for the ``what`` in ``whole``)."""
    return {
        f"{prefix}/{slug}/{what}": Cell(
            section, _row(**{row_column: text}), column, whole=what in whole
        )
        for slug, text in rows
        for what, column in columns
    }


def _quick(stage: str, key: str) -> Callable[[], Any]:
    def get() -> Any:
        from canonid.profiles import PROFILES

        return PROFILES["quick"][stage][key]

    return get


#: the row of RESULTS.md's "make demo" section that the pages quote: the latest timing on an
#: idle machine (later rows measured under load say so)
DEMO_RUN = "the same defaults, idle, on the AMD EPYC machine of 2026-11-29"
#: Table 1 and the compression study of one demo run (benchmarks/demo_record.py)
DEMO_TABLES = "make demo: Table 1 and compression"
#: one reduction and a sweep of the tank (benchmarks/reduce_record.py)
REDUCTION = "Reduction: tank"
#: the same of the planar drone's quick reproduce run
DRONE_TABLES = "Reproduce, quick profile: drone2d"
_DEMO_MODELS = (  # key slug, the model cell, the windows
    ("classic-gru", "Classic GRU", (5, 10)),
    ("masti", "Masti et al.", (5, 10)),
    ("gru", "Ours (GRU)", (5, 10)),
    ("mlp-paper", "Ours (MLP), paper options", (5, 10)),
    ("mlp-defaults", "Ours (MLP), canonid defaults", (10,)),
    ("arx", "ARX (linear)", (5, 10)),
)
_NOW = "feedthrough auto (now)"
_FEEDTHROUGH = "3e-3, clip 1, skip from zero, feedthrough"
_NO_FEEDTHROUGH = "3e-3, clip 1, skip from zero, no feedthrough"
_NO_SKIP = "3e-3, clip 1"
#: the overflow tanks' full run at ℓ = 10 in the screen lines: the epoch it ended at, of how many
_OVERFLOW_L10_FULL = r"ℓ = 10: [\d.e-]+ at epoch \d+, ended at epoch (\d+) of (\d+)"
LEARNED_MPC_ID = "NMPC on a learned model: informative drone data"
LEARNED_MPC_MEAN = "NMPC on a learned model: ensembles"
LEARNED_MPC_DEFAULTS = "NMPC on a learned model: the defaults on informative data"
LEARNED_MPC_LADDER = "NMPC on a learned model: the horizon ladder"


def _loop_figures(prefix: str, section: str, model: str) -> dict[str, Cell | Prose]:
    """The figures of one learned_mpc.py drone section: the loop's ratio and loops out, the
    judged step's learned / true change (px, θ; recorded states, rest), and γ_f and the bound's
    factor beside the loop."""
    row = {"model": model, "data": "drone2d-id"}
    figures: dict[str, Cell | Prose] = {
        f"{prefix}/ratio": Cell(section, _row(**row, output="px"), "learned / true tracking RMSE"),
        f"{prefix}/left": Cell(
            section, _row(**row, output="px"), "learned loops that left X", True
        ),
        f"{prefix}/gamma-low": Prose(
            section, r"loops visit \(600 samples\): sampled lower bound ([\d.]+)"
        ),
        f"{prefix}/gamma-high": Prose(
            section, r"exhausted\) and ([\d.]+) \(product of layer norms"
        ),
        f"{prefix}/factor-exponent": Prose(section, r"Factor 2 γ_f\^ℓ / α_ℓ = [\d.]+e\+(\d+)"),
    }
    for output in ("px", "theta"):
        for start, column in (("recorded", "recorded states"), ("rest", "from rest")):
            figures[f"{prefix}/{output}/{start}"] = Cell(
                section, _row(**row, output=output), f"learned / true change, {column}"
            )
    return figures


CANDIDATES = "Candidates side by side"
MEMBERS = "Members on small records"
_MEMBERS_LOOP = "`--members 4`: seed 3 alone, chosen on validation"
_MEMBER_RECORDS = (  # key slug, the record cell, the test part's row and unit
    ("silverbox-1k", "Silverbox, first 1,000 samples (800 / 200)", "multisine [mV]"),
    ("silverbox-3k", "Silverbox, first 3,000 samples (2,400 / 600)", "multisine [mV]"),
    ("overflow", "overflow tanks, 1,024 samples (819 / 205)", "test record [V]"),
)
HORIZON_STUDY = "Training horizon on validation"
EXCITATION_CHECK = "Residuals against the excitation"
#: the data engine's default controller, a row of the "Data engine" section
_DATAGEN_DEFAULT = "NMPC, fatrop-c (default)"
_CANONID_CLUSTER = "canonid (LOCAL_CLUSTER_CONFIG)"
_LEARNED_MPC_MEANS = (  # key slug, the model cell of the ensembles section's goals table
    ("single", "mlp, horizon 10"),
    ("mean4", "mlp, horizon 10, mean of 4"),
    ("mean6", "mlp, horizon 10, mean of 6"),
)
_LEARNED_MPC_RUNS = (  # key slug, the model and data cells of the section's goals table
    ("drone2d-id/mlp", "mlp", "drone2d-id"),
    ("drone2d-id/mlp-h10", "mlp, horizon 10", "drone2d-id"),
    ("drone2d/mlp-h10", "mlp, horizon 10", "drone2d"),
    ("drone2d-id/arx", "arx", "drone2d-id"),
    ("drone2d/arx", "arx", "drone2d"),
)

FIGURES: dict[str, Cell | Prose | Code] = {
    # per system and seed, a column of the defaults study: canonid's defaults; without the
    # linear skip (the defaults before it); the skip without, then with feedthrough
    **{
        f"{key}/{system}/{seed}": Cell(
            "Defaults study", _row(system=system, seed=str(seed)), column
        )
        for key, column in (
            ("defaults", _NOW),
            ("no-skip", _NO_SKIP),
            ("skip", _NO_FEEDTHROUGH),
            ("feedthrough", _FEEDTHROUGH),
        )
        for system, seeds in (("tank", (0, 1, 2)), ("silverbox", (0, 1, 2)), ("drone2d", (0, 1)))
        for seed in seeds
    },
    # the choice on validation: each column's validation loss over the defaults', per system
    **{
        f"validation-ratio/{name}/{system}": Cell(
            "Defaults study: the choice on validation",
            _row(column=label),
            f"{system}: validation ratio",
        )
        for name, label in (("feedthrough", _FEEDTHROUGH), ("no-feedthrough", _NO_FEEDTHROUGH))
        for system in ("tank", "silverbox", "drone2d")
    },
    **{
        f"feedthrough-test/{system}": Cell(
            "Defaults study: the choice on validation", _row(system=system), "with / without u_t"
        )
        for system in ("tank", "silverbox", "drone2d")
    },
    **{
        f"masses/lowest-fit/{ell}": Cell("Chain of masses", _row(**{"ℓ": str(ell)}), "lowest")
        for ell in (30, 40)
    },
    # Silverbox's training part cut short (small_data.py): multisine test RMSE of each
    **{
        f"small/{n}/{who}": Cell(
            "Small data", _row(**{"size (training / validation)": label}), column
        )
        for n, label in (
            (1000, "1,000 (800 / 200)"),
            (3000, "3,000 (2,400 / 600)"),
            (10000, "10,000 (8,000 / 2,000)"),
        )
        for who, column in (
            ("canonid", "multisine [mV]"),
            ("canonid/arrow-full", "arrow full [mV]"),  # canonid's: the first of that name
            ("deepsi", "deepSI: multisine [mV]"),
        )
    },
    "small/1000/best-epoch": Cell(
        "Small data",
        _row(**{"size (training / validation)": "1,000 (800 / 200)"}),
        "best epoch of last",
        whole=True,
    ),
    # the overflow tanks (bench_overflow_tanks.py): test RMSE per contestant, events per part
    **{
        f"overflow/rmse/{who}": Cell("Overflow tanks", _row(model=model), "RMSE [V]")
        for who, model in (
            ("defaults", "canonid defaults (Ours (MLP))"),
            ("l10", "Ours (MLP), ℓ = 10"),
            ("classic-gru", "Classic GRU"),
            ("arx", "ARX (linear)"),
            ("deepsi", "deepSI SUBNET (its defaults)"),
        )
    },
    **{
        f"overflow/{part}/{what}": Cell("Overflow tanks", _row(part=part), column, whole=True)
        for part in ("training", "validation", "test")
        for what, column in (
            ("samples", "samples"),
            ("rim", "at the rim (episodes)"),
            ("sensor", "at the sensor limit (episodes)"),
        )
    },
    **{
        f"overflow/validation/{who}": Cell("Overflow tanks", _row(run=run), "best validation loss")
        for who, run in (
            ("l10", "Ours (MLP), ℓ = 10"),
            ("l20", "ℓ = 20"),
            ("h64", "hidden 64 × 64 × 64"),
        )
    },
    # the defaults' window screen there (the section's screen lines): each window's screen loss,
    # then the epoch at which the full run at ℓ = 10 ended and its budget of epochs
    **{
        f"overflow/screen/l{ell}": Prose(
            "Overflow tanks", rf"ℓ: best validation loss [^)]*?\b{ell}: ([\d.e-]+)"
        )
        for ell in (10, 20)
    },
    # the spread over training seeds and data draws (bench_overflow_tanks.py --spread D S)
    "overflow/spread/below": Prose(
        "Overflow tanks", r"canonid's defaults below deepSI's in (\d+) of (\d+) cells"
    ),
    "overflow/spread/cells": Prose(
        "Overflow tanks", r"canonid's defaults below deepSI's in (\d+) of (\d+) cells", group=2
    ),
    "overflow/spread/geomean": Prose("Overflow tanks", r"geometric mean ([\d.]+)\)"),
    **{
        f"overflow/spread/d{d}s{s_}/{who}": Cell(
            "Overflow tanks",
            _row(**{"data seed D": str(d), "training seed S": str(s_)}),
            column,
        )
        for d, s_ in ((0, 1), (0, 2), (1, 0), (2, 0), (3, 0), (4, 0))
        for who, column in (
            ("defaults", "canonid defaults"),
            ("deepsi", "deepSI (its defaults)"),
            ("ratio", "deepSI / canonid"),
        )
    },
    # the validation part's span of the level in a spread cell, and the training samples beyond
    **{
        f"overflow/spread/d4s0/{what}": Cell(
            "Overflow tanks",
            _row(**{"data seed D": "4", "training seed S": "0"}),
            "validation span of the level; training samples outside it",
            pick=pick,
        )
        for what, pick in (("val-low", 0), ("val-high", 1), ("unseen", 2))
    },
    "overflow/valblock/geomean": Prose(
        "Validation block on one record (overflow tanks)", r"geometric mean ([\d.]+) over"
    ),
    "overflow/activation/validation": Prose(
        "Activation on one record (overflow tanks)", r"validation loss ([\d.]+) \(lower in"
    ),
    "overflow/activation/records": Prose(
        "Activation on one record (overflow tanks)", r"other draws' records ([\d.]+) \(lower"
    ),
    "overflow/full/l10/ended": Prose("Overflow tanks", _OVERFLOW_L10_FULL),
    "overflow/full/l10/budget": Prose("Overflow tanks", _OVERFLOW_L10_FULL, group=2),
    # the ARX start (round 1 of the defaults study), seed 0: score, and on the drone CPU seconds
    **{
        f"arx-start/{system}/0": Cell(
            "Defaults study", _row(system=system, seed="0"), "3e-3, clip 1, ARX start"
        )
        for system in ("tank", "silverbox", "drone2d")
    },
    "arx-start/drone2d/0/cpu": Cell(
        "Defaults study", _row(system="drone2d", seed="0"), "3e-3, clip 1, ARX start", pick=2
    ),
    "epochs900/silverbox/0": Cell(
        "Defaults study", _row(system="silverbox", seed="0"), "3e-3, 900 epochs"
    ),
    # the quick profile's rollouts and batches (round 2 of the defaults study): before, now
    **{
        f"budget/{slug}/{when}": Cell(
            "Quick profile: rollout length and batch", _row(data=label), column
        )
        for slug, label in (
            ("tank/0", "tank, test 100-step MSE vs y_clean, seed 0"),
            ("tank/1", "tank, seed 1"),
            ("tank/2", "tank, seed 2"),
            ("drone2d", "planar drone (`drone2d-small`), best val MSE (norm.) / test 100-step MSE"),
            ("silverbox", "Silverbox multisine test RMSE"),
        )
        for when, column in (
            ("before", "H 100, batch 16, 240 sub-windows/epoch (before)"),
            ("now", "H 50, batch 32, 480 sub-windows/epoch (now)"),
        )
    },
    # bench_silverbox.py's variants under the profile before: the default, the ARX start
    **{
        f"silverbox-variants/{name}": Cell("Silverbox", _row(variant=variant), "test RMSE [mV]")
        for name, variant in (
            ("default", "**default** (`--variants default`)"),
            ("linear", "`--linear` (`--variants linear`)"),
        )
    },
    "lr5e-3/tank/0": Cell("Defaults study", _row(system="tank", seed="0"), "5e-3"),
    "lr5e-3/tank/1": Cell("Defaults study", _row(system="tank", seed="1"), "5e-3"),
    "lr5e-3/tank/2": Cell("Defaults study", _row(system="tank", seed="2"), "5e-3"),
    # deepSI's SUBNET against Ours (MLP) at the same CPU budget
    **{
        f"deepsi/{system}/{who}/{target}": Cell(
            "Identification versus deepSI", _row(model=model), f"100-step MSE, {target}", nth=nth
        )
        for nth, system in enumerate(("tank", "drone2d"))
        for who, model in (("ours", "Ours (MLP)"), ("subnet", "deepSI SUBNET"))
        for target in ("y", "y_clean")
    },
    **{
        f"deepsi/{system}/{who}/{what}": Cell(
            "Identification versus deepSI", _row(model=model), column, nth=nth
        )
        for nth, system in enumerate(("tank", "drone2d"))
        for who, model in (("ours", "Ours (MLP)"), ("subnet", "deepSI SUBNET"))
        for what, column in (
            ("rmse", "RMSE after n_init, y"),
            ("best-val", "best val MSE (norm.)"),
            ("steps", "optimiser steps"),
        )
    },
    # the training CPU seconds each took to reach the validation MSE both reached
    **{
        f"deepsi/{system}/reach/{who}": Prose(
            "Identification versus deepSI",
            rf"### {system}:[\s\S]*?\(both reached\) \| (\d+) s \| (\d+) s \|",
            group,
        )
        for system in ("tank", "drone2d")
        for group, who in ((1, "ours"), (2, "subnet"))
    },
    # bench_training.py: accelerations of Ours (MLP) over its baseline; batched evaluation; the
    # wall seconds of the quick tank run to within 2× of its best validation MSE, and to it
    **{
        f"training/{name}": Cell(
            "Training throughput", _row(**{"variant (Ours (MLP))": variant}), "vs baseline"
        )
        for name, variant in (
            ("batch256", "1 thread, batch 256"),
            ("threads2", "2 threads, batch 16"),
            ("compile", "torch.compile(regressor), batch 16"),
        )
    },
    # bench_training.py: the default network's training step, hand-written back-propagation
    # against autograd through the step-by-step rollout (speed-up), with and without the branch
    **{
        f"training/bptt/{name}": Cell(
            "Training throughput",
            _row(**{"network (batch 32, H = 50, 1 thread)": network}),
            "speed-up [×]",
        )
        for name, network in (
            ("plain", "3 × 256 SiLU, skip, residual"),
            ("cubic", "3 × 256 SiLU, skip, residual, 16 cubic units"),
        )
    },
    "training/batched-evaluation": Prose(
        "Training throughput", r"\((\d+)× slower; `evaluate` batches them\)"
    ),
    **{
        f"training/target/{factor}x": Prose(
            "Training throughput", rf"≤ {factor} × final best \([\d.e-]+\) \| \d+ \| (\d+) \|"
        )
        for factor in (1, 2)
    },
    # bench_memory.py: peak RSS in MiB (the process's; with Dask, the process tree's)
    **{
        f"memory/{name}": Cell("Memory", _row(case=case), column)
        for name, case, column in (
            ("generate/54", "generate drone2d, 54 flights × 600, serial", "peak RSS, process MiB"),
            (
                "generate/540",
                "generate drone2d, 540 flights × 600, serial",
                "peak RSS, process MiB",
            ),
            (
                "generate/540/dask",
                "generate drone2d, 540 flights × 600, 2 Dask workers",
                "peak RSS, tree MiB",
            ),
            *(
                (
                    f"train/{slug}/{n}",
                    f"train Ours (MLP), paper profile, {n} epoch(s), {data}",
                    "peak RSS, process MiB",
                )
                for slug, data in (("drone2d", "drone2d (540 flights)"), ("tank", "tank"))
                for n in (1, 3)
            ),
        )
    },
    "memory/per-flight": Prose("Memory", r"each extra flight costs (\d+) KiB"),
    "memory/per-flight-ratio": Prose("Memory", r"flights\), ([\d.]+)× the \d+ KiB"),
    # the simulated quadrotor: Ours (MLP)'s 100-step MSE per window, and holding the last sample
    **{
        f"quadrotor/{ell}/{who}": Cell(
            "Quadrotor Ours (MLP), simulated stand-in", _row(**{"ℓ": str(ell)}), column
        )
        for ell in (5, 10, 20, 30)
        for who, column in (
            ("mlp", "simulated stand-in, vs measured y (×1e-2)"),
            ("hold", "hold-last baseline, same rollouts (×1e-2)"),
        )
    },
    # bench_quadrotor.py: the NMPC against the cascade on the 13-state quadrotor
    **{
        f"quadrotor-stand-in/{name}": Cell(
            "Quadrotor stand-in", _row(quantity=quantity), "value", pick=pick
        )
        for name, quantity, pick in (
            (
                "rmse/nmpc",
                "position RMSE, NMPC / cascade (4 flights × 400 samples, no excitation)",
                0,
            ),
            (
                "rmse/cascade",
                "position RMSE, NMPC / cascade (4 flights × 400 samples, no excitation)",
                1,
            ),
            ("step/nmpc", "NMPC (fatrop-c, N = 20), median / p95 per step", 0),
            ("step/cascade", "cascade on the same flights, median / p95 per step", 0),
            ("dataset/serial", "176 flights × 1000 samples, serial (measured)", 0),
            (
                "dataset/dask",
                "176 flights, 2 Dask worker processes incl. cluster start (measured)",
                0,
            ),
        )
    },
    "quadrotor-stand-in/nmpc-dataset-min": Prose(
        "Quadrotor stand-in", r"would need about (\d+) min of solver time"
    ),
    # the published Silverbox baselines (Champneys et al. 2024)
    "silverbox/published-gru": Code(lambda: _published("silverbox", "multisine", "GRU")),
    # `canonid benchmark silverbox`: canonid's defaults and the published recurrent baselines
    **{
        f"benchmark/silverbox/{part}/{who}": Cell(
            "Standard benchmarks", _row(**{"test part": part}), column
        )
        for part in ("multisine", "arrow-full", "arrow-no-extrapolation")
        for who, column in (
            ("canonid", "canonid [mV]"),
            ("gru", "GRU"),
            ("lstm", "LSTM"),
            ("gp-narx", "GP NARX"),
            ("dt-subnet", "DT SUBNET"),
            ("pnlss", "PNLSS"),
        )
    },
    # the runs of the same command side by side: this one, and the Intel and AMD runs made when
    # the cubic test trained one seed per network (its ratio and the scores of each)
    **{
        f"benchmark/silverbox/{name}{what}": Cell(
            "Standard benchmarks", _row(CPU=cpu), column, pick=pick
        )
        for name, cpu in (
            ("", "AMD EPYC, this run"),
            ("amd/", "AMD EPYC"),
            ("intel/", "Intel Xeon"),
        )
        for what, column, pick in (
            ("multisine", "multisine [mV]", 0),
            ("arrow-full", "arrow-full [mV]", 0),
            ("arrow-no-extrapolation", "arrow-no-extrapolation [mV]", 0),
            ("cubic-ratio", "branch / plain loss on the held-out peaks", 2),
        )
        if name or what == "cubic-ratio"  # this run's scores are the main table's
    },
    # that run's CPU minutes, and those of the earlier run with ℓ = 10 given (no window screen)
    "benchmark/silverbox/cpu-min": Prose(
        "Standard benchmarks", r"Wall [\d.]+ min, CPU ([\d.]+) min"
    ),
    "benchmark/silverbox/wall-min": Prose("Standard benchmarks", r"Wall ([\d.]+) min, CPU"),
    # the same command with --threads 1 on a shared machine (the runs' table)
    "benchmark/silverbox/threads1/cpu-min": Cell(
        "Standard benchmarks", _row(CPU="AMD EPYC, `--threads 1`, shared"), "CPU [min]"
    ),
    "benchmark/silverbox/window-10/cpu-min": Prose(
        "Standard benchmarks",
        r"ℓ = 10 given \(before the window screen\): [^;]*? in ([\d.]+) CPU minutes",
    ),
    # bench_datagen.py: the drone NMPC's step per controller, first use of the compiled solver,
    # CPU per flight of both loops and of the solver alone, start-up, the paper-size dataset on
    # 2 workers, the targets, and how the record reads the day (the machine, an A/B in it)
    **{
        f"datagen/step/{name}": Cell("Data engine", _row(controller=controller), column)
        for name, controller, column in (
            ("median", _DATAGEN_DEFAULT, "median ms/step"),
            ("p95", _DATAGEN_DEFAULT, "p95 ms/step"),
            ("plugin", "NMPC, fatrop plugin (no compiler)", "median ms/step"),
            ("opti", "baseline: Opti + IPOPT (defaults, warm start)", "median ms/step"),
        )
    },
    "datagen/speed-up": Cell(
        "Data engine", _row(controller=_DATAGEN_DEFAULT), "speed-up vs Opti (median)"
    ),
    "datagen/rmse": Cell("Data engine", _row(controller=_DATAGEN_DEFAULT), "RMSE position [m]"),
    **{
        f"datagen/cpu/{name}/{what}": Cell("Data engine", _row(loop=loop), column)
        for name, loop in (
            ("step", "step loop (one Python call into CasADi per solve and per f)"),
            ("compiled", "compiled loop (chunks of 50 steps, one CasADi call each; default)"),
            ("solver", "solver alone (the flight's 600 solves replayed in one mapped call)"),
        )
        for what, column in (("ms", "ms per flight"), ("ratio", "× solver alone"))
    },
    **{
        f"datagen/{name}": Prose("Data engine", pattern, group)
        for name, pattern, group in (
            ("date", r"— (\d{4}-\d\d-\d\d) \d\d:\d\d UTC", 1),
            ("load/start", r"at the start and after each part: ([\d.]+) /", 1),
            ("load/end", r"/ ([\d.]+) \(this benchmark's own", 1),
            ("first-use/wall", r"First use of the default solver [^:]*: ([\d.]+) s wall", 1),
            ("first-use/gcc", r"s wall \(([\d.]+) s CPU in gcc\)", 1),
            ("outside-solver/step", r"Outside the solver: (\d+)% of the step loop's", 1),
            ("outside-solver/compiled", r"step loop's CPU, (\d+)% of the compiled", 1),
            ("startup/cluster", r"closed, ([\d.]+) s wall", 1),
            ("startup/import", r"importing the data engine [\d.]+ s wall \(([\d.]+) s CPU\)", 1),
            ("startup/nmpc", r"from the cached library [\d.]+ s wall \(([\d.]+) s CPU\)", 1),
            ("startup/python-control", r"python-control import [^.]*? took ([\d.]+) s", 1),
            ("dataset/wall", r"measured: ([\d.]+) s for 540 flights", 1),
            ("dataset/workers", r"CPU: workers [\d.]+ s \((\d+) ms per flight", 1),
            ("dataset/main", r"dataset file\) [\d.]+ s \(([\d.]+) ms per flight\)", 1),
            ("dataset/bound", r"2 cores = (\d+) s", 1),
            ("dataset/bound-ratio", r"the run took ([\d.]+)× that", 1),
            ("target/step", r"median step ≤ ([\d.]+) ms", 1),
            ("target/dataset", r"paper-size dataset ≤ (\d+) s", 1),
            ("solver-before", r"against (\d+) ms in the previous\s+record", 1),
            ("ab/nmpc", r"NMPC call ([\d.]+) ms \(base ([\d.]+)\)", 1),
            ("ab/nmpc-base", r"NMPC call ([\d.]+) ms \(base ([\d.]+)\)", 2),
            ("took", r"This benchmark took ([\d.]+) min", 1),
        )
    },
    # bench_dask_overhead.py: an idle cluster's CPU ms per second, and CPU ms per drone flight,
    # under Dask's defaults and canonid's settings
    **{
        f"dask/{what}/{name}": Cell("Dask overhead", _row(settings=settings), column)
        for name, settings in (("defaults", "Dask defaults"), ("canonid", _CANONID_CLUSTER))
        for what, column in (("idle", "total"), ("per-flight", "CPU ms per flight"))
    },
    # bench_analysis.py: seconds of the certified γ_f to 5 %, of α_2 and α_3 (200,000 boxes)
    # and of 10⁴ Monte-Carlo trials with one start; the re-run's wall times over the run before
    "analysis/gamma-5pct": Cell("Analysis cost", _row(tolerance="0.05"), "seconds"),
    **{
        f"analysis/alpha{ell}": Cell(
            "Analysis cost", _row(**{"ℓ": str(ell), "box budget": "200000"}), "seconds", nth=1
        )
        for ell in (2, 3)
    },
    "analysis/monte-carlo": Cell("Analysis cost", _row(**{"argmin starts": "1"}), "seconds", nth=2),
    "analysis/slower": Prose("Analysis cost", r"Wall times are about ([\d.]+)× the old ones"),
    # how long `make demo` takes, and what it runs
    "demo/wall": Cell("make demo", _row(run=DEMO_RUN), "wall time", whole=True),
    # the tank's reductions of the Reduction page (benchmarks/reduce_record.py)
    **{
        f"reduce/single/{row}/{what}": Cell(REDUCTION, _row(model=label), column)
        for row, label in (
            ("full", "full Ours (MLP), ℓ = 10"),
            ("reduced", "reduced, r = 60 %"),
        )
        for what, column in (
            ("y", "vs measured y"),
            ("clean", "vs y_clean"),
            ("fit", "fit % (y_clean, after n_init = 50)"),
        )
    },
    "reduce/single/ratio": Prose(REDUCTION, r"Reduced over full: ([\d.]+)× \(measured\)"),
    "reduce/single/ratio-clean": Prose(REDUCTION, r"× \(measured\), ([\d.]+)× \(noise-free\)"),
    **{
        f"reduce/sweep/{window}/{rate}": Cell(
            REDUCTION, _row(**{"ℓ": str(window), "r": f"{rate} %"}), "reduced / full"
        )
        for window in (5, 10)
        for rate in (15, 30, 45, 60, 75, 90)
    },
    # Table 1 and the compression study of the demo run the Results page shows
    **{
        f"demo/t1/{slug}/{window}/{target}": Cell(
            DEMO_TABLES, _row(**{"model": label, "ℓ": str(window)}), column
        )
        for slug, label, windows in _DEMO_MODELS
        for window in windows
        for target, column in (("y", "measured y"), ("clean", "noise-free y"))
    },
    **{
        f"drone/t1/{slug}/{window}": Cell(
            DRONE_TABLES, _row(**{"model": label, "ℓ": str(window)}), "measured y"
        )
        for slug, label, windows in _DEMO_MODELS
        for window in windows
    },
    **{
        f"drone/compression/{rate}/{what}": Cell(
            DRONE_TABLES, _row(compression=f"{rate} %"), column
        )
        for rate in (30, 60, 90)
        for what, column in (("reduced", "reduced"), ("full", "full"))
    },
    **{
        f"demo/compression/{rate}/{what}": Cell(DEMO_TABLES, _row(compression=f"{rate} %"), column)
        for rate in (30, 60, 90)
        for what, column in (("reduced", "reduced"), ("full", "full"), ("ratio", "reduced / full"))
    },
    # the quick profile's training budget (canonid/profiles.py)
    "device/threshold": Code(lambda: _auto_cuda_work() / 1e6),
    "device/gpu/256/512": Cell(
        "Device", _row(widths="256 × 256 × 256", K="512"), "GPU candidate-epochs per s"
    ),
    "code/feedthrough-gain": Code(lambda: _feedthrough_gain()),
    "code/pool-min-steps": Code(lambda: _jobs().POOL_MIN_STEPS),
    "code/noted-beyond": Code(lambda: f"{100 * _coverage().NOTED_BEYOND:g}"),
    "code/unvalidated-share": Code(lambda: f"{100 * _coverage().UNVALIDATED_SHARE:g}"),
    # Silverbox's defaults with the short trainings side by side or one after the other
    **{
        f"candidates/{slug}/{what}": Cell(CANDIDATES, _row(run=run), column)
        for slug, run in (("side", "side by side"), ("sequential", "one after the other"))
        for what, column in (("wall", "wall [min]"), ("cpu", "CPU [min]"))
    },
    # the hand-added row of `canonid train --members 4` flown in the same section
    **{
        f"learned-mpc-members/{what}": Cell(
            LEARNED_MPC_MEAN,
            _row(**{"prediction model (members)": _MEMBERS_LOOP}),
            column,
            whole=what == "left",
        )
        for what, column in (
            ("ratio", "loop ratio, members"),
            ("left", "loops out of X, members"),
            ("px", "px from rest, members"),
        )
    },
    # seeds of one recipe on small records (members_study.py): validation, then the test
    **{
        f"members/{slug}/{what}": Cell(MEMBERS, _row(record=record), column, whole=whole)
        for slug, record, _ in _MEMBER_RECORDS
        for what, column, whole in (
            ("val-k2", "kept / seed 0, K = 2", False),
            ("val-k3", "kept / seed 0, K = 3", False),
            ("keeps-k2", "K = 2 keeps", True),
            ("keeps-k3", "K = 3 keeps", True),
        )
    },
    **{
        f"members/{slug}/test/{what}": Cell(MEMBERS, _row(record=record, part=part), column)
        for slug, record, part in _MEMBER_RECORDS
        for what, column in (("defaults", "defaults (seed 0)"), ("k2", "K = 2"), ("k3", "K = 3"))
    },
    # canonid's cubic test per system (extrapolation_study.py decide): held-out loss ratio
    **{
        f"cubic/decision/{system}": Cell("Extrapolation", _row(system=system), "ratio", nth=1)
        for system in ("silverbox", "masses", "silverbox-3k", "silverbox-10k", "tank", "drone2d")
    },
    # the cubic test across seeds (cubic_seeds.py): each seed's ratio, and how often a rule
    # agrees with the full runs' verdict on the worst system
    **{
        f"cubic-seeds/{system}/median": Cell(SEEDS_SECTION, _row(system=system), "median")
        for system in ("silverbox", "tank", "drone2d")
    },
    "cubic-seeds/silverbox/seeds": Cell(SEEDS_SECTION, _row(system="silverbox"), "seeds"),
    **{
        f"cubic-seeds/worst/{pool}{k}": Cell(
            SEEDS_SECTION,
            _row(system="**agreeing with the verdict, worst system**"),
            f"{pool}, k = {k}",
        )
        for pool, k in (("min", 1), ("min", 3))
    },
    "cubic-seeds/silverbox/min1": Cell(SEEDS_SECTION, _row(system="silverbox"), "min, k = 1"),
    "cubic-seeds/silverbox/min3": Cell(SEEDS_SECTION, _row(system="silverbox"), "min, k = 3"),
    "code/horizon-check-k": Code(lambda: _horizon_check().CHECK_K),
    "code/horizon-alternative/first": Code(lambda: _horizon_check().ALTERNATIVES[0]),
    "code/horizon-alternative/second": Code(lambda: _horizon_check().ALTERNATIVES[1]),
    # the defaults on the informative drone data (learned_mpc.py, and the hand note beside it),
    # before and with the horizon ladder
    **_loop_figures("learned-mpc/defaults", LEARNED_MPC_DEFAULTS, "mlp, horizon 10"),
    **_loop_figures("learned-mpc/ladder", LEARNED_MPC_LADDER, "mlp, horizon 20"),
    **{
        f"learned-mpc/ladder/{slug}/{what}": Cell(
            LEARNED_MPC_LADDER, _row(data=data), column, pick=pick
        )
        for slug, data in (("s0", "`drone2d-id`, seed 0"), ("s1", "`drone2d-id`, seed 1"))
        for what, column, pick in (
            ("h50", "H = 50 / 20 / 10: outside", 0),
            ("h20", "H = 50 / 20 / 10: outside", 1),
            ("val-before", "earlier defaults (H = 10): val loop", 0),
            ("val", "the ladder: val loop", 0),
        )
    },
    "learned-mpc/ladder/s1/test": Prose(
        LEARNED_MPC_LADDER, r"--json runs/hz5/loop-s1-test\.json`\): \*\*([\d.]+)\*\*"
    ),
    # the hand-added table of the same section: the defaults on two more drone datasets
    "learned-mpc/defaults-s1/px-rest": Cell(
        LEARNED_MPC_DEFAULTS, _row(kept="H = 10, ℓ = 10"), "px change, rest / recorded"
    ),
    "learned-mpc/defaults-s1/test": Cell(
        LEARNED_MPC_DEFAULTS, _row(kept="H = 10, ℓ = 10"), "test refs (loops out)"
    ),
    "learned-mpc/defaults-paper/test": Cell(
        LEARNED_MPC_DEFAULTS, _row(kept="H = 10, ℓ = 20"), "test refs (loops out)"
    ),
    # the same section's table of the three runs with --members 3: the test loop's ratio
    **{
        f"learned-mpc/members3/{slug}/test": Cell(
            LEARNED_MPC_DEFAULTS,
            _row(data=data),
            "test refs: single run → with members (loops out)",
            pick=1,
        )
        for slug, data in (
            ("s0", "`drone2d-id`, seed 0"),
            ("s1", "`drone2d-id`, seed 1"),
            ("paper", "`drone2d`, the paper's design"),
        )
    },
    "learned-mpc/paper-design/ratio": Prose(
        "NMPC on a learned model", r"drone2d: ratio learned / true tracking RMSE \*\*([\d.]+)\*\*"
    ),
    # the option --members 3 on the overflow tanks (a hand-added row of that section)
    **{
        f"overflow/members3/{what}": Cell(
            "Overflow tanks", _row(run="canonid defaults + `--members 3`"), column
        )
        for what, column in (("test", "test RMSE [V]"), ("cpu", "CPU s, run and members"))
    },
    "learned-mpc/defaults-now/mean-solve": Prose(
        LEARNED_MPC_DEFAULTS, r"NMPC on the kept mean solves about ([\d.]+)× slower"
    ),
    # the check on the validation flights (the section's correction), the seed-0 data
    **{
        f"horizon-check/drone2d-id/{which}": Cell(
            LEARNED_MPC_DEFAULTS,
            _row(data="`drone2d-id`, seed 0"),
            "the check on validation: H = 50 / H = 10, outside / 60",
            pick=pick,
        )
        for which, pick in (("own", 0), ("alternative", 1))
    },
    # the defaults behind the check (members) on five drone datasets: test refs, single and now
    **{
        f"learned-mpc/defaults-now/{slug}/{what}": Cell(
            LEARNED_MPC_DEFAULTS, _row(data=data), column
        )
        for slug, data in (
            ("s0", "`drone2d-id`, seed 0"),
            ("s1", "`drone2d-id`, seed 1"),
            ("paper", "`drone2d`, the paper's design"),
            ("s2", "`drone2d-id`, seed 2"),
            ("s3", "`drone2d-id`, seed 3"),
        )
        for what, column in (
            ("single", "single run: learned / true, test refs (loops out)"),
            ("test", "the defaults now: test refs (loops out)"),
        )
    },
    **{
        f"learned-mpc/defaults-now/{slug}/val-{which}": Cell(
            LEARNED_MPC_DEFAULTS,
            _row(data=data),
            "validation refs: single → kept (loops out)",
            pick=pick,
        )
        for slug, data in (("s1", "`drone2d-id`, seed 1"), ("s3", "`drone2d-id`, seed 3"))
        for which, pick in (("single", 0), ("kept", 2))
    },
    "horizon-check/drone2d-id/val-ratio": Prose(
        LEARNED_MPC_DEFAULTS, r"learned / true (\d+\.\d+) \("
    ),
    # where the short θ comes from (validation flights): the step a quarter as large, after 20
    # samples; the seed-0 member with the fewest correlations: its θ and its validation loop
    "learned-mpc/by-size/s0/quarter-20": Cell(
        LEARNED_MPC_DEFAULTS,
        _row(**{"data (the kept model)": "`drone2d-id`, seed 0 (ℓ = 40, seed 0)"}),
        "× 0.25, 20",
    ),
    "learned-mpc/candidates/s0-member2/theta": Cell(
        LEARNED_MPC_DEFAULTS,
        _row(data="seed 0", model="ℓ = 40, seed 2 (member)"),
        "px, θ: learned / true, recorded states",
        pick=1,
    ),
    "learned-mpc/candidates/s0-member2/outside": Cell(
        LEARNED_MPC_DEFAULTS,
        _row(data="seed 0", model="ℓ = 40, seed 2 (member)"),
        "k = 10 correlations outside the band, of 60",
    ),
    "learned-mpc/candidates/s0-member2/val-loop": Prose(
        LEARNED_MPC_DEFAULTS, r"seed-2 member tracks at \*\*([\d.]+)×"
    ),
    # the records too short for the cubic test's peaks (cubic_fallback.py): cubic / plain
    **{
        f"cubic-fallback/{slug}/{which}": Cell(
            "Cubic test on validation", _row(record=label), column
        )
        for slug, label in (
            ("silverbox-1k", "Silverbox, first 1,000 samples (800 / 200)"),
            ("overflow-tanks", "overflow tanks, 1,024 samples (819 / 205)"),
        )
        for which, column in (
            ("short-ratio", "short: best cubic / best plain"),
            ("full-ratio", "full: cubic / plain"),
        )
    },
    **{
        f"window/{system}/chosen": Cell(
            "Window on validation",
            (("system", system), ("fraction (epochs)", "0.1 (60)")),
            "the rule (×1.6)",
        )
        for system in ("tank", "drone2d", "silverbox", "masses")
    },
    "quick/train/epochs": Code(_quick("train", "epochs")),
    "quick/train/weight_decay": Code(_quick("train", "weight_decay")),
    "quick/train/horizon": Code(_quick("train", "horizon")),
    "quick/train/val_horizon": Code(_quick("train", "val_horizon")),
    "quick/train/batch_size": Code(_quick("train", "batch_size")),
    "quick/train/windows_per_epoch": Code(_quick("train", "windows_per_epoch")),
    "quick/train/lr": Code(_quick("train", "lr")),
    # the training rollout length on validation (horizon_study.py): H = 10 against H = 50
    **{
        f"horizon/{system}/{what}": Cell(HORIZON_STUDY, _row(system=system), column)
        for system in ("drone2d-id", "drone2d", "tank", "silverbox", "masses")
        for what, column in (
            ("ratio", "H = 10 / H = 50"),
            ("cpu50", "CPU s, H = 50"),
            ("cpu10", "CPU s, H = 10"),
        )
    },
    **{
        f"horizon/{system}/ramp": Cell(HORIZON_STUDY, _row(system=system, C="300"), "/ H = 50")
        for system in ("drone2d-id", "tank")
    },
    # the informative drone data's candidates: validation beside the NMPC loop
    **_grid(
        "horizon-loop",
        HORIZON_STUDY,
        "run",
        (
            ("defaults", "`runs/drone2d/id-def`"),
            ("h10", "`runs/drone2d/id-h10`"),
            ("ramp300", "`runs/hz/drone-id-c300`"),
            ("arx", "`runs/drone2d/arx-l10-drone2d-id`"),
        ),
        (
            ("val100", "best validation loss (100 samples)"),
            ("val20", "validation MSE, 20 samples"),
            ("ratio", "learned / true tracking RMSE"),
            ("px", "px change, learned / true"),
        ),
    ),
    # residuals against the excitation (excitation_check.py): correlations outside the 99 %
    # band at k = 1 (of 6) and k = 10 (of 60), per run and for the noise itself
    **{
        f"excitation/{slug}/k{k}": Cell(
            EXCITATION_CHECK, _row(run=run, k=str(k)), "excitation e + d, AR(10)"
        )
        for slug, run in (
            ("noise", "noise y − y_clean (reference: uses the true outputs)"),
            ("defaults", "`runs/drone2d/id-def`"),
            ("ramp300", "`runs/hz/drone-id-c300`"),
            ("linear-arx", "`runs/drone2d/id-arx`"),
            ("h10", "`runs/drone2d/id-h10`"),
            ("arx", "`runs/drone2d/arx-l10-drone2d-id`"),
        )
        for k in (1, 10)
    },
    # the check's blind test on six more seeds (hand-added table): its count, the loop after it
    **{
        f"excitation/blind/{run}/{what}": Cell(
            EXCITATION_CHECK, _row(**{"blind run": f"`{run}`"}), column
        )
        for run in ("id-def-s1", "id-h10-s1", "id-h10-s2", "id-h10-s3", "id-h10-s4", "id-h10-s5")
        for what, column in (
            ("k10", "excitation, AR(10), k = 10: outside / 60"),
            ("ratio", "blind loop RMSE ratio"),
            ("px", "blind px learned / true"),
            ("val", "best validation loss (epoch)"),
        )
    },
    # NMPC on drone models learned from the paper's and the informative drone data
    # (learned_mpc.py): learned / true tracking RMSE, loops out of X, step-response ratios
    **{
        f"learned-mpc/{slug}/{what}": Cell(LEARNED_MPC_ID, _row(model=model, data=data), *column)
        for slug, model, data in _LEARNED_MPC_RUNS
        for what, column in (
            ("ratio", ("learned / true tracking RMSE",)),
            ("left", ("learned loops that left X", True)),
        )
    },
    # NMPC on the mean of several seeds (learned_mpc.py RUN+RUN+…): the goals table's cells
    **{
        f"learned-mpc-mean/{slug}/{what}": Cell(
            LEARNED_MPC_MEAN, _row(model=model, data="drone2d-id", output="px"), *column
        )
        for slug, model in _LEARNED_MPC_MEANS
        for what, column in (
            ("ratio", ("learned / true tracking RMSE",)),
            ("left", ("learned loops that left X", True)),
            ("px", ("learned / true change, from rest",)),
        )
    },
    # the hand-added second batch of seeds in the same section
    **_grid(
        "learned-mpc-mean",
        LEARNED_MPC_MEAN,
        "prediction model (second batch)",
        (
            ("s6", "seed 6 alone"),
            ("s8", "seed 8 alone"),
            ("pair", "mean of seeds 6 and 8"),
            ("pass6", "mean of the six that pass (0, 2, 3, 4, 6, 8)"),
        ),
        (
            ("ratio", "loop ratio, second batch"),
            ("left", "loops out of X, second batch"),
            ("px", "px from rest, second batch"),
            ("seventh", "seventh reference, learned [m]"),
        ),
        whole=("left",),
    ),
    **{
        f"learned-mpc/{slug}/{output}/{start}": Cell(
            LEARNED_MPC_ID,
            _row(model=model, data=data, output=output),
            f"learned / true change, {column}",
        )
        for slug, model, data in _LEARNED_MPC_RUNS
        for output in ("px", "theta")
        for start, column in (("recorded", "recorded states"), ("rest", "from rest"))
    },
}


def _horizon_check() -> Any:
    from canonid import horizon_check

    return horizon_check


def _feedthrough_gain() -> float:
    from canonid.learning.linear import FEEDTHROUGH_GAIN

    return FEEDTHROUGH_GAIN


def _coverage() -> Any:
    """Where scores leave the training range (the tables' threshold)."""
    from canonid import coverage

    return coverage


def _auto_cuda_work() -> int:
    from canonid.learning.training import AUTO_CUDA_WORK

    return AUTO_CUDA_WORK


def _published(name: str, test: str, method: str) -> str:
    from canonid.datagen.benchmarks import benchmark

    found = [b.figure for b in benchmark(name).baselines if b.method == method and b.test == test]
    if not found:
        raise KeyError(f"no published {method} figure on {name} {test}")
    return found[0]


@cache
def _sections() -> dict[str, str]:
    text = RESULTS.read_text(encoding="utf-8")
    found = re.findall(r"<!-- BEGIN (.+?) -->\n(.*?)<!-- END \1 -->", text, re.S)
    return dict(found)


def _tables(section: str) -> list[tuple[list[str], list[list[str]]]]:
    """The Markdown tables of one RESULTS.md section: (header, rows of cells)."""
    body = _sections().get(section)
    if body is None:
        raise KeyError(f"{RESULTS.name} has no section {section!r}")
    tables, lines = [], body.splitlines()
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and line.startswith("|") and re.match(r"^\|[-:| ]+\|$", lines[i + 1]):
            rows = []
            for row in lines[i + 2 :]:
                if not row.startswith("|"):
                    break
                rows.append(_cells(row))
            tables.append((_cells(line), rows))
    return tables


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _number(text: str) -> Decimal | None:
    cleaned = text.replace("−", "-").replace(",", "").rstrip(".;:")
    try:
        return Decimal(cleaned)
    except InvalidOperation:
        return None


def agrees(quoted: str, source: str) -> bool:
    """Whether ``quoted`` is ``source`` rounded to the digits it shows (or, for text, equal)."""
    q, s = _number(quoted), _number(source)
    if q is None or s is None:
        return quoted == source
    half_unit = Decimal(1).scaleb(q.as_tuple().exponent) / 2
    return abs(q - s) <= half_unit * (1 + Decimal("1e-9"))


def value(key: str) -> str:
    """The source's value of ``key`` (KeyError naming what is missing)."""
    if key not in FIGURES:
        raise KeyError(f"no figure {key!r} in docs/hooks/figures.py FIGURES")
    return FIGURES[key].value()


def check(text: str, where: str) -> list[str]:
    """One line per marker of ``text`` whose quoted figure disagrees with its source."""
    problems = []
    for match in MARKER.finditer(text):
        key = match["key"]
        line = text.count("\n", 0, match.start()) + 1
        try:
            expected = value(key)
        except KeyError as err:
            problems.append(f"{where}:{line}: {err.args[0]}")
            continue
        before = text[: match.start()]
        if _number(expected) is None:
            ok = before.endswith(expected)
            quoted = before[-len(expected) - 10 :].strip()
        else:
            quoted = re.split(r"[\s(|/*`=×]", before.rstrip())[-1]
            ok = agrees(quoted, expected)
        if not ok:
            problems.append(
                f"{where}:{line}: {quoted!r} quotes {key}, whose source says {expected}"
            )
    return problems


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    """Warn (a failure of the strict build) for every figure that disagrees with its source."""
    for problem in check(markdown, page.file.src_path):
        log.warning(problem)
    return markdown


if __name__ == "__main__":
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    problems = [p for page in pages for p in check(page.read_text(encoding="utf-8"), str(page))]
    print("\n".join(problems) or "every quoted figure agrees with its source")
