"""``canonid analyze`` — the theory, numerically: γ_f, γ_h, α_ℓ brackets and Proposition 2.

Writes ``analysis.json`` (schema: :data:`canonid.analysis.report.SCHEMA`, copied into the file), the
figure ``bound_vs_window.png`` ("bound and observed error versus ℓ", log scale) and prints a
table. Without a system, ``--run RUN`` analyses the learned model alone (data with no registered
true system, e.g. measurements): γ_f of its ``f`` in z on its training hull, written to
``learned_analysis.json``. Sets are given as ``lo:hi`` per component separated by commas
(``--X 0.05:5,0.05:5``); one ``lo:hi`` applies to every component.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from canonid.analysis.estimate import Budget
from canonid.analysis.report import AnalysisReport, analyze
from canonid.commands import _data, _paths
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import CanonidError, DataError, SetError
from canonid.kernel.io import atomic_write_json, jsonable
from canonid.models.registry import get_system
from canonid.models.sets import Box
from canonid.runfolder import recipe_of


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "analyze",
        description=(
            "Estimate the Lipschitz constant γ_f and the observability constant α_ℓ of a "
            "registered system (certified bounds by interval branch-and-bound, sampled bounds "
            "by optimisation), evaluate Proposition 2's bound 2 γ_f^ℓ α_ℓ^-1 ‖w̄‖ and check it "
            "by Monte-Carlo trials of the output-error estimator. Writes analysis.json and the "
            "figure bound_vs_window.png to --out. Without SYSTEM, --run RUN bounds γ_f of the "
            "learned model alone (for data that no registered system produced)."
        ),
    )
    p.add_argument(
        "system",
        nargs="?",
        help="registered system name (see `canonid systems`); leave out with --run to analyse "
        "the learned model alone",
    )
    win = p.add_mutually_exclusive_group()
    win.add_argument("--window", type=int, metavar="L", help="one window ℓ >= 1")
    win.add_argument(
        "--windows", metavar="A-B", help="a range of windows, e.g. 1-10, or a list 2,5,10"
    )
    p.add_argument(
        "--trials", type=int, default=1000, help="Monte-Carlo trials per window (default 1000)"
    )
    p.add_argument(
        "--budget",
        type=float,
        default=20.0,
        metavar="SECONDS",
        help="wall-clock limit of each certified branch-and-bound search (default 20)",
    )
    p.add_argument(
        "--boxes",
        type=int,
        metavar="N",
        help="also stop each certified search after N boxes: with a budget in boxes (and the "
        "same --seed) the numbers do not depend on the machine's speed",
    )
    p.add_argument("--X", dest="X", metavar="BOX", help="state set, e.g. 0.05:5,0.05:5")
    p.add_argument("--U", dest="U", metavar="BOX", help="input set, e.g. 1:3")
    p.add_argument("--W", dest="W", metavar="BOX", help="noise set, e.g. -0.02:0.02")
    p.add_argument("--tol", type=float, default=0.05, help="relative tolerance of γ searches")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument(
        "--run",
        type=Path,
        metavar="RUN",
        help="a trained model's run folder: adds its one-step residual and a state probe, "
        "checked against the bound, on the test split of its data",
    )
    p.add_argument(
        "--learned-gamma",
        action="store_true",
        help="with --run: also bound γ_f of the learned model on its training hull (sampled, "
        "interval branch-and-bound within --budget, product of layer norms; about a minute "
        "for a 3 × 256 network); always on without SYSTEM",
    )
    p.add_argument(
        "--data",
        type=Path,
        metavar="FILE",
        help="data for --run: a canonid dataset, or CSV / .npz read with the run's data options "
        "(default: the run's own data, split as training split them)",
    )
    p.add_argument(
        "--out",
        type=_paths.folder,
        help="output folder (default runs/analyze-SYSTEM, or RUN/analysis without SYSTEM)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def parse_windows(text: str) -> list[int]:
    """``"1-10"`` → 1…10, ``"2,5,10"`` → [2, 5, 10]."""
    try:
        if "-" in text:
            lo, hi = (int(v) for v in text.split("-", 1))
            values = list(range(lo, hi + 1))
        else:
            values = [int(v) for v in text.split(",")]
    except ValueError:
        raise SetError(
            f"--windows: expected A-B or a comma list of integers, got {text!r}"
        ) from None
    if not values or min(values) < 1:
        raise SetError(f"--windows: windows must be integers >= 1 (A <= B), got {text!r}")
    return values


def parse_box(text: str, dim: int, name: str) -> Box:
    """``"lo:hi,lo:hi"`` (one pair per component, or one pair for all) → :class:`Box`."""
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


def load_trained_model(run_dir: Path) -> Any:
    """The model saved in ``run_dir`` (``canonid.learning.Model``).

    Its ``export()`` is the identification layer's contract with the analysis: an object with
    ``H(z, u) -> y``, ``window``, ``n_u`` and ``n_y`` (see ``learning/export.py``).
    """
    from canonid.learning import Model  # torch, only when a learned model is checked

    return Model.load(run_dir)


def learned_checks(
    model: Any,
    dataset: Dataset,
    report: AnalysisReport,
    *,
    source: Mapping[str, str],
    split: str | None = None,
) -> dict[str, Any]:
    """The report's checks of ``model`` (:meth:`AnalysisReport.learned_checks`) on split
    ``split`` of ``dataset`` (default ``test``, else its only split), as ``analysis.json`` holds
    them."""
    ell = int(model.window)
    if all(r.window != ell for r in report.results):
        raise SetError(f"the model has window ℓ = {ell}, which the analysis did not cover")
    _, test = _data.pick_split(dataset, split, where=source.get("data", "data"))
    checks = report.learned_checks([model], list(dataset.splits.get("train", ())), test)
    out: dict[str, Any] = {
        **source,
        "model": repr(model),
        "window": int(model.window),
        "residual": checks.residuals[0].to_dict(),
    }
    if checks.probes:
        out["probe"] = checks.probes[0].to_dict()
    return out


def _learned_source(
    run_dir: Path, data: Path | None, system: Any
) -> tuple[Any, Dataset, str, dict[str, str]]:
    """The run's exported model, the data that check it, their split and the source labels;
    refuses a run whose signals do not match ``system``."""
    trained = load_trained_model(run_dir)
    model, info = trained.export(), trained.info
    n_u, n_y = int(model.n_u), int(model.n_y)
    if (n_u, n_y) != (system.n_u, system.n_y):
        raise SetError(
            f"--run {run_dir}: the run has n_u={n_u}, n_y={n_y}; {system.name} has "
            f"{system.n_u}, {system.n_y}"
        )
    dataset, data_path, split = _data.scoring_data(run_dir, data, {}, split=None, model=info)
    name, test = _data.pick_split(dataset, split, where=data_path)
    if any(tr.y_clean is None for tr in test):
        raise DataError(
            f"--run: the residual check needs the noise w = y − y_clean, which {data_path} "
            f"[{name}] does not hold; give --data a canonid dataset or .npz with y_clean"
        )
    return model, dataset, name, {"run": str(run_dir), "data": data_path, "split": name}


def learned_gamma_record(
    model: Any, run_dir: Path, data: Path | None, *, budget: Budget, tol: float, seed: int
) -> dict[str, Any]:
    """γ_f of the run's model in its state on its training hull (:mod:`canonid.analysis.certify`),
    or why there is none (only canonical models are built as CasADi systems)."""
    from canonid.analysis.certify import learned_gamma
    from canonid.learned import learned_system

    if not hasattr(model, "network"):
        return {"available": False, "why": "the model does not export its weights"}
    try:
        model.network()
    except CanonidError as exc:  # only canonical models export
        return {"available": False, "why": str(exc)}
    # the training hull: the run's own training data when its recipe names them
    own = recipe_of(run_dir) is not None
    system = learned_system(run_dir, data=None if own else data).system
    gamma = learned_gamma(system, budget=budget, tol=tol, seed=seed)
    return {"available": True, "state_dim": system.n_x, **gamma.to_dict()}


def _value(record: Mapping[str, Any]) -> str:
    value = record.get("value")
    return "∞" if value is None else f"{value:.4g}"


def gamma_lines(report: AnalysisReport) -> str:
    """The true system's γ_f bracket at the model's window beside the learned model's."""
    learned = report.learned
    ell = int(learned["window"])
    true = next(r for r in report.results if r.window == ell).gamma_f
    lines = [
        f"γ_f at ℓ = {ell}: true system [{true.lower.value:.4g}, {true.upper.value:.4g}] "
        f"(its state x, on H_{{ℓ-1}} × U)"
    ]
    lines.append(learned_gamma_line(learned.get("gamma_f", {})))
    return "\n".join(lines)


