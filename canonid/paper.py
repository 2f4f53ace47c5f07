"""The paper's printed numbers, as data, so reports can set ours beside them.

Table 1 of Janny et al. (CDC 2022): MSE of 100-step open-loop rollouts, per system, model and window
ℓ, in the scale the paper prints (tank ×1e-4, 2D drone ×1e-2, 3D drone ×1e-2). The paper's 3D drone
column is measured on the real Blackbird flights; ours comes from the simulated stand-in, so the two
are never the same experiment.
"""

from __future__ import annotations

from dataclasses import dataclass

from canonid.kernel.catalog import MODEL_LABELS

__all__ = [
    "MODEL_LABELS",
    "PAPER_MODELS",
    "PAPER_WINDOWS",
    "TABLE1",
    "Table1Column",
    "table1_value",
]

PAPER_WINDOWS = (5, 10, 15, 20, 25, 30)
#: model names as our CLI spells them, in the paper's column order
PAPER_MODELS = ("classic-gru", "masti", "gru", "mlp")


@dataclass(frozen=True)
class Table1Column:
    """One system's block of Table 1: ``values[model][i]`` is for ``PAPER_WINDOWS[i]``, printed
    in units of ``scale`` (the MSE is ``value * scale``)."""

    system: str
    label: str
    scale: float
    values: dict[str, tuple[float, ...]]
    note: str = ""


TABLE1: dict[str, Table1Column] = {
    "tank": Table1Column(
        system="tank",
        label="Tank",
        scale=1e-4,
        values={
            "classic-gru": (163, 41.7, 4.57, 4.04, 0.600, 1.73),
            "masti": (1030, 1070, 957, 914, 915, 917),
            "gru": (138, 5.60, 3.06, 1.07, 0.481, 0.193),
            "mlp": (7.14, 0.930, 0.960, 0.761, 0.606, 0.448),
        },
    ),
    "drone2d": Table1Column(
        system="drone2d",
        label="2D Drone",
        scale=1e-2,
        values={
            "classic-gru": (62.8, 82.7, 61.9, 78.4, 80.3, 104),
            "masti": (60.5, 58.6, 58.2, 55.3, 53.6, 51.3),
            "gru": (106, 68.9, 35.2, 19.3, 23.0, 25.0),
            "mlp": (31.4, 9.95, 7.52, 8.06, 5.17, 3.13),
        },
    ),
    "quadrotor": Table1Column(
        system="quadrotor",
        label="3D Drone",
        scale=1e-2,
        values={
            "classic-gru": (24.8, 23.7, 23.4, 22.7, 21.3, 19.2),
            "masti": (14.6, 14.5, 13.0, 12.6, 12.1, 12.6),
            "gru": (6.44, 5.32, 5.07, 4.68, 4.83, 4.61),
            "mlp": (15.2, 14.2, 13.6, 13.5, 13.6, 13.1),
        },
        note="paper: real Blackbird flights; canonid: simulated stand-in",
    ),
}


def table1_value(system: str, model: str, window: int) -> float | None:
    """The paper's MSE (in physical units, i.e. already multiplied by the scale), or ``None``
    when the paper has no such cell."""
    column = TABLE1.get(system)
    if column is None or model not in column.values or window not in PAPER_WINDOWS:
        return None
    return column.values[model][PAPER_WINDOWS.index(window)] * column.scale
