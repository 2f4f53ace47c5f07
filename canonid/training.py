"""What ``canonid train`` (and ``canonid benchmark``) ask for, and the one call that does it.

A :class:`TrainRequest` holds the options as the user gave them (``None``: not given).
:func:`train` turns it into the run's recipe (:class:`canonid.runfolder.RunRecipe`: the
profile's options with the overrides, the network's options over :mod:`canonid.kernel.catalog`'s
presets), or checks it against the recipe of the run it resumes (the resume rule: of the training
options only :data:`canonid.learning.training.RESUMABLE_CHANGES` may change, the network's none).
What the user did not fix is chosen by the search of :mod:`canonid.learning.search`: the window
(``--window`` not given, or a list), Ours (MLP)'s cubic branch (``--cubic`` not given) and the
widths (``--hidden auto``) are the axes of its candidate table, ranked on the free-run
simulation of the validation records. It returns a :class:`TrainOutcome`, whose
:meth:`~TrainOutcome.summary` the command prints: validation scores only; the test split is
read by ``canonid evaluate`` (or ``canonid benchmark``), after the choice.

The module imports no torch: the command line reads its names for ``--help``; the training
loads when :func:`train` runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from canonid.coverage import recorded_unvalidated, unvalidated_line
from canonid.horizon_check import ALTERNATIVES as HORIZON_ALTERNATIVES
from canonid.horizon_check import HORIZON_CHECK_FILE
from canonid.kernel.catalog import parse_list
from canonid.kernel.errors import CheckpointError, OptionError, OutputError
from canonid.learning.search import CUBIC_UNITS, ETA, SEARCH_FILE, WINDOWS, Search, cubic_axis
from canonid.members import check_members
from canonid.profiles import profile_values

if TYPE_CHECKING:
    from canonid.horizon_check import HorizonChoice
    from canonid.learning import EpochReport, Model
    from canonid.learning.search import Candidate
    from canonid.members import MemberChoice, MemberJob
    from canonid.runfolder import RunRecipe, RunResult

__all__ = [
    "AUTO",
    "CUBIC_HELP",
    "HORIZON_HELP",
    "MEMBERS_HELP",
    "REQUEST_TEXT_FIELDS",
    "SEARCH_CUBIC_UNITS",
    "SEARCH_ETA",
    "TRAIN_OPTION_FIELDS",
    "WIDTH_CANDIDATES",
    "WINDOW_CANDIDATES",
    "TrainOutcome",
    "TrainRequest",
    "check_new_run",
    "check_request",
    "parse_cubic",
    "parse_weight_decay",
    "parse_widths",
    "parse_window",
    "request_fields",
    "same_run",
    "search_axes",
    "train",
    "windows_up_to",
]

AUTO = "auto"
#: the search's halving rate and cubic axis, for ``--help``
SEARCH_ETA, SEARCH_CUBIC_UNITS = ETA, CUBIC_UNITS
#: the windows that ``window="auto"`` searches (those the data allow)
WINDOW_CANDIDATES = WINDOWS
#: the hidden widths that ``hidden="auto"`` tries (three layers, up to the default 256)
WIDTH_CANDIDATES = ((64, 64, 64), (128, 128, 128), (256, 256, 256))
#: the request's fields that override the profile's training options (same names)
TRAIN_OPTION_FIELDS = (
    "epochs",
    "lr",
    "weight_decay",
    "batch_size",
    "horizon",
    "windows_per_epoch",
    "seed",
    "device",
)
#: the request's network options that are never given again to a resumed run
_NET_FLAGS = ("residual", "feedthrough", "linear", "cubic")
#: the options of ``canonid train`` that :func:`request_fields` reads as text
REQUEST_TEXT_FIELDS = ("window", "hidden", "weight_decay", "cubic", "max_window", "resume", "out")
#: ``canonid train --train-horizon``'s help
HORIZON_HELP = (
    f"final training rollout length ({profile_values('train', 'horizon')}; on a canonid "
    "generate dataset flown in closed loop with an excitation, where that model's residuals "
    "correlate with the excitation on validation more than chance allows, also "
    f"{' then '.join(map(str, HORIZON_ALTERNATIVES))} until one passes, the fewest kept: "
    f"RUN/{HORIZON_CHECK_FILE})"
)
#: ``canonid train --cubic``: what the branch is and how ``auto`` decides it
CUBIC_HELP = (
    "Ours (MLP)'s cubic branch C (W x + b)³ beside the network, K units (0: none); default "
    f"auto: the search keeps it or not ({' or '.join(map(str, CUBIC_UNITS))} units, "
    "ranked on the validation records' simulation)"
)

#: ``canonid train --members``
MEMBERS_HELP = (
    "Ours (MLP): train the run's recipe from K seeds (the run's seed and the K − 1 after it, "
    "each in RUN/members/sS) and keep the lowest validation loss among each alone and the means "
    "of the 2 … K best (their regressors averaged: one canonical model); where the input "
    "response was checked (closed-loop data with an excitation), none that answers the "
    "excitation worse than the run's own; members.json records the choice (default 1, or 3 "
    "where the horizon check kept the shorter rollouts; K times the training)"
)


@dataclass(frozen=True, kw_only=True)
class TrainRequest:
    """A training run as asked for; every option ``None`` (or ``False``) when not given.

    Attributes:
        data, data_options, val, val_fraction: the training data, the loader options
            (:data:`canonid.data_options.DATA_FLAGS`), a validation file, the share held out.
        model, window: registry name (default ``mlp``) and window ℓ; ``"auto"`` (a new run's
            default) or a tuple: the search's window axis (``window_candidates``, or the tuple).
        window_candidates: the windows ``window="auto"`` searches (those the data allow).
        profile: the training budget (default :data:`canonid.profiles.DEFAULT_PROFILE`).
        epochs … device: overrides of the profile's training options (:data:`TRAIN_OPTION_FIELDS`).
        hidden, activation, residual, feedthrough, linear, cubic, paper_options: the network's
            options (``hidden="auto"``, ``cubic="auto"``: axes of the search).
        out, resume: the new run's folder, or the run to continue.
        eval_horizon, threads: the final score's rollout length; torch CPU threads.
        members: train the run's recipe from this many seeds and keep the lowest validation
            loss among them and the means of their best (:mod:`canonid.members`; default 1,
            a resumed run the number it planned).
        figure_format: the figures' file format (one of :data:`canonid.kernel.io.FIGURE_FORMATS`).
        workers, scheduler, progress: where a search's candidates run (local worker
            processes; a cluster's scheduler address); progress bars.
        command: the command line that asked (recorded in ``run.json``).
    """

    data: str | None = None
    data_options: Mapping[str, Any] = field(default_factory=dict)
    val: str | None = None
    val_fraction: float | None = None
    model: str | None = None
    window: int | Literal["auto"] | tuple[int, ...] | None = None
    window_candidates: tuple[int, ...] = WINDOW_CANDIDATES
    profile: str | None = None
    epochs: int | None = None
    lr: float | None = None
    weight_decay: float | None = None
    batch_size: int | None = None
    horizon: int | None = None
    windows_per_epoch: int | None = None
    seed: int | None = None
    device: str | None = None
    hidden: tuple[int, ...] | Literal["auto"] | None = None
    activation: str | None = None
    residual: bool | None = None
    feedthrough: bool | None = None
    linear: str | None = None
    cubic: int | Literal["auto"] | None = None
    paper_options: bool = False
    out: Path | None = None
    resume: Path | None = None
    eval_horizon: int | None = None
    figure_format: str = "png"
    threads: int | None = None
    members: int | None = None
    workers: int | None = None
    scheduler: str | None = None
    progress: bool = True
    command: tuple[str, ...] = ()


@dataclass(frozen=True)
class TrainOutcome:
    """What :func:`train` did: the run trained into ``run_dir`` (``result``; ``search``: the
    search that chose its model), with its ``metrics.json`` body (scored on validation)."""

    run_dir: Path
    metrics: Mapping[str, Any]
    result: RunResult | None = None
    search: Search | None = None
    members: MemberChoice | None = None
    horizon: HorizonChoice | None = None
    #: lines the summary says whatever the progress display (the horizon check not made)
    notes: tuple[str, ...] = ()

    def summary(self) -> str:
        """What ``canonid train`` prints: the search, how training ended, the validation
        scores, where the run is."""
        from canonid.scoring import metrics_table

        assert self.result is not None
        fitted = self.result.fit
        head = []
        if self.search is not None:
            head = [self.search.table(), self.search.summary()]
        head.append(
            f"{self.result.recipe.model}: {fitted.stopped} after {fitted.epochs_run} epochs, "
            f"best validation loss {fitted.best_val_loss:.4g} (normalised) at epoch "
            f"{fitted.best_epoch}"
        )
        test = fitted.model.info.get("feedthrough_test")
        if test:  # feedthrough "auto": say what the data decided
            head.append(
                f"feedthrough {'on' if test['feedthrough'] else 'off'} (decided on validation: "
                f"with u_t the linear fit's one-step error is "
                f"{test['with_u'] / test['without_u']:.3g} of that without; "
                "--feedthrough / --no-feedthrough decide instead)"
            )
        unseen = unvalidated_line(recorded_unvalidated(fitted.model.info))
        if unseen:
            head.append(unseen)
        if self.horizon is not None:
            head.append(self.horizon.summary())
        head.extend(self.notes)
        if self.members is not None:
            head.append(f"{self.members.summary()}; the scores below are the kept model's")
        return "\n".join(
            [
                *head,
                metrics_table(self.metrics),
                f"run written to {self.run_dir} (scored on validation; canonid evaluate "
                f"{self.run_dir} scores the test split)",
            ]
        )


def parse_widths(text: str | None) -> tuple[int, ...] | Literal["auto"] | None:
    """``"2048,2048"`` → ``(2048, 2048)`` (positive integers), ``"auto"``, or
    :class:`OptionError` naming ``--hidden``."""
    if text is None or text == AUTO:
        return text  # type: ignore[return-value]
    try:
        widths = tuple(int(part) for part in text.split(","))
    except ValueError:
        widths = ()
    if not widths or min(widths) < 1:
        raise OptionError(
            f"--hidden: expected positive integer widths separated by commas (e.g. 2048,2048), "
            f"got {text!r}"
        )
    return widths


def parse_weight_decay(text: str | None) -> float | None:
    """``--weight-decay``: a number or ``None`` (not given); else an :class:`OptionError`
    naming the option (its range is checked with the other options)."""
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        raise OptionError(f"--weight-decay: expected a number >= 0, got {text!r}") from None


def parse_cubic(text: str | None) -> int | Literal["auto"] | None:
    """``--cubic``: a number of units >= 0, ``"auto"`` or ``None`` (not given); else an
    :class:`OptionError` naming the option."""
    if text is None or text == AUTO:
        return text  # type: ignore[return-value]
    if not (text.isascii() and text.isdigit()):
        raise OptionError(f"--cubic: expected a number of units >= 0 or auto, got {text!r}")
    return int(text)


def parse_window(text: str | None) -> int | Literal["auto"] | tuple[int, ...] | None:
    """``--window``: ``"10"`` → 10, ``"5,10,20"`` → ``(5, 10, 20)``, ``"5-7"`` → ``(5, 6, 7)``
    (the one list syntax, :func:`canonid.kernel.catalog.parse_list`), ``"auto"``, ``None`` (not
    given); else :class:`OptionError` naming ``--window``."""
    if text is None or text == AUTO:
        return text  # type: ignore[return-value]
    # '²'.isdigit() is true and int('²') fails: ASCII digits (and the ranges' dash) only
    try:
        if not text.isascii() or not set(text) <= set("0123456789,-"):
            raise OptionError(text)
        values = parse_list(text, int, "L")
    except OptionError:
        values = []
    if not values or min(values) < 1:
        raise OptionError(
            f"--window: expected an integer >= 1, a comma list of them (e.g. 5,10,20), a range "
            f"A-B or auto, got {text!r}"
        )
    windows = tuple(dict.fromkeys(values))
    return windows[0] if len(values) == 1 and "-" not in text else windows


def request_fields(
    *,
    window: str | None,
    hidden: str | None,
    weight_decay: str | None,
    cubic: str | None,
    max_window: int | None,
    resume: str | bool | None,
    out: Path | None,
) -> dict[str, Any]:
    """The fields of a :class:`TrainRequest` that ``canonid train`` writes as text or implies:
    ``window``, ``hidden``, ``weight_decay`` and ``cubic`` parsed (:func:`parse_window`,
    :func:`parse_widths`, :func:`parse_weight_decay`, :func:`parse_cubic`); ``resume`` and
    ``out`` from ``--resume [RUN]`` and ``--out`` (:func:`canonid.jobs.resume_target`);
    ``window_candidates``, the searched windows up to ``max_window`` (:func:`windows_up_to`),
    refused where the window is not searched (a window given, or a run resumed)."""
    from canonid.jobs import resume_target

    parsed = parse_window(window)
    run, folder = resume_target(resume, out)
    screened = parsed in (None, AUTO) and run is None
    return {
        "window": parsed,
        "resume": run,
        "out": folder,
        "hidden": parse_widths(hidden),
        "weight_decay": parse_weight_decay(weight_decay),
        "cubic": parse_cubic(cubic),
        "window_candidates": windows_up_to(max_window, screened=screened),
    }


def _flag(name: str) -> str:
    return f"--{name.replace('_', '-')}"


def _hidden_option(model: str) -> str:
    """The constructor argument of ``model`` that ``hidden`` sets."""
    from canonid.learning import NETS

    option = NETS[model].hidden_option
    if option is None:
        raise OptionError(f"--hidden does not apply to {model}: {NETS[model].no_widths}")
    return option


def check_new_run(run_dir: Path) -> None:
    """Refuse an output folder that holds another kind of run, or files canonid did not write
    (:func:`canonid.jobs.check_run_folder`), or a run already (resumed with ``--resume``)."""
    from canonid.jobs import check_run_folder
    from canonid.learning.training import CHECKPOINT_FILE

    check_run_folder(run_dir)
    for name in (CHECKPOINT_FILE, SEARCH_FILE):
        if (run_dir / name).exists():
            raise OutputError(
                f"{run_dir} already holds a training run; use --resume --out {run_dir} or "
                "another --out"
            )


def _recipe(request: TrainRequest) -> RunRecipe:
    """The recipe of a new run: the profile's training options with the overrides, the
    network's presets with the options given."""
    from canonid.kernel.catalog import DEFAULT_MODEL, DEFAULT_VAL_FRACTION, net_options
    from canonid.learning import NETS
    from canonid.learning.nets.base import CanonicalModel
    from canonid.profiles import DEFAULT_PROFILE, train_options
    from canonid.runfolder import RunRecipe

    if request.data is None:
        raise OptionError("give the training DATA (or --resume --out RUN)")
    if not isinstance(request.window, int):  # the callers resolve "auto" and lists
        raise OptionError(f"--window: a new run's recipe needs one window, got {request.window!r}")
    model = request.model or DEFAULT_MODEL
    if request.val_fraction is not None and not 0 < request.val_fraction < 1:
        raise OptionError(f"--val-fraction must be in (0, 1), got {request.val_fraction}")
    profile = request.profile or DEFAULT_PROFILE
    overrides = {key: getattr(request, key) for key in TRAIN_OPTION_FIELDS}
    opts = train_options(profile, **{**overrides, "device": request.device or "auto"})
    chosen: dict[str, Any] = {
        key: getattr(request, key)
        for key in ("feedthrough", "residual")
        if getattr(request, key) is not None
    }
    if request.hidden is not None:
        chosen[_hidden_option(model)] = list(request.hidden)
    if request.activation is not None:
        if model != "mlp":
            raise OptionError(f"--activation applies to Ours (MLP) only, not {model}")
        chosen["activation"] = request.activation
    if request.linear is not None:
        if not issubclass(NETS[model], CanonicalModel):
            raise OptionError(
                f"--linear applies to the canonical models (mlp, gru, arx), not {model}"
            )
        if model == "arx" and request.linear != "arx":
            raise OptionError(f"--linear {request.linear}: ARX is the affine path alone (arx)")
        chosen["linear"] = request.linear
    if request.cubic is not None:
        if model != "mlp":
            raise OptionError(f"--cubic applies to Ours (MLP) only, not {model}")
        chosen["cubic"] = request.cubic
    return RunRecipe(
        data=str(request.data),
        data_options=dict(request.data_options),
        val=request.val,
        val_fraction=(
            DEFAULT_VAL_FRACTION if request.val_fraction is None else request.val_fraction
        ),
        model=model,
        window=int(request.window),
        net_options=net_options(model, chosen, paper=request.paper_options),
        profile=profile,
        train_options=opts.to_dict(),
        given_options=tuple(key for key, value in overrides.items() if value is not None),
        members=request.members,
        command=request.command,
    )


