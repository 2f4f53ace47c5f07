"""Library functions with the application's defaults, for ``import canonid``.

:func:`canonid.learning.fit` is the library's trainer; without ``options`` it uses the bare
:class:`~canonid.learning.training.TrainOptions` defaults, a small budget meant for building blocks.
``canonid.fit`` is the same trainer with what ``canonid train`` uses when no flag is given: the
``train`` stage of the ``quick`` profile (:mod:`canonid.profiles`), so a first call from Python
gets the command line's model.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from canonid.kernel.errors import DataError, OptionError
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
    window: int | Literal["auto"] = "auto",
    max_window: int | None = None,
    options: TrainOptions | None = None,
    profile: str = DEFAULT_PROFILE,
    **kwargs: Any,
) -> FitResult:
    """Train ``model`` by output error (:func:`canonid.learning.fit`) with window ``window``.

    ``window="auto"`` (the default, as ``canonid train`` without ``--window``) screens the
    windows :data:`~canonid.learning.screen.SCREEN_WINDOWS` that the records allow on the
    validation trajectories (:func:`~canonid.learning.screen.screen_windows`: a short training
    each; ``max_window``: only those up to it, as ``--max-window``) and trains the chosen one
    fully; while the full runs together stop early, before
    :data:`~canonid.learning.window_screen.FOLLOWUP_SHARE` of the epochs, the screen's next
    near-tied window is trained fully too and the lowest full-run validation loss chooses.
    The result carries the screen's table as ``result.screen``; with ``run_dir`` the table is
    written there too (:data:`~canonid.learning.screen.SCREEN_FILE`), the follow-ups in
    ``run_dir/followups/lL`` (the chosen one's files copied into ``run_dir``), and
    ``resume=True`` continues from what is recorded there instead of screening again. An
    integer trains exactly that window.

    ``options`` default to the ``train`` stage of ``profile`` (the command line's default,
    ``quick``); ``canonid.train_options(profile, epochs=…)`` changes one value of it. The other
    keyword arguments (``net_options``, ``run_dir``, ``resume``, ``callback``, ``info``) go to
    :func:`canonid.learning.fit` unchanged.
    """
    import dataclasses

    from canonid.kernel.dataset import Trajectory as Record
    from canonid.learning.screen import (
        FOLLOWUPS_DIR,
        SCREEN_WINDOWS,
        WindowScreen,
        fit_row,
        fitting_windows,
    )
    from canonid.learning.screen import screen_windows as screen_of
    from canonid.learning.training import CHECKPOINT_FILE
    from canonid.learning.training import fit as fit_library  # torch, only when training
    from canonid.selection import adopt
    from canonid.training import windows_up_to

    if options is None:
        options = train_options(profile)
    if window != "auto":
        if max_window is not None:
            raise OptionError("max_window caps the screen's windows: give it with window='auto'")
        return fit_library(train, val, model=model, window=window, options=options, **kwargs)
    run_dir = None if kwargs.get("run_dir") is None else Path(kwargs["run_dir"])
    if kwargs.get("resume") and run_dir is not None:  # the window the interrupted run chose
        screen = WindowScreen.read(run_dir)
    else:
        train, val = [Record.of(t) for t in train], [Record.of(t) for t in val]
        windows = fitting_windows(train, val, windows_up_to(max_window, "max_window"), options)
        if not windows:
            raise DataError(
                f"window='auto': none of the windows {list(SCREEN_WINDOWS)} fits the records "
                f"(shortest {min(len(t.y) for t in [*train, *val])} samples; training rollouts "
                f"{options.horizon}, validation rollouts {options.rollout_horizon}); give window=L"
            )
        screen = screen_of(
            train,
            val,
            windows=windows,
            model=model,
            options=options,
            net_options=kwargs.get("net_options"),
        )
        if run_dir is not None:
            run_dir.mkdir(parents=True, exist_ok=True)
            screen.write(run_dir)
    result = fit_library(train, val, model=model, window=screen.chosen, options=options, **kwargs)
    if not screen.full_runs:
        screen = screen.with_full_run(fit_row(result), options.epochs)
        if run_dir is not None:
            screen.write(run_dir)
    # the screen's near-tied windows, while the full runs so far stopped early (as canonid train)
    while (ell := screen.next_followup()) is not None:
        folder = None if run_dir is None else run_dir / FOLLOWUPS_DIR / f"l{ell}"
        again = folder is not None and (folder / CHECKPOINT_FILE).is_file()
        other = fit_library(
            train,
            val,
            model=model,
            window=ell,
            options=options,
            **{**kwargs, "run_dir": folder, "resume": again},
        )
        screen = screen.with_full_run(fit_row(other), options.epochs)
        if screen.chosen == ell:
            result = other
            if folder is not None and run_dir is not None:  # its model and checkpoint
                adopt(folder, run_dir, checkpoint=True)
        if run_dir is not None:
            screen.write(run_dir)
    return dataclasses.replace(result, screen=screen)
