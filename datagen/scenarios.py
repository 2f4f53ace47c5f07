"""The scenario registry: how each system's closed-loop dataset is generated.

One :class:`Scenario` per system name (the name of :func:`canonid.models.registry.get_system`) gives
the reference sampler, the initial state, the controller factory, the flight length, the default
split sizes and the excitation. A new system joins generation with one :func:`register_scenario`
call (or one entry in ``_SCENARIOS``); :mod:`canonid.datagen.generate` needs nothing else.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from canonid.datagen.excitation import InputDesign, Multisine
from canonid.datagen.quadrotor_reference import (
    QUADROTOR_REFERENCE_NAMES,
    quadrotor_initial_state,
    quadrotor_reference,
)
from canonid.datagen.references import (
    DRONE2D_REFERENCE_NAMES,
    TANK_REFERENCE_NAMES,
    drone2d_reference,
    drone2d_step_reference,
    tank_reference,
)
from canonid.kernel.errors import ShapeError, UnknownSystemError

# The systems and controllers (CasADi) load when a scenario builds one, not with the names:
# `canonid generate --help` lists the scenarios without CasADi.
if TYPE_CHECKING:
    from canonid.datagen.controllers.base import Controller
    from canonid.models.base import System

__all__ = ["Scenario", "get_scenario", "register_scenario", "scenario_names"]

#: reference sampler: ``(system, rng, T) -> (T, n_r)`` array
ReferenceSampler = Callable[["System", np.random.Generator, int], np.ndarray]
#: controller factory: ``(system, options) -> Controller``; options are the user's overrides
ControllerFactory = Callable[["System", Mapping[str, Any]], "Controller"]


@dataclass(frozen=True)
class Scenario:
    """How to generate one system's dataset.

    Attributes:
        system: registry name of the true system.
        T: samples per flight.
        split_sizes: default number of flights per split (``train``, ``val``, ``test``).
        reference: the reference sampler.
        reference_names: names of the reference's columns.
        initial_state: ``(system, reference) -> x0``.
        controller: the controller factory.
        controller_options: the option names the factory accepts (e.g. ``"horizon"``); any
            other option is refused before generation starts.
        excitation_std: Gaussian excitation on every applied input (input units).
        loose_fraction: fraction of *training* flights that are loose.
        loose_probability: per-step probability of a random command on a loose flight.
        loose_std: standard deviation of that random command change.
        clip_input: clip applied inputs to the system's U after excitation.
        max_failure_fraction: a flight with more failed controller steps than this fraction of
            ``T`` (or a diverged one) is regenerated with a new derived seed.
        max_attempts: how many seeds a flight may use before generation gives up on it.
        chunk_length: when set, each flight is cut into consecutive chunks of this many samples
            when the dataset is assembled (:func:`canonid.datagen.chunks.cut_chunks`; the remainder
            of a flight is dropped): the dataset's trajectories are the chunks, its splits still by
            flight.
        notes: one paragraph for the dataset metadata (what was chosen and why).
        name: the scenario's name (default: ``system``); a system may have several, e.g. the
            planar drone's paper scenario ``drone2d`` and its informative design ``drone2d-id``.
        design: an input design added to every command (:mod:`canonid.datagen.excitation`), or
            ``None``; a scenario with one also writes the informativeness of its training split
            (:mod:`canonid.datagen.informativeness`) into the dataset metadata.
        reference_families: other reference samplers a user may pick by name instead of
            ``reference`` (``canonid generate --references NAME``).
        measure_window: the window ℓ of the informativeness written into the metadata.
        val_tail: when set, validation is the last ``val_tail`` share of every training flight
            (the first ``⌊(1 − val_tail) T⌋`` samples stay training data), as ``canonid
            benchmark`` cuts a single training record; the scenario then generates no
            validation flights.
        noise: the half-width(s) of the flights' measurement noise (one number, or one per
            output; inside the system's W), or ``None``: W itself. ``canonid generate --noise``
            overrides it.
    """

    system: str
    T: int
    split_sizes: Mapping[str, int]
    reference: ReferenceSampler
    reference_names: tuple[str, ...]
    initial_state: Callable[[System, np.ndarray], np.ndarray]
    controller: ControllerFactory
    controller_options: tuple[str, ...] = ()
    excitation_std: float = 0.0
    loose_fraction: float = 0.0
    loose_probability: float = 0.0
    loose_std: float = 0.0
    clip_input: bool = False
    max_failure_fraction: float = 0.05
    max_attempts: int = 5
    chunk_length: int | None = None
    notes: str = ""
    name: str = ""
    design: InputDesign | None = None
    reference_families: Mapping[str, ReferenceSampler] = field(default_factory=dict)
    measure_window: int = 10
    val_tail: float | None = None
    noise: float | tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", self.name or self.system)
        object.__setattr__(
            self, "reference_families", MappingProxyType(dict(self.reference_families))
        )
        if self.T < 2:
            raise ShapeError(f"scenario {self.system}: T must be >= 2, got {self.T}")
        if not 0.0 <= self.loose_fraction <= 1.0:
            raise ShapeError(
                f"scenario {self.system}: loose_fraction must be in [0, 1], got "
                f"{self.loose_fraction}"
            )
        if self.chunk_length is not None and not 1 <= self.chunk_length <= self.T:
            raise ShapeError(
                f"scenario {self.system}: chunk_length must be in [1, T={self.T}], got "
                f"{self.chunk_length}"
            )
        if self.val_tail is not None:
            if not 0.0 < self.val_tail < 1.0:
                raise ShapeError(
                    f"scenario {self.system}: val_tail must be in (0, 1), got {self.val_tail}"
                )
            if self.chunk_length is not None or self.split_sizes.get("val", 0):
                raise ShapeError(
                    f"scenario {self.system}: val_tail cuts validation from the training "
                    "flights; it takes no chunk_length and no validation flights"
                )
        object.__setattr__(self, "split_sizes", MappingProxyType(dict(self.split_sizes)))

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings for the dataset metadata (the keys of the design only for a
        scenario that has one: the paper's datasets keep their bytes)."""
        named = {} if self.name == self.system else {"name": self.name}
        designed = {} if self.design is None else {"design": self.design.describe()}
        return {
            **named,
            "system": self.system,
            "T": self.T,
            "reference_names": list(self.reference_names),
            "excitation_std": self.excitation_std,
            "loose_fraction": self.loose_fraction,
            "loose_probability": self.loose_probability,
            "loose_std": self.loose_std,
            "clip_input_to_U": self.clip_input,
            "max_failure_fraction": self.max_failure_fraction,
            "max_attempts": self.max_attempts,
            "chunk_length": self.chunk_length,
            "notes": self.notes,
            **designed,
            **({} if self.val_tail is None else {"val_tail": self.val_tail}),
            **({} if self.noise is None else {"noise": _listed(self.noise)}),
        }