def _resume_recipe(request: TrainRequest, run_dir: Path) -> RunRecipe:
    """The recipe of the run in ``run_dir`` with the options that may change when resuming
    (:data:`~canonid.learning.training.RESUMABLE_CHANGES`); any other option given must match
    the recorded one, and the training and network options may not be given at all."""
    import inspect

    from canonid.learning import NETS, TrainOptions
    from canonid.learning.training import CHECKPOINT_FILE, RESUMABLE_CHANGES
    from canonid.runfolder import RunRecipe

    if not any((run_dir / name).is_file() for name in (CHECKPOINT_FILE, SEARCH_FILE)):
        raise CheckpointError(f"{run_dir} holds no {CHECKPOINT_FILE} to resume from")
    changeable = [key for key in TRAIN_OPTION_FIELDS if key in RESUMABLE_CHANGES]
    fixed = [
        _flag(key)
        for key in (*(k for k in TRAIN_OPTION_FIELDS if k not in RESUMABLE_CHANGES), *_NET_FLAGS)
        if getattr(request, key) is not None
    ]
    if request.paper_options:
        fixed.append("--paper-options")
    if fixed:
        raise OptionError(
            f"{', '.join(fixed)} cannot change when resuming "
            f"(only {' and '.join(map(_flag, changeable))} can)"
        )
    recipe = RunRecipe.read(run_dir)
    if request.out is not None and request.out.resolve() != run_dir.resolve():
        raise OptionError(f"--out does not apply with --resume: the run continues in {run_dir}")
    diffs = [
        f"{key}: {getattr(recipe, key)!r} there, {value!r} here"
        for key, value in (
            ("model", request.model),
            ("window", request.window),
            ("data", request.data),
            ("profile", request.profile),
            ("val", request.val),
            ("val_fraction", request.val_fraction),
        )
        if value is not None and getattr(recipe, key) != value
    ]
    recorded = recipe.data_options
    diffs += [
        f"{key}: {recorded.get(key)!r} there, {value!r} here"
        for key, value in request.data_options.items()
        if value is not None and recorded.get(key) != value
    ]
    if request.hidden is not None:
        option = _hidden_option(recipe.model)
        default = inspect.signature(NETS[recipe.model]).parameters[option].default
        there, here = list(recipe.net_options.get(option, default)), list(request.hidden)
        if there != here:
            diffs.append(f"hidden widths: {there} there, {here} here")
    if request.activation is not None:
        there = recipe.net_options.get("activation", "relu")
        if there != request.activation:
            diffs.append(f"activation: {there} there, {request.activation} here")
    if diffs:
        raise CheckpointError(f"run {run_dir} does not match: " + "; ".join(diffs))
    changes = {k: getattr(request, k) for k in changeable if getattr(request, k) is not None}
    opts = {**recipe.train_options, **changes}
    return dataclasses.replace(
        recipe,
        train_options=TrainOptions.from_dict(opts).to_dict(),
        given_options=(*recipe.given_options, *changes),
        members=recipe.members if request.members is None else request.members,
    )