def learned_gamma_line(gamma: Mapping[str, Any]) -> str:
    """The learned model's γ_f bracket in one line (``learned_gamma_record``'s record)."""
    if not gamma.get("available"):
        return f"γ_f of the learned model: not computed ({gamma.get('why', 'no run')})"
    return (
        f"γ_f of the learned model (its state z, dim {gamma['state_dim']}, on the training "
        f"hull): sampled lower bound {_value(gamma['lower'])}, certified upper bound "
        f"{_value(gamma['branch_and_bound'])} (interval branch-and-bound, "
        f"{gamma['branch_and_bound']['details'].get('stop', '')}), "
        f"{_value(gamma['layer_norms'])} (product of layer norms, loose); so γ_f ≤ "
        f"{_value({'value': gamma.get('best_upper')})}"
    )


def learned_only(args: argparse.Namespace) -> int:
    """``canonid analyze --run RUN`` without a system: γ_f of the learned model alone."""
    for flag, value in (("--windows", args.windows), ("--X", args.X), ("--U", args.U)):
        if value is not None:
            raise SetError(f"{flag} applies to a registered SYSTEM; the run's model has its own")
    if args.W is not None:
        raise SetError("--W applies to a registered SYSTEM")
    check_numbers(args)
    budget = Budget(seconds=args.budget, boxes=args.boxes or 10**9)
    model = load_trained_model(args.run).export()
    if args.window is not None and args.window != int(model.window):
        raise SetError(f"--window {args.window}: the run's model has window ℓ = {model.window}")
    out = _paths.check_folder(args.out or args.run / "analysis")
    record = learned_gamma_record(
        model, args.run, args.data, budget=budget, tol=args.tol, seed=args.seed
    )
    if not record["available"]:
        raise SetError(f"--run {args.run}: {record['why']}")
    body = {
        "format": "canonid-learned-analysis",
        "run": str(args.run),
        "data": None if args.data is None else str(args.data),
        "model": repr(model),
        "window": int(model.window),
        "gamma_f": record,
    }
    path = atomic_write_json(out / "learned_analysis.json", jsonable(body))
    print(
        f"learned model ({body['model']}), ℓ = {body['window']}; no registered system, so no "
        "α_ℓ and no Proposition 2 bound (they need the true system)"
    )
    print(learned_gamma_line(record))
    print(f"analysis written to {path.resolve()}")
    return 0


