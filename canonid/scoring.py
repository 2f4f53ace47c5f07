"""What ``canonid evaluate`` asks for, the data that score a run, and the table of its scores.

:func:`score_run` reads the model of a run folder and either the data it was trained on, split
again exactly as training split them (``run.json``), or a file read with the run's loader options
(a CSV or ``.npz`` file's records form the split :data:`USER_DATA_SPLIT`); it scores the ``test``
split (else ``val``, or the one asked for) with :func:`canonid.runfolder.evaluate_run`, which
writes ``metrics.json`` and ``rollouts.png``. ``n_init`` defaults to
:func:`canonid.learning.evaluate.default_n_init`, the rule of ``canonid.evaluate`` too.
:func:`metrics_table` is the short table that ``train``, ``evaluate`` and ``reduce`` print.

The module imports no torch; scoring loads it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.errors import DataError, OptionError

if TYPE_CHECKING:
    from canonid.kernel.dataset import Dataset
    from canonid.runfolder import RunEvaluation

__all__ = [
    "USER_DATA_SPLIT",
    "EvaluateRequest",
    "check_signal_names",
    "metrics_table",
    "score_run",
    "scoring_data",
    "user_data_as_test",
]

#: the split name under which a CSV or .npz data file's records are scored
USER_DATA_SPLIT = "all"


@dataclass(frozen=True, kw_only=True)
class EvaluateRequest:
    """A run to score; ``None``: the default (see the module docstring).

    Attributes:
        run: the run folder. data, data_options: a data file and loader options overriding the
            run's. split: the split scored. horizon, stride, n_init: the rollouts and the
            simulation scores' initialisation. figure_format: the rollouts figure's format.
    """

    run: Path
    data: Path | None = None
    data_options: Mapping[str, Any] = field(default_factory=dict)
    split: str | None = None
    horizon: int | None = None
    stride: int = 1
    n_init: int | None = None
    figure_format: str = "png"


def score_run(request: EvaluateRequest) -> RunEvaluation:
    """Score the model of ``request.run``; write its ``metrics.json`` and ``rollouts.png``."""
    from canonid.jobs import run_folder_lock
    from canonid.learning import Model
    from canonid.runfolder import eval_defaults, evaluate_run, pick_split

    for flag, value in (("--horizon", request.horizon), ("--stride", request.stride)):
        if value is not None and value < 1:
            raise OptionError(f"{flag} must be an integer >= 1, got {value}")
    if request.n_init is not None and request.n_init < 0:
        raise OptionError(f"--n-init must be an integer >= 0, got {request.n_init}")
    model = Model.load(request.run)
    dataset, data_path, split = scoring_data(
        request.run, request.data, request.data_options, split=request.split, model=model.info
    )
    name, trajs = pick_split(dataset, split, where=data_path)
    horizon = eval_defaults(
        trajs,
        model.window,
        request.horizon or 100,
        where=f"{data_path} [{name}]",
        fit=request.horizon is None,
    )
    with run_folder_lock(request.run, flag="RUN"):  # no other writer of the run meanwhile
        return evaluate_run(
            request.run,
            model,
            dataset,
            data_path=data_path,
            split=name,
            horizon=horizon,
            stride=request.stride,
            n_init=request.n_init,
            figure_format=request.figure_format,
        )


def scoring_data(
    run_dir: Path,
    data: str | Path | None,
    given: Mapping[str, Any],
    *,
    split: str | None,
    model: Mapping[str, Any],
) -> tuple[Dataset, str, str | None]:
    """The data that score the run in ``run_dir``: ``(dataset, data path, split or None for the
    default)``.

    Without ``data``, the run's own data split as training split them (default: ``test``, else
    ``val``). With ``data``, that file read with the run's recorded loader options overridden by
    those ``given`` (a canonid dataset takes none), checked against the ``model``'s ``info``.
    """
    from canonid.datagen.loaders import is_dataset
    from canonid.runfolder import DATA_FLAGS, RUN_FILE, check_compatible, load, recipe_of, run_data

    recipe = recipe_of(run_dir)
    if data is None:
        if recipe is None:
            raise DataError(
                f"{run_dir / RUN_FILE} not found: the run names no data; give --data FILE"
            )
        if any(value is not None for value in given.values()):
            raise OptionError(
                f"{', '.join(DATA_FLAGS[k] for k, v in given.items() if v is not None)} apply "
                "to --data FILE; the run's own data are read with the options it recorded"
            )
        dataset, default_split = run_data(recipe)
        return dataset, recipe.data, split or default_split
    options = dict(given)
    if not is_dataset(data):
        recorded = recipe.data_options if recipe is not None else {}
        options = {k: recorded.get(k) if given.get(k) is None else given[k] for k in DATA_FLAGS}
    dataset = user_data_as_test(load(data, options))
    check_compatible(dataset, model, where=str(data))
    explicit = any(given.get(k) is not None for k in ("inputs", "outputs"))
    check_signal_names(dataset, model, where=str(data), explicit=explicit)
    return dataset, str(data), split


def check_signal_names(
    dataset: Dataset, info: Mapping[str, Any], *, where: str, explicit: bool
) -> None:
    """Refuse data whose signal names differ from those the run was trained on (``info``'s
    ``input_names`` / ``output_names``, where recorded): ``u``/``y`` scoring a model of
    ``pump``/``level`` is data of another system far more often than the same signals renamed.
    Columns chosen ``explicit``-ly with ``--inputs``/``--outputs`` are the user's statement
    that they are the run's signals, and are accepted; so are data without names (arrays of an
    ``.npz``, which the loader calls ``u1``, ``y1``, …)."""
    if explicit:
        return
    theirs = {"inputs": list(dataset.input_names), "outputs": list(dataset.output_names)}
    ours: dict[str, Any] = {"inputs": info.get("input_names"), "outputs": info.get("output_names")}
    generated = {"inputs": "u", "outputs": "y"}  # the loader's names for unnamed arrays
    unnamed = {
        k: theirs[k] == [f"{generated[k]}{i + 1}" for i in range(len(theirs[k]))] for k in theirs
    }
    differ = [
        k for k in theirs if ours[k] is not None and not unnamed[k] and list(ours[k]) != theirs[k]
    ]
    if differ:
        raise DataError(
            f"{where}: signals "
            + ", ".join(f"{k} {theirs[k]}" for k in differ)
            + "; the run was trained on "
            + ", ".join(f"{k} {ours[k]}" for k in differ)
            + ". If these are the same signals under other names, choose the columns with "
            "--inputs/--outputs (CSV and .npz data)"
        )


def user_data_as_test(dataset: Dataset) -> Dataset:
    """A CSV or .npz file read for scoring: its records are test data, not a ``train`` split,
    so they are named :data:`USER_DATA_SPLIT` (a canonid dataset keeps its splits)."""
    if dataset.metadata.get("source") not in ("csv", "npz") or set(dataset.splits) != {"train"}:
        return dataset
    return dataclasses.replace(dataset, splits={USER_DATA_SPLIT: dataset.split("train")})


def metrics_table(metrics: Mapping[str, Any]) -> str:
    """A short text table of the main scores (measured and, if any, noise-free targets) of a
    ``metrics.json`` body (:meth:`canonid.runfolder.RunEvaluation.to_json`); with several
    outputs, each target's row (scores over all outputs) is followed by one row per output."""
    rows = [("target", "rollout_mse", "rmse", "nrmse", "fit %")]
    names = metrics.get("output_names") or []
    for label, scores in (("y (measured)", metrics), ("y_clean", metrics.get("clean"))):
        if scores:
            rows.append((label, *_scores(scores, "")))
            if len(names) > 1:  # a MIMO run: each output's own scores
                rows.extend(
                    (f"  {name}", *_scores(scores, "_per_output", i))
                    for i, name in enumerate(names)
                )
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    head = (
        f"{metrics['model']} (ℓ = {metrics['window']}) on {metrics['data']['path']} "
        f"[{metrics['data']['split']}]: {metrics['n_rollouts']} rollouts of "
        f"{metrics['rollout_horizon']} steps; simulation scores after n_init = {metrics['n_init']}"
    )
    diverged = (
        []
        if metrics.get("finite", True)
        else [
            "warning: the model's open-loop predictions blew up (inf or NaN) on this data: the "
            "scores marked 'not finite' are written null in metrics.json; train longer or try "
            "--linear off / --linear arx"
        ]
    )
    return "\n".join([head, *lines, *diverged, *_worst_records(metrics)])


