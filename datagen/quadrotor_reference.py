"""Random smooth 3-D references for the simulated quadrotor (the Blackbird stand-in).

A flight's reference is a cubic spline through random waypoints, yaw included, sampled at the
system's rate. The construction mirrors the planar drone's (paper appendix) lifted to 3-D:

* the number of waypoints ``n`` is drawn uniformly in ``waypoints`` (5 … 10 by default);
* waypoint positions are uniform in the box ``box`` (``[−2, 2]² × [−1, 1]`` m by default, a
  room-sized volume like Blackbird's flight cage); waypoint yaws are uniform in
  ``[−yaw_range, yaw_range]`` (π by default) and unwrapped, so the yaw spline never jumps;
* waypoint ``i`` sits at time ``i · (steps − 1) · dt / (n − 1)``: evenly spread over the flight;
* ``scipy.interpolate.CubicSpline`` (not-a-knot) interpolates position and yaw; the target
  velocity is the spline's derivative.

Row ``t`` of the result, ``(px, py, pz, vx, vy, vz, yaw)`` [m, m/s, rad], is the target at time
``t · dt`` (sample ``t``), the layout :class:`~canonid.datagen.controllers.quadrotor_cascade.
QuadrotorCascade` reads. A spline that leaves ``position_limit`` or ``speed_limit`` (the
overshoot of a cubic between close waypoints) is redrawn, at most ``max_draws`` times.
"""

from __future__ import annotations

import math

import numpy as np

from canonid.kernel.errors import ShapeError

__all__ = ["QUADROTOR_REFERENCE_NAMES", "quadrotor_initial_state", "quadrotor_reference"]

#: names of a quadrotor reference's columns
QUADROTOR_REFERENCE_NAMES = ("px_ref", "py_ref", "pz_ref", "vx_ref", "vy_ref", "vz_ref", "yaw_ref")

_DEFAULT_BOX = ((-2.0, 2.0), (-2.0, 2.0), (-1.0, 1.0))


def quadrotor_reference(
    rng: np.random.Generator,
    *,
    steps: int = 1000,
    dt: float = 0.02,
    waypoints: tuple[int, int] = (5, 10),
    box: tuple[tuple[float, float], ...] = _DEFAULT_BOX,
    yaw_range: float = math.pi,
    position_limit: float = 4.0,
    speed_limit: float = 6.0,
    max_draws: int = 100,
) -> np.ndarray:
    """A random reference of ``steps`` rows ``(px, py, pz, vx, vy, vz, yaw)`` (module docstring).

    Args:
        rng: the only source of randomness (same state → same reference).
        steps: number of samples ``T``.
        dt: sampling time [s].
        waypoints: inclusive range of the number of waypoints.
        box: ``((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi))`` for the waypoints [m].
        yaw_range: waypoint yaws are uniform in ``[−yaw_range, yaw_range]`` [rad].
        position_limit: largest allowed ``|p|`` per axis along the spline [m].
        speed_limit: largest allowed ``|v|`` per axis along the spline [m/s].
        max_draws: redraws allowed before giving up.
    """
    from scipy.interpolate import CubicSpline  # scipy loads with the first reference

    lo_n, hi_n = waypoints
    if steps < 2 or not 2 <= lo_n <= hi_n:
        raise ShapeError(
            f"quadrotor reference: need steps >= 2 and 2 <= waypoints[0] <= waypoints[1], got "
            f"steps={steps}, waypoints={waypoints}"
        )
    if len(box) != 3 or any(lo > hi for lo, hi in box):
        raise ShapeError(f"quadrotor reference: box must be three (lo, hi) pairs, got {box}")
    lower = np.array([lo for lo, _ in box])
    upper = np.array([hi for _, hi in box])
    t = np.arange(steps) * dt
    for _ in range(max_draws):
        n = int(rng.integers(lo_n, hi_n + 1))
        knots = np.linspace(0.0, t[-1], n)
        points = rng.uniform(lower, upper, size=(n, 3))
        yaws = np.unwrap(rng.uniform(-yaw_range, yaw_range, size=n))
        spline = CubicSpline(knots, np.column_stack([points, yaws]), axis=0)
        values, rates = spline(t), spline(t, 1)
        if (
            np.max(np.abs(values[:, :3])) <= position_limit
            and np.max(np.abs(rates[:, :3])) <= speed_limit
        ):
            return np.column_stack([values[:, :3], rates[:, :3], values[:, 3]])
    raise ShapeError(
        f"quadrotor reference: no spline within |p| <= {position_limit} m and |v| <= "
        f"{speed_limit} m/s in {max_draws} draws; widen the limits or the waypoint spacing"
    )


def quadrotor_initial_state(reference: np.ndarray) -> np.ndarray:
    """Where a flight starts: on the reference's first position and velocity, level, with the
    reference's first yaw, body rates zero (the 13-state layout of
    :class:`canonid.models.quadrotor.Quadrotor`)."""
    px, py, pz, vx, vy, vz, yaw = np.asarray(reference, dtype=np.float64)[0, :7]
    half = 0.5 * yaw
    return np.array([px, py, pz, vx, vy, vz, math.cos(half), 0.0, 0.0, math.sin(half), 0, 0, 0.0])
