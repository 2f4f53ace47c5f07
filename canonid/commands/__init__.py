"""One module per subcommand; each exposes ``register(subparsers)``."""

from canonid.commands import (
    analyze,
    evaluate,
    export,
    generate,
    reduce,
    reproduce,
    systems,
    train,
)

#: registration order is the order shown by ``canonid --help``
COMMANDS = (systems, generate, train, reduce, evaluate, export, analyze, reproduce)

__all__ = ["COMMANDS"]
