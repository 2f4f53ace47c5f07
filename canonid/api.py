"""Library functions with the application's defaults, for ``import canonid``.

:func:`canonid.learning.fit` is the library's trainer; without ``options`` it uses the bare
:class:`~canonid.learning.training.TrainOptions` defaults, a small budget meant for building blocks.
``canonid.fit`` is the same trainer with what ``canonid train`` uses when no flag is given: the
``train`` stage of the ``quick`` profile (:mod:`canonid.profiles`), so a first call from Python
gets the command line's model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from canonid.profiles import DEFAULT_PROFILE, train_options

if TYPE_CHECKING:
    from canonid.kernel.dataset import Trajectory
    from canonid.learning.training import FitResult, TrainOptions

__all__ = ["fit"]


def fit(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    model: str = "mlp",
    window: int,
    options: TrainOptions | None = None,
    profile: str = DEFAULT_PROFILE,
    **kwargs: Any,
) -> FitResult:
    """Train ``model`` with window ``window`` by output error (:func:`canonid.learning.fit`).

    ``options`` default to the ``train`` stage of ``profile`` (the command line's default,
    ``quick``); ``canonid.train_options(profile, epochs=…)`` changes one value of it. The other
    keyword arguments (``net_options``, ``run_dir``, ``resume``, ``callback``, ``info``) go to
    :func:`canonid.learning.fit` unchanged.
    """
    from canonid.learning.training import fit as fit_library  # torch, only when training

    if options is None:
        options = train_options(profile)
    return fit_library(train, val, model=model, window=window, options=options, **kwargs)
