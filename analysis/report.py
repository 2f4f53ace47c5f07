"""One analysis of a system over a range of windows: constants, bound checks, JSON, table, figure.

:func:`analyze` computes, for each window ``ℓ``:

* the certified hull ``H_{ℓ−1}`` of the states reachable from X (:mod:`canonid.analysis.reach`);
* γ_f on ``H_{ℓ−1} × U`` and γ_h on ``H_ℓ × U`` (sampled lower bound, certified upper bound;
  where a hull has no finite certified box within the budget, the upper bound is the trivial
  ``∞`` and the lower bound is sampled on ``X ⊆ H``);
* α_ℓ on ``X × U^ℓ`` (sampled upper bounds, the best certified lower bound, using
  ``α_ℓ ≥ α_k`` for ``k < ℓ``);
* the Monte-Carlo check of Proposition 2 with the certified constants (γ_f upper, α_ℓ lower);

and :class:`AnalysisReport` writes ``analysis.json`` (schema in :data:`SCHEMA`), a text table,
the list of certified bounds that are out of reach and why (:mod:`canonid.analysis.limits`) and the
figure "bound and observed error versus ℓ". Every certified search (each hull step, each γ
search, each α pair search) stops at the budget's boxes or seconds and returns what it has;
the sampled bounds and the Monte-Carlo check are always computed.
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import casadi as ca
import numpy as np

from canonid.analysis.bound import BoundCheck, BoundConstants, check_bound
from canonid.analysis.estimate import Bracket, Budget, Estimate
from canonid.analysis.learned import ProbeResult, ResidualCheck, residual_check, state_probe
from canonid.analysis.limits import limitations
from canonid.analysis.lipschitz import lipschitz_bracket, lipschitz_lower
from canonid.analysis.maps import check_window
from canonid.analysis.observability import alpha_bracket
from canonid.analysis.reach import ReachableHulls, reach
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import DataError, SetError
from canonid.kernel.io import atomic_write_figure, atomic_write_json, jsonable, read_json
from canonid.models.base import System
from canonid.models.registry import get_system
from canonid.models.sets import Box

__all__ = ["SCHEMA", "AnalysisReport", "Exported", "LearnedChecks", "analyze"]

Progress = Callable[[str, float], None]

#: the documented layout of ``analysis.json`` (written into the file itself)
SCHEMA: dict[str, Any] = {
    "name": "canonid.analysis",
    "version": 1,
    "fields": {
        "system": "the system description (canonid.models.System.describe())",
        "sets": "boxes X, U, W used (lower/upper per component)",
        "windows": "the windows ℓ analysed",
        "hulls": (
            "per ℓ: the certified box H_{ℓ-1} ⊇ states reachable from X in ℓ-1 steps (null: no "
            "finite certified box within the budget)"
        ),
        "reach": (
            "the hull search: per step {step, boxes, stop, seconds}, and unbounded: why the "
            "hulls stop being finite (null when they do not); hulls: H_0, H_1, ... as far as "
            "they are finite; requested: the number of steps asked for"
        ),
        "limitations": "sentences: which certified bounds are out of reach, and why",
        "estimates": (
            "list of records {quantity: gamma_f|gamma_h|alpha, window, value (null = +inf), "
            "kind: lower|upper|estimate, method, seconds, sets, budget, details}; gamma_f for "
            "window ℓ holds on H_{ℓ-1}×U, gamma_h on H_ℓ×U, alpha on X×U^ℓ"
        ),
        "bound_checks": (
            "list of records {window, trials, violations, solver_failures, max_ratio "
            "(error/bound, solver failures excluded; null when the bound is infinite), "
            "ratio_quantiles, max_error, median_error, worst_case_bound, max_ratio_estimated, "
            "constants: the gamma_f/alpha records used and factor = gamma_f^ℓ/alpha}"
        ),
        "learned": (
            "optional: residual and probe checks of a trained model; gamma_f: its own γ_f in "
            "its state on its training hull (lower, branch_and_bound, layer_norms, best_upper)"
        ),
        "settings": "trials, budget, tolerances, seed",
        "software": "versions",
    },
}


@dataclass(frozen=True)
class WindowResult:
    """Everything computed for one window."""

    window: int
    hull: Box | None
    gamma_f: Bracket
    gamma_h: Bracket
    alpha: Bracket
    check: BoundCheck | None


class Exported(Protocol):
    """A learned model as the checks see it: ``H(z, u) -> y`` in numpy and its window ℓ
    (what ``canonid.learning.Model.export()`` returns)."""

    window: int

    def H(self, z: np.ndarray, u: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class LearnedChecks:
    """What :meth:`AnalysisReport.learned_checks` found: one residual check per model (in the
    order given) and one state probe per window (empty when the data carry no states)."""

    residuals: list[ResidualCheck]
    probes: list[ProbeResult]


@dataclass
class AnalysisReport:
    """The result of :func:`analyze`, with its JSON, table and figure."""

    system: System
    X: Box
    U: Box
    W: Box
    results: list[WindowResult]
    settings: Mapping[str, Any]
    seconds: float
    reach: ReachableHulls | None = None
    learned: dict[str, Any] = field(default_factory=dict)

    @property
    def estimates(self) -> list[Estimate]:
        out: list[Estimate] = []
        for r in self.results:
            for b in (r.gamma_f, r.gamma_h, r.alpha):
                out.extend([b.lower, b.upper])
        return out

    @property
    def limitations(self) -> list[str]:
        """Which certified bounds are out of reach, and why (:mod:`canonid.analysis.limits`)."""
        return limitations(self.system, self.results, reach=self.reach)

    @property
    def checks(self) -> list[BoundCheck]:
        return [r.check for r in self.results if r.check is not None]

    def to_dict(self) -> dict[str, Any]:
        """The content of ``analysis.json`` (see :data:`SCHEMA`)."""
        return {
            "schema": SCHEMA,
            "system": self.system.describe(),
            "sets": {"X": self.X.to_dict(), "U": self.U.to_dict(), "W": self.W.to_dict()},
            "windows": [r.window for r in self.results],
            "hulls": {
                str(r.window): None if r.hull is None else r.hull.to_dict() for r in self.results
            },
            "reach": None
            if self.reach is None
            else {
                "steps": list(self.reach.steps),
                "unbounded": self.reach.unbounded,
                "hulls": [h.to_dict() for h in self.reach.hulls],
                "requested": self.reach.requested,
            },
            "limitations": self.limitations,
            "estimates": [e.to_dict() for e in self.estimates],
            "bound_checks": [c.to_dict() for c in self.checks],
            "learned": self.learned,
            "settings": dict(self.settings),
            "seconds": round(self.seconds, 3),
            "software": _versions(),
        }

    def write_json(self, path: str | Path) -> Path:
        return atomic_write_json(path, jsonable(self.to_dict()))

    @classmethod
    def from_json(cls, path: str | Path, *, system: System | None = None) -> AnalysisReport:
        """The report written by :meth:`write_json` to ``path`` (without the per-trial arrays
        of the bound checks). ``system``: the analysed system when it is not in the registry
        under the name the file gives. A file without the hulls of the reach search (written
        before they were) gives a report without it (``reach = None``)."""
        body = read_json(path, what="analysis")
        if system is None:
            name = body.get("system", {}).get("name") if isinstance(body, dict) else None
            if not isinstance(name, str):
                raise DataError(f"{path} is not an analysis.json of canonid (no system name)")
            system = get_system(name)
        try:
            estimates = {
                (e["window"], e["quantity"], e["kind"]): Estimate.from_dict(e)
                for e in body["estimates"]
            }
            checks = {c["window"]: BoundCheck.from_dict(c) for c in body["bound_checks"]}
            hulls = body["hulls"]

            def bracket(ell: int, quantity: str) -> Bracket:
                return Bracket(
                    estimates[(ell, quantity, "lower")], estimates[(ell, quantity, "upper")]
                )

            results = [
                WindowResult(
                    ell,
                    None if hulls[str(ell)] is None else Box.from_dict(hulls[str(ell)]),
                    gamma_f=bracket(ell, "gamma_f"),
                    gamma_h=bracket(ell, "gamma_h"),
                    alpha=bracket(ell, "alpha"),
                    check=checks.get(ell),
                )
                for ell in body["windows"]
            ]
            sets = {name: Box.from_dict(body["sets"][name]) for name in ("X", "U", "W")}
            reach = body["reach"]
            return cls(
                system=system,
                **sets,
                results=results,
                settings=body["settings"],
                seconds=float(body["seconds"]),
                reach=None
                if reach is None or "hulls" not in reach
                else ReachableHulls(
                    tuple(Box.from_dict(h) for h in reach["hulls"]),
                    tuple(reach["steps"]),
                    int(reach["requested"]),
                    reach["unbounded"],
                ),
                learned=body.get("learned") or {},
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"{path} is not an analysis.json of canonid ({exc!r})") from exc

    def constants(self, window: int) -> BoundConstants:
        """The certified constants of Proposition 2 for ``window``: γ_f and γ_h upper bounds,
        α_ℓ lower bound."""
        r = next((r for r in self.results if r.window == window), None)
        if r is None:
            raise SetError(
                f"window ℓ = {window} is not among the analysed windows "
                f"{[r.window for r in self.results]}"
            )
        return BoundConstants(window, r.gamma_f.upper, r.alpha.lower, r.gamma_h.upper)

    def learned_checks(
        self,
        models: Sequence[Exported],
        train: Sequence[Trajectory],
        test: Sequence[Trajectory],
    ) -> LearnedChecks:
        """Checks of learned models with this report's certified constants and X: for each
        model (numpy ``H(z, u)`` and ``window``) its one-step residual on ``test`` against the
        noise-induced level (:func:`canonid.analysis.learned.residual_check`); for each of their
        windows, when ``train`` is given and every trajectory carries its states, an affine probe
        z_t → x_t against Proposition 2's bound (:func:`canonid.analysis.learned.state_probe`).
        Objects with ``.u``, ``.y`` that are not trajectories are converted once
        (:func:`~canonid.kernel.dataset.as_trajectories`)."""
        test = as_trajectories(test, what="test data")
        train = as_trajectories(train, what="training data") if train else ()
        residuals = [
            residual_check(m.H, test, self.constants(int(m.window)), X=self.X) for m in models
        ]
        probes = []
        if train and all(t.x is not None for t in [*train, *test]):
            probes = [
                state_probe(train, test, window=ell, constants=self.constants(ell), X=self.X)
                for ell in sorted({int(m.window) for m in models})
            ]
        return LearnedChecks(residuals, probes)

    def table(self) -> str:
        """A plain-text table: one line per window."""
        head = (
            f"{'ℓ':>3}  {'γ_f lower':>10} {'γ_f upper':>10}  {'α_ℓ lower':>10} {'α_ℓ upper':>10}  "
            f"{'bound(max w̄)':>13} {'max error':>10} {'max err/bound':>13} {'viol.':>5} "
            f"{'fail':>5}"
        )
        lines = [head, "-" * len(head)]
        for r in self.results:
            c = r.check
            check = (
                ["-"] * 5
                if c is None
                else [
                    _fmt(c.worst_case_bound),  # None: α_ℓ = 0, the bound is infinite
                    f"{c.max_error:.4g}",
                    _fmt(c.max_ratio),
                    str(c.violations),
                    str(c.solver_failures),
                ]
            )
            gf, al = r.gamma_f, r.alpha
            lines.append(
                f"{r.window:>3}  {_fmt(gf.lower.value):>10} {_fmt(gf.upper.value):>10}  "
                f"{_fmt(al.lower.value):>10} {_fmt(al.upper.value):>10}  "
                f"{check[0]:>13} {check[1]:>10} {check[2]:>13} {check[3]:>5} {check[4]:>5}"
            )
        lines.append(
            "γ_f on the reachable hull H_{ℓ−1}×U; α_ℓ lower certified, upper sampled; bound = "
            "2 γ_f^ℓ α_ℓ^{−1} ‖w̄‖ with the certified constants (∞ when α_ℓ = 0)."
        )
        limits = self.limitations
        if limits:
            lines.append("Certified bounds out of reach:")
            lines.extend(f"  - {line}" for line in limits)
        skipped = self._skipped_samples()
        if skipped:
            lines.append("Sampled bounds:")
            lines.extend(f"  - {line}" for line in skipped)
        return "\n".join(lines)

    def _skipped_samples(self) -> list[str]:
        """One line per window whose sampled α_ℓ upper bound left out points where ∂O_ℓ/∂x is
        not finite (the label the estimator put in its details)."""
        lines = []
        for r in self.results:
            details = r.alpha.upper.details
            if "nonfinite_samples" in details:
                lines.append(
                    f"α_ℓ upper, ℓ = {r.window}: {details['nonfinite_samples']} of "
                    f"{details['samples']} samples have no finite ∂O_ℓ/∂x — "
                    f"{details['nonfinite_reason']}"
                )
        return lines

    def figure(self, path: str | Path) -> Path:
        """Write the figure "bound and observed error versus ℓ" (log scale), in the format of
        the suffix of ``path`` (``.png``, ``.pdf``, ``.svg``), without a date stamp."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7, 4.8), layout="constrained")
        ax = fig.add_subplot(1, 1, 1)
        ells, bound, est, worst_err, med_err = [], [], [], [], []
        for r in self.results:
            if r.check is None:
                continue
            ells.append(r.window)
            bound.append(r.check.worst_case_bound or np.nan)
            est_factor = _factor(r.gamma_f.lower.value, r.alpha.upper.value, r.window)
            est.append(2 * est_factor * math.sqrt(r.window) * self.W.radius)
            worst_err.append(r.check.max_error)
            med_err.append(r.check.median_error)
        w_bar = r"$\max\,\Vert\bar{w}\Vert$"
        ax.semilogy(ells, bound, "o-", label=f"bound, certified constants ({w_bar})")
        ax.semilogy(ells, est, "s--", label=f"bound, estimated constants ({w_bar})")
        ax.semilogy(ells, np.maximum(worst_err, 1e-300), "v-", label="observed error, max")
        ax.semilogy(ells, np.maximum(med_err, 1e-300), "^:", label="observed error, median")
        for ell, b in zip(ells, bound):
            if not np.isfinite(b):
                ax.annotate(
                    "$\\alpha_\\ell = 0$:\nno bound",
                    xy=(ell, 0.03),
                    xycoords=("data", "axes fraction"),
                    ha="center",
                    va="bottom",
                    fontsize=8,
                )
        ax.set_xlabel(r"window $\ell$ [samples]")
        ax.set_ylabel(
            r"state error $\Vert\hat{x}_t - x_t\Vert$" + f" [{_norm_unit(self.system.state_units)}]"
        )
        trials = self.settings.get("trials")
        ax.set_title(
            f"{self.system.name}: Proposition 2 bound and observed error ({trials} trials per ℓ)"
        )
        ax.set_xticks(ells)
        ax.grid(True, which="both", alpha=0.3)
        fig.legend(fontsize=8, loc="outside lower center", ncol=2, frameon=False)
        return atomic_write_figure(path, fig, dpi=150, stamped=False)


