"""The subcommands: one module each, imported only when its command runs.

Each module exposes ``register(parser)``, which gives the parser that :mod:`canonid.cli` made for
the command its description and arguments, and ``run(args) -> int``, which the parsed arguments
call. :data:`COMMANDS` names every subcommand with the one-line help that ``canonid --help``
lists, so the listing needs none of the modules (nor the torch, CasADi or matplotlib they
import).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType

__all__ = ["COMMANDS", "Command", "command_names"]


@dataclass(frozen=True)
class Command:
    """A subcommand: its name (also its module's name) and its line in ``canonid --help``."""

    name: str
    help: str

    def load(self) -> ModuleType:
        """Import the module that registers and runs the command."""
        return importlib.import_module(f"{__name__}.{self.name}")


#: registration order is the order shown by ``canonid --help``; help is an argparse format
#: string (``%%`` is a percent sign)
COMMANDS = (
    Command("systems", "list the registered true systems"),
    Command("generate", "generate a closed-loop dataset (tank PID, planar-drone NMPC)"),
    Command(
        "train", "identify a model (Ours MLP/GRU, Classic GRU, Masti et al., ARX) by output error"
    ),
    Command(
        "reduce", "auto-encoder reduction of a trained canonical model (one rate, or the study)"
    ),
    Command("evaluate", "score a trained model: 100-step rollout MSE, RMSE / NRMSE / fit %%"),
    Command("export", "write a trained canonical model as a CasADi Function (.casadi)"),
    Command(
        "analyze", "γ_f, α_ℓ brackets (certified and sampled) and the Proposition 2 bound check"
    ),
    Command(
        "benchmark", "train and score on a standard benchmark (Silverbox, Cascaded Tanks, ...)"
    ),
    Command(
        "reproduce", "the paper's Table 1, compression study, analysis and figures: one report"
    ),
)


def command_names() -> list[str]:
    return [c.name for c in COMMANDS]
