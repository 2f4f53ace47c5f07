"""A run folder: its recipe, its file names, the data its recipe names, its training, history
and evaluation.

``canonid train``, ``canonid reduce``, ``canonid evaluate``, the reductions of the compression
study and the Table-1 jobs of ``canonid reproduce`` all write the same folder:

* ``run.json`` (:data:`RUN_FILE`) — the recipe (:class:`RunRecipe` for a training run,
  :class:`ReductionRecipe` for a reduction; :func:`read_recipe` reads either): ``data``,
  ``data_options``, ``val``, ``val_fraction``, the model and its options; ``data`` and ``val``
  by absolute path and SHA-256 (:func:`canonid.datagen.loaders.data_checksum`), so that data
  read back for the run (:func:`run_data`) are the data it was trained on, or refused;
* the model (``config.json``, ``weights.pt``, ``normalisation.json``) and ``checkpoint.pt``;
* ``history.csv`` and ``training_curve.png`` (:func:`write_history`);
* ``metrics.json`` (:data:`METRICS_FILE`) and ``rollouts.png`` (:func:`evaluate_run`): the
  scores training wrote, which nothing else rewrites;
* ``evaluations/NAME/`` (:data:`EVALUATIONS_DIR`): one folder per ``canonid evaluate`` (its own
  ``metrics.json`` and ``rollouts.png``), named by the data it scored and its options
  (:func:`canonid.scoring.evaluation_name`);
* ``test-ledger.jsonl`` (:data:`TEST_LEDGER_FILE`): one JSON line per read of a split named
  ``test`` by ``canonid evaluate`` or ``canonid benchmark`` (:func:`record_test_read`): when,
  which command, the split, the data file and its checksum, so that "the test split was read
  once, after the model was chosen" can be checked from the folder.

Figures are PNG unless another of :data:`canonid.kernel.io.FIGURE_FORMATS` is asked for
(``training_curve.pdf``, ``rollouts.svg``, …; :func:`figure_file`); ``metrics.json`` names its
figure.

:func:`train_run` trains the model of a :class:`RunRecipe` into a folder and scores it: the one
function behind ``canonid train``, the Table-1 jobs and the candidates of ``--window auto``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import logging
import math
import os
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, NoReturn, TypeAlias, TypeVar

import numpy as np

from canonid.coverage import INFO_KEY as COVERAGE_KEY
from canonid.coverage import (
    VALIDATION_KEY,
    OutsideRange,
    outside_training_range,
    training_ranges,
    unvalidated,
)
from canonid.data_options import DATA_FLAGS
from canonid.datagen.loaders import data_checksum, is_dataset, load_data, split_train_val
from canonid.jobs import run_folder_lock
from canonid.kernel.catalog import DEFAULT_VAL_FRACTION, EVAL_HORIZON
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import CheckpointError, DataError, OptionError, OutputError
from canonid.kernel.io import (
    append_line,
    atomic_write_json,
    atomic_write_text,
    check_appendable,
    confined,
    figure_name,
    guarded,
    is_json_number,
    read_json,
    sha256_bytes,
)
from canonid.learning import EpochReport, Evaluation, FitResult, Model, TrainOptions, fit
from canonid.learning.evaluate import default_n_init, evaluate
from canonid.learning.model import CONFIG_FILE
from canonid.learning.plots import plot_rollouts, plot_training_curve
from canonid.learning.search import (
    SEARCH_DIR,
    SEARCH_FILE,
    Candidate,
    Search,
    adopt,
    candidate_table,
    cubic_axis,
    fitting_windows,
)
from canonid.learning.search import search as run_search
from canonid.learning.training import CHECKPOINT_FILE
from canonid.models.registry import signal_units

__all__ = [
    "EVALUATIONS_DIR",
    "FIGURES",
    "HISTORY_FILE",
    "METRICS_FILE",
    "RECIPE_VERSION",
    "RUN_FILE",
    "TEST_LEDGER_FILE",
    "TEST_SPLIT",
    "Recipe",
    "ReductionRecipe",
    "RunEvaluation",
    "RunRecipe",
    "RunResult",
    "RunSource",
    "check_compatible",
    "check_metrics",
    "check_recorded",
    "check_test_ledger",
    "data_info",
    "eval_defaults",
    "evaluate_run",
    "figure_file",
    "finish_run",
    "load",
    "load_splits",
    "pick_split",
    "read_metrics",
    "read_recipe",
    "recipe_of",
    "record_test_read",
    "rescore_run",
    "run_data",
    "score_horizon",
    "scoring_source",
    "train_run",
    "write_history",
]

log = logging.getLogger(__name__)

RUN_FILE = "run.json"
METRICS_FILE = "metrics.json"
#: the folder of a run's evaluations, one subfolder each (``canonid evaluate``)
EVALUATIONS_DIR = "evaluations"
HISTORY_FILE = "history.csv"
#: the ledger of the run's test reads, one JSON line each (:func:`record_test_read`)
TEST_LEDGER_FILE = "test-ledger.jsonl"
#: the split whose every read is recorded in the ledger
TEST_SPLIT = "test"
LEDGER_WHAT = "ledger of test reads"
RECIPE_FORMAT = "canonid-run"
#: the version of :class:`RunRecipe`'s JSON (a recipe without one is of version 1)
RECIPE_VERSION = 1
_S = TypeVar("_S", bound="RunSource")


@dataclass(frozen=True, kw_only=True)
class RunSource:
    """What every run recipe holds: the data, how training split them, and who asked.

    Attributes:
        data: the training data (a canonid dataset, a CSV file or folder, an ``.npz``).
        data_options: loader options (:data:`canonid.data_options.DATA_FLAGS`), ``None`` where
            not given.
        val: a validation file, else ``None`` (DATA's own ``val`` split, else ``val_fraction``).
        val_fraction: share of DATA's ``train`` split held out when it has no ``val`` split.
        profile: the profile the options came from.
        command: the command line that asked for the run (a record, not part of what is run).
        data_sha256, val_sha256: the checksums of ``data`` and ``val`` (``None``: a recipe of
            an older canonid, or one not yet written: :meth:`pinned`).
        recorded_in: the ``run.json`` the recipe was read from (not part of it; messages).
    """

    data: str
    data_options: Mapping[str, Any] = field(default_factory=dict)
    val: str | None = None
    val_fraction: float = DEFAULT_VAL_FRACTION
    profile: str = "quick"
    command: Sequence[str] = ()
    data_sha256: str | None = None
    val_sha256: str | None = None
    recorded_in: str | None = field(default=None, compare=False, metadata={"json": False})

    def source(self) -> dict[str, Any]:
        """The data fields (JSON-ready): what a run derived from this one trains on."""
        return {
            "data": self.data,
            "data_sha256": self.data_sha256,
            "data_options": dict(self.data_options),
            "val": self.val,
            "val_sha256": self.val_sha256,
            "val_fraction": self.val_fraction,
        }

    def pinned(self: _S) -> _S:
        """This recipe with ``data`` and ``val`` as absolute paths and their checksums, as a new
        run records them (a recipe that has its checksums is returned as it is)."""
        if self.data_sha256 is not None:
            return self
        val = None if self.val is None else os.path.abspath(self.val)
        return dataclasses.replace(
            self,
            data=os.path.abspath(self.data),
            data_sha256=data_checksum(self.data),
            val=val,
            val_sha256=None if val is None else data_checksum(val),
        )

    def located(self: _S, run_dir: Path) -> _S:
        """This recipe as read from ``run_dir/run.json``: a relative ``data`` or ``val`` (a
        recipe of an older canonid) resolved against the folder the run was trained from
        (:func:`_origin`), else against the current folder as those versions did."""
        origin = _origin(run_dir, self.command)

        def place(path: str) -> str:
            return str(Path(origin, path)) if origin and not Path(path).is_absolute() else path

        return dataclasses.replace(
            self,
            data=place(self.data),
            val=None if self.val is None else place(self.val),
            recorded_in=str(run_dir / RUN_FILE),
        )


@dataclass(frozen=True)
class RunRecipe(RunSource):
    """What a training run trains, on which data, with which options: ``run.json``.

    Attributes (and those of :class:`RunSource`):
        model, window: the model's registry name and its window ℓ.
        train_options: :class:`canonid.learning.TrainOptions` as a mapping (resolved, profile
        applied). net_options: the network's constructor options.
        given_options: the names of the training options the request set (the others are the
            profile's; empty in a recipe of an older canonid), so that a resumed run knows what
            its user chose even where it equals the profile's value.
        members: the ``--members`` the command gave (``None``: not given, the default decides),
            so that a run interrupted before its members started keeps the count on ``--resume``.
    """

    model: str
    window: int
    train_options: Mapping[str, Any]
    net_options: Mapping[str, Any] = field(default_factory=dict)
    given_options: Sequence[str] = ()
    members: int | None = None
    kind: ClassVar[str] = "train"

    def __post_init__(self) -> None:
        object.__setattr__(self, "given_options", tuple(sorted(set(self.given_options))))

    def options(self) -> TrainOptions:
        return TrainOptions.from_dict(self.train_options)

    def to_dict(self) -> dict[str, Any]:
        """The JSON body of ``run.json``."""
        return {
            "format": RECIPE_FORMAT,
            "version": RECIPE_VERSION,
            **self.source(),
            "model": self.model,
            "window": self.window,
            "net_options": dict(self.net_options),
            "profile": self.profile,
            "train_options": dict(self.train_options),
            "given_options": list(self.given_options),
            # only where given: the recipes of runs without it stay as they were
            **({} if self.members is None else {"members": self.members}),
            "command": list(self.command),
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> RunRecipe:
        """Read a ``run.json`` body; a key this version does not know is refused by name."""
        body = _recipe_body(cls, data, where=where)
        body["given_options"] = body.get("given_options") or ()
        return cls(**body)

    @classmethod
    def read(cls, run_dir: Path) -> RunRecipe:
        """The recipe in ``run_dir/run.json`` (its data located: :meth:`located`)."""
        path = run_dir / RUN_FILE
        recipe = cls.from_dict(read_json(path, what="run recipe"), where=str(path))
        return recipe.located(run_dir)

    def write(self, run_dir: Path) -> None:
        atomic_write_json(run_dir / RUN_FILE, self.to_dict())


@dataclass(frozen=True)
class ReductionRecipe(RunSource):
    """What a reduction run reduces, on which data, with which options: the ``run.json`` of
    ``canonid reduce`` (:func:`canonid.reduction.reduce_run`).

    Attributes (and those of :class:`RunSource`: the source run's data, split as it split them):
        regressor, window: the reduced model's registry name and its window ℓ.
        latent_dim: the reduced state's dimension n̄.
        source_run, compression, seed: the reduction asked for (the source run's absolute path).
        train_options, reduction_options: the resolved options (profile and overrides applied).
    """

    regressor: str
    window: int
    latent_dim: int
    source_run: str
    compression: float
    seed: int
    train_options: Mapping[str, Any]
    reduction_options: Mapping[str, Any]
    kind: ClassVar[str] = "reduction"
    #: the model's registry name, the same for every reduction
    model: ClassVar[str] = "reduced"

    def to_dict(self) -> dict[str, Any]:
        """The JSON body of ``run.json``."""
        return {
            "format": RECIPE_FORMAT,
            "version": RECIPE_VERSION,
            "kind": self.kind,
            **self.source(),
            "model": self.model,
            "regressor": self.regressor,
            "window": self.window,
            "latent_dim": self.latent_dim,
            "source_run": self.source_run,
            "compression": self.compression,
            "seed": self.seed,
            "profile": self.profile,
            "train_options": dict(self.train_options),
            "reduction_options": dict(self.reduction_options),
            "command": list(self.command),
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> ReductionRecipe:
        """Read a ``run.json`` body; a key this version does not know is refused by name."""
        body = _recipe_body(cls, data, where=where)
        if data.get("model", cls.model) != cls.model:
            raise CheckpointError(
                f"{where}: model {data['model']!r}; a reduction's is {cls.model!r}"
            )
        return cls(**body)

    def write(self, run_dir: Path) -> None:
        atomic_write_json(run_dir / RUN_FILE, self.to_dict())


#: the recipe of a run folder (:func:`read_recipe`)
Recipe: TypeAlias = RunRecipe | ReductionRecipe
#: the recipe class of each kind of run (a ``run.json`` without ``kind`` is a training run's)
_KINDS: dict[str, type[Recipe]] = {cls.kind: cls for cls in (RunRecipe, ReductionRecipe)}


def _recipe_body(cls: type[Recipe], data: Any, *, where: str) -> dict[str, Any]:
    """The constructor arguments of ``cls`` from a ``run.json`` body: its format, version and
    kind checked, unknown keys and missing required ones refused by name."""
    if not isinstance(data, Mapping) or data.get("format") != RECIPE_FORMAT:
        raise CheckpointError(f"{where} is not a canonid run recipe")
    version = data.get("version", 1)
    if version != RECIPE_VERSION:
        raise CheckpointError(
            f"{where}: run recipe version {version!r}; this canonid reads version {RECIPE_VERSION}"
        )
    kind = data.get("kind", "train")
    if kind != cls.kind:
        raise CheckpointError(
            f"{where} is the recipe of a {kind} run, not of a {cls.kind} run"
            if kind in _KINDS
            else f"{where}: unknown run kind {kind!r}; expected one of {sorted(_KINDS)}"
        )
    fields = [f for f in dataclasses.fields(cls) if f.metadata.get("json", True)]
    known = {f.name for f in fields}
    header = {"format", "version", "kind", "model"} - known  # model: a class constant
    unknown = sorted(set(data) - known - header)
    if unknown:
        raise CheckpointError(f"{where}: unknown run recipe key(s) {unknown}")
    required = [
        f.name
        for f in fields
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    missing = sorted(k for k in required if k not in data)
    if missing:
        raise CheckpointError(f"{where}: the run recipe lacks {missing}")
    body = {k: v for k, v in data.items() if k in known}
    _check_types(body, where=where)
    body["data_options"] = dict(body.get("data_options") or {})
    body["command"] = tuple(body.get("command") or ())
    return body


def _is_text(value: Any) -> bool:
    return isinstance(value, str)


def _is_count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


#: what each field of a ``run.json`` body must hold (a field absent here is not read as a value)
_FIELD_TYPES: dict[str, tuple[Callable[[Any], bool], str]] = {
    "data": (_is_text, "a path (a string)"),
    "data_options": (lambda v: v is None or isinstance(v, Mapping), "an object"),
    "val": (lambda v: v is None or _is_text(v), "a path (a string) or null"),
    "val_fraction": (lambda v: _is_real(v) and 0 < v < 1, "a number between 0 and 1"),
    "profile": (_is_text, "a profile name (a string)"),
    "command": (
        lambda v: v is None or (isinstance(v, list) and all(map(_is_text, v))),
        "a list of strings",
    ),
    "window": (_is_count, "an integer >= 1"),
    "latent_dim": (_is_count, "an integer >= 1"),
    "seed": (lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer"),
    "compression": (_is_real, "a number"),
    "regressor": (_is_text, "a model name (a string)"),
    "source_run": (_is_text, "a path (a string)"),
    "model": (_is_text, "a model name (a string)"),
    "train_options": (lambda v: isinstance(v, Mapping), "an object"),
    "given_options": (
        lambda v: v is None or (isinstance(v, list) and all(map(_is_text, v))),
        "a list of option names",
    ),
    "net_options": (lambda v: isinstance(v, Mapping), "an object"),
    "members": (_is_count, "an integer >= 1"),
    "reduction_options": (lambda v: isinstance(v, Mapping), "an object"),
}


def _is_names(value: Any) -> bool:
    return _is_text(value) or (isinstance(value, list) and all(map(_is_text, value)))


#: what each loader option in ``data_options`` must hold when not null
_OPTION_TYPES: dict[str, tuple[Callable[[Any], bool], str]] = {
    "inputs": (_is_names, "a list of column names"),
    "outputs": (_is_names, "a list of column names"),
    "experiment_column": (_is_text, "a column name"),
    "time_column": (_is_text, "a column name"),
    "dt": (lambda v: _is_real(v) and v > 0, "a positive number of seconds"),
}


def _check_types(body: Mapping[str, Any], *, where: str) -> None:
    """Refuse a ``run.json`` field of the wrong type, by name (``"data": {"x": 1}`` would
    otherwise reach the loader as a path)."""
    for key, value in body.items():
        check, expected = _FIELD_TYPES.get(key, (lambda v: True, ""))
        if not check(value):
            raise CheckpointError(f"{where}: field {key!r} must be {expected}, got {value!r}")
    for key, value in (body.get("data_options") or {}).items():
        check, expected = _OPTION_TYPES.get(key, (lambda v: False, f"one of {sorted(DATA_FLAGS)}"))
        if value is not None and not check(value):
            field = f"data_options.{key}" if key in DATA_FLAGS else "data_options"
            got = value if key in DATA_FLAGS else key
            raise CheckpointError(f"{where}: field {field!r} must be {expected}, got {got!r}")


def read_recipe(run_dir: Path) -> Recipe:
    """The recipe of any run folder (a training or a reduction run): ``run_dir/run.json``,
    refused in one line naming the file when missing, corrupt or of another version."""
    path = run_dir / RUN_FILE
    if not run_dir.is_dir():
        raise DataError(f"run folder not found: {run_dir}")
    if not path.exists() and not (run_dir / CONFIG_FILE).exists():
        raise DataError(
            f"{run_dir} holds no run: no {RUN_FILE} (give a run folder that canonid train "
            "wrote, its --out)"
        )
    data = read_json(path, what="run recipe")
    kind = data.get("kind", "train") if isinstance(data, Mapping) else "train"
    recipe = _KINDS.get(kind, RunRecipe).from_dict(data, where=str(path))
    return recipe.located(run_dir)


def _origin(run_dir: Path, command: Sequence[str]) -> Path | None:
    """The folder a run was trained from, found from its recorded command line: ``run_dir``
    less the relative ``--out`` that led to it (or less ``runs/NAME``, the default folder of
    ``train`` and ``benchmark``); ``None`` when the command does not tell."""
    out: str | None = None
    args = [str(a) for a in command]
    for i, arg in enumerate(args):
        if arg == "--out" and i + 1 < len(args):
            out = args[i + 1]
        elif arg.startswith("--out="):
            out = arg.removeprefix("--out=")
    here = Path(os.path.abspath(run_dir))
    if out is None:
        return here.parent.parent if here.parent.name == "runs" else None
    tail = Path(os.path.normpath(out)).parts
    if Path(out).is_absolute() or ".." in tail or here.parts[-len(tail) :] != tail:
        return None
    return Path(*here.parts[: -len(tail)])


def load_run_model(run_dir: Path) -> Model:
    """The model of the run folder ``run_dir`` (:meth:`Model.load`), checked against the
    folder's ``run.json`` where it has one: a training run's ``model`` and ``window`` must be
    those of ``config.json``, else one :class:`CheckpointError` names both files. A folder
    without a model yet, whose lock another process holds, is named as being written by it."""
    from canonid.jobs import writer_of

    with confined(run_dir):  # run.json and the model's files: no link below the run followed
        return _load_run_model(run_dir, writer_of)


def _load_run_model(run_dir: Path, writer_of: Callable[[Path], str | None]) -> Model:
    if not (run_dir / CONFIG_FILE).exists() and (writer := writer_of(run_dir)) is not None:
        raise OutputError(
            f"{run_dir} is being written by another canonid process ({writer}) and holds no "
            "model yet; wait for it to save one (its first epoch), then try again"
        )
    model = Model.load(run_dir)
    recipe = recipe_of(run_dir)
    if isinstance(recipe, RunRecipe):
        for key, recorded, saved in (
            ("model", recipe.model, model.name),
            ("window", recipe.window, model.window),
        ):
            if recorded != saved:
                raise CheckpointError(
                    f"{run_dir / RUN_FILE}: field '{key}' is {recorded!r}, but "
                    f"{run_dir / CONFIG_FILE} holds a model with {key} {saved!r}; the two files "
                    "disagree (edited by hand, or copied from another run)"
                )
    return model


def recipe_of(run_dir: Path) -> Recipe | None:
    """:func:`read_recipe`, or ``None`` when the folder has no ``run.json`` (a model saved
    without a run)."""
    return read_recipe(run_dir) if (run_dir / RUN_FILE).is_file() else None


@dataclass(frozen=True)
class RunEvaluation:
    """The scores of a run's model on one split (:func:`evaluate_run`), as in ``metrics.json``.

    Attributes:
        scores: the scores against the measured and, if any, the noise-free outputs.
        data_path, split, n_trajectories: the data scored.
        figure: the file name of the rollouts figure written beside ``metrics.json``.
        data_sha256: the checksum of the data scored (:func:`data_checksum`), if recorded.
        request: what asked for the scores (``canonid evaluate``'s options and the checksum of
            the weights scored), written as ``evaluation``; ``None`` for training's own score.
        outside: the signals of the data scored that leave the model's training span
            (:func:`canonid.coverage.outside_training_range`; ``()``: none), written as
            ``outside_training_range``; ``None`` where the model recorded no spans.
    """

    scores: Evaluation
    data_path: str
    split: str
    n_trajectories: int
    figure: str | None = None
    data_sha256: str | None = None
    request: Mapping[str, Any] | None = None
    outside: tuple[OutsideRange, ...] | None = None

    @property
    def rollout_mse(self) -> float:
        """The paper metric against the measured outputs."""
        return self.scores.measured.rollout_mse

    @property
    def rollout_mse_clean(self) -> float | None:
        """The paper metric against the noise-free outputs (``None`` without them)."""
        return self.scores.clean.rollout_mse if self.scores.clean else None

    def to_json(self) -> dict[str, Any]:
        """The body of ``metrics.json``."""
        data: dict[str, Any] = {
            "path": self.data_path,
            "split": self.split,
            "n_trajectories": self.n_trajectories,
        }
        if self.data_sha256 is not None:
            data["sha256"] = self.data_sha256
        return {
            "schema": 1,
            **self.scores.to_json(),
            "data": data,
            **({"figure": self.figure} if self.figure else {}),
            **({} if self.request is None else {"evaluation": dict(self.request)}),
            **(
                {}
                if self.outside is None
                else {"outside_training_range": [o.to_json() for o in self.outside]}
            ),
        }


#: an output column whose range is at most this share of its magnitude (or 1) is constant
_FLAT = 1e-12
#: the scores :func:`canonid.scoring.metrics_table` prints, each with its per-output list
_PRINTED_SCORES = ("rollout_mse", "rmse", "nrmse", "fit_percent")


def record_test_read(
    run_dir: Path, *, command: str, split: str, data: str | Path, sha256: str
) -> Path:
    """Append one line to ``run_dir``'s ledger of test reads (:data:`TEST_LEDGER_FILE`): a JSON
    object with ``time`` (UTC, ISO 8601), ``command`` (``evaluate``, ``benchmark``), ``split``,
    ``data`` (the data file read) and ``sha256`` (its checksum, as ``run.json`` and
    ``metrics.json`` record it: :func:`canonid.datagen.loaders.data_checksum`). Called before
    the split is scored, so a read that fails half-way is recorded too; a ledger that is a
    symbolic link, or not a regular file, is refused in one line
    (:func:`canonid.kernel.io.append_line`) and nothing is scored."""
    from datetime import datetime, timezone

    when = datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    entry = {
        "time": when,
        "command": command,
        "split": split,
        "data": str(data),
        "sha256": sha256,
    }
    line = json.dumps(entry, ensure_ascii=False)
    return append_line(Path(run_dir) / TEST_LEDGER_FILE, line, what=LEDGER_WHAT)


def check_test_ledger(run_dir: Path) -> None:
    """Refuse ``run_dir``'s ledger of test reads now if :func:`record_test_read` would refuse it
    (a symbolic link, not a regular file): before a benchmark's training, not after it."""
    check_appendable(Path(run_dir) / TEST_LEDGER_FILE, what=LEDGER_WHAT)


def read_metrics(path: Path) -> dict[str, Any]:
    """A ``metrics.json`` body read back (:meth:`RunEvaluation.to_json`), its printed fields
    checked (:func:`check_metrics`): a damaged or hand-edited file is one :class:`DataError`."""
    body = read_json(path, what="metrics")
    check_metrics(body, where=path)
    return body


def check_metrics(body: Any, *, where: Path) -> None:
    """Refuse a ``metrics.json`` body whose fields that canonid prints are not of their type:
    ``model`` a string; ``window``, ``n_rollouts``, ``rollout_horizon``, ``n_init`` integers
    >= 0; ``data`` an object with string ``path`` and ``split``; ``output_names`` a non-empty
    list of strings; the scores (top level and ``clean``, an object or null) numbers or null,
    their ``_per_output`` lists one per output, ``rollout_mse_per_record`` a list of them;
    ``finite`` a boolean; ``outside_training_range`` a list of
    :meth:`~canonid.coverage.OutsideRange.to_json` records."""

    def refuse(field: str, expected: str, got: Any) -> NoReturn:
        raise DataError(f"{where}: field '{field}' must be {expected}, got {got!r}")

    if not isinstance(body, Mapping):
        refuse("(top level)", "an object", body)
    if not isinstance(body.get("model"), str):
        refuse("model", "a string", body.get("model"))
    for key in ("window", "n_rollouts", "rollout_horizon", "n_init"):
        value = body.get(key)
        if not (is_json_number(value) and isinstance(value, int) and value >= 0):
            refuse(key, "an integer >= 0", value)
    data = body.get("data")
    if not (
        isinstance(data, Mapping) and all(isinstance(data.get(k), str) for k in ("path", "split"))
    ):
        refuse("data", "an object with the strings path and split", data)
    names = body.get("output_names")
    if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
        refuse("output_names", "a non-empty list of strings", names)
    for prefix, scores in (("", body), ("clean.", body.get("clean"))):
        if prefix and scores is None:
            continue
        if not isinstance(scores, Mapping):
            refuse("clean", "an object or null", scores)
        for key in _PRINTED_SCORES:
            if not _score(scores.get(key)):
                refuse(prefix + key, "a number or null", scores.get(key))
            per = scores.get(f"{key}_per_output")
            if not (isinstance(per, list) and len(per) == len(names) and all(map(_score, per))):
                refuse(
                    f"{prefix}{key}_per_output",
                    f"a list of {len(names)} number(s) or null (one per output)",
                    per,
                )
        per_record = scores.get("rollout_mse_per_record")
        if per_record is not None and not (
            isinstance(per_record, list) and all(map(_score, per_record))
        ):
            refuse(f"{prefix}rollout_mse_per_record", "a list of numbers or null", per_record)
        _check_kstep(scores, prefix, len(names), refuse)
    if not isinstance(body.get("finite", True), bool):
        refuse("finite", "a boolean", body.get("finite"))
    outside = body.get("outside_training_range")
    if outside is not None and not isinstance(outside, list):
        refuse("outside_training_range", "a list or null", outside)
    for i, found in enumerate(outside or []):
        try:
            OutsideRange.from_json(found)
        except ValueError as exc:
            raise DataError(f"{where}: field 'outside_training_range[{i}]': {exc}") from exc


def _check_kstep(
    scores: Mapping[str, Any], prefix: str, n_outputs: int, refuse: Callable[..., NoReturn]
) -> None:
    """``kstep_nrmse``, where present: a list of scores (one per step k), and
    ``kstep_nrmse_per_output`` one such list per output, each as long."""
    steps = scores.get("kstep_nrmse")
    if steps is None and "kstep_nrmse" not in scores:
        return
    if not (isinstance(steps, list) and all(map(_score, steps))):
        refuse(f"{prefix}kstep_nrmse", "a list of numbers or null (one per step k)", steps)
    per = scores.get("kstep_nrmse_per_output")
    if per is not None and not (
        isinstance(per, list)
        and len(per) == n_outputs
        and all(isinstance(p, list) and len(p) == len(steps) and all(map(_score, p)) for p in per)
    ):
        refuse(
            f"{prefix}kstep_nrmse_per_output",
            f"{n_outputs} list(s) of {len(steps)} numbers or null (per output, per step k)",
            per,
        )


def _score(value: Any) -> bool:
    """A score as ``metrics.json`` writes it: a finite number, or null where it was not finite
    (a NaN or an infinity there was written by hand: JSON has neither)."""
    return value is None or (
        is_json_number(value) and (isinstance(value, int) or math.isfinite(value))
    )


#: the field of ``metrics.json`` that holds the checksum of the rest of its content
CONTENT_CHECKSUM = "content_sha256"


def _content_checksum(body: Mapping[str, Any]) -> str:
    """SHA-256 of ``body`` less :data:`CONTENT_CHECKSUM`, as compact key-sorted JSON (the same
    for the parsed file as for what was written: floats round-trip exactly)."""
    rest = {k: v for k, v in body.items() if k != CONTENT_CHECKSUM}
    text = json.dumps(rest, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return sha256_bytes(text.encode("ascii"))


def sealed(body: Mapping[str, Any]) -> dict[str, Any]:
    """``body`` with the checksum of its own content (:data:`CONTENT_CHECKSUM`), so that a
    hand edit of the file is named as such when it is read back (:func:`check_sealed`)."""
    return {**body, CONTENT_CHECKSUM: _content_checksum(body)}


def check_sealed(body: Mapping[str, Any], *, where: Path) -> None:
    """Refuse a ``metrics.json`` body whose :data:`CONTENT_CHECKSUM` is missing or is not that
    of its content: edited by hand (or written by a canonid before the checksum)."""
    recorded = body.get(CONTENT_CHECKSUM)
    if recorded is None:
        raise DataError(
            f"{where}: field '{CONTENT_CHECKSUM}' missing (an older canonid, or edited by hand); "
            "remove that folder to score again"
        )
    if recorded != _content_checksum(body):
        raise DataError(
            f"{where}: its content does not match its field '{CONTENT_CHECKSUM}' (edited by "
            "hand?); remove that folder to score again"
        )


@dataclass(frozen=True)
class RunResult:
    """What :func:`train_run` did: the fit, the evaluation on the scoring split, and timings
    (``cpu_seconds``: this process's and, for a cubic branch trained beside, its worker's)."""

    run_dir: Path
    recipe: RunRecipe
    fit: FitResult
    evaluation: RunEvaluation
    resumed: bool
    seconds: float
    cpu_seconds: float


def load_splits(
    recipe: Recipe,
) -> tuple[Dataset, list[Trajectory], list[Trajectory], str, str]:
    """The data of ``recipe``: ``(dataset, train, val, scoring split name, the file that split
    came from)``, split as :func:`run_data` splits them (a ``--val FILE`` run scores FILE)."""
    dataset, scoring = run_data(recipe)
    train, val = list(dataset.split("train")), list(dataset.split("val"))
    return dataset, train, val, scoring, scoring_source(recipe, scoring)


def check_outputs_vary(path: str, dataset: Dataset, train: Sequence[Trajectory]) -> None:
    """Refuse training data ``train`` (of the file ``path``) in which an output column never
    changes: there is nothing to identify, and its spread, 0, cannot scale it."""
    y = np.concatenate([t.y for t in train])
    for k, name in enumerate(dataset.output_names):
        column = y[:, k]
        if column.size and float(np.ptp(column)) <= _FLAT * max(1.0, float(np.abs(column).max())):
            raise DataError(
                f"{path}: output column {name!r} is constant ({float(column[0]):g}) over the "
                "training records: expected an output that varies (there is nothing to identify)"
            )


def _constant(column: np.ndarray) -> bool:
    return bool(column.size) and float(np.ptp(column)) <= _FLAT * max(
        1.0, float(np.abs(column).max())
    )


def note_constant_inputs(path: str, dataset: Dataset, train: Sequence[Trajectory]) -> list[str]:
    """Say (one warning line) which input columns of the training data ``train`` (of the file
    ``path``) never change: the run trains, but cannot learn the output's response to them.
    Returns their names."""
    u = np.concatenate([t.u for t in train])
    flat = [name for k, name in enumerate(dataset.input_names) if _constant(u[:, k])]
    if flat:
        log.warning(
            "%s: input column(s) %s constant over the training records: the model cannot learn "
            "how the outputs respond to them (its scores hold only for data where they keep "
            "that value)",
            path,
            ", ".join(repr(n) for n in flat),
        )
    return flat


def scoring_source(recipe: Recipe, split: str) -> str:
    """The file split ``split`` of ``recipe``'s data comes from: ``--val FILE`` for ``val`` when
    the run has one, else its data."""
    return recipe.val if split == "val" and recipe.val is not None else recipe.data


def load(path: str | Path, options: Mapping[str, Any]) -> Dataset:
    """Read ``path`` with the loader ``options``; a canonid dataset carries its own names and
    sampling time, so options given with one are refused rather than silently ignored."""
    given = [DATA_FLAGS[key] for key, value in options.items() if value is not None]
    if given and is_dataset(path):
        raise DataError(
            f"{path} is a canonid dataset, which carries its own signal names and sampling "
            f"time: {', '.join(given)} apply to CSV and .npz data only"
        )
    return load_data(path, **options)


def check_compatible(
    dataset: Dataset,
    reference: Dataset | Mapping[str, Any],
    *,
    where: str,
    whose: str = "the run's",
) -> None:
    """Refuse data whose sampling time or signals differ from ``reference`` (a dataset, or a
    model's ``info`` with ``dt``, ``input_names`` and ``output_names``)."""
    if isinstance(reference, Dataset):
        ref: Mapping[str, Any] = {
            "dt": reference.dt,
            "input_names": list(reference.input_names),
            "output_names": list(reference.output_names),
        }
    else:
        ref = reference
    dt = ref.get("dt")
    if isinstance(dt, (int, float)) and not math.isclose(dataset.dt, dt, rel_tol=1e-9):
        raise DataError(f"{where}: sampling time dt = {dataset.dt:g} s, {whose} is {dt:g} s")
    for key, kind in (("input_names", "input"), ("output_names", "output")):
        names = ref.get(key)
        have = list(getattr(dataset, key))
        if isinstance(names, list) and len(names) != len(have):
            raise DataError(f"{where}: {len(have)} {kind}(s) {have}, {whose} are {names}")


def check_recorded(recipe: RunSource, path: str, sha256: str | None, *, what: str) -> None:
    """Refuse data at ``path`` (named by ``recipe``) whose checksum is not the recorded
    ``sha256``, in one line saying where the path came from and what to do. A recipe of an
    older canonid records no checksum: its data are used unchecked, with a warning."""
    where = recipe.recorded_in or RUN_FILE
    if sha256 is None and recipe.recorded_in is not None and not os.path.isabs(path):
        # neither checksum nor a folder to resolve it against: the current folder would decide
        raise DataError(
            f"{where} names the {what} by the relative path {path} and records no checksum: "
            f"canonid would read {os.path.abspath(path)} unchecked; give the data with --data "
            f"FILE, or write their absolute path into {where}"
        )
    if sha256 is None:
        if recipe.recorded_in is not None:
            log.warning(
                "%s records no checksum of its %s (an older canonid wrote it): %s is used "
                "unchecked",
                where,
                what,
                path,
            )
        return
    fix = "put them back there, or give the data with --data FILE"
    try:
        found = data_checksum(path)
    except DataError as exc:
        raise DataError(f"{where} names the {what} {path}: {exc}; {fix}") from None
    if found != sha256:
        raise DataError(
            f"{where} names the {what} {path}, but the data there have SHA-256 {found[:12]}…, "
            f"not the {sha256[:12]}… the run was trained on; {fix}"
        )


def run_data(recipe: Recipe) -> tuple[Dataset, str]:
    """The data of a training run split as training used them, and the split that scores it.

    The splits are ``train``, ``val`` (from the ``--val`` file, else DATA's own ``val`` split,
    else — none or an empty one — cut off DATA's ``train`` split by ``val_fraction``) and DATA's
    ``test`` split if any;
    the score uses ``test`` when there is one, else ``val``.
    """
    data_path, options = recipe.data, dict(recipe.data_options)
    check_recorded(recipe, data_path, recipe.data_sha256, what="training data")
    if recipe.val is not None:
        check_recorded(recipe, recipe.val, recipe.val_sha256, what="validation data")
    dataset = load(data_path, options)
    if "train" not in dataset.splits:
        raise DataError(
            f"{data_path}: no 'train' split to train on; it has {sorted(dataset.splits)}"
        )
    if not dataset.splits["train"]:
        raise DataError(
            f"{data_path}: its 'train' split holds no record (canonid generate --n-train 0?); "
            "give data with training records"
        )
    if recipe.val is not None:
        val_path = recipe.val
        val_set = load(val_path, options)
        check_compatible(val_set, dataset, where=val_path, whose=f"{data_path}'s")
        if "val" in val_set.splits:
            val = val_set.split("val")
        elif len(val_set.splits) == 1:
            val = val_set.split(next(iter(val_set.splits)))
        else:
            raise DataError(
                f"{val_path}: validation data need a 'val' split or a single split; it has "
                f"{sorted(val_set.splits)}"
            )
        if not val:
            raise DataError(f"{val_path}: its validation split holds no record")
        dataset = dataclasses.replace(
            dataset,
            splits={**dataset.splits, "val": val},
            metadata={**dataset.metadata, "validation_split": f"the file {val_path}"},
        )
    elif not dataset.splits.get("val"):  # none, or empty (canonid generate --n-val 0)
        splits = {k: v for k, v in dataset.splits.items() if k != "val"}
        dataset = split_train_val(
            dataclasses.replace(dataset, splits=splits), val_fraction=recipe.val_fraction
        )
    # an empty test split (``canonid generate --n-test 0``) scores like none: on validation
    return dataset, "test" if dataset.splits.get("test") else "val"


def pick_split(dataset: Dataset, name: str | None, *, where: str) -> tuple[str, list[Trajectory]]:
    """Split ``name``; by default ``test`` if it holds records, else the only split there is.
    A split without a record is refused, naming the splits that hold some."""
    held = sorted(k for k, v in dataset.splits.items() if v)
    if name is None:
        if dataset.splits.get("test"):
            name = "test"
        elif len(dataset.splits) == 1:
            name = next(iter(dataset.splits))
        else:
            what = "holds no record" if "test" in dataset.splits else "is missing"
            raise DataError(f"{where}: its 'test' split {what}; choose one of {held} with --split")
    if name not in dataset.splits:
        raise DataError(f"{where}: no split {name!r}; it has {sorted(dataset.splits)}")
    if not dataset.splits[name]:
        raise DataError(f"{where}: its split {name!r} holds no record; splits with records: {held}")
    return name, list(dataset.split(name))


#: the figures of a run folder, by name without the format's suffix
FIGURES = ("training_curve", "rollouts")


def figure_file(name: str, figure_format: str) -> str:
    """The file name of figure ``name`` (one of :data:`FIGURES`, or another figure a command
    writes) in ``figure_format`` (:func:`canonid.kernel.io.figure_name`)."""
    return figure_name(name, figure_format)


def write_history(
    run_dir: Path,
    history: list[dict[str, Any]],
    *,
    best_epoch: int | None = None,
    figure_format: str = "png",
) -> None:
    """``history.csv`` (one row per epoch, a column per key any row has) and its figure (the
    kept epoch ``best_epoch`` marked)."""
    keys: list[str] = []
    for row in history:
        keys += [k for k in row if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: ("" if row.get(k) is None else row[k]) for k in keys})
    atomic_write_text(run_dir / HISTORY_FILE, buf.getvalue())
    plot_training_curve(
        history, run_dir / figure_file("training_curve", figure_format), best_epoch=best_epoch
    )


def eval_defaults(
    trajs: Sequence[Trajectory], window: int, horizon: int, *, where: str, fit: bool
) -> int:
    """The rollout length that scores ``trajs``: ``horizon``, or with ``fit`` at most what the
    longest record holds after its ℓ-sample burn-in. Records too short to score at all (no
    record of ℓ + 1 samples) are refused here, before any work is done."""
    longest = max((tr.T for tr in trajs), default=0)
    if longest < window + 1:
        raise DataError(
            f"{where}: the longest record has {longest} samples; scoring a model with window "
            f"ℓ = {window} needs at least ℓ + 1 = {window + 1}"
        )
    return min(horizon, longest - window) if fit else horizon


def score_horizon(recipe: RunRecipe, dataset: Dataset, split: str, eval_horizon: int | None) -> int:
    """The rollout length :func:`train_run` scores ``recipe``'s model with on ``dataset``'s
    ``split`` (:func:`eval_defaults`: ``eval_horizon``, else 100 or the final training rollout
    when shorter, at most what the records hold)."""
    return eval_defaults(
        dataset.split(split),
        recipe.window,
        eval_horizon or min(EVAL_HORIZON, recipe.options().rollout_horizon),
        where=f"{scoring_source(recipe, split)} [{split}]",
        fit=eval_horizon is None,
    )


def rescore_run(
    run_dir: Path,
    recipe: RunRecipe,
    model: Model,
    *,
    eval_horizon: int | None = None,
    eval_stride: int = 1,
    figure_format: str = "png",
    split: str = "val",
) -> RunEvaluation:
    """Score ``model``, now the model of the run in ``run_dir``, as :func:`train_run` scored
    the one it trained (the same split, rollout length and figures; ``metrics.json`` and the
    rollout figure rewritten)."""
    dataset, _, _, _, _ = load_splits(recipe)
    return evaluate_run(
        run_dir,
        model,
        dataset,
        data_path=scoring_source(recipe, split),
        split=split,
        horizon=score_horizon(recipe, dataset, split, eval_horizon),
        stride=eval_stride,
        n_init=None,
        figure_format=figure_format,
    )


def data_info(
    dataset: Dataset, path: str, train: Sequence[Trajectory], val: Sequence[Trajectory]
) -> dict[str, Any]:
    """What a trained model's ``info`` says of its data: the file and its splits' sizes, the
    signals' names, the sampling time, each signal's span over the ``train`` part
    (:func:`canonid.coverage.training_ranges`) and where the ``train`` part leaves the ``val``
    part's spans (:func:`canonid.coverage.unvalidated`)."""
    names = {"input_names": list(dataset.input_names), "output_names": list(dataset.output_names)}
    return {
        "data": {"path": path, "splits": dataset.counts()},
        **names,
        "dt": dataset.dt,
        COVERAGE_KEY: training_ranges(train),
        VALIDATION_KEY: [o.to_json() for o in unvalidated(train, val, **names)],
    }


def evaluate_run(
    run_dir: Path,
    model: Model,
    dataset: Dataset,
    *,
    data_path: str,
    split: str | None,
    horizon: int,
    stride: int,
    n_init: int | None,
    figure_format: str = "png",
    data_sha256: str | None = None,
    request: Mapping[str, Any] | None = None,
) -> RunEvaluation:
    """Score ``model`` on ``dataset``; write rollouts.png (or .pdf, .svg: ``figure_format``),
    then metrics.json (the last file: a folder with it is complete) to ``run_dir``
    (``data_sha256``, ``request``: what :class:`RunEvaluation` records)."""
    name, trajs = pick_split(dataset, split, where=data_path)
    if n_init is None:
        n_init = default_n_init(
            model.window, [tr.T for tr in trajs], dataset.metadata.get("n_init")
        )
    ev = evaluate(
        model,
        trajs,
        horizon=horizon,
        stride=stride,
        n_init=n_init,
        output_names=dataset.output_names,
    )
    figure = figure_file("rollouts", figure_format)
    outside = outside_training_range(
        model.info,
        trajs,
        input_names=dataset.input_names,
        output_names=dataset.output_names,
    )
    result = RunEvaluation(
        ev,
        data_path,
        name,
        len(trajs),
        figure,
        data_sha256=data_sha256,
        request=request,
        outside=outside,
    )
    plot_rollouts(
        model,
        trajs,
        run_dir / figure,
        n_init=ev.n_init,
        output_names=dataset.output_names,
        output_units=signal_units(dataset.metadata, dataset.output_names, "outputs"),
        dt=dataset.dt,
        source=f"{Path(data_path).name} [{name}]",
    )
    body = result.to_json()  # an evaluation stored for `evaluate` to read back: sealed
    atomic_write_json(run_dir / METRICS_FILE, body if request is None else sealed(body))
    return result


def _discard(run_dir: Path) -> None:
    """Remove what a new run wrote before it failed without a checkpoint: its recipe (the
    lock removes the folder when this run made it and nothing else is in it)."""
    (run_dir / RUN_FILE).unlink(missing_ok=True)


def train_run(
    recipe: RunRecipe,
    run_dir: Path,
    *,
    resume: bool = False,
    eval_horizon: int | None = None,
    eval_stride: int = 1,
    callback: Callable[[EpochReport], None] | None = None,
    figure_format: str = "png",
    split: str = "val",
    table: Sequence[Candidate] | None = None,
    executor: Executor | None = None,
    record: Callable[[Search], None] | None = None,
) -> RunResult:
    """Train the model of ``recipe`` into ``run_dir`` (or continue it from its checkpoint with
    ``resume``), write ``run.json``, the model, ``history.csv`` and the figures, and score it
    on ``split``: validation, what ``canonid train`` reports (``"test"``: the test split, for a
    command that reads it after every choice is made, as ``canonid reproduce`` does).

    With more than one candidate to choose from — ``table``, or Ours (MLP)'s ``cubic="auto"``
    (the branch or not, at the recipe's window) — the model is chosen by the search of
    :mod:`canonid.learning.search` (its candidates in ``RUN/search``, on ``executor``'s
    workers; ``record`` sees the search after each rung), and ``run.json`` then names the
    chosen window and branch; a resumed run continues the search recorded in ``search.json``.

    ``eval_horizon`` is the rollout length of the score; ``None``: 100, or the final training
    rollout length when shorter, at most what the scored records hold. Data that cannot be
    scored are refused before anything is written; a new run that fails before its first
    checkpoint leaves no recipe behind. The folder's lock is held throughout
    (:func:`canonid.jobs.run_folder_lock`); a new run records its data by absolute path and
    checksum (:meth:`RunSource.pinned`) and refuses a folder holding another run or the user's
    own files.
    """
    t0, cpu0 = time.perf_counter(), time.process_time()
    dataset, train, val, _, _ = load_splits(recipe)  # the loader's checks first
    check_outputs_vary(recipe.data, dataset, train)
    if not resume:
        note_constant_inputs(recipe.data, dataset, train)
        recipe = recipe.pinned()
    table = _table(recipe, run_dir, table, resume=resume)
    if len(table) > 1:
        table = _fitting(table, train, val, recipe)
    chosen = recipe if len(table) > 1 else _with_candidate(recipe, table[0])
    opts = chosen.options()
    horizon = score_horizon(chosen, dataset, split, eval_horizon)
    info = {"profile": recipe.profile, **data_info(dataset, recipe.data, train, val)}
    with run_folder_lock(run_dir, new=not resume):
        if not resume and (run_dir / CHECKPOINT_FILE).exists():
            raise OutputError(
                f"{run_dir} already holds a training run; use --resume --out {run_dir} or "
                "another --out"
            )
        chosen.write(run_dir)
        try:
            if len(table) > 1:
                chosen, fitted = _searched(
                    recipe, run_dir, table, train, val, info=info, executor=executor, record=record
                )
            else:
                fitted = fit(
                    train,
                    val,
                    model=chosen.model,
                    window=chosen.window,
                    options=opts,
                    net_options=dict(chosen.net_options),
                    run_dir=run_dir,
                    resume=resume,
                    callback=callback,
                    info=info,
                )
        except BaseException:
            if not resume and not _trained_any(run_dir):
                _discard(run_dir)
            raise
        return finish_run(
            chosen,
            run_dir,
            fitted,
            dataset=dataset,
            split=split,
            horizon=horizon,
            eval_stride=eval_stride,
            figure_format=figure_format,
            resumed=resume,
            started=(t0, cpu0),
        )


def _trained_any(run_dir: Path) -> bool:
    """Whether ``run_dir`` holds a checkpoint to continue, its own or a search candidate's;
    without one, what a failed new run wrote goes (the search's record and folder too)."""
    guarded(run_dir / SEARCH_DIR)  # a link there is refused, never searched or removed
    if (run_dir / CHECKPOINT_FILE).exists() or any(
        (run_dir / SEARCH_DIR).glob(f"*/{CHECKPOINT_FILE}")
    ):
        return True
    (run_dir / SEARCH_FILE).unlink(missing_ok=True)
    if (run_dir / SEARCH_DIR).is_dir():
        shutil.rmtree(run_dir / SEARCH_DIR)
    return False


def _table(
    recipe: RunRecipe, run_dir: Path, table: Sequence[Candidate] | None, *, resume: bool
) -> list[Candidate]:
    """The candidates to choose among: those a resumed search recorded, ``table``, or the
    recipe's own model (with and without the cubic branch where its ``cubic`` is ``"auto"``)."""
    if resume and (run_dir / SEARCH_FILE).is_file():
        recorded = Search.read(run_dir)
        if recorded.chosen is not None and (run_dir / CHECKPOINT_FILE).is_file():
            return [recorded.chosen]  # the chosen model, adopted: it continues as one run
        return list(recorded.candidates)
    if table is not None:
        if not table:
            raise OptionError("the candidate table is empty")
        return list(table)
    cubic = recipe.net_options.get("cubic")
    if resume and cubic == "auto":
        raise CheckpointError(
            f"{run_dir} was trained by an older canonid, whose cubic test this version no longer "
            "runs: it cannot be resumed (canonid evaluate, analyze and export still read it); "
            "train it again"
        )
    return list(candidate_table((recipe.window,), cubic_axis(cubic)))


def _fitting(
    table: Sequence[Candidate],
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    recipe: RunRecipe,
) -> list[Candidate]:
    """The candidates whose window the data allow
    (:func:`~canonid.learning.search.fitting_windows`); none is a :class:`DataError` naming the
    records' lengths."""
    windows = sorted({c.window for c in table})
    horizon = recipe.options().horizon
    fits = set(fitting_windows(train, val, windows, horizon))
    kept = [c for c in table if c.window in fits]
    if not kept:
        raise DataError(
            f"{recipe.data}: no candidate window of {windows} fits the records (shortest training "
            f"or validation record {min(t.T for t in [*train, *val])} samples, longest validation "
            f"record {max(t.T for t in val)}: it must hold twice the window; training rollouts "
            f"{horizon}); give --window L"
        )
    return kept


def _with_candidate(recipe: RunRecipe, candidate: Candidate) -> RunRecipe:
    """``recipe`` with ``candidate``'s window, cubic branch and widths."""
    from canonid.learning.nets import NETS

    options = candidate.net_options(recipe.net_options, NETS[recipe.model].hidden_option)
    return dataclasses.replace(recipe, window=candidate.window, net_options=options)


def _searched(
    recipe: RunRecipe,
    run_dir: Path,
    table: Sequence[Candidate],
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    info: Mapping[str, Any],
    executor: Executor | None,
    record: Callable[[Search], None] | None,
) -> tuple[RunRecipe, FitResult]:
    """The search among ``table`` in ``run_dir`` (continued where one is recorded), its chosen
    candidate's model and checkpoint copied into ``run_dir`` and its recipe written there."""
    net_options = {k: v for k, v in recipe.net_options.items() if v != "auto" or k != "cubic"}
    search, fitted, folder = run_search(
        train,
        val,
        model=recipe.model,
        table=table,
        options=recipe.options(),
        net_options=net_options,
        run_dir=run_dir,
        executor=executor,
        record=record,
        info=info,
    )
    assert folder is not None and search.chosen is not None
    adopt(folder, run_dir)
    chosen = _with_candidate(recipe, search.chosen)
    measure = {"val_measure": "simulation", "val_n_init": search.val_n_init}  # as it trained
    chosen = dataclasses.replace(chosen, train_options={**chosen.train_options, **measure})
    chosen.write(run_dir)
    return chosen, fitted


def finish_run(
    recipe: RunRecipe,
    run_dir: Path,
    fitted: FitResult,
    *,
    dataset: Dataset,
    split: str,
    horizon: int,
    eval_stride: int,
    figure_format: str,
    resumed: bool,
    started: tuple[float, float],
) -> RunResult:
    """The end of a training run whose model is in ``run_dir``: ``history.csv`` and its figure,
    the score on ``split`` (``metrics.json``, the last file written) and the run's timings
    since ``started`` (wall and CPU clocks), with the CPU its workers spent."""
    write_history(
        run_dir, fitted.history, best_epoch=fitted.best_epoch, figure_format=figure_format
    )
    if split == "test":  # a command that reads the test split after training (reproduce)
        record_test_read(
            run_dir,
            command=" ".join(recipe.command[:2]) or "train_run",
            split=split,
            data=scoring_source(recipe, split),
            sha256=recipe.data_sha256 or data_checksum(scoring_source(recipe, split)),
        )
    evaluation = evaluate_run(
        run_dir,
        fitted.model,
        dataset,
        data_path=scoring_source(recipe, split),
        split=split,
        horizon=horizon,
        stride=eval_stride,
        n_init=None,
        figure_format=figure_format,
    )
    t0, cpu0 = started
    return RunResult(
        run_dir=run_dir,
        recipe=recipe,
        fit=fitted,
        evaluation=evaluation,
        resumed=resumed,
        seconds=round(time.perf_counter() - t0, 3),
        cpu_seconds=round(time.process_time() - cpu0 + fitted.cpu_elsewhere, 3),
    )