def _norm_unit(units: Sequence[str]) -> str:
    """The unit of the Euclidean norm of a vector of ``units``: the one unit they share, else
    the mixture (the norm adds their numbers as they are)."""
    distinct = list(dict.fromkeys(units))
    if len(distinct) == 1:
        return "dimensionless" if distinct[0] == "-" else distinct[0]
    return "mixed: " + ", ".join(distinct)


def _factor(gamma: float, alpha: float, ell: int) -> float:
    if alpha <= 0:
        return math.inf
    try:
        return gamma**ell / alpha
    except OverflowError:
        return math.inf


def _fmt(v: float | None) -> str:
    if v is None or v == math.inf:
        return "∞"
    return f"{v:.4g}"


def _versions() -> dict[str, str]:
    import flint
    import scipy

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "casadi": str(getattr(ca, "__version__", "unknown")),
        "python-flint": str(getattr(flint, "__version__", "unknown")),
    }


def analyze(
    system: System,
    windows: Sequence[int],
    *,
    X: Box | None = None,
    U: Box | None = None,
    W: Box | None = None,
    trials: int = 1000,
    budget: Budget | None = None,
    gamma_tol: float = 0.05,
    alpha_tol: float = 0.1,
    max_pair_dims: int = 5,
    starts: int = 8,
    seed: int = 0,
    progress: Progress | None = None,
) -> AnalysisReport:
    """Constants and Proposition 2 checks of ``system`` for each window (module docstring).

    Args:
        system: the true system.
        windows: the windows ``ℓ`` (each ``>= 1``); α is also computed for the shorter windows
            that the monotonicity ``α_ℓ ≥ α_k`` uses.
        X, U, W: the sets (default: the system's).
        trials: Monte-Carlo trials per window (0: no check).
        budget: budget of each certified search and sampled bound.
        gamma_tol, alpha_tol: relative tolerances of the γ and α branch-and-bound searches.
        max_pair_dims: largest dimension of the α pairs search.
        starts: argmin starts per trial.
        seed: random seed (same seed, same numbers).
        progress: optional callback ``(message, fraction)`` (fraction of the windows done).
    """
    t0 = time.perf_counter()
    ells = sorted({check_window(w) for w in windows})
    if not ells:
        raise SetError("no window given")
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 0:
        raise SetError(f"trials must be an integer >= 0, got {trials!r}")
    X, U, W = X or system.X, U or system.U, W or system.W
    for name, box, dim in (("X", X, system.n_x), ("U", U, system.n_u), ("W", W, system.n_y)):
        if box.dim != dim:
            raise SetError(f"{system.name}: set {name} has dimension {box.dim}, expected {dim}")
    budget = budget or Budget()
    note = progress or (lambda message, fraction: None)
    note("reachable hulls", 0.0)
    hulls = reach(system, max(ells), X=X, U=U, budget=budget)
    alphas: dict[int, Bracket] = {}
    results: list[WindowResult] = []
    for done, ell in enumerate(range(1, max(ells) + 1)):
        frac = done / max(ells)

        def sub(message: str, fraction: float, ell: int = ell, frac: float = frac) -> None:
            note(f"ℓ={ell}: {message}", frac + fraction / max(ells))

        sub("α_ℓ", 0.0)
        alphas[ell] = alpha_bracket(
            system,
            ell,
            X=X,
            U=U,
            previous=[b.lower for b in alphas.values()],
            tol=alpha_tol,
            budget=budget,
            max_pair_dims=max_pair_dims,
            seed=seed,
            progress=sub,
        )
        if ell not in ells:
            continue
        brackets = {}
        for quantity, fun, step in (("gamma_f", system.f, ell - 1), ("gamma_h", system.h, ell)):
            sub(quantity, 0.3)
            brackets[quantity] = _gamma_on_hull(
                fun,
                hulls,
                step,
                U,
                quantity=quantity,
                window=ell,
                tol=gamma_tol,
                budget=budget,
                seed=seed,
                smaller=getattr(results[-1], quantity).lower if results else None,
            )
        gamma_f, gamma_h = brackets["gamma_f"], brackets["gamma_h"]
        check = None
        if trials:
            sub(f"{trials} Monte-Carlo trials", 0.6)
            certified = BoundConstants(ell, gamma_f.upper, alphas[ell].lower, gamma_h.upper)
            estimated = BoundConstants(ell, gamma_f.lower, alphas[ell].upper, gamma_h.lower)
            check = check_bound(
                system,
                certified,
                trials=trials,
                X=X,
                U=U,
                W=W,
                starts=starts,
                seed=seed + ell,
                estimated=estimated,
            )
        results.append(WindowResult(ell, hulls.hull(ell - 1), gamma_f, gamma_h, alphas[ell], check))
    note("done", 1.0)
    return AnalysisReport(
        system=system,
        X=X,
        U=U,
        W=W,
        results=results,
        settings={
            "trials": trials,
            "budget": budget.to_dict(),
            "gamma_tol": gamma_tol,
            "alpha_tol": alpha_tol,
            "max_pair_dims": max_pair_dims,
            "argmin_starts": starts,
            "seed": seed,
        },
        seconds=time.perf_counter() - t0,
        reach=hulls,
    )