def _searched(request: TrainRequest) -> bool:
    """Whether ``request``, a new run, leaves an axis of the search open: the window (not given,
    ``auto`` or a list), the widths (``hidden="auto"``) or Ours (MLP)'s cubic branch (not
    given, without ``--paper-options``)."""
    if isinstance(request.window, tuple) or request.window in (None, AUTO):
        return True
    if request.hidden == AUTO:
        return True
    model = request.model or "mlp"
    return model == "mlp" and not request.paper_options and request.cubic in (None, AUTO)


def windows_up_to(
    limit: int | None, what: str = "--max-window", *, screened: bool = True
) -> tuple[int, ...]:
    """The windows the search tries that are no longer than ``limit`` (all for ``None``): a
    scoring rule that feeds the model ``n_init`` measured samples caps the window at it.
    ``screened``: whether the window is searched at all (a cap without a search is refused)."""
    if limit is None:
        return WINDOW_CANDIDATES
    if not screened:
        raise OptionError(
            f"{what} caps the searched windows: give it without --window L and --resume"
        )
    kept = tuple(w for w in WINDOW_CANDIDATES if w <= limit)
    if not kept:
        raise OptionError(
            f"{what} {limit} is below every window the search tries "
            f"({', '.join(map(str, WINDOW_CANDIDATES))}); give one window ≤ {limit} instead"
        )
    return kept


