"""Dataset generation: independent flights, per-flight seeds, resumable parts, one final file.

A dataset is planned as one :class:`FlightJob` per flight (split, index). Each job is a pure
function of the :class:`GenerationConfig` and its position: its generator is seeded with
``SeedSequence(seed, spawn_key=(SPLIT_CODES[split], index, attempt))`` (``attempt`` = 0 unless
the flight had to be regenerated), so no random stream is shared between flights and the result
does not depend on which process ran which flight, nor in what order.

Within a flight the seed sequence spawns three children: the first draws the reference, the
second the simulation's random numbers (noise, excitation, loose steps; see
:mod:`canonid.datagen.simulate`), the third the input design's signal (phases or levels; see
:mod:`canonid.datagen.excitation`), used only when there is a design. The first two are the
children a dataset without a design always had, so its bytes did not change.

A configuration with an input design or another reference family (the scenario's, e.g.
``drone2d-id``, or the caller's) also records the informativeness of its training flights
(:mod:`canonid.datagen.informativeness`) in the metadata's ``informativeness``.

Training flight ``i`` is *loose* when ``⌊(i+1)·f⌋ > ⌊i·f⌋`` with ``f`` the scenario's loose
fraction: exactly ``⌊n·f⌋`` of ``n`` flights, spread evenly (every fifth for ``f = 0.2``).

A flight whose controller failed on more than ``max_failure_fraction · T`` steps, or whose state
diverged, is regenerated with the next ``attempt``; the replaced seeds and their failure counts
are recorded in the kept flight's ``info["replaced"]``. A flight that fails ``max_attempts`` times
stops the generation with a :class:`~canonid.kernel.errors.DataError`.

On disk (``out`` is the folder the caller names)::

    out/dataset.npz, out/dataset.json      the dataset (Dataset.save), written last
    out/parts/config.json                  the configuration the parts belong to
    out/parts/<split>-<index>.npz/.json    one finished flight each (removed after assembly
                                           unless keep_parts)

When the scenario has a ``val_tail`` (``tanks-overflow``: 0.2), it generates no validation flights:
the validation split is the last ``val_tail`` share of every training flight, and the training
split keeps the rest of it (the single-record cut of ``canonid benchmark``).

When the scenario has a ``chunk_length`` (the quadrotor's 200), the assembled dataset holds each
flight's consecutive chunks (:func:`canonid.datagen.chunks.cut_chunks`) in flight order; parts stay
whole flights.

Re-running with ``resume=True`` keeps the finished parts of the same configuration and runs
only the missing flights; the assembled dataset has the same bytes as an uninterrupted run.
Parts are replaced atomically but not fsynced (the dataset file is): a killed run leaves whole
parts, and a part that a power failure damaged fails its checksum and is regenerated.
Jobs are run by a ``run_jobs`` callable (serially by default); the application layer passes its
process or Dask runner through the same argument.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import platform
import shutil
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np

from canonid.datagen.chunks import cut_chunks
from canonid.datagen.controllers.base import Controller
from canonid.datagen.excitation import InputDesign, design_from_description
from canonid.datagen.informativeness import Informativeness, measure_informativeness
from canonid.datagen.scenarios import ReferenceSampler, Scenario, get_scenario
from canonid.datagen.simulate import Excitation, flight_draws, noise_box, simulate_closed_loop
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import DataError, OptionError, ShapeError
from canonid.kernel.io import atomic_write_json, read_json
from canonid.models.base import System
from canonid.models.registry import get_system

__all__ = [
    "FLIGHTS_PER_TASK",
    "SPLIT_CODES",
    "FlightExcitation",
    "FlightJob",
    "FlightResult",
    "GenerationConfig",
    "GenerationResult",
    "JobRunner",
    "dataset_excitation",
    "flight_excitation",
    "flight_seed",
    "generate_dataset",
    "is_loose",
    "plan_flights",
    "run_flight",
    "run_serially",
]

log = logging.getLogger(__name__)

#: the split's code in every flight's spawn key; fixed so seeds never depend on dict order
SPLIT_CODES: Mapping[str, int] = {"train": 0, "val": 1, "test": 2}
PARTS = "parts"
DATASET_FILE = "dataset.npz"
#: flights a batching runner may send in one task (``canonid.runner.run_jobs(batch=...)``): a
#: drone flight takes ~0.15 s, a Dask task ~3 ms of the main process's CPU
FLIGHTS_PER_TASK = 8

J = TypeVar("J")
R = TypeVar("R")


class JobRunner(Protocol):
    """Runs ``fn`` on every job and returns the results in job order, calling
    ``on_result(position, result)`` in the caller's process as each job finishes."""

    def __call__(
        self,
        fn: Callable[[Any], Any],
        jobs: Sequence[Any],
        *,
        on_result: Callable[[int, Any], None] | None = None,
    ) -> list[Any]: ...