def _listed(value: float | tuple[float, ...]) -> float | list[float]:
    return list(value) if isinstance(value, tuple) else value


# ---------------------------------------------------------------------------- tank
def _tank_reference(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return tank_reference(rng, T=T)


def _zero_state(system: System, reference: np.ndarray) -> np.ndarray:
    return np.zeros(system.n_x)


def _tank_pid(system: System, options: Mapping[str, Any]) -> Controller:
    from canonid.datagen.controllers.pid import PID

    return PID(kp=4.0, ki=0.6, kd=4.0, state_index=1)


# ---------------------------------------------------------------------------- planar drone
#: the authors' tracking weights on (px, pz, θ, ṗx, ṗz, θ̇)
DRONE2D_STATE_WEIGHTS = (5.0, 5.0, 0.0, 1.0, 1.0, 0.01)
#: weight on each rotor's deviation from hover, (rad/s)⁻²
DRONE2D_INPUT_WEIGHTS = (1e-3, 1e-3)


def _drone2d_reference(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return drone2d_reference(rng, T=T, dt=system.dt)


def _drone2d_steps(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return drone2d_step_reference(rng, T=T, dt=system.dt)


def _reference_start(system: System, reference: np.ndarray) -> np.ndarray:
    """Start on the reference: its first row is a full target state (angle and rate 0)."""
    return np.array(reference[0], dtype=np.float64)


def _drone2d_nmpc(system: System, options: Mapping[str, Any]) -> Controller:
    from canonid.datagen.controllers.nmpc import NMPC
    from canonid.models.drone2d import Drone2D

    if not isinstance(system, Drone2D):
        raise ShapeError(f"the planar-drone NMPC needs a Drone2D, got {system!r}")
    hover = system.hover_speed
    return NMPC(
        system,
        u_eq=(hover, hover),
        horizon=int(options.get("horizon", 20)),
        state_weights=DRONE2D_STATE_WEIGHTS,
        input_weights=DRONE2D_INPUT_WEIGHTS,
        terminal="lqr",
    )


# ---------------------------------------------------------------------------- quadrotor
def _quadrotor_reference(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return quadrotor_reference(rng, steps=T, dt=system.dt)


def _quadrotor_start(system: System, reference: np.ndarray) -> np.ndarray:
    return quadrotor_initial_state(reference)


def _quadrotor_cascade(system: System, options: Mapping[str, Any]) -> Controller:
    from canonid.datagen.controllers.quadrotor_cascade import QuadrotorCascade
    from canonid.models.quadrotor import Quadrotor

    return QuadrotorCascade(cast(Quadrotor, system))  # it checks the type itself


_QUADROTOR = Scenario(
    system="quadrotor",
    T=1000,
    split_sizes={"train": 146, "val": 20, "test": 10},
    reference=_quadrotor_reference,
    reference_names=QUADROTOR_REFERENCE_NAMES,
    initial_state=_quadrotor_start,
    controller=_quadrotor_cascade,
    excitation_std=10.0,
    clip_input=True,
    chunk_length=200,
    notes=(
        "SIMULATED stand-in for the Blackbird UAV dataset (real flights). Flights of 20 s "
        "(1000 samples at 50 Hz), cut into 200-sample chunks; 146 / 20 / 10 flights as in "
        "Blackbird's split. Reference: cubic spline through 5-10 waypoints uniform in "
        "[-2, 2]^2 x [-1, 1] m with yaws uniform in [-pi, pi] (unwrapped), velocity from the "
        "spline; the flight starts on it, level, at rest in rotation. Tracked by the cascaded "
        "position/attitude/rate controller; Gaussian excitation of 10 rad/s (about 1 % of "
        "hover speed, the planar drone's ratio) on each rotor, applied speeds clipped to U; no "
        "loose flights (Blackbird has none)."
    ),
)

_DRONE2D = Scenario(
    system="drone2d",
    T=600,
    split_sizes={"train": 500, "val": 20, "test": 20},
    reference=_drone2d_reference,
    reference_names=DRONE2D_REFERENCE_NAMES,
    initial_state=_reference_start,
    controller=_drone2d_nmpc,
    controller_options=("horizon",),
    excitation_std=1.0,
    loose_fraction=0.2,
    loose_probability=0.1,
    loose_std=10.0,
    clip_input=True,
    reference_families={"spline": _drone2d_reference, "steps": _drone2d_steps},
    notes=(
        "Authors' generator: 5-10 waypoints in [-2, 2]^2 evenly spread over 20 s, cubic "
        "spline, velocities from its derivative, angle target 0; each flight starts on the "
        "reference's initial state. Nonlinear MPC (fatrop) with the authors' tracking weights "
        "(5, 5, 0, 1, 1, 0.01); Gaussian excitation sigma = 1 rad/s on the applied rotor "
        "speeds; every fifth training flight is loose (each step, with probability 0.1, the "
        "previous input plus N(0, 10^2) replaces the controller's). Applied inputs are "
        "clipped to U = [0, 250] rad/s (the authors' rotors allowed about 733 rad/s)."
    ),
)

#: the informative design: a multisine on each rotor, on top of the paper's references,
#: excitation and loose flights (RMS 10 rad/s or ±2 m steps leave the flight box in every flight)
DRONE2D_ID_DESIGN = Multisine(band=(0.1, 5.0), lines=20, amplitude=5.0)

_DRONE2D_ID = replace(
    _DRONE2D,
    name="drone2d-id",
    design=DRONE2D_ID_DESIGN,
    notes=(
        "Informative design for identification for control (docs: Data generation). "
        "As drone2d (references, NMPC, weights, excitation sigma = 1 rad/s, loose flights, U), "
        "and each rotor speed gets a random-phase multisine, 20 lines per rotor interleaved on "
        "the 0.05 Hz grid of a 20-s flight between 0.1 and 5 Hz, RMS 5 rad/s (about 4.5 % of "
        "hover), added to the command before clipping to U."
    ),
)


# ---------------------------------------------------------------------------- chain of masses
def _zero_reference(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return np.zeros((T, system.n_u))


def _feedforward(system: System, options: Mapping[str, Any]) -> Controller:
    from canonid.datagen.controllers.feedforward import Feedforward

    return Feedforward(system.n_u)


#: a multisine over the whole band below Nyquist, so that the regressor of a long window is not
#: rank-deficient (a band-limited input's lags are nearly collinear); RMS 4 N peaks near 15 N,
#: inside U = [-20, 20] N, and moves the wall joint (|q1| up to about 0.16 m) enough that its cubic
#: term changes the outputs by about a third of their RMS
MASSES_ID_DESIGN = Multisine(band=(0.1, 25.0), lines=400, amplitude=4.0)

_MASSES_ID = Scenario(
    system="masses",
    name="masses-id",
    T=2000,
    split_sizes={"train": 20, "val": 5, "test": 5},
    reference=_zero_reference,
    reference_names=("F_nominal",),
    initial_state=_zero_state,
    controller=_feedforward,
    clip_input=True,
    design=MASSES_ID_DESIGN,
    measure_window=60,
    notes=(
        "Open loop (the chain is stable): each flight starts at rest and is driven by a "
        "random-phase multisine force on mass 3, 400 lines on the 0.025 Hz grid of a 40-s "
        "flight (2000 samples at 50 Hz) between 0.1 Hz and Nyquist (25 Hz), RMS 4 N, "
        "clipped to U; the reference is zero and there is no feedback."
    ),
)

# ---------------------------------------------------------------------------- tanks with overflow
#: the pump's mean voltage: the multisine swings around it
TANKS_OVERFLOW_OFFSET = 5.3
#: a random-phase multisine on every grid line of a 1,024-sample record (4,096 s) up to 0.0144 Hz
#: (58 lines, about a ninth of Nyquist): slow enough for the tanks (time constants near 50 s) to
#: follow, so that peaks of the input fill the upper tank to its rim and lift the lower one past
#: the sensor's range a few times per record; with RMS 1.2 V around 5.3 V the voltage seldom
#: reaches the edges of U = [0, 10] V (clipped there: a broadband kink the rest of the record lacks)
TANKS_OVERFLOW_DESIGN = Multisine(band=(0.0, 0.0144), lines=58, amplitude=1.2)


def _offset_reference(system: System, rng: np.random.Generator, T: int) -> np.ndarray:
    return np.full((T, system.n_u), TANKS_OVERFLOW_OFFSET)


def _offset_equilibrium(system: System, reference: np.ndarray) -> np.ndarray:
    """Start at rest at the levels the mean pump voltage holds."""
    from canonid.models.overflow_tanks import OverflowTanks

    if not isinstance(system, OverflowTanks):
        raise ShapeError(f"the tanks-overflow scenario needs an OverflowTanks, got {system!r}")
    return np.array(system.equilibrium(float(reference[0, 0])))


_TANKS_OVERFLOW = Scenario(
    system="tanks-overflow",
    T=1024,
    split_sizes={"train": 1, "val": 0, "test": 1},
    reference=_offset_reference,
    reference_names=("u_offset",),
    initial_state=_offset_equilibrium,
    controller=_feedforward,
    clip_input=True,
    design=TANKS_OVERFLOW_DESIGN,
    val_tail=0.2,
    notes=(
        "The shape of the Cascaded Tanks benchmark: one training and one test record of 1024 "
        "samples at Ts = 4 s, each driven open loop by its own random-phase multisine (every "
        "line of the 1/4096 Hz grid up to 0.0144 Hz, RMS 1.2 V) around a pump voltage of 5.3 V, "
        "clipped to U = [0, 10] V, from rest at the levels 5.3 V holds; validation is the last "
        "20 % of the training record (samples 819-1023), as canonid benchmark cuts it."
    ),
)


# ---------------------------------------------------------------------------- the suite's systems
def _feedforward_compiled(system: System, options: Mapping[str, Any]) -> Controller:
    """Open loop through the compiled loop: the same bytes as step by step, long records fast."""
    from canonid.datagen.controllers.feedforward import Feedforward

    return Feedforward(system.n_u, system=system)


#: a random-phase multisine on every tenth line of the 0.5-Hz grid of a 20,000-sample record (2 s
#: at 10 kHz) up to 2 kHz, past both filters' corners; RMS 0.5 V swings the first filter's output
#: over about ±1.7 V, so the curve clamps the deep negative half-waves near −0.4 V and bends the
#: positive peaks (the output differs from the linear chain's by about 45 % of its RMS)
WIENER_HAMMERSTEIN_DESIGN = Multisine(band=(0.0, 2000.0), lines=400, amplitude=0.5)
#: white Gaussian input on top, a tenth of the multisine's RMS (1 % of its power): a band-limited
#: input alone leaves the lags of the window regressor collinear (its smallest eigenvalue about
#: 1e-8 at ℓ = 10, "singular to rounding" for the friction drive); with it they sit at the output
#: noise's floor (5e-5 to 1e-4), and so for the Bouc-Wen and friction records below
WIENER_HAMMERSTEIN_WHITE = 0.05
#: measurement noise of its records, V: about 0.7 % of the output's RMS (0.24 V)
WIENER_HAMMERSTEIN_NOISE = 0.003

_WIENER_HAMMERSTEIN = Scenario(
    system="wiener-hammerstein",
    T=20000,
    split_sizes={"train": 1, "val": 1, "test": 1},
    reference=_zero_reference,
    reference_names=("u_nominal",),
    initial_state=_zero_state,
    controller=_feedforward_compiled,
    excitation_std=WIENER_HAMMERSTEIN_WHITE,
    clip_input=True,
    design=WIENER_HAMMERSTEIN_DESIGN,
    noise=WIENER_HAMMERSTEIN_NOISE,
    notes=(
        "Open loop from rest: one training, one validation and one test record of 20,000 "
        "samples (2 s at 10 kHz), each driven by its own random-phase multisine voltage, 400 "
        "lines on every tenth line of the 0.5-Hz grid up to 2 kHz, RMS 0.5 V, plus white "
        "Gaussian noise of standard deviation 0.05 V, clipped to U; "
        "uniform output noise of half-width 0.003 V (about 0.7 % of the output's RMS)."
    ),
)

#: every line of the 10-Hz grid of a 1,000-sample record up to 2 kHz, at the main design's RMS
WIENER_HAMMERSTEIN_SMALL_DESIGN = Multisine(band=(0.0, 2000.0), lines=200, amplitude=0.5)

_WIENER_HAMMERSTEIN_SMALL = Scenario(
    system="wiener-hammerstein",
    name="wiener-hammerstein-small",
    T=1000,
    split_sizes={"train": 1, "val": 0, "test": 1},
    reference=_zero_reference,
    reference_names=("u_nominal",),
    initial_state=_zero_state,
    controller=_feedforward_compiled,
    excitation_std=WIENER_HAMMERSTEIN_WHITE,
    clip_input=True,
    design=WIENER_HAMMERSTEIN_SMALL_DESIGN,
    val_tail=0.2,
    notes=(
        "A small, noisy record: one training and one test record of 1,000 samples (0.1 s at "
        "10 kHz) from rest, each driven by its own random-phase multisine voltage on every line "
        "of the 10-Hz grid up to 2 kHz, RMS 0.5 V, plus white Gaussian noise of standard "
        "deviation 0.05 V, clipped to U; uniform output noise of "
        "half-width 0.015 V, the system's W (about 3.6 % of the output's RMS); validation is "
        "the last 20 % of the training record (samples 800-999)."
    ),
)

#: white Gaussian force of 10 N standard deviation: flat up to Nyquist (100 Hz), past the three
#: modes (7.1, 19.8, 28.7 Hz); the cubic joint then stiffens by up to about 30 % and changes the
#: accelerations by 13-17 % of their RMS
VIBRATION_FORCE_STD = 10.0

_VIBRATION = Scenario(
    system="vibration",
    T=100000,
    split_sizes={"train": 1, "val": 1, "test": 1},
    reference=_zero_reference,
    reference_names=("F_nominal",),
    initial_state=_zero_state,
    controller=_feedforward_compiled,
    excitation_std=VIBRATION_FORCE_STD,
    clip_input=True,
    notes=(
        "A ground-vibration test: open loop from rest, one training, one validation and one "
        "test record of 100,000 samples (500 s at 200 Hz), the shaker's force white Gaussian "
        "noise of standard deviation 10 N (drawn per record), clipped to U = [-60, 60] N; the "
        "three accelerations with uniform noise of half-width 0.3 m/s^2 (W)."
    ),
)

#: a random-phase multisine of RMS 10 N between 1 and 80 Hz (300 lines on the 0.05-Hz grid of a
#: 10,000-sample record): the mass moves 0.64 mm RMS, past the 0.5 mm beyond which the
#: hysteretic force saturates, so most cycles open a loop
BOUC_WEN_DESIGN = Multisine(band=(1.0, 80.0), lines=300, amplitude=10.0)
#: white Gaussian force on top, a tenth of the multisine's RMS (see WIENER_HAMMERSTEIN_WHITE)
BOUC_WEN_WHITE = 1.0

_BOUC_WEN = Scenario(
    system="bouc-wen",
    T=10000,
    split_sizes={"train": 1, "val": 1, "test": 1},
    reference=_zero_reference,
    reference_names=("u_nominal",),
    initial_state=_zero_state,
    controller=_feedforward_compiled,
    excitation_std=BOUC_WEN_WHITE,
    clip_input=True,
    design=BOUC_WEN_DESIGN,
    notes=(
        "Open loop from rest: one training, one validation and one test record of 10,000 "
        "samples (20 s at 500 Hz), each driven by its own random-phase multisine force, 300 "
        "lines between 1 and 80 Hz, RMS 10 N, plus white Gaussian noise of standard deviation "
        "1 N, clipped to U; uniform displacement noise of "
        "half-width 1e-5 m (W)."
    ),
)

#: a random-phase multisine of RMS 2 N·m up to 5 Hz (100 lines on the 0.01-Hz grid of a
#: 10,000-sample record): slow parts slide the drive at several rad/s, reversals stick it
FRICTION_DRIVE_DESIGN = Multisine(band=(0.01, 5.0), lines=100, amplitude=2.0)
#: white Gaussian torque on top, a tenth of the multisine's RMS (see WIENER_HAMMERSTEIN_WHITE)
FRICTION_DRIVE_WHITE = 0.2

_FRICTION_DRIVE = Scenario(
    system="friction-drive",
    T=10000,
    split_sizes={"train": 1, "val": 1, "test": 1},
    reference=_zero_reference,
    reference_names=("tau_nominal",),
    initial_state=_zero_state,
    controller=_feedforward_compiled,
    excitation_std=FRICTION_DRIVE_WHITE,
    clip_input=True,
    design=FRICTION_DRIVE_DESIGN,
    notes=(
        "Open loop from rest: one training, one validation and one test record of 10,000 "
        "samples (100 s at 100 Hz), each driven by its own random-phase multisine torque, 100 "
        "lines between 0.01 and 5 Hz, RMS 2 N*m, plus white Gaussian noise of standard "
        "deviation 0.2 N*m, clipped to U; uniform speed noise of "
        "half-width 0.02 rad/s (W)."
    ),
)

_SCENARIOS: dict[str, Scenario] = {
    "tank": Scenario(
        system="tank",
        T=200,
        split_sizes={"train": 60, "val": 20, "test": 20},
        reference=_tank_reference,
        reference_names=TANK_REFERENCE_NAMES,
        initial_state=_zero_state,
        controller=_tank_pid,
        notes=(
            "Authors' generator: reference through level 0 at sample 0 and 5 uniform levels in "
            "[0, 5] at samples 40, 80, ..., 200 (cubic, redrawn if negative), x0 = (0, 0), "
            "PID (4, 0.6, 4) on the true lower level, command not saturated, no excitation."
        ),
    ),
    "drone2d": _DRONE2D,
    "drone2d-id": _DRONE2D_ID,
    "quadrotor": _QUADROTOR,
    "masses-id": _MASSES_ID,
    "tanks-overflow": _TANKS_OVERFLOW,
    "wiener-hammerstein": _WIENER_HAMMERSTEIN,
    "wiener-hammerstein-small": _WIENER_HAMMERSTEIN_SMALL,
    "vibration": _VIBRATION,
    "bouc-wen": _BOUC_WEN,
    "friction-drive": _FRICTION_DRIVE,
}


def register_scenario(scenario: Scenario) -> None:
    """Add a scenario under its name (raises if the name is taken)."""
    if scenario.name in _SCENARIOS:
        raise ValueError(f"scenario {scenario.name!r} already exists")
    _SCENARIOS[scenario.name] = scenario


def scenario_names() -> list[str]:
    """The scenarios' names (systems and named designs), in registration order."""
    return list(_SCENARIOS)


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name`` (a system's name or a named design, e.g. ``drone2d-id``)."""
    try:
        return _SCENARIOS[name]
    except KeyError:
        raise UnknownSystemError(
            f"no dataset scenario for system {name!r}; expected one of: "
            f"{', '.join(scenario_names())}"
        ) from None
