"""canonid: learn reduced nonlinear state-space models with the output-error canonical method.

The application layer (CLI, experiment profiles, sweeps, reports) lives here; the library layers
are the top-level packages ``models``, ``datagen``, ``learning`` and ``analysis``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("canonid")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.1.0"

__all__ = ["__version__"]