def run_serially(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    *,
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]:
    """The default :class:`JobRunner`: one job after the other in this process."""
    results = []
    for position, job in enumerate(jobs):
        result = fn(job)
        if on_result is not None:
            on_result(position, result)
        results.append(result)
    return results


# ---------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class GenerationConfig:
    """What to generate; validated on construction.

    Attributes:
        system: a scenario's name (:func:`canonid.datagen.scenarios.scenario_names`): a
            system's, or a named design such as ``drone2d-id``.
        seed: the root seed (integer >= 0).
        counts: flights per split; splits left out get the scenario's default size.
        noise: measurement-noise half-width(s), see :func:`canonid.datagen.simulate.noise_box`;
            ``None`` uses the scenario's (``Scenario.noise``, recorded here in its place), else
            the system's W.
        controller_options: overrides passed to the scenario's controller factory (only the
            names the scenario lists, e.g. ``{"horizon": 20}``).
        T: samples per flight; ``None`` uses the scenario's.
        design: an input design added to the controller's command
            (:mod:`canonid.datagen.excitation`); ``None`` uses the scenario's (most have none).
        references: a reference family of the scenario (``Scenario.reference_families``);
            ``None`` uses the scenario's own reference.
    """

    system: str
    seed: int = 0
    counts: Mapping[str, int] = field(default_factory=dict)
    noise: float | tuple[float, ...] | None = None
    controller_options: Mapping[str, Any] = field(default_factory=dict)
    T: int | None = None
    design: InputDesign | None = None
    references: str | None = None

    def __post_init__(self) -> None:
        scenario = get_scenario(self.system)
        if self.references is not None and self.references not in scenario.reference_families:
            accepted = ", ".join(scenario.reference_families) or "none"
            raise ShapeError(
                f"reference family {self.references!r} does not apply to {self.system} "
                f"(accepted: {accepted})"
            )
        if not (isinstance(self.seed, (int, np.integer)) and self.seed >= 0):
            raise ShapeError(f"seed must be an integer >= 0, got {self.seed!r}")
        counts = dict(scenario.split_sizes)
        for split, n in dict(self.counts).items():
            if split not in SPLIT_CODES:
                raise ShapeError(f"unknown split {split!r}; expected one of {list(SPLIT_CODES)}")
            if not (isinstance(n, (int, np.integer)) and n >= 0):
                raise ShapeError(f"number of {split} flights must be an integer >= 0, got {n!r}")
            counts[split] = int(n)
        if sum(counts.values()) == 0:
            raise ShapeError("nothing to generate: every split has 0 flights")
        if scenario.val_tail is not None and counts.get("val", 0):
            raise ShapeError(
                f"{self.system} takes its validation from the last {scenario.val_tail:.0%} of "
                f"each training flight: ask for 0 validation flights, not {counts['val']}"
            )
        object.__setattr__(self, "counts", counts)
        unknown = sorted(set(self.controller_options) - set(scenario.controller_options))
        if unknown:
            accepted = ", ".join(scenario.controller_options) or "none"
            raise ShapeError(
                f"controller option(s) {unknown} do not apply to {self.system} (accepted: "
                f"{accepted})"
            )
        object.__setattr__(self, "controller_options", dict(self.controller_options))
        if self.T is not None and not (isinstance(self.T, (int, np.integer)) and self.T >= 2):
            raise ShapeError(f"T (samples per flight) must be an integer >= 2, got {self.T!r}")
        chunk = scenario.chunk_length
        if chunk is not None and self.steps < chunk:
            raise ShapeError(
                f"T = {self.steps} samples per flight is shorter than one {self.system} chunk "
                f"({chunk} samples)"
            )
        if self.noise is None and scenario.noise is not None:
            object.__setattr__(self, "noise", scenario.noise)
        if isinstance(self.noise, (int, float, np.number)):
            object.__setattr__(self, "noise", float(self.noise))
        elif self.noise is not None:
            object.__setattr__(self, "noise", tuple(float(v) for v in self.noise))
        system = _system(scenario.system)
        noise_box(system, self.noise)  # raises if outside W
        if self.input_design is not None:  # a band too narrow for T fails before any flight
            self.input_design.signal(np.random.default_rng(0), self.steps, system.dt, system.n_u)

    @property
    def scenario(self) -> Scenario:
        return get_scenario(self.system)

    @property
    def true_system(self) -> System:
        """The system the scenario flies."""
        return _system(self.scenario.system)

    @property
    def input_design(self) -> InputDesign | None:
        """The design added to the commands: the configuration's, else the scenario's."""
        return self.design if self.design is not None else self.scenario.design

    @property
    def reference_sampler(self) -> ReferenceSampler:
        scenario = self.scenario
        if self.references is None:
            return scenario.reference
        return scenario.reference_families[self.references]

    @property
    def designed(self) -> bool:
        """Whether the configuration departs from a plain scenario (its data are measured)."""
        return self.input_design is not None or self.references is not None

    @property
    def steps(self) -> int:
        """Samples per flight."""
        return int(self.T if self.T is not None else self.scenario.T)

    def to_json(self) -> dict[str, Any]:
        return {
            "system": self.system,
            "seed": int(self.seed),
            "counts": {k: self.counts[k] for k in SPLIT_CODES if k in self.counts},
            "noise": self.noise
            if self.noise is None or isinstance(self.noise, float)
            else list(self.noise),
            "controller_options": dict(sorted(self.controller_options.items())),
            "T": self.steps,
            # only when given: the configurations of earlier datasets keep their JSON
            **({} if self.design is None else {"design": self.design.describe()}),
            **({} if self.references is None else {"references": self.references}),
        }

    @classmethod
    def from_json(cls, data: Any) -> GenerationConfig:
        """The configuration that :meth:`to_json` wrote (a dataset's
        ``metadata["generation"]``); raises :class:`DataError` when ``data`` is not one, or
        when the configuration read back does not write the same JSON."""
        if not isinstance(data, dict) or "system" not in data:
            raise DataError(f"not a generation configuration: {data!r:.80}")
        noise = data.get("noise")
        try:
            config = cls(
                system=data["system"],
                seed=data.get("seed", 0),
                counts=data.get("counts", {}),
                noise=tuple(noise) if isinstance(noise, list) else noise,
                controller_options=data.get("controller_options", {}),
                T=data.get("T"),
                design=None
                if data.get("design") is None
                else design_from_description(data["design"]),
                references=data.get("references"),
            )
        except (ShapeError, OptionError, TypeError) as exc:
            raise DataError(f"generation configuration {data!r:.80} is not valid: {exc}") from None
        if config.to_json() != data:
            raise DataError(
                f"generation configuration {data!r:.80} does not read back as itself "
                f"({config.to_json()!r:.80})"
            )
        return config


