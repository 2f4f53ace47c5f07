"""What ``canonid evaluate`` asks for, the data that score a run, and the table of its scores.

:func:`score_run` reads the model of a run folder and either the data it was trained on, split
again exactly as training split them (``run.json``), or a file read with the run's loader options
overridden by those given (a CSV or ``.npz`` file's records form the split
:data:`USER_DATA_SPLIT`); it scores the ``test`` split (else ``val``, or the one asked for) with
:func:`canonid.runfolder.evaluate_run` into its own folder ``RUN/evaluations/NAME``
(:func:`evaluation_name`): the data's name and checksum and the options, so that training's
``metrics.json`` and every other evaluation stay. The same evaluation asked again of the same
weights is not redone (its folder is read back); of other weights (a run trained further) it is
refused. Scoring a split named ``test`` first appends a line to the run's ledger of test reads
(:func:`canonid.runfolder.record_test_read`); an evaluation read back scores nothing and adds
none. ``n_init`` defaults to :func:`canonid.learning.evaluate.default_n_init`, the rule of
``canonid.evaluate`` too.
:func:`metrics_table` is the short table that ``train``, ``evaluate`` and ``reduce`` print.

The module imports no torch; scoring loads it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import re
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.data_options import DATA_FLAGS
from canonid.kernel.catalog import EVAL_HORIZON
from canonid.kernel.errors import DataError, OptionError, OutputError

if TYPE_CHECKING:
    from canonid.kernel.dataset import Dataset

__all__ = [
    "USER_DATA_SPLIT",
    "EvaluateRequest",
    "Scored",
    "check_signal_names",
    "evaluation_name",
    "load_with_run_options",
    "metrics_table",
    "run_options",
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


@dataclass(frozen=True)
class Scored:
    """What :func:`score_run` did: the ``metrics.json`` body of the evaluation in ``folder``,
    and whether that folder held it already (``reused``: nothing was written)."""

    folder: Path
    metrics: Mapping[str, Any]
    reused: bool

    def summary(self) -> str:
        """What ``canonid evaluate`` prints: the scores and where they are."""
        from canonid.runfolder import METRICS_FILE

        where = (
            f"already evaluated: {self.folder} (remove it to score again)"
            if self.reused
            else f"metrics written to {self.folder / METRICS_FILE}"
        )
        return f"{metrics_table(self.metrics)}\n{where}"


def score_run(request: EvaluateRequest) -> Scored:
    """Score the model of ``request.run`` into ``RUN/evaluations/NAME`` (see the module
    docstring): its own ``metrics.json`` and ``rollouts.png``."""
    from canonid.datagen.loaders import data_checksum
    from canonid.jobs import run_folder_lock
    from canonid.kernel.io import guarded, make_folder, sha256_file
    from canonid.runfolder import (
        EVALUATIONS_DIR,
        METRICS_FILE,
        TEST_SPLIT,
        check_sealed,
        eval_defaults,
        evaluate_run,
        load_run_model,
        pick_split,
        read_metrics,
        read_recipe,
        record_test_read,
        scoring_source,
    )

    for flag, value in (("--eval-horizon", request.horizon), ("--stride", request.stride)):
        if value is not None and value < 1:
            raise OptionError(f"{flag} must be an integer >= 1, got {value}")
    if request.n_init is not None and request.n_init < 0:
        raise OptionError(f"--n-init must be an integer >= 0, got {request.n_init}")
    model = load_run_model(request.run)
    dataset, data_path, split = scoring_data(
        request.run, request.data, request.data_options, split=request.split, model=model.info
    )
    name, trajs = pick_split(dataset, split, where=data_path)
    horizon = eval_defaults(
        trajs,
        model.window,
        request.horizon or EVAL_HORIZON,
        where=f"{data_path} [{name}]",
        fit=request.horizon is None,
    )
    if request.data is None:  # the file the split came from: a --val FILE run's val is FILE
        data_path = scoring_source(read_recipe(request.run), name)
    checksum = data_checksum(data_path)
    asked: dict[str, Any] = {
        "split": name,
        "horizon": request.horizon,
        "stride": request.stride,
        "n_init": request.n_init,
        **({"figure_format": request.figure_format} if request.figure_format != "png" else {}),
    }
    changed: dict[str, Any] = {}
    if request.data is not None:
        asked["data_options"] = run_options(request.run, request.data, request.data_options)
        own = run_options(request.run, request.data, {})
        changed = {k: v for k, v in asked["data_options"].items() if own.get(k) != v}
    weights = request.run / "weights.pt"
    record = {**asked, "weights_sha256": sha256_file(weights) if weights.is_file() else None}
    tag = {**asked, "data_options": changed}
    folder = request.run / EVALUATIONS_DIR / evaluation_name(data_path, checksum, tag)
    with run_folder_lock(request.run, flag="RUN"):  # no other writer of the run meanwhile
        done = folder / METRICS_FILE
        if done.is_file():
            metrics = read_metrics(done)
            stored = metrics.get("evaluation")
            if stored == record:
                check_sealed(metrics, where=done)  # a hand edit of a score is named as such
                return Scored(folder, metrics, reused=True)
            if (
                isinstance(stored, Mapping)
                and stored.get("weights_sha256") != record["weights_sha256"]
            ):
                raise OutputError(
                    f"{folder} holds this evaluation of other weights (the run was trained "
                    "further since); remove that folder to score the run's weights now"
                )
            raise OutputError(
                f"{done}: field 'evaluation' does not record this evaluation (edited by hand?); "
                "remove that folder to score again"
            )
        if name == TEST_SPLIT:  # the test split is read: the ledger says so, first
            record_test_read(
                request.run, command="evaluate", split=name, data=data_path, sha256=checksum
            )
        made = [p for p in (folder, folder.parent) if not guarded(p).exists()]
        had = set() if made else {entry.name for entry in folder.iterdir()}
        make_folder(folder)
        try:
            result = evaluate_run(
                folder,
                model,
                dataset,
                data_path=data_path,
                split=name,
                horizon=horizon,
                stride=request.stride,
                n_init=request.n_init,
                figure_format=request.figure_format,
                data_sha256=checksum,
                request=record,
            )
        except BaseException:
            if not done.is_file():  # nothing half-written, and only what this command made
                _remove_new(folder, had, made)
            raise
    return Scored(folder, result.to_json(), reused=False)


def _remove_new(folder: Path, had: set[str], made: list[Path]) -> None:
    """Undo a failed evaluation: the folders in ``made`` (this command made them) go whole, else
    only the entries of ``folder`` not among ``had`` (what was there before stays)."""
    if made:
        shutil.rmtree(folder, ignore_errors=True)
        for parent in made[1:]:
            with contextlib.suppress(OSError):
                parent.rmdir()  # the evaluations folder, if this was its first
        return
    with contextlib.suppress(OSError):
        for entry in folder.iterdir():
            if entry.name in had:
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def evaluation_name(data_path: str | Path, sha256: str, asked: Mapping[str, Any]) -> str:
    """``STEM-SHA8-SPLIT[-OPTIONS]``: the folder of one evaluation, named by the data scored
    (its file or folder name without suffix, the first 8 hex digits of its checksum), the split
    and the options given (``h20``, ``stride5``, ``ninit10``, a figure format other than
    ``png``; ``csv`` and 8 hex digits of the loader options, when they are not the run's own)."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(data_path).stem)[:40].strip("._") or "data"
    parts = [stem, sha256[:8], re.sub(r"[^A-Za-z0-9._-]+", "_", str(asked["split"]))]
    for key, label in (("horizon", "h"), ("stride", "stride"), ("n_init", "ninit")):
        value = asked.get(key)
        if value is not None and not (key == "stride" and value == 1):
            parts.append(f"{label}{value}")
    if asked.get("figure_format"):
        parts.append(str(asked["figure_format"]))
    if asked.get("data_options"):
        text = json.dumps(asked["data_options"], sort_keys=True)
        parts.append("csv" + hashlib.sha256(text.encode()).hexdigest()[:8])
    return "-".join(parts)


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
    those ``given`` (:func:`load_with_run_options`), checked against the ``model``'s ``info``.
    """
    from canonid.runfolder import RUN_FILE, check_compatible, recipe_of, run_data

    if data is None:
        recipe = recipe_of(run_dir)
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
    dataset = user_data_as_test(load_with_run_options(run_dir, data, given))
    check_compatible(dataset, model, where=str(data))
    explicit = any(given.get(k) is not None for k in ("inputs", "outputs"))
    check_signal_names(dataset, model, where=str(data), explicit=explicit)
    return dataset, str(data), split


def run_options(run_dir: Path, data: str | Path, given: Mapping[str, Any]) -> dict[str, Any]:
    """The loader options that read ``data`` for the run in ``run_dir``: those it recorded
    (``run.json``), each overridden by one ``given`` (not ``None``); none for a canonid dataset."""
    from canonid.datagen.loaders import is_dataset
    from canonid.runfolder import recipe_of

    if is_dataset(data):
        return dict(given)
    recipe = recipe_of(run_dir)
    recorded = recipe.data_options if recipe is not None else {}
    return {k: recorded.get(k) if given.get(k) is None else given[k] for k in DATA_FLAGS}


def load_with_run_options(run_dir: Path, data: str | Path, given: Mapping[str, Any]) -> Dataset:
    """``data`` read with :func:`run_options`; a problem reading it names the options that came
    from the run, and how to override them."""
    from canonid.runfolder import load

    options = run_options(run_dir, data, given)
    try:
        return load(data, options)
    except DataError as exc:
        inherited = [
            f"{DATA_FLAGS[k]} {_shown(v)}"
            for k, v in options.items()
            if given.get(k) is None and v not in (None, "")
        ]
        if not inherited:
            raise
        raise DataError(
            f"{exc} (read with the run's options {', '.join(inherited)}: give another to "
            "override one, e.g. --experiment-column none)"
        ) from None


def _shown(value: Any) -> str:
    """An option's value as typed on the command line."""
    return ",".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


#: what a command that chooses columns (evaluate) says to do about other signal names
CHOOSE_COLUMNS = (
    "If these are the same signals under other names, choose the columns with "
    "--inputs/--outputs (CSV and .npz data)"
)


def check_signal_names(
    dataset: Dataset,
    info: Mapping[str, Any],
    *,
    where: str,
    explicit: bool,
    remedy: str = CHOOSE_COLUMNS,
) -> None:
    """Refuse data whose signal names differ from those the run was trained on (``info``'s
    ``input_names`` / ``output_names``, where recorded): ``u``/``y`` scoring a model of
    ``pump``/``level`` is data of another system far more often than the same signals renamed.
    Columns chosen ``explicit``-ly with ``--inputs``/``--outputs`` are the user's statement
    that they are the run's signals, and are accepted; so are data without names (arrays of an
    ``.npz``, which the loader calls ``u1``, ``y1``, …). ``remedy``: what the command lets the
    user do about it (a command without ``--inputs`` names what it does accept)."""
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
            + f". {remedy}"
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
    from canonid.learning.evaluate import score_rows  # numpy and torch, when scores are shown

    lines = score_rows(metrics)
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
    return "\n".join([head, *lines, *diverged, *_worst_records(metrics), *_outside(metrics)])


def _outside(metrics: Mapping[str, Any]) -> list[str]:
    """One line naming the signals of the data scored that go beyond the model's training span
    by more than :data:`canonid.coverage.NOTED_BEYOND` of it."""
    from canonid.coverage import OutsideRange

    found = [OutsideRange.from_json(o) for o in metrics.get("outside_training_range") or []]
    said = "; ".join(o.describe() for o in found if o.noted)
    return [f"outside the training range (the model extrapolates there): {said}"] if said else []


def _worst_records(metrics: Mapping[str, Any], count: int = 3) -> list[str]:
    """One line naming the records with the largest rollout MSE (noise-free target if any)."""
    label, scores = ("y_clean", metrics["clean"]) if metrics.get("clean") else ("y", metrics)
    per = scores.get("rollout_mse_per_record") or []
    scored = sorted(((value, i) for i, value in enumerate(per) if value is not None), reverse=True)
    if len(scored) < 2:
        return []
    worst = ", ".join(f"#{i} {value:.3g}" for value, i in scored[:count])
    return [f"largest rollout_mse per record ({label}; of {len(scored)}): {worst}"]
