"""Library functions with the application's defaults, for ``import canonid``.

:func:`canonid.learning.fit` is the library's trainer; without ``options`` it uses the bare
:class:`~canonid.learning.training.TrainOptions` defaults, a small budget meant for building blocks.
``canonid.fit`` is the same trainer with what ``canonid train`` uses when no flag is given: the
``train`` stage of the ``quick`` profile (:mod:`canonid.profiles`), so a first call from Python
gets the command line's model.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from canonid.kernel.errors import DataError, OptionError
from canonid.profiles import DEFAULT_PROFILE, train_options

if TYPE_CHECKING:
    from canonid.kernel.dataset import Trajectory
    from canonid.learning.training import EpochReport, FitResult, TrainOptions

__all__ = ["fit"]


def fit(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    model: str = "mlp",
    window: int | Sequence[int] | Literal["auto"] = "auto",
    cubic: int | Literal["auto"] = "auto",
    max_window: int | None = None,
    options: TrainOptions | None = None,
    profile: str = DEFAULT_PROFILE,
    net_options: Mapping[str, Any] | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    callback: Callable[[EpochReport], None] | None = None,
    info: Mapping[str, Any] | None = None,
) -> FitResult:
    """Train ``model`` by output error, choosing what is not given as ``canonid train`` does.

    Without ``window`` (``"auto"``) and ``cubic`` (``"auto"``), the model is chosen by the
    search of :mod:`canonid.learning.search` (successive halving over the windows
    :data:`~canonid.learning.search.WINDOWS` that the records allow, up to ``max_window``, and
    Ours (MLP)'s cubic branch :data:`~canonid.learning.search.CUBIC_UNITS`), ranked on the
    free-run simulation of ``val``; the result carries it as ``result.search``. An integer (or,
    for ``window``, a list) fixes that axis; both fixed train exactly that model. With
    ``run_dir`` the candidates train in ``run_dir/search/<name>``, the search is recorded in
    ``run_dir/search.json`` and the chosen model's files are copied into ``run_dir``; calling
    again with the same arguments continues an interrupted search.

    ``options`` default to the ``train`` stage of ``profile`` (the command line's default,
    ``quick``); ``canonid.train_options(profile, epochs=…)`` changes one value of it.
    ``net_options`` (the network's sizes, ``activation``, ``residual``, ``feedthrough``,
    ``linear``, ``cubic``), ``run_dir``, ``resume``, ``callback`` (called after every epoch) and
    ``info`` (recorded in the model) are :func:`canonid.learning.fit`'s; a search takes
    ``net_options``, ``run_dir`` and ``resume`` alone.
    """
    from canonid.kernel.dataset import Trajectory as Record
    from canonid.learning.search import adopt, candidate_table, fitting_windows, search
    from canonid.learning.training import fit as fit_library  # torch, only when training
    from canonid.training import search_axes

    if options is None:
        options = train_options(profile)
    if max_window is not None and window != "auto":
        raise OptionError("max_window caps the searched windows: give it with window='auto'")
    windows, cubics = search_axes(model, window, cubic, max_window, net_options)
    if len(windows) == 1 and len(cubics) == 1:
        network = dict(net_options or {})
        if model == "mlp" or "cubic" in network:
            network["cubic"] = cubics[0]
        return fit_library(
            train,
            val,
            model=model,
            window=windows[0],
            options=options,
            net_options=network,
            run_dir=run_dir,
            resume=resume,
            callback=callback,
            info=info,
        )
    if val is None or not len(val):
        raise OptionError(
            "val: validation trajectories are required (the search ranks its candidates on their "
            "simulation); hold out a few records or the tail of one"
        )
    train, val = [Record.of(t) for t in train], [Record.of(t) for t in val]
    fits = fitting_windows(train, val, windows, options.horizon)
    if not fits:
        raise DataError(
            f"window='auto': none of the windows {list(windows)} fits the records (shortest "
            f"{min(len(t.y) for t in [*train, *val])} samples, longest validation record "
            f"{max(len(t.y) for t in val)}; training rollouts {options.horizon}); give window=L"
        )
    unknown = [name for name, value in (("callback", callback), ("info", info)) if value]
    if unknown:
        raise OptionError(f"canonid.fit: {unknown} do not apply to a search")
    folder_in = None if run_dir is None else Path(run_dir)
    _, result, folder = search(
        train,
        val,
        model=model,
        table=candidate_table(fits, cubics),
        options=options,
        net_options=net_options,
        run_dir=folder_in,
    )
    if folder is not None and folder_in is not None:  # the chosen model, continued by a resume
        adopt(folder, folder_in)
    return result
