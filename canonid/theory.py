"""What ``canonid analyze`` asks for, and the one call that does it: the theory, numerically.

:func:`run_analysis` bounds γ_f, γ_h and α_ℓ of a registered system (certified and sampled),
evaluates Proposition 2's bound and checks it by Monte-Carlo trials
(:func:`canonid.analysis.report.analyze`); with a trained run it adds the learned model's checks
(:func:`canonid.learned.learned_checks`, shared with ``canonid reproduce``) and, if asked, γ_f of
the learned model on its training hull. Without a system it bounds γ_f of the learned model alone.
With a system it writes ``analysis.json`` and, where trials ran, ``bound_vs_window.png``
(``.pdf``, ``.svg``: ``--figure-format``); without one, ``learned_analysis.json``. It returns an
:class:`AnalysisOutcome` whose text the command prints.

The module imports neither torch nor CasADi; the analysis loads them.
"""

from __future__ import annotations

import logging
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.catalog import parse_list
from canonid.kernel.errors import CanonidError, DataError, OptionError, SetError

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from canonid.analysis.estimate import Budget
    from canonid.analysis.report import AnalysisReport
    from canonid.models.sets import Box

__all__ = [
    "MAX_BUDGET",
    "AnalysisOutcome",
    "AnalyzeRequest",
    "parse_box",
    "parse_windows",
    "run_analysis",
]

#: the largest ``--budget``, in seconds (one day): a stage's wall-clock limit must be one a user
#: can wait for
MAX_BUDGET = 86_400.0
#: the files an analysis writes into --out: a folder holding one is an analysis folder
WRITTEN = ("analysis.json", "learned_analysis.json")


@dataclass(frozen=True, kw_only=True)
class AnalyzeRequest:
    """An analysis as asked for (the options of ``canonid analyze``; ``None``: the default).

    Attributes:
        system: a registered system, or ``None`` to analyse the model of ``run`` alone.
        window, windows: one window ℓ, or several: a list, or its text in the one list syntax
            (``"2,5,10"``, ``"1-10"``: :func:`canonid.kernel.catalog.parse_list`).
        trials, budget, boxes, tol, seed: Monte-Carlo trials per window; each certified search's
            limits in seconds and boxes; the γ searches' relative tolerance; the random seed.
        X, U, W: the sets as ``lo:hi`` per component (default: the system's).
        run, data, learned_gamma: a trained run checked beside the theory, its data, and whether
            γ_f of its model is bounded too.
        out, progress: the output folder; a progress bar.
        figure_format: the figure's file format (``png``, ``pdf`` or ``svg``).
    """

    system: str | None = None
    window: int | None = None
    windows: str | Sequence[int] | None = None
    trials: int = 1000
    budget: float = 20.0
    boxes: int | None = None
    X: str | None = None
    U: str | None = None
    W: str | None = None
    tol: float = 0.05
    seed: int = 0
    run: Path | None = None
    data: Path | None = None
    learned_gamma: bool = False
    out: Path | None = None
    progress: bool = True
    figure_format: str = "png"


@dataclass(frozen=True)
class AnalysisOutcome:
    """What :func:`run_analysis` did: the lines to print, the Proposition 2 violations with
    certified constants (a bug if any) and the report (``None`` for a learned model alone)."""

    text: str
    violations: int = 0
    report: AnalysisReport | None = None

    def warning(self) -> str | None:
        """The line that reports violations of Proposition 2 (``None`` when there are none)."""
        if not self.violations:
            return None
        return (
            f"warning: {self.violations} violation(s) of Proposition 2 with certified "
            "constants — this is a bug, please report it with analysis.json"
        )


