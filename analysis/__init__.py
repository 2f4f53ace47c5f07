"""The theory, numerically: γ_f, α_ℓ, the Proposition 2 bound and checks of learned models.

Never imports torch: learned models arrive as plain numpy callables exported by ``learning``.
Every estimate says whether it is a lower bound, an upper bound or an estimate
(:class:`Estimate`). One module per estimator family:

* :mod:`canonid.analysis.lipschitz` — γ_f / γ_h (sampled lower bound, certified upper bound);
* :mod:`canonid.analysis.observability` — α_ℓ (sampled upper bounds, certified lower bound);
* :mod:`canonid.analysis.linear` — closed forms for linear systems (the oracle);
* :mod:`canonid.analysis.bound` — Proposition 2, its Monte-Carlo check and its value along
  recorded trajectories;
* :mod:`canonid.analysis.learned` — residual and state-probe checks of learned regressors;
* :mod:`canonid.analysis.residuals` — prediction residuals against an instrument (the recorded
  excitation, or prewhitened inputs): the correlation test of a model's input response;
* :mod:`canonid.analysis.report` — everything for a range of windows, JSON, table, figure.

Certified bounds rest on :mod:`canonid.analysis.interval` (outward-rounded interval arithmetic, arb
for transcendental functions), :mod:`canonid.analysis.enclosure` (enclosures of CasADi SX functions
and their Jacobians) and :mod:`canonid.analysis.matrix_bounds` (verified singular-value bounds).

The names below are imported lazily (PEP 562): importing the package loads neither CasADi nor
scipy.
"""

from __future__ import annotations

from canonid.kernel.lazy import lazy_exports

_EXPORTS = {
    "BoundCheck": "canonid.analysis.bound",
    "BoundConstants": "canonid.analysis.bound",
    "TrajectoryBound": "canonid.analysis.bound",
    "bound_along": "canonid.analysis.bound",
    "check_bound": "canonid.analysis.bound",
    "Bracket": "canonid.analysis.estimate",
    "Budget": "canonid.analysis.estimate",
    "Estimate": "canonid.analysis.estimate",
    "ProbeResult": "canonid.analysis.learned",
    "ResidualCheck": "canonid.analysis.learned",
    "residual_check": "canonid.analysis.learned",
    "state_probe": "canonid.analysis.learned",
    "lipschitz_bracket": "canonid.analysis.lipschitz",
    "lipschitz_lower": "canonid.analysis.lipschitz",
    "lipschitz_upper": "canonid.analysis.lipschitz",
    "Horizon": "canonid.analysis.maps",
    "CorrelationTest": "canonid.analysis.residuals",
    "correlation_test": "canonid.analysis.residuals",
    "alpha_bracket": "canonid.analysis.observability",
    "alpha_lower": "canonid.analysis.observability",
    "alpha_upper": "canonid.analysis.observability",
    "reachable_hulls": "canonid.analysis.reach",
    "AnalysisReport": "canonid.analysis.report",
    "analyze": "canonid.analysis.report",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
