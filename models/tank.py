"""Cascaded tanks (paper §V-A; Schoukens et al., 2017), in discrete time.

    x1[t+1] = max(0, x1 − k1 √x1 + k2 u)
    x2[t+1] = max(0, x2 + k3 √x1 − k4 √x2)
    y[t]    = x2[t]                      (+ w[t] in a dataset)

with k = (0.5, 0.4, 0.2, 0.3) (the paper's appendix prints the fourth as "k_1 = 0.3": it is k4).
Levels are clipped at 0 after each step, as the authors' generator does; the square roots read
``max(x, 0)`` so that ``f`` is defined (and equal to the clipped map) everywhere.

√x has an unbounded slope at 0, so the Lipschitz constant γ_f is infinite on any X touching 0:
the analysis set is ``X = [eps, x_max]²`` with ``eps > 0`` a documented parameter.
"""

from __future__ import annotations

import casadi as ca

from canonid.kernel.errors import SetError
from canonid.models.base import System
from canonid.models.sets import Box

__all__ = ["Tank"]


class Tank(System):
    """Two cascaded water tanks, input the pump command, output the lower tank's level.

    Args:
        k: the four coefficients (k1, k2, k3, k4).
        eps: lower edge of X in both levels (must be > 0: γ_f is infinite at 0).
        x_max: upper edge of X in both levels.
        u_box: the input set U (the PID of the datasets is not saturated; U is where the theory
            is evaluated).
        noise: half-width of the bounded measurement-noise box W = [−noise, noise].
    """

    description = "Cascaded water tanks (paper §V-A), discrete time, levels clipped at 0"

    def __init__(
        self,
        *,
        k: tuple[float, float, float, float] = (0.5, 0.4, 0.2, 0.3),
        eps: float = 0.05,
        x_max: float = 6.0,
        u_box: tuple[float, float] = (0.0, 6.0),
        noise: float = 0.02,
        dt: float = 1.0,
    ) -> None:
        if len(k) != 4 or any(not (c > 0) for c in k):
            raise SetError(f"tank: k must be four positive coefficients, got {k}")
        if not (eps > 0):
            raise SetError(
                f"tank: eps must be > 0 (√x has unbounded slope at 0, so γ_f would be infinite), "
                f"got {eps}"
            )
        if not (noise >= 0):
            raise SetError(f"tank: noise half-width must be >= 0, got {noise}")
        self.k = tuple(float(c) for c in k)
        super().__init__(
            name="tank",
            dt=dt,
            state_names=("x1", "x2"),
            state_units=("m", "m"),
            input_names=("u",),
            input_units=("-",),
            output_names=("y",),
            output_units=("m",),
            X=Box([eps, eps], [x_max, x_max]),
            U=Box([u_box[0]], [u_box[1]]),
            W=Box([-noise], [noise]),
            discretisation="exact (the model is defined in discrete time)",
            parameters={"k": self.k, "eps": eps, "x_max": x_max, "clip_at_zero": True},
        )

    def _f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        k1, k2, k3, k4 = self.k
        s1 = ca.sqrt(ca.fmax(x[0], 0))
        s2 = ca.sqrt(ca.fmax(x[1], 0))
        x1 = ca.fmax(x[0] - k1 * s1 + k2 * u[0], 0)
        x2 = ca.fmax(x[1] + k3 * s1 - k4 * s2, 0)
        return ca.vertcat(x1, x2)

    def _h_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        return x[1]

    def equilibrium_input(self, level: float) -> float:
        """Pump command that holds the lower tank at ``level`` in steady state."""
        k1, k2, k3, k4 = self.k
        return float(k1 * k4 * level**0.5 / (k2 * k3))
