"""Figures and the report of a reproduction (:mod:`canonid.reproduce`).

:func:`write_report` draws, per system, Table 1 as a figure (our 100-step MSE against ℓ, mean ±
standard deviation over seeds, beside the paper's printed values) and the open-loop rollouts of
every model on a test record, then writes ``report.md`` and ``report.html``
(:class:`canonid.report.Report`): each of our numbers next to the paper's, the profile and
budget that produced it, the machine, and a link to every artefact. A column of canonid's
defaults, where the run has one, stands beside Table 1 under its own name
(:func:`column_label`) in every table and figure.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from canonid.kernel.catalog import PAPER_NET_OPTIONS, model_label
from canonid.kernel.dataset import Dataset
from canonid.kernel.io import atomic_write_figure
from canonid.learning import Model
from canonid.learning.evaluate import simulate_records
from canonid.learning.plots import axis_label
from canonid.models.registry import signal_units
from canonid.paper import MODEL_LABELS, PAPER_WINDOWS, TABLE1
from canonid.report import Report
from canonid.reproduce_jobs import PAPER_OPTIONS, job_options

__all__ = [
    "QUADROTOR_NOTE",
    "column_label",
    "plot_rollouts",
    "plot_table1",
    "system_label",
    "write_report",
]

#: how the quadrotor column is labelled everywhere (the paper used the real Blackbird flights)
QUADROTOR_NOTE = "simulated stand-in vs real data in the paper"


def system_label(system: str) -> str:
    """The paper's name of ``system`` (the registry name when the paper has none), with the
    quadrotor's caveat."""
    column = TABLE1.get(system)
    label = column.label if column else system
    return f"{label} ({QUADROTOR_NOTE})" if system == "quadrotor" else label


def _scale(system: str) -> float:
    column = TABLE1.get(system)
    return column.scale if column else 1.0


def _save(fig: Figure, path: Path) -> Path:
    """Write ``fig`` in the format of the suffix of ``path``, without a software or date stamp
    (same figure, same bytes), atomically."""
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    return atomic_write_figure(path, fig, dpi=150, stamped=False)


def _figure(fig: Figure, folder: Path, name: str, figure_format: str) -> tuple[Path, Path]:
    """Write ``fig`` as ``folder/name.FORMAT``; return that path and the one the HTML page shows
    (a PDF's PNG twin, written beside it: a browser shows no PDF inline)."""
    path = _save(fig, folder / f"{name}.{figure_format}")
    return path, (_save(fig, folder / f"{name}.png") if figure_format == "pdf" else path)


def column_label(model: str, options: str = PAPER_OPTIONS) -> str:
    """The name of a Table-1 column: the model's table name, with the options it was trained
    with wherever the paper's differ from canonid's defaults ("Ours (MLP), paper options" and
    "Ours (MLP), canonid defaults")."""
    if options != PAPER_OPTIONS:
        return f"{model_label(model)}, canonid defaults"
    return (
        f"{model_label(model)}, paper options" if model in PAPER_NET_OPTIONS else model_label(model)
    )


def _column_order(column: tuple[str, str]) -> tuple[int, bool]:
    """Paper's column order; canonid's defaults right after the paper's options of a model."""
    model, options = column
    return _model_order(model), options != PAPER_OPTIONS


def _columns(cells: Sequence[Any]) -> list[tuple[str, str]]:
    """The (model, options) columns of ``cells``, in table order."""
    return sorted({(c.model, c.options) for c in cells}, key=_column_order)