def check_numbers(args: argparse.Namespace) -> None:
    """The numeric options every analysis shares, each checked with its flag's name."""
    if args.trials < 0:
        raise SetError(f"--trials must be >= 0, got {args.trials}")
    if not args.budget > 0:
        raise SetError(f"--budget must be a positive number of seconds, got {args.budget}")
    if not args.tol > 0:
        raise SetError(f"--tol must be a positive relative tolerance, got {args.tol}")
    if args.seed < 0:
        raise SetError(f"--seed must be an integer >= 0, got {args.seed}")
    if args.boxes is not None and args.boxes < 1:
        raise SetError(f"--boxes must be an integer >= 1, got {args.boxes}")


def run(args: argparse.Namespace) -> int:
    if args.window is not None and args.window < 1:
        raise SetError(f"--window must be an integer >= 1, got {args.window}")
    if args.system is None:
        if args.run is None:
            raise SetError(
                "give a registered SYSTEM (see `canonid systems`), or --run RUN to analyse a "
                "learned model alone"
            )
        return learned_only(args)
    system = get_system(args.system)
    if args.window is None and args.windows is None:
        raise SetError("one of --window L or --windows A-B is required with a SYSTEM")
    windows = [args.window] if args.window is not None else parse_windows(args.windows)
    check_numbers(args)
    if args.data is not None and args.run is None:
        raise SetError("--data applies to --run RUN only")
    model, dataset, split = None, None, None
    source: dict[str, str] = {}
    if args.run is not None:
        model, dataset, split, source = _learned_source(args.run, args.data, system)
        windows = sorted({*windows, int(model.window)})
    X = parse_box(args.X, system.n_x, "X") if args.X else system.X
    U = parse_box(args.U, system.n_u, "U") if args.U else system.U
    W = parse_box(args.W, system.n_y, "W") if args.W else system.W
    out = _paths.check_folder(args.out or Path("runs") / f"analyze-{system.name}")
    budget = Budget(seconds=args.budget, boxes=args.boxes or 10**9)

    bar = None
    if not args.quiet:
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

    try:
        report = analyze(
            system,
            windows,
            X=X,
            U=U,
            W=W,
            trials=args.trials,
            budget=budget,
            gamma_tol=args.tol,
            seed=args.seed,
            progress=progress,
        )
    finally:
        if bar is not None:
            bar.close()
    if model is not None and dataset is not None:
        report.learned = learned_checks(model, dataset, report, source=source, split=split)
        report.learned["gamma_f"] = (
            learned_gamma_record(
                model, args.run, args.data, budget=budget, tol=args.tol, seed=args.seed
            )
            if args.learned_gamma
            else {"available": False, "why": "not asked for (--learned-gamma)"}
        )
    json_path = report.write_json(out / "analysis.json")
    print(report.table())
    if report.learned:
        res = report.learned["residual"]
        print(
            f"learned model ({report.learned['model']}), ℓ = {report.learned['window']}: "
            f"one-step residual within the noise-induced level on {res['within']} of "
            f"{res['rows']} test rows ({res['excluded']} rows start outside X)"
        )
        print(gamma_lines(report))
    lines = [f"analysis written to {json_path.resolve()}"]
    if report.checks:
        figure = report.figure(out / "bound_vs_window.png")
        lines.append(f"  figure: {figure.resolve()}")
    print("\n".join(lines))
    violations = sum(c.violations for c in report.checks)
    if violations:
        print(
            f"warning: {violations} violation(s) of Proposition 2 with certified constants — "
            "this is a bug, please report it with analysis.json",
            file=sys.stderr,
        )
        return 1
    return 0
