"""What ``canonid generate`` asks for, and the one call that does it: a closed-loop dataset.

:func:`generate` simulates the flights of a :class:`GenerateRequest` serially, on a local Dask
cluster or on an existing one (:func:`canonid.runner.run_jobs`; the same seed gives the same bytes
whichever is used) through :func:`canonid.datagen.generate.generate_dataset`, and returns what
the command prints. See :mod:`canonid.datagen.generate` for seeds, parts and resuming.

The module imports no CasADi; generating loads it.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from canonid.kernel.catalog import parse_list
from canonid.kernel.errors import OptionError
from canonid.kernel.io import atomic_write_figure, figure_name

if TYPE_CHECKING:
    from canonid.datagen.excitation import InputDesign
    from canonid.datagen.generate import FlightResult
    from canonid.datagen.informativeness import Informativeness
    from canonid.kernel.dataset import Dataset

__all__ = ["GenerateRequest", "generate", "informativeness_line", "plot_flights", "scenario_names"]


def scenario_names() -> list[str]:
    """The systems a dataset can be generated for (imports the scenarios: CasADi)."""
    from canonid.datagen.scenarios import scenario_names as names

    return names()


@dataclass(frozen=True, kw_only=True)
class GenerateRequest:
    """A dataset to generate (``None``: the system's default).

    Attributes:
        system, seed: the scenario and the root seed. counts: flights per split given.
        noise: the measurement noise's half-width, as given (``"0.01"`` or ``"0.01,0.02"``).
        horizon, steps: the MPC horizon; samples per flight. out: the dataset's folder.
        workers, scheduler, resume, plot, progress: where the flights run; keep finished
            flights; draw a few (``flights.png``); a progress bar.
        figure_format: the file format of that figure (one of
            :data:`canonid.kernel.io.FIGURE_FORMATS`).
        excitation, amplitude, band, lines, clock: an input design added to the controller's
            command (``multisine`` or ``prbs``, :mod:`canonid.datagen.excitation`), as given.
        references: a reference family of the scenario (e.g. ``steps``).
    """

    system: str
    seed: int = 0
    counts: Mapping[str, int] = field(default_factory=dict)
    noise: str | None = None
    horizon: int | None = None
    steps: int | None = None
    out: Path | None = None
    workers: int = 0
    scheduler: str | None = None
    resume: bool = False
    plot: bool = False
    progress: bool = True
    excitation: str | None = None
    amplitude: str | None = None
    band: str | None = None
    lines: int | None = None
    clock: int | None = None
    references: str | None = None
    figure_format: str = "png"


def _numbers(text: str, option: str) -> tuple[float, ...]:
    """``text`` in the one list syntax (:func:`canonid.kernel.catalog.parse_list`) of numbers."""
    try:
        return tuple(parse_list(text, float, "X"))
    except OptionError:
        raise OptionError(
            f"{option} must be a number or numbers separated by commas, got {text!r}"
        ) from None


def _design(request: GenerateRequest) -> InputDesign | None:
    from canonid.datagen.excitation import design_from_options

    given = [request.amplitude, request.band, request.lines, request.clock]
    if request.excitation is None:
        if any(v is not None for v in given):
            raise OptionError("--amplitude, --band, --lines and --clock need --excitation")
        return None
    band: tuple[float, float] | None = None
    if request.band is not None:
        numbers = _numbers(request.band, "--band")
        if len(numbers) != 2:
            raise OptionError(f"--band must be LOW,HIGH in Hz, got {request.band!r}")
        band = (numbers[0], numbers[1])
    amplitude = None if request.amplitude is None else _numbers(request.amplitude, "--amplitude")
    return design_from_options(
        request.excitation,
        amplitude=amplitude,
        band=band,
        lines=request.lines,
        clock=request.clock,
    )


def _noise(text: str | None) -> float | tuple[float, ...] | None:
    if text is None:
        return None
    values = _numbers(text, "--noise")
    return values[0] if len(values) == 1 else values


def _tally(result: FlightResult) -> int:
    return result.solver_failures


def generate(request: GenerateRequest) -> str:
    """Generate the dataset of ``request``; the lines that say what was written."""
    from canonid.datagen.generate import (
        DATASET_FILE,
        FLIGHTS_PER_TASK,
        PARTS,
        GenerationConfig,
        generate_dataset,
    )
    from canonid.datagen.scenarios import get_scenario
    from canonid.jobs import check_run_folder
    from canonid.kernel.dataset import Dataset
    from canonid.runner import run_jobs

    system = request.system
    get_scenario(system)  # unknown system: one-line error before anything else
    config = GenerationConfig(
        system=system,
        seed=request.seed,
        counts=dict(request.counts),
        noise=_noise(request.noise),
        controller_options={} if request.horizon is None else {"horizon": request.horizon},
        T=request.steps,
        design=_design(request),
        references=request.references,
    )
    if request.workers < 0:
        raise OptionError(f"--workers must be >= 0, got {request.workers}")
    figure = figure_name("flights", request.figure_format)  # an unknown format, before any work
    out = request.out or Path("runs") / "data" / f"{system}-s{request.seed}"
    written = (DATASET_FILE, str(Path(DATASET_FILE).with_suffix(".json")), PARTS)
    check_run_folder(out, own=written)  # a folder of other files: refused before any flight
    runner = functools.partial(
        run_jobs,
        workers=request.workers,
        scheduler=request.scheduler,
        progress=request.progress,
        description=f"{system} flights",
        tally=_tally,
        tally_name="solver failures",
        batch=FLIGHTS_PER_TASK,
    )
    result = generate_dataset(config, out, run_jobs=runner, resume=request.resume)
    counts_text = ", ".join(f"{k} {v}" for k, v in result.counts.items())
    lines = [f"dataset written to {result.path.resolve()} ({counts_text} flights)"]
    if result.chunks is not None:
        chunks_text = ", ".join(f"{k} {v}" for k, v in result.chunks.items())
        length = get_scenario(system).chunk_length
        lines.append(f"  flights cut into {length}-sample chunks: {chunks_text} chunks")
    if result.validation is not None:
        lines.append(f"  validation: {result.validation}")
    stand_in = config.true_system.simulated_stand_in_for
    if stand_in:
        lines.append(f"  SIMULATED data: {system} is a simulated stand-in for {stand_in}")
    if result.informativeness is not None:
        lines.append(informativeness_line(result.informativeness))
    lines.append(
        f"  generated {result.generated}, resumed {result.resumed}; solver failures (fell back) "
        f"{result.solver_failures}; flights regenerated with a new seed {result.replaced}"
    )
    if request.plot:
        drawn = plot_flights(Dataset.load(result.path), out / figure)
        lines.append(f"  figure: {drawn.resolve()}")
    return "\n".join(lines)


#: a regressor covariance whose smallest eigenvalue is below this share of its largest is
#: singular to float64 rounding (its eigenvalues are computed to about 1e-16 of the largest)
SINGULAR_SHARE = 1e-12


def informativeness_line(info: Informativeness) -> str:
    """What ``canonid generate`` prints of the data's informativeness; a covariance singular to
    rounding says so (its smallest eigenvalue alone would read as a plain 0)."""
    line = (
        f"  informativeness (window {info.window}): smallest eigenvalue of the regressor "
        f"covariance {info.smallest:.3g}, of the inputs given the outputs "
        f"{info.input_given_outputs:.3g} (dataset.json: metadata.informativeness)"
    )
    if info.smallest <= SINGULAR_SHARE * info.eigenvalues[0]:
        line += (
            "; the covariance is singular to rounding: at this window some combination of the "
            "lagged inputs and outputs carries no variance (e.g. inputs with no power at high "
            "frequencies)"
        )
    return line


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
    return atomic_write_figure(path, fig, dpi=110)