@dataclass(frozen=True)
class FlightJob:
    """One flight to generate (picklable; sent to worker processes)."""

    config: GenerationConfig
    split: str
    index: int

    @property
    def name(self) -> str:
        return f"{self.split}-{self.index:05d}"


@dataclass(frozen=True)
class FlightResult:
    """A finished flight: its trajectory and the number of failed controller steps it kept."""

    job: FlightJob
    trajectory: Trajectory

    @property
    def solver_failures(self) -> int:
        return int(self.trajectory.info.get("solver_failures", 0))


@dataclass(frozen=True)
class GenerationResult:
    """What :func:`generate_dataset` did.

    Attributes:
        path: the dataset file (``out/dataset.npz``).
        counts: flights per split.
        chunks: trajectories per split when the scenario cuts flights into chunks, else None.
        generated: flights simulated in this call.
        resumed: flights taken from existing parts.
        solver_failures: failed controller steps in the kept flights (all fell back).
        replaced: flights that were regenerated with a new seed at least once.
        informativeness: the measure written into the metadata (designed configurations only).
        validation: how the validation split was cut from the training flights (scenarios with
            a ``val_tail``), else None.
    """

    path: Path
    counts: dict[str, int]
    generated: int
    resumed: int
    solver_failures: int
    replaced: int
    chunks: dict[str, int] | None = None
    informativeness: Informativeness | None = None
    validation: str | None = None


