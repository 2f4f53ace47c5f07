"""Random references for closed-loop data generation (the authors' generator).

Every sampler is a pure function of a :class:`numpy.random.Generator`: the same generator state
gives the same reference, so a flight's reference is fixed by its seed alone.

Time convention: row ``t`` of a reference is the target for sample ``t`` (time ``t · dt``),
``t = 0 … T−1``, the same indexing as the trajectory it is tracked in (see
:mod:`canonid.kernel.dataset`).
"""

from __future__ import annotations

import numpy as np

from canonid.kernel.errors import ShapeError

__all__ = [
    "DRONE2D_REFERENCE_NAMES",
    "TANK_REFERENCE_NAMES",
    "drone2d_reference",
    "drone2d_step_reference",
    "tank_reference",
]

TANK_REFERENCE_NAMES = ("y_ref",)
DRONE2D_REFERENCE_NAMES = ("px_ref", "pz_ref", "theta_ref", "vx_ref", "vz_ref", "omega_ref")

#: redraws allowed before a sampler gives up (a tank spline dips below 0 in a few % of draws)
_MAX_REDRAWS = 1000


def _require_positive_int(value: int, name: str, *, minimum: int = 1) -> int:
    if int(value) != value or value < minimum:
        raise ShapeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def tank_reference(
    rng: np.random.Generator,
    *,
    T: int = 200,
    n_waypoints: int = 5,
    low: float = 0.0,
    high: float = 5.0,
    start: float = 0.0,
) -> np.ndarray:
    """Level set-point for the lower tank, shape ``(T, 1)``.

    Knots: the level ``start`` at sample 0, then ``n_waypoints`` levels drawn uniformly in
    ``[low, high]`` at samples ``T/n_waypoints, 2T/n_waypoints, …, T`` (for the defaults
    0, 40, 80, 120, 160, 200). A cubic spline (not-a-knot, as ``interp1d(kind="cubic")``) through
    the knots is evaluated at samples ``0 … T−1``; a draw whose spline goes below ``low`` there is
    redrawn with the next numbers of ``rng``.
    """
    from scipy.interpolate import CubicSpline  # scipy loads with the first reference

    T = _require_positive_int(T, "T", minimum=2)
    n = _require_positive_int(n_waypoints, "n_waypoints", minimum=3)
    if not (high > low):
        raise ShapeError(f"tank reference needs high > low, got low={low}, high={high}")
    knots = np.linspace(0.0, float(T), n + 1)
    samples = np.arange(T, dtype=np.float64)
    for _ in range(_MAX_REDRAWS):
        levels = np.concatenate(([start], rng.uniform(low, high, size=n)))
        ref = CubicSpline(knots, levels, bc_type="not-a-knot")(samples)
        if np.all(ref >= low):
            return ref[:, None]
    raise ShapeError(  # pragma: no cover - needs an absurd (start, low, high)
        f"no tank reference stayed above {low} in {_MAX_REDRAWS} draws (start={start})"
    )


def drone2d_reference(
    rng: np.random.Generator,
    *,
    T: int = 600,
    dt: float = 1.0 / 30.0,
    n_waypoints: tuple[int, int] = (5, 10),
    half_width: float = 2.0,
) -> np.ndarray:
    """Target state for the planar drone, shape ``(T, 6)``, columns
    :data:`DRONE2D_REFERENCE_NAMES` = ``(px, pz, θ, ṗx, ṗz, θ̇)`` targets.

    The number of waypoints ``n`` is drawn uniformly among the integers
    ``n_waypoints[0] … n_waypoints[1]`` (inclusive); the waypoints are drawn uniformly in
    ``[−half_width, half_width]²`` and placed at the evenly spread times
    ``linspace(0, T·dt, n)``. Positions are a cubic spline (not-a-knot) through them evaluated at
    ``t·dt``, ``t = 0 … T−1``; velocities are the spline's derivative at the same times; the
    angle and angular-rate targets are 0.
    """
    from scipy.interpolate import CubicSpline  # scipy loads with the first reference

    T = _require_positive_int(T, "T", minimum=2)
    lo, hi = (int(v) for v in n_waypoints)
    if not (3 <= lo <= hi):
        raise ShapeError(f"n_waypoints must be (min, max) with 3 <= min <= max, got {n_waypoints}")
    if not (dt > 0 and half_width > 0):
        raise ShapeError(f"dt and half_width must be > 0, got dt={dt}, half_width={half_width}")
    n = int(rng.integers(lo, hi + 1))
    waypoints = rng.uniform(-half_width, half_width, size=(n, 2))
    spline = CubicSpline(np.linspace(0.0, T * dt, n), waypoints, axis=0, bc_type="not-a-knot")
    times = np.arange(T, dtype=np.float64) * dt
    ref = np.zeros((T, 6))
    ref[:, 0:2] = spline(times)
    ref[:, 3:5] = spline(times, 1)
    return ref


def drone2d_step_reference(
    rng: np.random.Generator,
    *,
    T: int = 600,
    dt: float = 1.0 / 30.0,
    hold: tuple[float, float] = (1.0, 3.0),
    half_width: float = 2.0,
) -> np.ndarray:
    """Position steps for the planar drone, shape ``(T, 6)``, columns as
    :func:`drone2d_reference`: targets that jump, so the controller tilts hard to follow.

    Each target ``(px, pz)`` is drawn uniformly in ``[−half_width, half_width]²`` and held for a
    duration drawn uniformly in ``hold`` (seconds); velocity, angle and rate targets are 0. The
    first target holds from sample 0 (a flight that starts on the reference starts at rest there).
    """
    T = _require_positive_int(T, "T", minimum=2)
    if not (dt > 0 and half_width > 0 and 0 < hold[0] <= hold[1]):
        raise ShapeError(
            f"dt and half_width must be > 0 and hold (min, max) seconds with 0 < min <= max, got "
            f"dt={dt}, half_width={half_width}, hold={hold}"
        )
    ref = np.zeros((T, 6))
    start = 0
    while start < T:
        length = max(1, round(rng.uniform(hold[0], hold[1]) / dt))
        ref[start : start + length, 0:2] = rng.uniform(-half_width, half_width, size=2)
        start += length
    return ref