def search_axes(
    model: str,
    window: int | Sequence[int] | str | None,
    cubic: int | str | None,
    max_window: int | None = None,
    net_options: Mapping[str, Any] | None = None,
    *,
    paper: bool = False,
) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The search's window and cubic axes: what is given fixes an axis, ``"auto"`` (or not
    given) opens it (the windows :data:`WINDOW_CANDIDATES` up to ``max_window``; the cubic
    branch :data:`~canonid.learning.search.CUBIC_UNITS` for Ours (MLP) without the paper's
    options, where ``net_options`` do not give it)."""
    if isinstance(window, int):
        windows: tuple[int, ...] = (window,)
    elif window is None or window == AUTO:
        windows = windows_up_to(max_window, "max_window")
    else:
        windows = tuple(int(w) for w in window)
    given = (net_options or {}).get("cubic", cubic)
    if given in (None, AUTO):  # open where the model has the branch (not the paper's network)
        given = AUTO if model == "mlp" and not paper else None
    return windows, cubic_axis(given)


def _table(request: TrainRequest, base: RunRecipe) -> tuple[Candidate, ...]:
    """The candidate table of ``request`` (its data decide later which windows fit)."""
    from canonid.learning.search import candidate_table

    if isinstance(request.window, tuple):
        windows: tuple[int, ...] = request.window
    elif isinstance(request.window, int):
        windows = (request.window,)
    else:
        windows = request.window_candidates
    widths: Sequence[tuple[int, ...] | None] = (
        WIDTH_CANDIDATES if request.hidden == AUTO else (None,)
    )
    return candidate_table(windows, cubic_axis(base.net_options.get("cubic")), widths)


def _candidates_base(request: TrainRequest) -> RunRecipe:
    """The recipe that the candidates of a search vary, at their first window: every option
    checked before any data are read."""
    if isinstance(request.window, tuple):
        windows = request.window
    elif isinstance(request.window, int):
        windows = (request.window,)
    else:
        windows = request.window_candidates
    if not windows:
        raise OptionError("--window: no candidate window to try")
    hidden_auto = request.hidden == AUTO
    base = _recipe(
        dataclasses.replace(
            request, window=windows[0], hidden=None if hidden_auto else request.hidden
        )
    )
    if hidden_auto:
        _hidden_option(base.model)  # refuses a model without hidden widths
    return base


def _candidates_folder(request: TrainRequest, base: RunRecipe) -> Path:
    """``--out``, else ``runs/MODEL-lauto`` (the window searched), ``runs/MODEL-l5-10-20`` (a
    list), ``runs/MODEL-l10`` (one window), with ``-hauto`` for ``hidden="auto"``."""
    if isinstance(request.window, tuple):
        window = "-".join(str(w) for w in request.window)
    elif isinstance(request.window, int):
        window = str(request.window)
    else:
        window = AUTO
    return request.out or Path("runs") / (
        f"{base.model}-l{window}" + ("-hauto" if request.hidden == AUTO else "")
    )


def _plan(request: TrainRequest) -> tuple[Path, RunRecipe, tuple[Candidate, ...] | None]:
    """Check ``request`` as far as it can be without its data: the options and their
    combinations, the recipe of a new run (refusing a folder that holds another run), or the
    resume rule against the recorded recipe. Returns the run folder, the recipe to train and
    the candidate table of a new search (``None``: one model, or the search a resumed run
    recorded)."""
    for flag, value in (("--threads", request.threads), ("--eval-horizon", request.eval_horizon)):
        if value is not None and value < 1:
            raise OptionError(f"{flag} must be an integer >= 1, got {value}")
    _check_ranges(request)
    if request.workers is not None and request.workers < 0:
        raise OptionError(f"--workers must be an integer >= 0, got {request.workers}")
    if request.workers is not None and request.scheduler is not None:
        raise OptionError("give either --workers (a local cluster) or --scheduler, not both")
    if request.resume is not None:
        if isinstance(request.window, tuple) or request.hidden == AUTO:
            given = (
                "--hidden auto"
                if request.hidden == AUTO
                else "--window "
                + ",".join(
                    map(str, request.window)  # type: ignore[arg-type]
                )
            )
            raise OptionError(
                f"{given} does not combine with --resume: the run continues the search it recorded"
            )
        recipe = _resume_recipe(request, request.resume)
        if request.members is not None:
            check_members(request.members, recipe.model, mode="run")
        return request.resume, recipe, None
    if request.hidden == AUTO and not isinstance(request.window, (int, tuple)):
        raise OptionError(
            "--hidden auto needs the window: give --window L or a list (e.g. --window 5,10,20)"
        )
    if not _searched(request):
        recipe = _recipe(request)
        _check_sizes(request)
        run_dir = request.out or Path("runs") / f"{recipe.model}-l{recipe.window}"
        check_new_run(run_dir)
        if request.members is not None:
            check_members(request.members, recipe.model, mode="run")
        return run_dir, recipe, None
    base = _candidates_base(request)
    _check_sizes(request)
    if request.members is not None:  # a list of windows or of widths: members would not fit
        listed = isinstance(request.window, tuple) or request.hidden == AUTO
        check_members(request.members, base.model, mode="select" if listed else "search")
    run_dir = _candidates_folder(request, base)
    check_new_run(run_dir)
    return run_dir, base, _table(request, base)


def _check_ranges(request: TrainRequest) -> None:
    """Refuse ``--lr`` and ``--windows-per-epoch`` outside their documented ranges, naming the
    option, before anything is read or written (:class:`~canonid.learning.TrainOptions` checks
    the same bounds for the API)."""
    from canonid.kernel.catalog import MAX_LR, MAX_WINDOWS_PER_EPOCH

    lr, per_epoch = request.lr, request.windows_per_epoch
    if lr is not None and not (math.isfinite(lr) and 0 < lr <= MAX_LR):
        raise OptionError(f"--lr must be a number in (0, {MAX_LR:g}], got {lr:g}")
    if per_epoch is not None and not 1 <= per_epoch <= MAX_WINDOWS_PER_EPOCH:
        raise OptionError(
            f"--windows-per-epoch must be an integer from 1 to {MAX_WINDOWS_PER_EPOCH:,}, got "
            f"{per_epoch:,}"
        )


def _check_sizes(request: TrainRequest) -> None:
    """Refuse ``--hidden`` widths and ``--cubic`` units whose network would pass the memory
    ceiling (:func:`~canonid.kernel.catalog.check_network_memory`), before the data are read:
    counted at the least the data can make it, one input, one output and the smallest window."""
    from canonid.kernel.catalog import check_network_memory

    widths = request.hidden if isinstance(request.hidden, tuple) else ()
    cubic = request.cubic if isinstance(request.cubic, int) else 0
    if not widths and not cubic:
        return
    if isinstance(request.window, int):
        window = request.window
    else:
        window = min(request.window if isinstance(request.window, tuple) else WINDOW_CANDIDATES)
    given = " ".join(
        f"{flag} {text}"
        for flag, text in (("--hidden", ",".join(map(str, widths))), ("--cubic", str(cubic)))
        if text not in ("", "0")
    )
    check_network_memory(widths, cubic, 2 * window, 1, given=given)


def check_request(request: TrainRequest) -> Path:
    """What :func:`train` checks before it reads data or writes anything (see :func:`_plan`):
    ``canonid benchmark`` checks its training this way before it writes its data. Returns the
    run folder."""
    return _plan(request)[0]


def same_run(request: TrainRequest, run_dir: Path) -> RunRecipe:
    """The recipe recorded in ``run_dir`` when ``request``, a new run, asks for the same run
    (the same recipe but for the command line, its data compared by checksum by the caller);
    else a :class:`CheckpointError` naming the differences."""
    from canonid.runfolder import RunRecipe

    recorded = RunRecipe.read(run_dir)
    wanted_recipe = _plan_recipe(request)
    if (run_dir / SEARCH_FILE).is_file():  # what the search chose is the run's
        chosen = Search.read(run_dir).chosen
        searched = ("val_measure", "val_n_init")  # how the search validated its candidates
        wanted_recipe = dataclasses.replace(
            wanted_recipe,
            window=recorded.window if chosen is None else chosen.window,
            net_options={
                **wanted_recipe.net_options,
                **{k: v for k, v in recorded.net_options.items() if k in ("cubic", "hidden")},
            },
            train_options={
                **wanted_recipe.train_options,
                **{k: v for k, v in recorded.train_options.items() if k in searched},
            },
        )
    # how the options were asked for is not what runs: --epochs 600 continues a run of the profile's
    ignored = {"command", "given_options", "members", "data", "data_sha256", "val_sha256"}
    there = _flat({k: v for k, v in recorded.to_dict().items() if k not in ignored})
    wanted = _flat({k: v for k, v in wanted_recipe.to_dict().items() if k not in ignored})
    diffs = [
        f"{key}: {there.get(key)!r} there, {wanted.get(key)!r} here"
        for key in sorted({*wanted, *there})
        if there.get(key) != wanted.get(key)
    ]
    if diffs:
        raise CheckpointError(
            f"{run_dir} holds a run started with other options ({'; '.join(diffs)}); give the "
            f"same options to continue it, resume it (--resume --out {run_dir}), or choose "
            "another --out"
        )
    return recorded


def _plan_recipe(request: TrainRequest) -> RunRecipe:
    """The recipe a new ``request`` starts from (a search's: at its first window)."""
    return _candidates_base(request) if _searched(request) else _recipe(request)


def _flat(body: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` → ``{"a.b": 1}`` (the differences of two recipes, by name)."""
    flat: dict[str, Any] = {}
    for key, value in body.items():
        if isinstance(value, Mapping):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def train(
    request: TrainRequest, *, callback: Callable[[EpochReport], None] | None = None
) -> TrainOutcome:
    """Train (or resume) the run that ``request`` asks for — the search's choice where an axis
    is open — write its run folder and score it on validation; a single run shows its epochs in
    a progress bar (``request.progress``) and passes them to ``callback``."""
    from canonid.horizon_check import finish_adoption
    from canonid.jobs import run_folder_lock

    resumed = request.resume
    if resumed is not None and (resumed / HORIZON_CHECK_FILE).is_file():
        with run_folder_lock(resumed, flag="--resume"):  # an adoption left half done, finished
            finish_adoption(resumed)
    run_dir, recipe, table = _plan(request)
    outcome = _train_one(
        request, recipe, run_dir, resume=resumed is not None, callback=callback, table=table
    )
    return _members(request, _horizon(request, outcome))


def _horizon(request: TrainRequest, outcome: TrainOutcome) -> TrainOutcome:
    """The training horizon chosen by the input response (:mod:`canonid.horizon_check`) where
    it applies: the run's own model, or the alternative trained with shorter rollouts and
    adopted as the run folder's."""
    import sys

    from canonid.horizon_check import applies, choose_horizon
    from canonid.jobs import run_folder_lock

    run_dir = outcome.run_dir
    if outcome.result is None or not applies(run_dir, horizon_given=request.horizon is not None):
        return outcome
    trained: dict[int, TrainOutcome] = {}

    def alternative(folder: Path, resume: bool, horizon: int) -> None:
        trained[horizon] = _train_alternative(request, run_dir, folder, resume, horizon)

    notes: list[str] = []

    def say(line: str) -> None:
        if "not checked" in line:  # a verdict, not progress: in the summary, bars on or off
            notes.append(line)
        elif request.progress:
            print(line, file=sys.stderr)

    with run_folder_lock(run_dir, flag="--out"):
        choice = choose_horizon(run_dir, alternative, say=say)
    outcome = dataclasses.replace(outcome, notes=(*outcome.notes, *notes))
    if choice is None:
        return outcome
    if choice.adopted and choice.chosen in trained:  # trained here: its outcome is the run's now
        outcome = dataclasses.replace(trained[choice.chosen], run_dir=run_dir)
    return dataclasses.replace(outcome, horizon=choice)


def _train_alternative(
    request: TrainRequest, run_dir: Path, folder: Path, resume: bool, horizon: int
) -> TrainOutcome:
    """The run of ``run_dir`` again with rollouts of ``horizon`` samples (one of
    :data:`~canonid.horizon_check.ALTERNATIVES`), into ``folder``: the model the run chose (its
    window and branch) with that horizon, or continued from ``folder``'s checkpoint."""
    from canonid.runfolder import RunRecipe

    if resume:
        return _train_one(request, RunRecipe.read(folder), folder, resume=True, callback=None)
    own = RunRecipe.read(run_dir)
    base = dataclasses.replace(own, train_options={**own.train_options, "horizon": horizon})
    return _train_one(request, base, folder, resume=False, callback=None)


def _member_count(request: TrainRequest, outcome: TrainOutcome) -> int:
    """``--members``, else what a resumed run planned (``members.json``) or was given when it
    began (``run.json``), else :data:`~canonid.horizon_check.MEMBERS` where the horizon check
    kept an alternative, else 1."""
    from canonid.horizon_check import MEMBERS
    from canonid.members import planned_members
    from canonid.runfolder import RunRecipe

    if request.members is not None:
        return request.members
    if request.resume is not None:
        planned = planned_members(outcome.run_dir) or RunRecipe.read(outcome.run_dir).members
        if planned:
            return planned
    return MEMBERS if outcome.horizon is not None and outcome.horizon.adopted else 1


def _members(request: TrainRequest, outcome: TrainOutcome) -> TrainOutcome:
    """After the run's own training: its members and the choice among them
    (:func:`canonid.members.choose_members`), where more than one is asked for."""
    from canonid.horizon_check import response_count
    from canonid.jobs import run_folder_lock
    from canonid.members import choose_members
    from canonid.runfolder import METRICS_FILE, read_metrics

    count = _member_count(request, outcome)
    if count == 1 or outcome.result is None:
        return outcome
    # where the input response was checked, no candidate may answer the excitation worse
    response = None if outcome.horizon is None else response_count(outcome.run_dir)
    with run_folder_lock(outcome.run_dir, flag="--members"):
        choice = choose_members(
            outcome.result,
            outcome.run_dir,
            count,
            train=lambda jobs: _train_members(request, jobs),
            eval_horizon=request.eval_horizon,
            figure_format=request.figure_format,
            response=response,
        )
        metrics = read_metrics(outcome.run_dir / METRICS_FILE)
    return dataclasses.replace(outcome, metrics=metrics, members=choice)


def _train_members(request: TrainRequest, jobs: Sequence[MemberJob]) -> list[Model]:
    """Train (or resume) the members ``jobs`` and return their models, in order. Each trains as
    it would alone with ``--threads 1``: side by side in worker processes of one thread when the
    run may use several cores (:func:`canonid.jobs.candidate_pool`), else one after the other
    here; so a member's weights depend on its seed, not on K or ``--threads``. On a GPU they
    train one after the other on it."""
    import sys
    from concurrent.futures import as_completed

    from canonid.jobs import POOL_MIN_STEPS, candidate_pool
    from canonid.learning import Model

    device = jobs[0].recipe.options().device
    # at least two workers when the run has two threads: one member trains in one thread too
    workers = candidate_pool(
        request.threads, steps=POOL_MIN_STEPS, candidates=max(2, len(jobs)), device=device
    )
    with workers as pool:
        if pool is not None:
            if request.progress:
                seeds = ", ".join(str(job.recipe.options().seed) for job in jobs)
                print(f"members: training seeds {seeds} side by side", file=sys.stderr)
            futures = {
                pool.submit(
                    _member_in_worker, job, request.eval_horizon, request.figure_format
                ): job
                for job in jobs
            }
            for finished, future in enumerate(as_completed(futures), start=1):
                future.result()
                if request.progress:
                    job = futures[future]
                    print(
                        f"members: seed {job.recipe.options().seed} trained in {job.folder} "
                        f"({finished}/{len(jobs)})",
                        file=sys.stderr,
                    )
            return [Model.load(job.folder) for job in jobs]
    models = []
    for job in jobs:
        if request.progress:
            seed = job.recipe.options().seed
            print(f"members: training seed {seed} in {job.folder}", file=sys.stderr)
        done = _train_one(request, job.recipe, job.folder, resume=job.resume, callback=None)
        assert done.result is not None
        models.append(done.result.fit.model)
    return models


def _member_in_worker(job: MemberJob, eval_horizon: int | None, figure_format: str) -> None:
    """One member in a worker process (one torch thread): trained and scored into its folder
    (the member's recipe holds the run's decisions: nothing is searched)."""
    from canonid.runfolder import train_run

    train_run(
        job.recipe,
        job.folder,
        resume=job.resume,
        eval_horizon=eval_horizon,
        figure_format=figure_format,
    )


def _search_steps(recipe: RunRecipe, table: Sequence[Candidate]) -> int:
    """The optimiser steps of one candidate of the first rung (whether workers pay off)."""
    from canonid.learning.search import rung_budgets

    opts = recipe.options()
    first = rung_budgets(len(table), opts.epochs, ETA)[0][1]
    return first * -(-opts.windows_per_epoch // opts.batch_size)


def _train_one(
    request: TrainRequest,
    recipe: RunRecipe,
    run_dir: Path,
    *,
    resume: bool,
    callback: Callable[[EpochReport], None] | None,
    table: Sequence[Candidate] | None = None,
) -> TrainOutcome:
    """Train (or resume) ``recipe`` into ``run_dir`` and score it on validation
    (:func:`train_run`): a search over ``table`` (or the one a resumed run recorded, or the
    cubic branch where the recipe leaves it open) with its candidates side by side on a
    :func:`candidate_pool` of one process per core, else one run with a progress bar."""
    import contextlib
    import sys

    from canonid.jobs import candidate_pool, torch_threads
    from canonid.learning.search import candidate_table
    from canonid.runfolder import train_run
    from canonid.runner import EpochBar

    searched = (
        table is not None
        or (resume and (run_dir / SEARCH_FILE).is_file())
        or (recipe.net_options.get("cubic") == AUTO)
    )
    bar = EpochBar(
        f"train {recipe.model}", enabled=request.progress and not searched, dynamic_ncols=True
    )

    def progress(report: EpochReport) -> None:
        val_text = "-" if report.val_loss is None else f"{report.val_loss:.3g}"
        bar.show(
            report.epoch,
            report.epochs,
            f"H={report.horizon} train={report.train_loss:.3g} val={val_text} "
            f"best={report.best_val_loss:.3g}@{report.best_epoch}",
        )
        if callback is not None:
            callback(report)

    def shown(search: Search) -> None:
        if request.progress:
            rung = max(r.rung for r in search.rows)
            print(f"search: rung {rung + 1} of {len(search.budgets)} trained", file=sys.stderr)

    planned = table or candidate_table((recipe.window,), CUBIC_UNITS)
    try:
        with contextlib.ExitStack() as stack:
            pool = None
            if searched and (request.workers or request.scheduler is not None):
                from canonid.runner import cluster_executor

                pool, _ = stack.enter_context(
                    cluster_executor(
                        request.workers or 0,
                        request.scheduler,
                        connect_timeout=5.0,
                        processes=True,
                    )
                )
            elif searched:
                pool = stack.enter_context(
                    candidate_pool(
                        request.threads,
                        steps=_search_steps(recipe, planned),
                        candidates=len(planned),
                        device=recipe.options().device,
                    )
                )
            with torch_threads(request.threads):
                result = train_run(
                    recipe,
                    run_dir,
                    resume=resume,
                    eval_horizon=request.eval_horizon,
                    callback=progress,
                    figure_format=request.figure_format,
                    table=table,
                    executor=pool,
                    record=shown,
                )
    finally:
        bar.close()
    search = Search.read(run_dir) if (run_dir / SEARCH_FILE).is_file() else None
    return TrainOutcome(run_dir, result.evaluation.to_json(), result=result, search=search)
