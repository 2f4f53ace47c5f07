"""One module per subcommand; each exposes ``register(subparsers)``."""

from canonid.commands import (
    analyze,
    benchmark,
    evaluate,
    generate,
    reduce,
    reproduce,
    systems,
    train,
)

#: registration order is the order shown by ``canonid --help``
COMMANDS = (systems, generate, train, reduce, evaluate, analyze, benchmark, reproduce)

__all__ = ["COMMANDS"]