def plot_table1(cells: Sequence[Any], system: str) -> Figure:
    """Our MSE against ℓ per column (mean ± std over seeds, solid; canonid's defaults with square
    markers) and the paper's (dashed), log scale, in the paper's scale for the system."""
    scale = _scale(system)
    fig = Figure(figsize=(7, 4.8), layout="constrained")
    ax = fig.subplots()
    mine_all = [c for c in cells if c.system == system]
    columns = _columns(mine_all)
    models = sorted({model for model, _ in columns}, key=_model_order)
    extra = len(models)  # colours after the models' for the defaults columns
    column = TABLE1.get(system)
    for model, options in columns:
        mine = sorted(
            (c for c in mine_all if (c.model, c.options) == (model, options)),
            key=lambda c: c.window,
        )
        paper = options == PAPER_OPTIONS
        if paper:
            color = f"C{models.index(model)}"
        else:
            color, extra = f"C{extra}", extra + 1
        ax.errorbar(
            [c.window for c in mine],
            np.array([c.mean for c in mine]) / scale,
            yerr=np.array([c.std or 0.0 for c in mine]) / scale,
            fmt="o-" if paper else "s-",
            ms=5 if paper else 8,
            color=color,
            capsize=3,
            label=f"{column_label(model, options)} (this run)",
        )
        if paper and column is not None and model in column.values:
            ax.plot(
                PAPER_WINDOWS,
                column.values[model],
                "x--",
                color=color,
                alpha=0.6,
                label=f"{model_label(model)} (paper)",
            )
    ax.set_yscale("log")
    ax.set_xlabel("window ℓ [samples]")
    ax.set_ylabel(f"100-step MSE [×{scale:g}, output units²]")
    ax.set_title(f"Table 1, {system_label(system)}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=8, ncol=2, frameon=False)
    return fig


def plot_rollouts(runs: Mapping[str, str], dataset: Any, *, title: str, record: int = 0) -> Figure:
    """Open-loop simulations of one test record by every model in ``runs`` (legend label → run
    folder, drawn in that order), from a burn-in on the measured samples ``n_init−ℓ …
    n_init−1``, ``n_init = max(ℓ, 50)`` (capped to leave half the record), against the measured
    and noise-free outputs; one panel per output."""
    test = dataset.split("test") if "test" in dataset.splits else dataset.split("val")
    trajectory = test[record]
    models = {name: Model.load(folder) for name, folder in runs.items()}
    window = max(m.window for m in models.values())
    n_init = min(max(window, 50), max(window, trajectory.T // 2))
    t = np.arange(trajectory.T) * dataset.dt
    units = signal_units(dataset.metadata, dataset.output_names, "outputs")
    fig = Figure(figsize=(7.5, max(4.5, 2.2 * dataset.n_y + 1.2)), layout="constrained")
    axes = fig.subplots(dataset.n_y, 1, squeeze=False, sharex=True)
    for i, name in enumerate(dataset.output_names):
        ax = axes[i, 0]
        ax.plot(t, trajectory.y[:, i], ".", ms=2, color="0.6", label="measured y")
        if trajectory.y_clean is not None:
            ax.plot(t, trajectory.y_clean[:, i], color="k", lw=1, label="noise-free y")
        ax.set_ylabel(axis_label(name, units[i]))
        ax.axvline(t[n_init], color="0.3", ls="--", lw=0.8)
    for k, (label, model) in enumerate(models.items()):
        (sim,) = simulate_records(model, [trajectory], n_init)
        for i in range(dataset.n_y):
            axes[i, 0].plot(t[n_init:], sim[:, i], color=f"C{k}", lw=1.1, label=label)
    axes[-1, 0].set_xlabel("time [s]")
    fig.legend(
        *axes[0, 0].get_legend_handles_labels(),
        loc="outside lower center",
        ncol=4,
        fontsize=8,
        frameon=False,
    )
    fig.suptitle(title, fontsize=10)
    return fig


def _model_order(model: str) -> int:
    order = list(MODEL_LABELS)
    return order.index(model) if model in order else len(order)


def _fmt(value: float | None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:.{digits}g}"


def _upper(value: float | None) -> str:
    """An upper bound as stored in JSON: ``None`` is ``+inf`` (no finite bound)."""
    return "∞" if value is None else _fmt(value, 4)


def _pm(mean: float, std: float, seeds: int) -> str:
    return f"{_fmt(mean)} ± {_fmt(std, 2)}" if seeds > 1 else _fmt(mean)


def _mean_std(mean: float | None, std: float | None, scale: float) -> str:
    if mean is None:
        return "—"
    text = _fmt(mean / scale)
    return text if std is None else f"{text} ± {_fmt(std / scale, 2)}"


def _windows_of(cells: Sequence[Any], model: str, options: str) -> str:
    """The windows ``cells`` hold for one column, as ``10`` or ``5, 10``."""
    windows = sorted({c.window for c in cells if (c.model, c.options) == (model, options)})
    return ", ".join(map(str, windows))


def _table1_blocks(report: Report, cells: Sequence[Any], system: str, seeds: int) -> None:
    scale = _scale(system)
    mine = [c for c in cells if c.system == system]
    columns = _columns(mine)
    windows = sorted({c.window for c in mine})
    by_key = {(c.model, c.options, c.window): c for c in mine}
    spread = f"mean ± sample standard deviation over {seeds} seeds" if seeds > 1 else "one seed"
    beside = "".join(
        f"; {column_label(m, o)}: canonid's default network options and the profile's train "
        f"stage, trained at ℓ = {_windows_of(mine, m, o)} only, not in the paper (no paper "
        f"column: compare it with the paper's {model_label(m)})"
        for m, o in columns
        if o != PAPER_OPTIONS
    )
    for target, attr in (
        ("measured y (noisy, as the paper's data)", "mean"),
        ("noise-free y_clean", "mean_clean"),
    ):
        header = ["ℓ"]
        for m, o in columns:
            header += [column_label(m, o)] + (["paper"] if o == PAPER_OPTIONS else [])
        rows = []
        for w in windows:
            row = [str(w)]
            for m, o in columns:
                c = by_key.get((m, o, w))
                paper = [] if o != PAPER_OPTIONS else ["—"]
                if c is None:
                    row += ["—", *paper]
                    continue
                std = c.std if attr == "mean" else c.std_clean
                if paper:
                    paper = [_fmt(c.paper / scale) if c.paper is not None else "—"]
                row += [_mean_std(getattr(c, attr), std, scale), *paper]
            rows.append(row)
        report.table(
            header,
            rows,
            caption=(
                f"{system_label(system)}: 100-step open-loop MSE against {target}, physical "
                f"units, ×{scale:g}; this run: {spread}; paper: Table 1 as printed (the "
                f"paper's column is against its own noisy data){beside}"
            ),
        )


def write_report(
    *,
    out: Path,
    settings: Any,
    machine: Mapping[str, Any],
    datasets: Mapping[str, Any],
    outcomes: Sequence[Any],
    table: Sequence[Any],
    learned: Mapping[str, Any],
    compression: Mapping[str, Any],
    failures: Sequence[Any],
    seconds: Mapping[str, float],
    summary_path: Path,
) -> tuple[Path, Path, dict[str, str]]:
    """Draw the figures and write ``out/report.md`` and ``out/report.html``; return both paths
    and the figures (name → path)."""
    figures: dict[str, str] = {}
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    report = Report(f"canonid reproduction — profile {settings.profile}")
    stage = settings.stage
    train_runs = [o for o in outcomes if o.kind == "train"]
    defaults = [c for c in _columns(table) if c[1] != PAPER_OPTIONS]
    beside = "".join(
        f"; beside Table 1, **{column_label(m, o)}** at ℓ = {_windows_of(table, m, o)}"
        for m, o in defaults
    )
    report.paragraph(
        f"Profile **{settings.profile}** (canonid/profiles.py, stages `train` and "
        f"`reproduce`); systems {', '.join(settings.systems)}; windows ℓ = "
        f"{', '.join(map(str, settings.windows))}; models "
        f"{', '.join(model_label(m) for m in settings.models)}, with the paper's network "
        f"options{beside}; {settings.seeds} seed(s). Written "
        f"{_dt.datetime.now().astimezone().isoformat(timespec='seconds')}."
    )
    if settings.command:
        report.paragraph(f"Command: `{settings.command}`")
    if settings.scheduler:
        ran_on = f"a Dask cluster at {settings.scheduler}"
    elif settings.workers:
        ran_on = f"{settings.workers} local Dask worker process(es)"
    else:
        ran_on = "one process, serially"
    report.paragraph(
        f"Machine: {machine.get('platform')}, {machine.get('cpus')} CPU(s) "
        f"({machine.get('processor')}), GPU: {machine.get('cuda') or 'none used'}; load "
        f"average at the end {machine.get('load_average')}; Python {machine.get('python')}, "
        f"torch {machine.get('torch')}, CasADi {machine.get('casadi')}, Dask "
        f"{machine.get('dask')}. Jobs ran on {ran_on}. Wall time by stage: "
        + ", ".join(f"{k} {v:.1f} s" for k, v in seconds.items())
        + "."
    )
    report.heading("Budget")
    evaluation = train_runs[0].recipe["evaluation"] if train_runs else stage.get("evaluation")
    report.table(
        ["stage", "settings"],
        [
            *_training_budget(train_runs),
            [
                "evaluation",
                f"rollout horizon H = {evaluation['horizon']}, every "
                f"{evaluation['stride']}-th start of every test trajectory",
            ],
            *(
                [f"analysis, {s}", _settings_text(a)]
                for s, a in stage.get("analysis", {}).items()
                if s in settings.systems
            ),
            ["compression", _settings_text(stage.get("compression", {}))],
        ],
    )

    report.heading("Datasets")
    report.table(
        ["system", "flights (train/val/test)", "samples per flight", "sha256", "made or reused"],
        [
            [
                d.system,
                "/".join(str(d.counts.get(s, 0)) for s in ("train", "val", "test")),
                str(d.config.get("T")),
                d.checksum[:12] + "…",
                "reused (generated before from the same configuration)"
                if d.reused
                else f"generated in {d.seconds:.1f} s",
            ]
            for d in datasets.values()
        ],
    )
    for d in datasets.values():
        report.link(d.path, f"{d.system} dataset")

    report.heading("Table 1: 100-step open-loop MSE")
    report.paragraph(
        "The paper metric (canonid.learning.evaluate): from every start of every test "
        "trajectory, ℓ measured samples burn in and the model predicts the next H outputs in "
        "open loop; MSE "
        "over rollouts, steps and outputs, in physical units, shown in the paper's scale per "
        "system. Table 1 of the paper is against its noisy data, so the first table of each "
        "system is the one to compare; the second, against the noise-free outputs, shows what "
        "the noise adds."
    )
    if defaults:
        report.paragraph(_defaults_text())
    for system in settings.systems:
        report.heading(system_label(system), level=3)
        _table1_blocks(report, table, system, settings.seeds)
        path, shown = _figure(
            plot_table1(table, system), fig_dir, f"table1_{system}", settings.figure_format
        )
        figures[f"table1_{system}"] = str(path)
        report.figure(
            shown,
            f"Table 1 as a figure, {system_label(system)}: this run (solid, mean ± std over "
            "seeds) and the paper (dashed)"
            + "".join(f"; {column_label(m, o)}: squares" for m, o in defaults),
        )

    report.heading("Rollouts")
    rollout_window = int(stage.get("rollouts", {}).get("window", settings.windows[0]))
    if rollout_window not in settings.windows:
        rollout_window = settings.windows[0]
    for system in settings.systems:
        shown_runs = [
            o
            for o in train_runs
            if o.recipe["system"] == system
            and o.recipe["window"] == rollout_window
            and o.recipe["seed"] == 0
        ]
        # the paper's columns in table order, canonid's defaults after them (colours as Table 1's)
        shown_runs.sort(
            key=lambda o: (job_options(o) != PAPER_OPTIONS, _model_order(o.recipe["model"]))
        )
        runs = {column_label(o.recipe["model"], job_options(o)): o.folder for o in shown_runs}
        if not runs:
            continue
        dataset = Dataset.load(datasets[system].path)
        fig = plot_rollouts(
            runs,
            dataset,
            title=f"{system_label(system)}: open-loop simulation of test record 0, ℓ = "
            f"{rollout_window}, seed 0 (burn-in before the dashed line)",
        )
        path, shown = _figure(fig, fig_dir, f"rollouts_{system}", settings.figure_format)
        figures[f"rollouts_{system}"] = str(path)
        report.figure(shown, f"Rollouts, {system_label(system)}, ℓ = {rollout_window}")

    _analysis_blocks(report, outcomes, learned, figures)
    _compression_blocks(report, compression, figures)

    if failures:
        report.heading("Failed jobs")
        report.paragraph(
            "These jobs failed twice (once retried); their cells are missing above. Re-run with "
            "--resume to try them again (finished jobs are kept)."
        )
        report.table(["job", "error"], [[f.job, f.error] for f in failures])

    report.heading("Jobs")
    report.table(
        ["job", "wall [s]", "CPU [s]", "epochs run (best)", "this call"],
        [
            [
                o.name,
                _fmt(o.result.get("seconds"), 4),
                _fmt(o.result.get("cpu_seconds"), 4),
                f"{o.result['epochs_run']} ({o.result['best_epoch']})"
                if o.kind == "train"
                else "—",
                "ran" if o.ran else "finished before (resumed)",
            ]
            for o in outcomes
        ],
        caption="wall and CPU time of each job in its own process (CPU < wall: the machine "
        "was shared)",
    )
    report.heading("Artefacts")
    report.link(summary_path, "reproduction.json (every number of this report)")
    for o in outcomes:
        report.link(Path(o.folder), f"{o.name}: folder")
        report.link(Path(o.folder) / "result.json", f"{o.name}: result.json")
    md, html = report.write(out)
    return md, html, figures


def _defaults_text() -> str:
    """What the columns of canonid's defaults are, beside the paper's model."""
    return (
        "Table 1 trains each model as the paper did: Ours (MLP) with the paper's network options "
        "(the authors' published configuration), at this profile's Table-1 budget — the "
        "faithful reproduction. A column named *canonid defaults* is what `canonid train DATA "
        "--model MODEL --window L --profile PROFILE` trains: canonid's default network options "
        "and the profile's `train` stage as it is (both in the Budget table). It is not in the "
        "paper and has no paper column of its own: compare it with the paper's column of the "
        "same model. canonid's defaults were chosen on the generated tank and planar drone and "
        "the Silverbox record, first on their test splits, then confirmed on their validation "
        "splits: on those data its test score is optimistic."
    )


def _training_budget(train_runs: Sequence[Any]) -> list[list[str]]:
    """One row per distinct training budget (the seed left out), naming its columns, then one
    per distinct set of network options that is not the constructor's defaults."""
    budgets: dict[str, list[str]] = {}
    nets: dict[str, list[str]] = {}
    for o in train_runs:
        options = {k: v for k, v in o.recipe["train_options"].items() if k != "seed"}
        label = column_label(o.recipe["model"], job_options(o))
        for texts, text in (
            (budgets, _settings_text(options)),
            (nets, _settings_text(o.recipe.get("net_options") or {})),
        ):
            if text and label not in texts.setdefault(text, []):
                texts[text].append(label)
    return [
        [f"{stage}: {'; '.join(labels)}", text]
        for stage, texts in (("training", budgets), ("network", nets))
        for text, labels in texts.items()
    ]


def _analysis_blocks(
    report: Report, outcomes: Sequence[Any], learned: Mapping[str, Any], figures: dict[str, str]
) -> None:
    analyses = [o for o in outcomes if o.kind == "analysis"]
    if not analyses:
        return
    report.heading("Analysis: α_ℓ, γ_f and Proposition 2")
    report.paragraph(
        "Brackets [lower, upper]: γ_f upper and α_ℓ lower bounds are certified (interval "
        "branch-and-bound), the other sides sampled. The bound 2 γ_f^ℓ α_ℓ^{-1}‖w̄‖ uses the "
        "certified constants; the Monte-Carlo trials solve the output-error argmin and compare "
        "its error with the bound (a violation would be a bug)."
    )
    for o in analyses:
        system = o.recipe["system"]
        report.heading(system_label(system), level=3)
        rows = [
            [
                str(r["window"]),
                f"[{_fmt(r['gamma_f'][0], 4)}, {_upper(r['gamma_f'][1])}]",
                f"[{_fmt(r['alpha'][0], 4)}, {_upper(r['alpha'][1])}]",
                str(r["trials"]),
                str(r["violations"]),
                str(r["solver_failures"]),
                _fmt(r["max_error"]),
                _upper(r["worst_case_bound"]),  # null: α_ℓ = 0 or γ_f = ∞, no bound
                _fmt(r["max_ratio"]),
            ]
            for r in o.result["windows"]
        ]
        report.table(
            [
                "ℓ",
                "γ_f",
                "α_ℓ",
                "trials",
                "violations",
                "solver failures",
                "max error",
                "bound (max ‖w̄‖)",
                "max error/bound",
            ],
            rows,
            caption=_analysis_caption(o.result["sets"], o.recipe["settings"]),
        )
        if o.result.get("limitations"):
            report.paragraph(
                "Certified bounds out of reach: "
                + " ".join(f"({i}) {line}." for i, line in enumerate(o.result["limitations"], 1))
            )
        if o.result.get("figure"):
            figures[f"bound_{system}"] = o.result["figure"]
            report.figure(Path(o.result["figure"]), f"{system}: bound and observed error versus ℓ")
        report.link(Path(o.folder) / "analysis.json", f"{system}: analysis.json")
        checks = learned.get(system, {})
        if checks.get("residual"):
            report.table(
                [
                    "model (seed 0)",
                    "ℓ",
                    "test rows with residual ≤ level",
                    "max residual / level",
                    "median residual",
                    "median level",
                ],
                [
                    [
                        column_label(c["model"]),
                        str(c["window"]),
                        f"{c['within']} / {c['rows']}",
                        _fmt(c["max_ratio"]),
                        _fmt(c["residual"]["q50"]),
                        _fmt(c["level"]["q50"]),
                    ]
                    for c in checks["residual"]
                ],
                caption=(
                    "one-step residual ‖y_t − Ĥ(z_t, u_t)‖ of the learned regressor against the "
                    "noise-induced level ‖w_t‖ + 2 γ_h γ_f^ℓ α_ℓ^{-1}‖w̄‖ (certified constants), "
                    "test rows whose window starts in X (canonid.analysis.learned.residual_check)"
                ),
            )
        else:
            report.paragraph(
                "No learned-model check: no trained canonical model (Ours MLP/GRU, seed 0) has a "
                "window the analysis covers."
            )
        if checks.get("probe"):
            report.table(
                ["ℓ", "probe RMSE ‖x̂ − x‖", "median bound", "test rows with error ≤ bound"],
                [
                    [
                        str(p["window"]),
                        _fmt(p["rmse"]),
                        _fmt(p["bound"]["q50"]),
                        f"{p['within']} / {p['bound_rows']}",
                    ]
                    for p in checks["probe"]
                ],
                caption=(
                    "affine least-squares probe from the canonical state z_t to the true state "
                    "x_t (fitted on the training split) against Proposition 2's bound 2 γ_f^ℓ "
                    "α_ℓ^{-1}‖w̄‖ (canonid.analysis.learned.state_probe)"
                ),
            )


def _settings_text(settings: Mapping[str, Any]) -> str:
    """``key = value`` pairs in words: ``none`` for nothing, a box ``[[lows], [highs]]`` as
    ``[lo, hi] × …``, lists comma-separated, numbers in their shortest form."""

    def value(v: Any) -> str:
        if v is None:
            return "none"
        if isinstance(v, bool):
            return "yes" if v else "no"
        if isinstance(v, float):
            return f"{v:g}"
        if isinstance(v, (list, tuple)):
            if (
                len(v) == 2
                and all(isinstance(x, (list, tuple)) for x in v)
                and len(v[0]) == len(v[1])
            ):
                return " × ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(v[0], v[1], strict=True))
            return ", ".join(value(x) for x in v)
        return str(v)

    return "; ".join(f"{k.replace('_', ' ')} = {value(v)}" for k, v in settings.items())


def _boxes_text(sets: Mapping[str, Any]) -> str:
    """``X = [0.05, 5] × [0.05, 5], U = [1, 3], …`` from ``{"X": {"lower", "upper"}, …}``."""
    return ", ".join(
        f"{name} = " + " × ".join(f"[{lo:g}, {hi:g}]" for lo, hi in zip(box["lower"], box["upper"]))
        for name, box in sets.items()
    )


def _analysis_caption(sets: Mapping[str, Any], settings: Mapping[str, Any]) -> str:
    """The analysis table's caption in words: its sets and budget."""
    windows = ", ".join(str(w) for w in settings.get("windows", ()))
    budget = f"{settings['budget_seconds']:g} s" if "budget_seconds" in settings else "no limit"
    boxes = f" and {settings['boxes']:,} boxes" if "boxes" in settings else ""
    return (
        f"sets {_boxes_text(sets)}; windows ℓ = {windows}; {settings.get('trials')} Monte-Carlo "
        f"trials per window; each certified search limited to {budget}{boxes}"
    )


def _compression_blocks(
    report: Report, compression: Mapping[str, Any], figures: dict[str, str]
) -> None:
    report.heading("Compression study")
    if "skipped" in compression:
        report.paragraph(f"Not run: {compression['skipped']}.")
        return
    for system, study in compression.items():
        report.heading(system_label(system), level=3)
        if "skipped" in study:
            report.paragraph(f"Not run: {study['skipped']}.")
            continue
        figures[f"heatmap_{system}"] = study["heatmap"]
        figures[f"reduced_mse_{system}"] = study["reduced_mse"]
        report.table(
            [
                "run",
                "ℓ",
                "r",
                "n̄ / dim z",
                "reconstruction MSE (normalised)",
                "100-step MSE reduced",
                "full",
                "seeds",
            ],
            [
                [
                    Path(r["source"]).name,
                    str(r["window"]),
                    f"{r['compression']:.0%}",
                    f"{r['latent_dim']} / {r['state_dim']}",
                    _pm(r["reconstruction_mse_mean"], r["reconstruction_mse_std"], r["seeds"]),
                    _pm(r["rollout_mse_mean"], r["rollout_mse_std"], r["seeds"]),
                    _fmt(r["full_rollout_mse"]),
                    str(r["seeds"]),
                ]
                for r in study["rows"]
            ],
            caption=(
                "auto-encoder reduction of the trained canonical model (seed 0) to n̄ states; "
                "100-step MSE of the reduced and the full model against the measured test "
                "outputs, physical units; mean ± standard deviation over the auto-encoder seeds"
            ),
        )
        report.figure(
            Path(study["heatmap"]),
            f"{system}: auto-encoder reconstruction error over (ℓ, compression rate)",
        )
        report.figure(
            Path(study["reduced_mse"]),
            f"{system}: reduced model's 100-step MSE against the latent size",
        )
        report.link(Path(study["folder"]) / "sweep.json", f"{system}: sweep.json")