def plan_flights(config: GenerationConfig) -> list[FlightJob]:
    """One job per flight, in dataset order: train 0…, val 0…, test 0…."""
    return [
        FlightJob(config, split, i)
        for split in SPLIT_CODES
        for i in range(config.counts.get(split, 0))
    ]


def flight_seed(seed: int, split: str, index: int, attempt: int = 0) -> np.random.SeedSequence:
    """The seed sequence of one flight attempt (see the module docstring)."""
    return np.random.SeedSequence(int(seed), spawn_key=(SPLIT_CODES[split], index, attempt))


def is_loose(split: str, index: int, fraction: float) -> bool:
    """Whether flight ``index`` of ``split`` is loose (training flights only)."""
    if split != "train" or fraction <= 0:
        return False
    return math.floor((index + 1) * fraction + 1e-9) > math.floor(index * fraction + 1e-9)


# ---------------------------------------------------------------------------- one flight
@functools.lru_cache(maxsize=8)
def _system(name: str) -> System:
    return get_system(name)


_local = threading.local()


def _controller_cache() -> dict[tuple[Any, ...], Controller]:
    """This thread's controllers, one per (system, options): building an NMPC costs far more
    than a flight, and ``Controller.reset`` clears everything a flight leaves behind. Per thread,
    because a controller keeps per-flight state (threaded Dask workers share the module)."""
    cache: dict[tuple[Any, ...], Controller] | None = getattr(_local, "controllers", None)
    if cache is None:
        cache = _local.controllers = {}
    return cache


def _controller_for(config: GenerationConfig) -> Controller:
    factory = config.scenario.controller
    key = (config.system, factory, json.dumps(config.controller_options, sort_keys=True))
    cache = _controller_cache()
    if key not in cache:
        cache[key] = factory(config.true_system, config.controller_options)
    return cache[key]


def _excitation(config: GenerationConfig, split: str, index: int) -> Excitation:
    """The Gaussian excitation and loose-step settings of flight ``index`` of ``split``."""
    scenario = config.scenario
    loose = is_loose(split, index, scenario.loose_fraction)
    return Excitation(
        std=scenario.excitation_std,
        loose_probability=scenario.loose_probability if loose else 0.0,
        loose_std=scenario.loose_std,
    )


def _design_signal(
    config: GenerationConfig, design_seq: np.random.SeedSequence
) -> np.ndarray | None:
    """The input design's ``(T, n_u)`` signal drawn from the flight's third child seed."""
    design, system = config.input_design, config.true_system
    if design is None:
        return None
    return design.signal(np.random.default_rng(design_seq), config.steps, system.dt, system.n_u)


@dataclass(frozen=True)
class FlightExcitation:
    """The known signals that the data engine added to one flight's commands, regenerated from
    the flight's seed by the same calls that drew them (:func:`flight_excitation`).

    Attributes:
        gaussian: the Gaussian excitation ``e`` ``(T, n_u)`` (zeros when the scenario has none).
        design: the input design's signal ``d`` ``(T, n_u)``, or ``None`` without a design.
    """

    gaussian: np.ndarray
    design: np.ndarray | None

    @property
    def total(self) -> np.ndarray:
        """``e + d``: what was added to the command before clipping to U (``u = clip(c + e + d,
        U)``, :mod:`canonid.datagen.simulate`)."""
        return self.gaussian if self.design is None else self.gaussian + self.design


def flight_excitation(
    config: GenerationConfig, split: str, index: int, attempt: int = 0
) -> FlightExcitation:
    """The excitation of flight ``index`` of ``split`` (its ``attempt``, the third entry of its
    ``info["spawn_key"]``), drawn again from the flight's seed sequence: child 1 through
    :func:`canonid.datagen.simulate.flight_draws` (the Gaussian ``e``), child 2 through the
    design (``d``), as :func:`run_flight` drew them. Loose steps (training flights) replace the
    controller's command but not ``e + d``, which is added to every command."""
    system = config.true_system
    seq = flight_seed(config.seed, split, index, attempt)
    _, simulation_seq, design_seq = seq.spawn(3)
    _, gaussian, _, _ = flight_draws(
        np.random.default_rng(simulation_seq),
        config.steps,
        box=noise_box(system, config.noise),
        n_u=system.n_u,
        excitation=_excitation(config, split, index),
    )
    return FlightExcitation(gaussian=gaussian, design=_design_signal(config, design_seq))