def run_analysis(request: AnalyzeRequest) -> AnalysisOutcome:
    """Run the analysis of ``request`` (see the module docstring)."""
    from canonid.analysis.report import analyze
    from canonid.jobs import check_run_folder, run_folder_lock
    from canonid.models.registry import get_system

    if request.window is not None and request.window < 1:
        raise OptionError(f"--window must be an integer >= 1, got {request.window}")
    if request.system is None:
        if request.run is None:
            raise OptionError(
                "give a registered SYSTEM (see `canonid systems`), or --run RUN to analyse a "
                "learned model alone"
            )
        return _learned_only(request)
    system = get_system(request.system)
    if request.window is not None:
        windows = [request.window]
    elif request.windows is not None:
        windows = parse_windows(request.windows)
    else:
        raise OptionError("one of --window L or --windows A-B is required with a SYSTEM")
    budget = _check_numbers(request)
    if request.data is not None and request.run is None:
        raise OptionError("--data applies to --run RUN only")
    X = system.X if request.X is None else parse_box(request.X, system.n_x, "X")
    U = system.U if request.U is None else parse_box(request.U, system.n_u, "U")
    W = system.W if request.W is None else parse_box(request.W, system.n_y, "W")
    model, dataset, split = None, None, None
    source: dict[str, str] = {}
    if request.run is not None:
        model, dataset, split, source = _learned_source(request.run, request.data, system)
        windows = sorted({*windows, int(model.window)})
    # a folder of the user's own files is refused, as train --out refuses it
    out = check_run_folder(request.out or Path("runs") / f"analyze-{system.name}", own=WRITTEN)
    bar, progress = _progress_bar(request.progress)
    try:
        report = analyze(
            system,
            windows,
            X=X,
            U=U,
            W=W,
            trials=request.trials,
            budget=budget,
            gamma_tol=request.tol,
            seed=request.seed,
            progress=progress,
        )
    finally:
        if bar is not None:
            bar.close()
    if model is not None and dataset is not None:
        from canonid.learned import learned_checks

        checks = learned_checks(report, [model], dataset, split=split, where=source["data"])
        report.learned = {
            **source,
            "model": repr(model),
            "window": int(model.window),
            "residual": checks.residuals[0].to_dict(),
        }
        if checks.probes:
            report.learned["probe"] = checks.probes[0].to_dict()
        report.learned["gamma_f"] = (
            _learned_gamma_record(model, request, budget)
            if request.learned_gamma
            else {"available": False, "why": "not asked for (--learned-gamma)"}
        )
    with run_folder_lock(out, new=True):  # one writer of the analysis folder at a time
        json_path = report.write_json(out / "analysis.json")
    lines = [report.table()]
    if report.learned:
        res = report.learned["residual"]
        lines.append(
            f"learned model ({report.learned['model']}), ℓ = {report.learned['window']}: "
            f"one-step residual within the noise-induced level on {res['within']} of "
            f"{res['rows']} test rows ({res['excluded']} rows start outside X)"
        )
        lines.append(_gamma_lines(report))
    lines.append(f"analysis written to {json_path.resolve()}")
    if report.checks:
        figure = report.figure(out / f"bound_vs_window.{request.figure_format}")
        lines.append(f"  figure: {figure.resolve()}")
    violations = sum(c.violations for c in report.checks)
    return AnalysisOutcome("\n".join(lines), violations, report)


def _progress_bar(enabled: bool) -> tuple[Any, Any]:
    """A progress bar over the analysis (``None`` when disabled) and the callback that moves it."""
    bar = None
    if enabled:
        from tqdm import tqdm

        bar = tqdm(
            total=100,
            desc="analyze",
            file=sys.stderr,
            leave=False,
            bar_format="{l_bar}{bar}| {elapsed}",
        )

    def progress(message: str, fraction: float) -> None:
        if bar is not None:
            bar.set_description_str(message[:60])
            bar.n = int(100 * min(max(fraction, 0.0), 1.0))
            bar.refresh()

    return bar, progress


def _check_numbers(request: AnalyzeRequest) -> Budget:
    """The numeric options every analysis shares, each checked with its flag's name; the
    budget of each certified search."""
    from canonid.analysis.estimate import Budget

    if request.trials < 0:
        raise OptionError(f"--trials must be >= 0, got {request.trials}")
    if not 0 < request.budget <= MAX_BUDGET:  # NaN fails too
        raise OptionError(
            f"--budget must be a number of seconds in (0, {MAX_BUDGET:g}] (one day), got "
            f"{request.budget:g}"
        )
    if not 0 < request.tol < math.inf:
        raise OptionError(f"--tol must be a positive finite relative tolerance, got {request.tol}")
    if request.seed < 0:
        raise OptionError(f"--seed must be an integer >= 0, got {request.seed}")
    if request.boxes is not None and request.boxes < 1:
        raise OptionError(f"--boxes must be an integer >= 1, got {request.boxes}")
    return Budget(seconds=request.budget, boxes=request.boxes or 10**9)


