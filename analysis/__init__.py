"""The theory, numerically: γ_f, α_ℓ, the Proposition 2 bound and checks of learned models.

Never imports torch: learned models arrive as plain numpy callables exported by ``learning``.
Every estimate says whether it is a lower bound, an upper bound or an estimate
(:class:`Estimate`). One module per estimator family:

* :mod:`analysis.lipschitz` — γ_f / γ_h (sampled lower bound, certified upper bound);
* :mod:`analysis.observability` — α_ℓ (sampled upper bounds, certified lower bound);
* :mod:`analysis.linear` — closed forms for linear systems (the oracle);
* :mod:`analysis.bound` — Proposition 2 and its Monte-Carlo check;
* :mod:`analysis.learned` — residual and state-probe checks of learned regressors;
* :mod:`analysis.report` — everything for a range of windows, JSON, table, figure.

Certified bounds rest on :mod:`analysis.interval` (outward-rounded interval arithmetic, arb for
transcendental functions), :mod:`analysis.enclosure` (enclosures of CasADi SX functions and
their Jacobians) and :mod:`analysis.matrix_bounds` (verified singular-value bounds).
"""

from analysis.bound import BoundCheck, BoundConstants, check_bound
from analysis.estimate import Bracket, Budget, Estimate
from analysis.learned import ProbeResult, ResidualCheck, residual_check, state_probe
from analysis.lipschitz import lipschitz_bracket, lipschitz_lower, lipschitz_upper
from analysis.maps import Horizon
from analysis.observability import alpha_bracket, alpha_lower, alpha_upper
from analysis.reach import reachable_hulls
from analysis.report import AnalysisReport, analyze

__all__ = [
    "AnalysisReport",
    "BoundCheck",
    "BoundConstants",
    "Bracket",
    "Budget",
    "Estimate",
    "Horizon",
    "ProbeResult",
    "ResidualCheck",
    "alpha_bracket",
    "alpha_lower",
    "alpha_upper",
    "analyze",
    "check_bound",
    "lipschitz_bracket",
    "lipschitz_lower",
    "lipschitz_upper",
    "reachable_hulls",
    "residual_check",
    "state_probe",
]