def dataset_excitation(dataset: Dataset, split: str) -> list[FlightExcitation]:
    """The excitation of every trajectory of ``split`` of a dataset that ``canonid generate``
    wrote, regenerated from the configuration and seeds its metadata records
    (:func:`flight_excitation`; a chunk or a validation tail gets the samples of its flight that
    it holds). Raises :class:`DataError` for data from elsewhere."""
    metadata = dataset.metadata
    if metadata.get("source") != "canonid generate":
        raise DataError(
            "the excitation can be regenerated only for datasets written by canonid generate "
            f"(metadata 'source' is {metadata.get('source')!r}); record your own instead"
        )
    config = GenerationConfig.from_json(metadata.get("generation"))
    out = []
    for i, tr in enumerate(dataset.split(split)):
        info = tr.info
        key = info.get("spawn_key")
        if not (isinstance(key, list) and len(key) == 3 and "split" in info and "index" in info):
            raise DataError(f"split {split!r}, trajectory {i}: info has no flight seed")
        flight = flight_excitation(config, info["split"], int(info["index"]), int(key[2]))
        start = int(info.get("chunk_start", (info.get("samples") or [0])[0]))
        cut = slice(start, start + tr.T)
        out.append(
            FlightExcitation(
                gaussian=flight.gaussian[cut],
                design=None if flight.design is None else flight.design[cut],
            )
        )
    return out


def run_flight(job: FlightJob) -> FlightResult:
    """Simulate one flight, regenerating it with the next seed while it fails (module docs)."""
    config, scenario = job.config, job.config.scenario
    system, controller = config.true_system, _controller_for(config)
    noise = noise_box(system, config.noise)
    loose = is_loose(job.split, job.index, scenario.loose_fraction)
    excitation = _excitation(config, job.split, job.index)
    allowed = int(scenario.max_failure_fraction * config.steps)
    replaced: list[dict[str, Any]] = []
    for attempt in range(scenario.max_attempts):
        seq = flight_seed(config.seed, job.split, job.index, attempt)
        reference_seq, simulation_seq, design_seq = seq.spawn(3)
        reference = config.reference_sampler(
            system, np.random.default_rng(reference_seq), config.steps
        )
        signal = _design_signal(config, design_seq)
        loop = simulate_closed_loop(
            system,
            controller,
            reference,
            x0=scenario.initial_state(system, reference),
            rng=np.random.default_rng(simulation_seq),
            noise=noise,
            excitation=excitation,
            clip_input=scenario.clip_input,
            input_signal=signal,
        )
        spawn_key = [int(k) for k in seq.spawn_key]
        if loop.diverged_at is None and loop.failures <= allowed:
            info = {
                "split": job.split,
                "index": job.index,
                "seed": int(config.seed),
                "spawn_key": spawn_key,
                "loose": loose,
                **loop.summary(),
                "replaced": replaced,
            }
            trajectory = Trajectory(
                u=loop.u,
                y=loop.y,
                y_clean=loop.y_clean,
                x=loop.x,
                reference=loop.reference,
                info=info,
            )
            return FlightResult(job, trajectory)
        log.info("flight %s attempt %d rejected: %s", job.name, attempt, loop.summary())
        replaced.append({"spawn_key": spawn_key, **loop.summary()})
    raise DataError(
        f"flight {job.name} of {config.system} failed {scenario.max_attempts} times (more than "
        f"{allowed} failed controller steps or a diverged state): {replaced}"
    )


# ---------------------------------------------------------------------------- the dataset
def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for package in ("canonid", "numpy", "scipy", "casadi"):
        try:
            out[package] = version(package)
        except PackageNotFoundError:
            out[package] = "unknown"
    return out