def _learned_source(
    run_dir: Path, data: Path | None, system: Any
) -> tuple[Any, Any, str, dict[str, str]]:
    """The run's exported model, the data that check it, their split and the source labels;
    refuses a run whose signals do not match ``system``."""
    from canonid.runfolder import load_run_model, pick_split
    from canonid.scoring import scoring_data

    trained = load_run_model(run_dir)
    model, info = trained.export(), trained.info
    _check_run_matches_system(run_dir, info, int(model.n_u), int(model.n_y), system)
    dataset, data_path, split = scoring_data(run_dir, data, {}, split=None, model=info)
    name, test = pick_split(dataset, split, where=data_path)
    if any(tr.y_clean is None for tr in test):
        raise DataError(
            f"--run: the residual check needs the noise w = y − y_clean, which {data_path} "
            f"[{name}] does not hold; give --data a canonid dataset or .npz with y_clean"
        )
    return model, dataset, name, {"run": str(run_dir), "data": data_path, "split": name}


def _check_run_matches_system(
    run_dir: Path, info: Mapping[str, Any], n_u: int, n_y: int, system: Any
) -> None:
    """Refuse a run that was not trained on data of ``system``: the numbers of inputs and
    outputs always, the sampling time where the run records it (``config.json`` ``info``: a
    model saved without data records none). Signal names that differ only warn: a CSV's column
    names are the user's labels (``pump``, ``level``), the registry's are generic (``u``, ``y``)."""
    have: dict[str, Any] = {"number of inputs": n_u, "number of outputs": n_y}
    want: dict[str, Any] = {"number of inputs": system.n_u, "number of outputs": system.n_y}
    if info.get("dt") is not None:
        have["sampling time dt"], want["sampling time dt"] = float(info["dt"]), system.dt
    renamed = [
        f"{label} {list(info[key])!r} (the run) vs {list(getattr(system, key))!r}"
        for key, label in (("input_names", "input names"), ("output_names", "output names"))
        if info.get(key) is not None and list(info[key]) != list(getattr(system, key))
    ]
    if renamed:
        log.warning(
            "--run %s: %s; compared as the same signals, in order", run_dir, "; ".join(renamed)
        )
    differ = [
        f"{label} {have[label]!r} (the run) vs {want[label]!r} ({system.name})"
        for label in have
        if (
            not math.isclose(have[label], want[label], rel_tol=1e-9)
            if label == "sampling time dt"
            else have[label] != want[label]
        )
    ]
    if differ:
        raise DataError(
            f"--run {run_dir} was not trained on data of {system.name}: " + "; ".join(differ)
        )


def _learned_only(request: AnalyzeRequest) -> AnalysisOutcome:
    """``canonid analyze --run RUN`` without a system: γ_f of the learned model alone."""
    from canonid.jobs import check_run_folder, run_folder_lock
    from canonid.kernel.io import atomic_write_json, check_inside, jsonable
    from canonid.runfolder import load_run_model

    assert request.run is not None
    for flag, value in (("--windows", request.windows), ("--X", request.X), ("--U", request.U)):
        if value is not None:
            raise OptionError(f"{flag} applies to a registered SYSTEM; the run's model has its own")
    if request.W is not None:
        raise OptionError("--W applies to a registered SYSTEM")
    budget = _check_numbers(request)
    model = load_run_model(request.run).export()
    if request.window is not None and request.window != int(model.window):
        raise OptionError(
            f"--window {request.window}: the run's model has window ℓ = {model.window}"
        )
    if request.out is None:  # RUN/analysis: no link there is followed
        check_inside(request.run, request.run / "analysis")
    out = check_run_folder(request.out or request.run / "analysis", own=WRITTEN)
    record = _learned_gamma_record(model, request, budget)
    if not record["available"]:
        raise OptionError(f"--run {request.run}: {record['why']}")
    body = {
        "format": "canonid-learned-analysis",
        "run": str(request.run),
        "data": None if request.data is None else str(request.data),
        "model": repr(model),
        "window": int(model.window),
        "gamma_f": record,
    }
    with run_folder_lock(out, new=True):
        path = atomic_write_json(out / "learned_analysis.json", jsonable(body))
    return AnalysisOutcome(
        f"learned model ({body['model']}), ℓ = {body['window']}; no registered system, so no "
        "α_ℓ and no Proposition 2 bound (they need the true system)\n"
        f"{_learned_gamma_line(record)}\nanalysis written to {path.resolve()}"
    )


