"""``canonid demo`` — the job ``make demo`` runs, on the built-in tank system.

It grows with the project: today it simulates the cascaded tanks under a staircase of pump
commands and plots the levels; later it runs the whole quick-profile pipeline.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from models.io import atomic_write_json
from models.tank import Tank


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "demo",
        help="run the end-to-end demo on the tank system (what `make demo` runs)",
        description="Run the end-to-end demo on the built-in tank system.",
    )
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tank = Tank()
    levels = np.repeat([1.0, 3.0, 2.0, 4.0, 0.5], 40)
    u = np.array([tank.equilibrium_input(level) for level in levels])[:, None]
    sim = tank.simulate([0.0, 0.0], u)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(2, 1, sharex=True, figsize=(7, 4.5))
    t = np.arange(len(u)) * tank.dt
    ax[0].plot(t, sim.x[:, 0], label="x1 (upper tank)")
    ax[0].plot(t, sim.x[:, 1], label="x2 = y (lower tank)")
    ax[0].plot(t, levels, "k--", lw=0.8, label="steady-state target of u")
    ax[0].set_ylabel("level [m]")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].step(t, u[:, 0], where="post")
    ax[1].set_ylabel("pump command u")
    ax[1].set_xlabel("time [s]")
    fig.suptitle("Cascaded tanks, open loop under a staircase of pump commands")
    fig.tight_layout()
    figure = out / "tank_open_loop.png"
    fig.savefig(figure, dpi=120)
    plt.close(fig)
    atomic_write_json(
        out / "tank_open_loop.json",
        {"system": tank.describe(), "final_state": sim.x_final.tolist()},
    )
    print(f"demo output written to {out.resolve()}")
    print(f"  figure: {figure.resolve()}")
    return 0
