"""Shared body of subcommands whose issue has not landed yet."""

from __future__ import annotations

import argparse

from models.errors import NotImplementedYetError


def not_yet(feature: str) -> object:
    def run(args: argparse.Namespace) -> int:
        raise NotImplementedYetError(
            f"{feature} is not implemented yet in this version of canonid (exit code 2)"
        )

    return run
