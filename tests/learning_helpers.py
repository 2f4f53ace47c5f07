"""Small data sets for the learning tests: linear systems under piecewise-constant inputs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from canonid.models.linear import LinearSystem


def damped_siso() -> LinearSystem:
    """Poles 0.8 ± 0.2j, x⁺ = A x + B u, y = x1: well damped, so rollouts forget the burn-in."""
    A = np.array([[0.8, 0.2], [-0.2, 0.8]])
    return LinearSystem(A, [[0.5], [1.0]], [[1.0, 0.0]], name="damped")


def trajectories(system, n: int, T: int, *, noise: float, seed: int, hold: int = 6):
    """``n`` trajectories of ``T`` samples: inputs held for ``hold`` samples, uniform in
    [−1, 1]; outputs with uniform noise in [−noise, noise] (``y_clean`` kept)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        levels = rng.uniform(-1, 1, size=(T // hold + 1, system.n_u))
        u = np.repeat(levels, hold, axis=0)[:T]
        y_clean = system.simulate(rng.uniform(-1, 1, system.n_x), u).y
        y = y_clean + rng.uniform(-noise, noise, size=y_clean.shape)
        out.append(SimpleNamespace(u=u, y=y, y_clean=y_clean))
    return out


def siso_dataset_file(folder, T: int = 110):
    """A canonid dataset of :func:`damped_siso` (3 train, 1 val, 2 test records of ``T``
    samples, noise 0.01, ``y_clean`` kept) saved in ``folder``; returns its path."""
    from canonid.kernel.dataset import Dataset, Trajectory

    system = damped_siso()

    def make(n: int, seed: int) -> tuple[Trajectory, ...]:
        return tuple(
            Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)
            for t in trajectories(system, n, T, noise=0.01, seed=seed)
        )

    ds = Dataset(
        splits={"train": make(3, 1), "val": make(1, 2), "test": make(2, 3)},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
    )
    return ds.save(folder / "dataset.npz")


def damped_split(n_train: int = 6, n_val: int = 2, T: int = 40):
    """Training and validation trajectories of :func:`damped_siso` (seeds 10 and 11, noise
    0.01): the small data most learning tests train on."""
    system = damped_siso()
    return (
        trajectories(system, n_train, T, noise=0.01, seed=10),
        trajectories(system, n_val, T, noise=0.01, seed=11),
    )