def parse_windows(text: str | Sequence[int]) -> list[int]:
    """``"1-10"`` → 1…10, ``"2,5,10"`` → [2, 5, 10] (the one list syntax), or a list as given;
    every window an integer >= 1."""
    try:
        values = parse_list(text, int, "L") if isinstance(text, str) else list(text)
    except OptionError as exc:
        raise OptionError(f"--windows: {exc}") from None
    if not values or min(values) < 1:
        raise OptionError(f"--windows: windows must be integers >= 1, got {text!r}")
    return values


def parse_box(text: str, dim: int, name: str) -> Box:
    """``"lo:hi,lo:hi"`` (one pair per component, or one pair for all) → :class:`Box`."""
    from canonid.models.sets import Box

    try:
        pairs = [tuple(float(v) for v in part.split(":")) for part in text.split(",")]
    except ValueError:
        raise SetError(f"--{name}: expected lo:hi[,lo:hi...], got {text!r}") from None
    if any(len(p) != 2 for p in pairs):
        raise SetError(f"--{name}: each component needs lo:hi, got {text!r}")
    if len(pairs) == 1:
        pairs = pairs * dim
    if len(pairs) != dim:
        raise SetError(f"--{name}: {len(pairs)} components given, the system needs {dim}")
    try:
        return Box([p[0] for p in pairs], [p[1] for p in pairs])
    except SetError as exc:
        raise SetError(f"--{name}: {exc}") from None


def _learned_gamma_record(model: Any, request: AnalyzeRequest, budget: Budget) -> dict[str, Any]:
    """γ_f of the run's model in its state on its training hull (:mod:`canonid.analysis.certify`),
    or why there is none (only canonical models are built as CasADi systems)."""
    from canonid.analysis.certify import learned_gamma
    from canonid.learned import learned_system

    run = request.run
    if run is None:  # only called for a run's model
        raise OptionError("the learned model's γ_f needs --run RUN")
    if not hasattr(model, "network"):
        return {"available": False, "why": "the model does not export its weights"}
    try:
        model.network()
    except CanonidError as exc:  # only canonical models export
        return {"available": False, "why": str(exc)}
    # the hull: of the run's own training data, or of --data when given (it replaces them)
    system = learned_system(run, data=request.data).system
    gamma = learned_gamma(system, budget=budget, tol=request.tol, seed=request.seed)
    return {"available": True, "state_dim": system.n_x, **gamma.to_dict()}


def _value(record: Mapping[str, Any]) -> str:
    value = record.get("value")
    return "∞" if value is None else f"{value:.4g}"


def _gamma_lines(report: AnalysisReport) -> str:
    """The true system's γ_f bracket at the model's window beside the learned model's."""
    learned = report.learned
    ell = int(learned["window"])
    true = next(r for r in report.results if r.window == ell).gamma_f
    lines = [
        f"γ_f at ℓ = {ell}: true system [{true.lower.value:.4g}, {true.upper.value:.4g}] "
        f"(its state x, on H_{{ℓ-1}} × U)"
    ]
    lines.append(_learned_gamma_line(learned.get("gamma_f", {})))
    return "\n".join(lines)


def _learned_gamma_line(gamma: Mapping[str, Any]) -> str:
    """The learned model's γ_f bracket in one line (``_learned_gamma_record``'s record)."""
    if not gamma.get("available"):
        return f"γ_f of the learned model: not computed ({gamma.get('why', 'no run')})"
    from canonid.analysis.certify import layer_norm_words

    layer_norms = layer_norm_words(gamma["layer_norms"])
    return (
        f"γ_f of the learned model (its state z, dim {gamma['state_dim']}, on the training "
        f"hull): sampled lower bound {_value(gamma['lower'])}, certified upper bound "
        f"{_value(gamma['branch_and_bound'])} (interval branch-and-bound, "
        f"{gamma['branch_and_bound']['details'].get('stop', '')}), "
        f"{_value(gamma['layer_norms'])} ({layer_norms}); so γ_f ≤ "
        f"{_value({'value': gamma.get('best_upper')})}"
    )