def _metadata(config: GenerationConfig) -> dict[str, Any]:
    system = config.true_system
    seeding = (
        "flight (split, index) uses SeedSequence(seed, spawn_key=(split_code, index, "
        "attempt)); children 0 and 1 draw the reference and the simulation noise"
    )
    if config.input_design is not None:
        seeding += ", child 2 the input design's signal"
    return {
        "source": "canonid generate",
        "simulated": True,
        "simulated_stand_in_for": system.simulated_stand_in_for,
        "system": system.describe(),
        "units": {
            "inputs": dict(zip(system.input_names, system.input_units)),
            "outputs": dict(zip(system.output_names, system.output_units)),
            "states": dict(zip(system.state_names, system.state_units)),
        },
        "generation": config.to_json(),
        "scenario": config.scenario.describe(),
        "controller": _controller_for(config).settings(),
        "noise": {
            "distribution": "uniform, independent per sample and output",
            "box": noise_box(system, config.noise).to_dict(),
            "inside_W": True,
        },
        "seeding": seeding,
        "split_codes": dict(SPLIT_CODES),
        "versions": _versions(),
    }


def _part_path(parts: Path, job: FlightJob) -> Path:
    return parts / f"{job.name}.npz"


def _save_part(parts: Path, result: FlightResult, system: System) -> None:
    Dataset(
        splits={result.job.split: (result.trajectory,)},
        dt=system.dt,
        input_names=system.input_names,
        output_names=system.output_names,
        state_names=system.state_names,
        metadata={"part_of": result.job.config.to_json()},
    ).save(_part_path(parts, result.job), durable=False)  # no fsync: checked when resumed


def _load_part(parts: Path, job: FlightJob) -> Trajectory | None:
    path = _part_path(parts, job)
    if not path.with_suffix(".json").exists():
        return None
    try:
        part = Dataset.load(path)
        (trajectory,) = part.split(job.split)
    except (DataError, ValueError) as exc:
        log.warning("part %s is unusable and will be regenerated: %s", path, exc)
        return None
    return trajectory


def _check_parts(parts: Path, config: GenerationConfig | None) -> None:
    """Refuse a parts folder that canonid did not write or (with ``config``) that belongs to
    another configuration."""
    if not parts.exists():
        return
    stamp = parts / "config.json"
    if not stamp.exists():
        raise DataError(
            f"{parts} exists but is not a canonid parts folder (no config.json); move it away"
        )
    if config is not None:
        found, wanted = read_json(stamp, what="parts configuration"), config.to_json()
        if found != wanted:
            raise DataError(
                f"cannot resume: the parts in {parts} were made with {found}, not {wanted}; "
                "generate into another folder or drop --resume"
            )


def _check_existing(dataset_path: Path, config: GenerationConfig) -> None:
    """Refuse to replace a finished dataset of another configuration (the same configuration
    gives the same bytes again)."""
    meta = dataset_path.with_suffix(".json")
    if not meta.is_file():
        return
    header = read_json(meta, what="dataset metadata")
    body = header.get("metadata") if isinstance(header, dict) else None
    found = body.get("generation") if isinstance(body, dict) else None
    if not isinstance(found, Mapping):  # no generation recorded: not a canonid generate dataset
        raise DataError(
            f"{meta} is not the record of a dataset canonid generate wrote (no "
            "'metadata.generation' in it); generate into another --out, or move it away first"
        )
    if found != config.to_json():
        raise DataError(
            f"{dataset_path.parent} already holds a dataset of another configuration "
            f"({found}); generate into another --out, or delete it first"
        )


def _validation_tails(
    splits: Mapping[str, tuple[Trajectory, ...]], tail: float, steps: int
) -> tuple[dict[str, tuple[Trajectory, ...]], str]:
    """Every training flight of ``steps`` samples cut in two: samples ``0 … ⌊(1 − tail)·steps⌋
    − 1`` stay training data, the rest becomes its validation part (``info["samples"]``: each
    part's ``[start, stop)`` within its flight); and the sentence the metadata keeps."""
    cut = int((1 - tail) * steps)
    if not 2 <= cut <= steps - 2:
        raise ShapeError(
            f"a flight of {steps} samples is too short to cut a validation tail of {tail:.0%}"
        )
    heads = tuple(tr.part(0, cut, samples=[0, cut]) for tr in splits["train"])
    tails = tuple(tr.part(cut, steps, samples=[cut, steps]) for tr in splits["train"])
    how = f"the last {tail:.0%} of every training flight: samples {cut}…{steps - 1} of {steps}"
    return {**splits, "train": heads, "val": tails}, how


