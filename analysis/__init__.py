"""The theory, numerically: γ_f, α_ℓ, the Proposition 2 bound and checks of learned models.

Never imports torch: learned models arrive as plain numpy callables exported by ``learning``.
Every estimate says whether it is a lower bound, an upper bound or an estimate
(:class:`Estimate`). One module per estimator family:

* :mod:`canonid.analysis.lipschitz` — γ_f / γ_h (sampled lower bound, certified upper bound);
* :mod:`canonid.analysis.observability` — α_ℓ (sampled upper bounds, certified lower bound);
* :mod:`canonid.analysis.linear` — closed forms for linear systems (the oracle);
* :mod:`canonid.analysis.bound` — Proposition 2 and its Monte-Carlo check;
* :mod:`canonid.analysis.learned` — residual and state-probe checks of learned regressors;
* :mod:`canonid.analysis.report` — everything for a range of windows, JSON, table, figure.

Certified bounds rest on :mod:`canonid.analysis.interval` (outward-rounded interval arithmetic, arb
for transcendental functions), :mod:`canonid.analysis.enclosure` (enclosures of CasADi SX functions
and their Jacobians) and :mod:`canonid.analysis.matrix_bounds` (verified singular-value bounds).
"""

from canonid.analysis.bound import BoundCheck, BoundConstants, check_bound
from canonid.analysis.estimate import Bracket, Budget, Estimate
from canonid.analysis.learned import ProbeResult, ResidualCheck, residual_check, state_probe
from canonid.analysis.lipschitz import lipschitz_bracket, lipschitz_lower, lipschitz_upper
from canonid.analysis.maps import Horizon
from canonid.analysis.observability import alpha_bracket, alpha_lower, alpha_upper
from canonid.analysis.reach import reachable_hulls
from canonid.analysis.report import AnalysisReport, analyze

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