def _gamma_on_hull(
    fun: ca.Function,
    hulls: ReachableHulls,
    step: int,
    U: Box,
    *,
    quantity: str,
    window: int,
    tol: float,
    budget: Budget,
    seed: int,
    smaller: Estimate | None = None,
) -> Bracket:
    """γ of ``fun`` on ``H_step × U``: the sampled lower and the certified upper bound.

    Where ``H_step`` has no finite certified box, or ``fun``'s Jacobian cannot be bounded on it
    (for ``step ≥ 1``: the hull, loose or not, may reach a singularity or overflow where X does
    not), the upper bound is the trivial ``∞`` with the reason, and the lower bound is
    ``smaller`` (a lower bound on an earlier, smaller hull) or else one sampled on ``X = H_0``:
    the hulls are nested, so either is a lower bound of the supremum over ``H_step``.
    """
    X = hulls.hulls[0]
    hull = hulls.hull(step)
    reach_words = "X" if step == 0 else f"the hull reachable from X in {step} step(s)"
    why = None
    if hull is not None:
        try:
            return lipschitz_bracket(
                fun,
                hull,
                U,
                quantity=quantity,
                window=window,
                tol=tol,
                budget=budget,
                seed=seed,
                where=f"{reach_words} × U",
            )
        except SetError as exc:
            if step == 0:
                raise
            why = str(exc)
    else:
        why = f"H_{step} has no finite certified box (see the reachable hulls)"
    if smaller is not None:
        low = replace(smaller, window=window, method=f"{smaller.method}, on a hull ⊆ H_{step}")
    else:
        low = lipschitz_lower(
            fun, X, U, quantity=quantity, window=window, budget=budget, seed=seed, where="X × U"
        )
        low = replace(low, method=f"{low.method}, on X ⊆ H_{step}")
    up = Estimate(
        quantity=quantity,
        value=math.inf,
        kind="upper",
        sets={"X": hull or X, "U": U},
        method=f"trivial: no finite certified bound on H_{step} × U",
        window=window,
        budget=budget.to_dict(),
        details={"why": why},
    )
    return Bracket(low, up)