def _scores(scores: Mapping[str, Any], suffix: str, index: int | None = None) -> tuple[str, ...]:
    """The table's four scores of ``scores`` (``suffix`` ``"_per_output"``: output ``index``)."""
    keys = (("rollout_mse", ".4g"), ("rmse", ".4g"), ("nrmse", ".4g"), ("fit_percent", ".2f"))
    values = [scores[key + suffix] for key, _ in keys]
    if index is not None:
        values = [None if v is None else v[index] for v in values]
    return tuple(_number(v, spec) for v, (_, spec) in zip(values, keys))


def _number(value: float | None, spec: str) -> str:
    """``value`` formatted, or ``not finite`` for a score written ``null``."""
    return "not finite" if value is None else format(value, spec)


def _worst_records(metrics: Mapping[str, Any], count: int = 3) -> list[str]:
    """One line naming the records with the largest rollout MSE (noise-free target if any)."""
    label, scores = ("y_clean", metrics["clean"]) if metrics.get("clean") else ("y", metrics)
    per = scores.get("rollout_mse_per_record") or []
    scored = sorted(((value, i) for i, value in enumerate(per) if value is not None), reverse=True)
    if len(scored) < 2:
        return []
    worst = ", ".join(f"#{i} {value:.3g}" for value, i in scored[:count])
    return [f"largest rollout_mse per record ({label}; of {len(scored)}): {worst}"]
