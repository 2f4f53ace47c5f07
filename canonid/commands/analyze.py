"""`canonid analyze` — the analysis (α_ℓ, γ_f, Proposition 2) (not implemented yet)."""

from __future__ import annotations

import argparse
from typing import Any

from canonid.commands._pending import not_yet


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "analyze",
        help="the analysis (α_ℓ, γ_f, Proposition 2) (not implemented yet)",
        description="the analysis (α_ℓ, γ_f, Proposition 2) (not implemented yet)",
    )
    p.set_defaults(func=not_yet("the analysis (α_ℓ, γ_f, Proposition 2)"))