def generate_dataset(
    config: GenerationConfig,
    out: str | Path,
    *,
    run_jobs: JobRunner | None = None,
    resume: bool = False,
    keep_parts: bool = False,
) -> GenerationResult:
    """Generate the dataset ``config`` describes into the folder ``out``.

    Args:
        config: what to generate.
        out: the output folder (created); the dataset is ``out/dataset.npz`` + ``.json``.
        run_jobs: how to run the flights (default :func:`run_serially`); results arrive through
            ``on_result`` and are written as parts as they finish.
        resume: keep finished parts of the same configuration; without it existing parts are
            discarded.
        keep_parts: keep ``out/parts`` after the dataset is assembled.
    """
    out_dir = Path(out)
    parts = out_dir / PARTS
    system = config.true_system
    dataset_path = out_dir / DATASET_FILE
    jobs = plan_flights(config)
    finished: dict[str, Trajectory] = {}
    if resume:
        _check_parts(parts, config)
        for job in jobs:
            found = _load_part(parts, job)
            if found is not None:
                finished[job.name] = found
    _check_existing(dataset_path, config)
    todo = [job for job in jobs if job.name not in finished]
    resumed = len(finished)
    # Build the controller here first: bad options fail before any job runs, and a compiled
    # solver is built once into the cache instead of by every worker at the same time.
    _controller_for(config)
    prepared = False

    def prepare() -> None:
        # Nothing is written before the first flight is back: a runner that cannot start
        # (say, a scheduler that does not answer) leaves ``out`` as it was.
        nonlocal prepared
        if not prepared:
            for stale in (dataset_path.with_suffix(".json"), dataset_path):
                stale.unlink(missing_ok=True)  # the JSON (completion marker) first
            if not resume and parts.exists():
                _check_parts(parts, None)
                shutil.rmtree(parts)
            atomic_write_json(parts / "config.json", config.to_json())
            prepared = True

    def keep(position: int, result: FlightResult) -> None:
        prepare()
        _save_part(parts, result, system)
        finished[result.job.name] = result.trajectory

    if todo:
        (run_jobs or run_serially)(run_flight, todo, on_result=keep)
    prepare()
    missing = [job.name for job in jobs if job.name not in finished]
    if missing:
        raise DataError(f"the job runner returned without flights {missing[:5]}")

    splits = {
        split: tuple(finished[job.name] for job in jobs if job.split == split)
        for split in SPLIT_CODES
    }
    kept = [tr for trs in splits.values() for tr in trs]
    flights = {split: len(trs) for split, trs in splits.items()}
    metadata = _metadata(config)
    tail = config.scenario.val_tail
    if tail is not None:
        splits, metadata["validation_split"] = _validation_tails(splits, tail, config.steps)
    measure = None
    if config.designed and splits["train"]:
        measure = measure_informativeness(
            [(tr.u, tr.y) for tr in splits["train"]],
            window=config.scenario.measure_window,
            dt=system.dt,
            input_names=system.input_names,
        )
        metadata["informativeness"] = measure.to_dict()
    chunk = config.scenario.chunk_length
    if chunk is not None:
        splits = {
            split: tuple(c for tr in trs for c in cut_chunks(tr, chunk))
            for split, trs in splits.items()
        }
    dataset = Dataset(
        splits=splits,
        dt=system.dt,
        input_names=system.input_names,
        output_names=system.output_names,
        state_names=system.state_names,
        metadata=metadata,
    )
    dataset.save(dataset_path)
    if not keep_parts:
        shutil.rmtree(parts)
    return GenerationResult(
        path=dataset_path,
        counts=flights,
        generated=len(todo),
        resumed=resumed,
        solver_failures=sum(int(tr.info.get("solver_failures", 0)) for tr in kept),
        replaced=sum(1 for tr in kept if tr.info.get("replaced")),
        chunks=dataset.counts() if chunk is not None else None,
        informativeness=measure,
        validation=metadata.get("validation_split"),
    )
