"""A run folder's trained model as a CasADi system, with its sets from the run's training data;
the checks of learned models against an analysis; the export of ``canonid export``.

``learned_system(RUN)`` reads the model of ``RUN`` (``canonid.learning.Model.load``), exports its
weights (``NumpyModel.network()``: Ours (MLP), Ours (GRU) and their reduced models) and builds a
:class:`canonid.models.learned.LearnedSystem` with

* ``dt``, input and output names from the data the run was trained on (``RUN/run.json``), units
  from the dataset's metadata where it has them;
* X and U the hulls of the training split's windows and inputs (the same training trajectories
  ``canonid train`` used, validation split included when it was cut from the data);
* W the dataset's noise box (``metadata["noise"]["box"]``) when it records one, else the hull of
  the training noise ``y − y_clean``, else ``{0}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.errors import DataError, OutputError, SetError
from canonid.kernel.io import atomic_write_json
from canonid.learning import Model
from canonid.models.learned import LearnedSystem
from canonid.models.sets import Box
from canonid.runfolder import (
    RUN_FILE,
    check_compatible,
    load_run_model,
    load_splits,
    pick_split,
    recipe_of,
)

if TYPE_CHECKING:
    from canonid.analysis.report import AnalysisReport, LearnedChecks

__all__ = [
    "Exported",
    "LearnedRun",
    "encoder_path",
    "export_casadi",
    "learned_checks",
    "learned_system",
]


@dataclass(frozen=True)
class LearnedRun:
    """A trained model of a run folder, its system and the data it came from."""

    run: Path
    model: Model
    system: LearnedSystem
    dataset: Any
    train: list[Any]


def _noise_box(dataset: Any, n_y: int) -> Box | None:
    box = dataset.metadata.get("noise", {}).get("box") if dataset.metadata else None
    if not isinstance(box, dict) or len(box.get("lower", ())) != n_y:
        return None
    return Box(box["lower"], box["upper"])


def learned_system(
    run_dir: Path, *, data: Path | None = None, members: Sequence[Path] = ()
) -> LearnedRun:
    """The model of ``run_dir`` as a system (see the module docstring).

    ``data`` replaces the training data named in ``run_dir/run.json`` (its ``train`` split, or
    all of it when it has no such split). ``members``: further run folders of canonical models
    of the same window and signals, e.g. other seeds; the system is then the mean of all of them
    (:class:`~canonid.models.learned.LearnedSystem`, "Ensembles"), its sets from ``run_dir``'s
    data.

    Raises:
        NotExportableError: the run's model is not a canonical model (or a reduced one).
        DataError: the run has no recipe naming its data and ``data`` is not given.
    """

    model = load_run_model(run_dir)
    net = model.export().network()  # refuses the non-canonical models first
    recipe = recipe_of(run_dir)
    if data is None:
        if recipe is None:
            raise DataError(f"{run_dir / RUN_FILE} not found: the run names no data; give them")
        dataset, train, *_ = load_splits(recipe)  # the training split as `train` cut it
    else:
        from canonid.scoring import check_signal_names, load_with_run_options

        dataset = load_with_run_options(run_dir, data, {})
        # the sets of another sampling time or other signals would describe another model
        check_compatible(dataset, model.info, where=str(data))
        check_signal_names(
            dataset,
            model.info,
            where=str(data),
            explicit=False,
            remedy="Give --data with the run's signals (their names as it recorded them), or "
            "leave out --data to use the data the run was trained on",
        )
        splits = dataset.splits
        train = (
            list(splits["train"]) if "train" in splits else [t for s in splits.values() for t in s]
        )
    units = dataset.metadata.get("units", {}) if dataset.metadata else {}
    nets = [_member_network(member, dataset, net.window) for member in members]
    name = run_dir.name if not nets else f"mean of {run_dir.name} and {len(nets)} more"
    system = LearnedSystem.from_data(
        net,
        train,
        dt=float(model.info.get("dt", dataset.dt)),
        input_names=dataset.input_names,
        output_names=dataset.output_names,
        input_units=[units.get("inputs", {}).get(n, "-") for n in dataset.input_names],
        output_units=[units.get("outputs", {}).get(n, "-") for n in dataset.output_names],
        W=_noise_box(dataset, model.n_y),
        name=f"learned:{name}",
        members=nets,
    )
    return LearnedRun(run=run_dir, model=model, system=system, dataset=dataset, train=train)


def _member_network(run_dir: Path, dataset: Any, window: int) -> Any:
    """The canonical network of the ensemble member ``run_dir``, checked against the first run's
    data (sampling time, signals) and window."""
    from canonid.kernel.network import CanonicalNet
    from canonid.scoring import check_signal_names

    model = load_run_model(run_dir)
    net = model.export().network()  # refuses the non-canonical models first
    check_compatible(dataset, model.info, where=str(run_dir))
    check_signal_names(dataset, model.info, where=str(run_dir), explicit=False)
    if not isinstance(net, CanonicalNet):
        raise DataError(f"{run_dir}: a reduced model cannot be averaged with others")
    if net.window != window:
        raise DataError(
            f"{run_dir}: window ℓ = {net.window}, the first run's is {window}; the models of an "
            "ensemble share the window state"
        )
    return net


def learned_checks(
    report: AnalysisReport,
    models: Sequence[Any],
    dataset: Any,
    *,
    split: str | None = None,
    where: str = "data",
) -> LearnedChecks:
    """The checks of the exported ``models`` (``H(z, u)``, ``window``) with the certified
    constants of ``report`` (:meth:`~canonid.analysis.report.AnalysisReport.learned_checks`) on
    split ``split`` of ``dataset`` (default ``test``, else its only split), its ``train`` split
    feeding the state probe: what ``canonid analyze --run`` and ``canonid reproduce`` record."""
    covered = {r.window for r in report.results}
    for model in models:
        if int(model.window) not in covered:
            raise SetError(
                f"the model has window ℓ = {int(model.window)}, which the analysis did not cover"
            )
    _, test = pick_split(dataset, split, where=where)
    return report.learned_checks(list(models), list(dataset.splits.get("train", ())), test)


def encoder_path(path: Path) -> Path:
    """Where the encoder of a reduced model is written beside ``path``."""
    return path.with_name(f"{path.stem}.encoder.casadi")


def _check_output(*paths: Path) -> None:
    """Refuse an output of ``canonid export`` that is a folder, or whose folder is a file (it
    could not be written)."""
    for path in paths:
        if path.is_dir():
            raise OutputError(f"--casadi: {path} is a folder, expected a file name")
        for part in path.parents:  # the first that exists must be a folder to write into
            if part.exists():
                if not part.is_dir():
                    raise OutputError(f"--casadi {path}: {part} is a file; expected a folder")
                break


@dataclass(frozen=True)
class Exported:
    """What :func:`export_casadi` wrote: ``headline``, a one-line description of the model, and
    ``files``."""

    headline: str
    files: tuple[Path, ...]

    def summary(self) -> str:
        """What ``canonid export`` prints: the model, then each file written."""
        return "\n".join([self.headline, *(f"  wrote {path}" for path in self.files)])


def export_casadi(
    run_dir: Path, target: Path, *, data: Path | None = None, members: Sequence[Path] = ()
) -> Exported:
    """Write the canonical model of ``run_dir`` as the ``casadi.Function`` ``target``,
    ``learned_model(x, u) -> (x_next, y)`` (load it with ``casadi.Function.load``), and its
    description ``target.json`` (dimensions, names, units, ``dt``, the sets X, U, W, how the
    state is filled from measured data); a reduced model also gets its encoder
    ``encode(z) -> x`` beside it (suffix ``.encoder.casadi``). The sets come from ``data``
    (default: the run's training data). Only canonical models export (Ours (MLP), Ours (GRU) and
    their reduced models). With ``members`` (further run folders, :func:`learned_system`) the
    function is the mean of all the models. Returns :class:`Exported`: the model in one line, the
    files written."""
    from canonid.models.learned import model_function, save_function

    if target.suffix != ".casadi":
        raise DataError(f"--casadi: expected a file name ending in .casadi, got {target}")
    described = target.with_name(target.name + ".json")
    _check_output(target, described)
    learned = learned_system(run_dir, data=data, members=members)
    system = learned.system
    fun = model_function(system)
    reduced = system.reduced
    outputs = [(target, fun)] + ([(encoder_path(target), system.encoder)] if reduced else [])
    _check_output(*(path for path, _ in outputs), described)  # all of them, before any is written
    description = {
        "format": "canonid-casadi-model",
        "run": str(run_dir),
        **({"members": [str(run_dir), *map(str, members)]} if members else {}),
        "model": learned.model.name,
        "function": {
            "name": fun.name(),
            "inputs": {"x": system.n_x, "u": system.n_u},
            "outputs": {"x_next": system.n_x, "y": system.n_y},
        },
        "state": (
            "reduced state x̄ = E(z_t): run the encoder file on the measured window z_t"
            if reduced
            else "canonical window z_t = (u[t-ℓ], y[t-ℓ], …, u[t-1], y[t-1]), oldest first"
        ),
        "window": system.regressor.window,
        **system.describe(),
    }
    files: list[Path] = []
    try:
        for path, function in outputs:
            files.append(save_function(function, path))
        files.append(atomic_write_json(described, description))
    except BaseException:
        for path in files:  # the files belong together: none is left without the others
            path.unlink(missing_ok=True)
        raise
    count = f"the mean of {len(members) + 1} " if members else ""
    what = f"{count}{learned.model.name} model{'s' if members else ''}"
    headline = (
        f"{what} of {', '.join(map(str, [run_dir, *members]))}: {system.n_x} states, {system.n_u} "
        f"input(s), {system.n_y} output(s), dt = {system.dt:g} s"
    )
    return Exported(headline, tuple(files))
