"""Nonlinear MPC by multiple shooting, solved with fatrop (CasADi), for data generation.

At sample ``t`` with true state ``x[t]`` and reference rows ``r[t], …, r[t+N]`` (rows past the
end of the reference repeat its last row), the controller solves::

    min   Σ_{k=0}^{N−1} ( ‖x_k − r_{t+k}‖²_Q + ‖u_k − u_eq‖²_R ) + ‖x_N − r_{t+N}‖²_P
    s.t.  x_0 = x[t],   x_{k+1} − f(x_k, u_k) = 0  (k = 0 … N−1),   u_k ∈ U

and applies ``u_0``. ``f`` is the system's own discrete map; Q and R are diagonal; P is the
Riccati solution of the LQR of the linearisation at ``(x_eq, u_eq)`` (SciPy
``solve_discrete_are``, what python-control's ``dlqr`` calls without slycot)
with ``terminal="lqr"``, or Q with ``terminal="none"``.

Output reference (``track="output"``): the reference rows are targets for the outputs and the
tracking terms become ``‖h(x_k, u_k) − r_{t+k}‖²_Q`` (Q from ``output_weights``), the terminal
one ``‖h(x_N, u_eq) − r_{t+N}‖²_Q`` (``terminal="none"`` only: the LQR weight is a state weight).
This is the form for a learned model, whose state (a window of past signals) has no target of
its own.

Decision vector and constraint order are the stage order fatrop's structure detection needs:
``w = (x_0, u_0, x_1, u_1, …, x_{N−1}, u_{N−1}, x_N)``, ``g = (x_0 − x[t], x_1 − f(x_0, u_0), …)``
(the dynamics as ``x_{k+1} − f`` — the other sign is a "structure mismatch" for fatrop).

Warm start: each solve starts from the previous plan shifted by one stage (last stage
repeated). A solve that fails (solver status, or a non-finite plan) returns
``ControlStep(ok=False)`` with the *shifted previous plan*'s next input (``u_eq`` if there is no
plan yet); the next solve is warm-started from that plan shifted again.

Compiled loop (:meth:`NMPC.compiled_loop`): the same solve, warm start and shift as one CasADi
policy ``(warm start, x[t], reference rows) -> (u_0, shifted plan, plan finite)`` around which
:mod:`canonid.datagen.compiled_loop` builds whole chunks of a flight; the simulator uses it for
flights of the NMPC's own system and falls back on the step loop (and the failure handling above)
for a flight in which a solve fails.

Gauss-Newton SQP (``hessian="gauss-newton"``): for a prediction model whose exact Hessian is
costly (a learned MLP: every solve differentiates the network twice per stage), each solve is a
short sequential quadratic programme instead. From the warm start ``w̄`` (first state set to
``x[t]``) it linearises ``f`` and the tracked quantity (``x`` or ``h``) at every stage of ``w̄``
(:meth:`canonid.models.base.System.linearise`, one batched call), writes the NLP above with ``f``
and ``h`` replaced by these linearisations — the Gauss-Newton Hessian: the cost's own, no second
derivatives of the model — and eliminates the states (condensing: ``x_k`` is affine in the inputs),
which leaves a dense quadratic programme in the ``N · n_u`` inputs with their bounds, solved by DAQP
(an active-set solver in the CasADi wheel). The states of the plan follow from the linearised
dynamics. It repeats from that plan until no entry ``w_i`` moves by more than ``sqp_tol · (1 +
|w_i|)`` or after ``sqp_max_iter`` programmes; once a step is not at most half the previous one
(Gauss-Newton can oscillate, e.g. on an unstable model), the next linearisation point is the
midpoint of the plan and the solution (a damped fixed-point step: the same fixed point; an
oscillation of ratio −1 becomes contracting). A fixed point is a KKT point of the NLP above (the
linearisations are exact there), so both options plan the same inputs when both converge. Condensing
makes a learned model's long state (``ℓ (n_u + n_y)`` entries) cheap: the programme's size does not
depend on it. No compiled loop: flights go step by step.

Solvers (``solver=``): ``"fatrop-c"`` generates the whole fatrop solver, with the step and the
compiled loop around it, to C, compiles it on first use and caches the library (see
:mod:`canonid.datagen.controllers._compiled`); ``"fatrop"`` is the plugin of the CasADi wheel;
``"auto"`` (default) is ``"fatrop-c"`` when a C compiler is found, the build succeeds and the
model is small (``f`` and ``h`` below :data:`COMPILE_LIMIT` SX instructions: the C of a learned
MLP's exact Hessian is too large for gcc), else ``"fatrop"``; ``"ipopt"`` solves the same NLP
with IPOPT (for comparisons). :meth:`NMPC.settings` names the solver actually used.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from canonid.datagen.compiled_loop import CompiledLoop, casadi_dump_captured, loop_functions
from canonid.datagen.controllers._buffered import BufferedFunction
from canonid.datagen.controllers._compiled import compile_functions
from canonid.datagen.controllers.base import Controller, ControlStep
from canonid.kernel.errors import ShapeError
from canonid.kernel.validate import as_matrix, as_vector
from canonid.models.base import System

__all__ = ["COMPILE_LIMIT", "HESSIANS", "NMPC", "SOLVERS"]

log = logging.getLogger(__name__)

SOLVERS = ("auto", "fatrop-c", "fatrop", "ipopt")

#: ``"exact"``: the NLP's exact Hessian; ``"gauss-newton"``: SQP on linearisations (docstring)
HESSIANS = ("exact", "gauss-newton")

#: ``solver="auto"`` compiles only prediction models with fewer SX instructions than this (a
#: 64 × 64 MLP has ~15,000; gcc had not finished its solver after 5 min and 9 GB)
COMPILE_LIMIT = 2_000


class NMPC(Controller):
    """Nonlinear MPC tracking a full-state or an output reference (see the module docstring).

    Args:
        system: the prediction model (its ``f``, and ``h`` for an output reference) and its U
            the input bounds: a true system or a learned one (``canonid.models.learned``).
        u_eq: the input the ``R`` term pulls towards and the LQR linearises at (e.g. hover).
        x_eq: the state the LQR linearises at (default 0).
        horizon: N, the number of predicted inputs.
        state_weights: diagonal of Q, one per state (``track="state"``).
        input_weights: diagonal of R, one per input.
        terminal: ``"lqr"`` or ``"none"``.
        track: ``"state"`` (a reference row per state) or ``"output"`` (per output).
        output_weights: diagonal of Q, one per output (``track="output"``).
        solver: one of :data:`SOLVERS`.
        tol: solver tolerance. The default 1e-4 was chosen by measurement: on drone flights
            the applied rotor speeds differed from those of IPOPT at tolerance 1e-10 by at most
            1.4e-5 rad/s (the excitation is 1 rad/s), with one fewer fatrop iteration per step
            than at 1e-6.
        mu_init: initial barrier parameter of fatrop / IPOPT (small suits warm starts).
        max_iter: iteration limit per solve (a solve that reaches it has failed).
        cache_dir: where ``"fatrop-c"`` keeps compiled solvers (default: the user's cache
            folder, see :func:`canonid.datagen.controllers._compiled.default_cache_dir`).
        hessian: one of :data:`HESSIANS`; ``"gauss-newton"`` solves its programmes with DAQP
            (``solver`` stays ``"auto"``).
        sqp_max_iter, sqp_tol: the Gauss-Newton SQP's limit on quadratic programmes per solve
            and its relative step tolerance (a solve that reaches the limit keeps its last plan
            and says so in ``info["status"]``).
    """

    name = "nmpc"

    def __init__(
        self,
        system: System,
        *,
        u_eq: Sequence[float],
        x_eq: Sequence[float] | None = None,
        horizon: int = 20,
        state_weights: Sequence[float] | None = None,
        input_weights: Sequence[float],
        terminal: str = "lqr",
        track: str = "state",
        output_weights: Sequence[float] | None = None,
        solver: str = "auto",
        tol: float = 1e-4,
        mu_init: float = 1e-3,
        max_iter: int = 100,
        cache_dir: str | os.PathLike[str] | None = None,
        hessian: str = "exact",
        sqp_max_iter: int = 10,
        sqp_tol: float = 1e-4,
    ) -> None:
        if int(horizon) != horizon or horizon < 1:
            raise ShapeError(f"NMPC horizon must be an integer >= 1, got {horizon!r}")
        if solver not in SOLVERS:
            raise ShapeError(f"NMPC solver must be one of {SOLVERS}, got {solver!r}")
        if hessian not in HESSIANS:
            raise ShapeError(f"NMPC hessian must be one of {HESSIANS}, got {hessian!r}")
        if hessian == "gauss-newton" and solver != "auto":
            raise ShapeError(
                "NMPC hessian='gauss-newton' solves condensed quadratic programmes with DAQP; "
                f"leave solver='auto' (got {solver!r})"
            )
        if int(sqp_max_iter) != sqp_max_iter or sqp_max_iter < 1 or not sqp_tol > 0:
            raise ShapeError(
                f"NMPC sqp_max_iter must be an integer >= 1 and sqp_tol > 0, got "
                f"{sqp_max_iter!r} and {sqp_tol!r}"
            )
        if terminal not in ("lqr", "none"):
            raise ShapeError(f"NMPC terminal must be 'lqr' or 'none', got {terminal!r}")
        if track not in ("state", "output"):
            raise ShapeError(f"NMPC track must be 'state' or 'output', got {track!r}")
        tracked, weights = (
            ("state", state_weights) if track == "state" else ("output", output_weights)
        )
        other = output_weights if track == "state" else state_weights
        if weights is None or other is not None:
            raise ShapeError(
                f"NMPC with track={track!r} needs {tracked}_weights (one per {tracked}) and no "
                f"{'output' if track == 'state' else 'state'}_weights"
            )
        if track == "output" and terminal == "lqr":
            raise ShapeError("NMPC track='output' needs terminal='none' (LQR weighs states)")
        self.system = system
        self.track = track
        self.horizon = N = int(horizon)
        nx, nu = system.n_x, system.n_u
        self._n_ref = nx if track == "state" else system.n_y
        self.u_eq = as_vector(u_eq, nu, "NMPC u_eq")
        self.x_eq = np.zeros(nx) if x_eq is None else as_vector(x_eq, nx, "NMPC x_eq")
        q = as_vector(weights, self._n_ref, f"NMPC {tracked}_weights")
        r = as_vector(input_weights, nu, "NMPC input_weights")
        if np.any(q < 0) or np.any(r <= 0):
            raise ShapeError("NMPC weights: state weights must be >= 0 and input weights > 0")
        self.Q, self.R = np.diag(q), np.diag(r)
        self.terminal = terminal
        self.P = self._terminal_weight() if terminal == "lqr" else self.Q
        self.tol, self.mu_init, self.max_iter = float(tol), float(mu_init), int(max_iter)
        self.hessian = hessian
        self.sqp_max_iter, self.sqp_tol = int(sqp_max_iter), float(sqp_tol)

        self._nw = nx * (N + 1) + nu * N
        self._u_index = np.concatenate(
            [np.arange(nu) + k * (nx + nu) + nx for k in range(N)]
        ).reshape(N, nu)
        self._lbx = np.full(self._nw, -np.inf)
        self._ubx = np.full(self._nw, np.inf)
        self._lbx[self._u_index] = system.U.lo
        self._ubx[self._u_index] = system.U.hi
        self._ng = nx * (N + 1)
        self._zeros_g = np.zeros(self._ng)

        self._loop: CompiledLoop | None = None
        if hessian == "gauss-newton":
            n_in = N * nu
            self.solver_used = "daqp"
            self._qp = ca.conic(
                "nmpc_qp",
                "daqp",
                {"h": ca.Sparsity.dense(n_in, n_in), "a": ca.Sparsity(0, n_in)},
                {"error_on_fail": True, "print_time": False},
            )
        else:
            nlp = self._nlp()
            self.solver_used, self._solve, loop = self._build(nlp, solver, cache_dir)
            self._solve_buffered = BufferedFunction(self._solve)  # ~70 µs less per step
            self._loop = CompiledLoop(
                system, *loop, window=N + 1, initial_memory=self._initial_guess
            )
        self._reference: np.ndarray | None = None
        self._windows = np.zeros(0)  # the reference rows of reset, last row repeated N times
        self._guess = np.zeros(self._nw)
        self._plan: np.ndarray | None = None  # (N, nu) inputs of the last usable plan
        self._since_plan = 0

    # ------------------------------------------------------------------ construction
    def _terminal_weight(self) -> np.ndarray:
        from scipy.linalg import solve_discrete_are  # python-control would import matplotlib

        x = ca.SX.sym("x", self.system.n_x)
        u = ca.SX.sym("u", self.system.n_u)
        fx = self.system.f(x, u)
        linear = ca.Function("linearisation", [x, u], [ca.jacobian(fx, x), ca.jacobian(fx, u)])
        A, B = (np.asarray(m, dtype=np.float64) for m in linear(self.x_eq, self.u_eq))
        P = np.asarray(solve_discrete_are(A, B, self.Q, self.R), dtype=np.float64)
        return 0.5 * (P + P.T)

    def _nlp(self) -> dict[str, Any]:
        nx, nu, N = self.system.n_x, self.system.n_u, self.horizon
        X = [ca.MX.sym(f"x{k}", nx) for k in range(N + 1)]
        U = [ca.MX.sym(f"u{k}", nu) for k in range(N)]
        x_now = ca.MX.sym("x_now", nx)
        ref = ca.MX.sym("ref", self._n_ref, N + 1)
        Q, R, P = ca.DM(self.Q), ca.DM(self.R), ca.DM(self.P)
        u_eq = ca.DM(self.u_eq)

        w, g = [], [X[0] - x_now]
        cost: Any = 0
        for k in range(N):
            w += [X[k], U[k]]
            e, du = self._tracked(X[k], U[k]) - ref[:, k], U[k] - u_eq
            cost += ca.bilin(Q, e, e) + ca.bilin(R, du, du)
            g.append(X[k + 1] - self.system.f(X[k], U[k]))
        w.append(X[N])
        e = self._tracked(X[N], u_eq) - ref[:, N]
        cost += ca.bilin(P, e, e)
        return {"x": ca.vcat(w), "f": cost, "g": ca.vcat(g), "p": ca.vertcat(x_now, ca.vec(ref))}

    def _tracked(self, x: Any, u: Any) -> Any:
        return x if self.track == "state" else self.system.h(x, u)

    def _condensed_step(self, w: np.ndarray, params: np.ndarray) -> np.ndarray:
        """The plan solving the quadratic programme linearised at ``w`` (module docstring):
        ``x_k = S_k U + s_k`` from the linearised dynamics, the tracking errors ``G_k U + g_k``,
        the dense programme in ``U`` by DAQP, the states from ``U``.

        Raises:
            RuntimeError: DAQP failed.
        """
        nx, nu, N, nr = self.system.n_x, self.system.n_u, self.horizon, self._n_ref
        stages = w[: (nx + nu) * N].reshape(N, nx + nu)
        xs = np.vstack([stages[:, :nx], w[None, self._nw - nx :]])
        us = np.vstack([stages[:, nx:], self.u_eq[None, :]])
        lin = self.system.linearise(xs, us)
        if self.track == "state":
            r, r_x, r_u = (
                xs,
                np.broadcast_to(np.eye(nx), (N + 1, nx, nx)),
                np.zeros((N + 1, nx, nu)),
            )
        else:
            r, r_x, r_u = lin.h, lin.h_x, lin.h_u
        ref = params[nx:].reshape(N + 1, nr)
        # offsets of the linearisations: f ≈ A x + B u + c, tracked ≈ C x + D u + d
        c = lin.f - np.einsum("kij,kj->ki", lin.f_x, xs) - np.einsum("kij,kj->ki", lin.f_u, us)
        d = r - np.einsum("kij,kj->ki", r_x, xs) - np.einsum("kij,kj->ki", r_u, us)
        S = np.zeros((N + 1, nx, N * nu))
        s = np.zeros((N + 1, nx))
        s[0] = params[:nx]
        G = np.zeros((N + 1, nr, N * nu))
        g = np.zeros((N + 1, nr))
        for k in range(N + 1):
            G[k] = r_x[k] @ S[k]
            g[k] = r_x[k] @ s[k] + d[k] - ref[k]
            if k == N:
                break
            G[k, :, k * nu : (k + 1) * nu] += r_u[k]
            S[k + 1] = lin.f_x[k] @ S[k]
            S[k + 1, :, k * nu : (k + 1) * nu] += lin.f_u[k]
            s[k + 1] = lin.f_x[k] @ s[k] + c[k]
        weights = np.concatenate([np.broadcast_to(self.Q, (N, nr, nr)), self.P[None]], axis=0)
        QG = weights @ G
        H = 2.0 * np.einsum("kia,kib->ab", G, QG) + 2.0 * np.kron(np.eye(N), self.R)
        grad = 2.0 * np.einsum("kia,ki->a", QG, g) - 2.0 * np.tile(self.R @ self.u_eq, N)
        lo, hi = self._lbx[self._u_index].ravel(), self._ubx[self._u_index].ravel()
        sol = self._qp(h=0.5 * (H + H.T), g=grad, lbx=lo, ubx=hi)
        U = np.asarray(sol["x"], dtype=np.float64).ravel()
        states = S @ U + s
        plan = np.empty(self._nw)
        plan[self._u_index.ravel()] = U
        for k in range(N + 1):
            plan[k * (nx + nu) : k * (nx + nu) + nx] = states[k]
        return plan

    def _build(
        self, nlp: dict[str, Any], solver: str, cache_dir: str | os.PathLike[str] | None
    ) -> tuple[str, ca.Function, tuple[ca.Function, ca.Function]]:
        """The solver used, the step function ``(initial guess, parameters) -> plan`` and the
        compiled loop's (step, chunk) functions for ``solver``.

        The bounds are baked in, so a step passes two arrays (fewer conversions than the six
        inputs of an ``nlpsol``), and ``error_on_fail`` makes a failed solve raise: the generated
        C has no ``stats()`` to ask.
        """
        common: dict[str, Any] = {"expand": True, "print_time": False, "error_on_fail": True}
        if solver == "ipopt":
            opts: dict[str, Any] = {
                **common,
                "ipopt": {
                    "print_level": 0,
                    "sb": "yes",
                    "tol": self.tol,
                    "mu_init": self.mu_init,
                    "max_iter": self.max_iter,
                },
            }
            step = self._step_function(ca.nlpsol("nmpc", "ipopt", nlp, opts))
            return "ipopt", step, self._loop_functions(step)
        fatrop_opts: dict[str, Any] = {
            **common,
            "structure_detection": "auto",
            "equality": [True] * self._ng,
            "fatrop": {
                "print_level": 0,
                "tol": self.tol,
                "mu_init": self.mu_init,
                "max_iter": self.max_iter,
            },
        }
        step = self._step_function(ca.nlpsol("nmpc", "fatrop", nlp, fatrop_opts))
        loops = self._loop_functions(step)
        size = self.system.f.n_instructions() + self.system.h.n_instructions()
        if solver == "auto" and size >= COMPILE_LIMIT:
            log.info("NMPC: %d SX instructions in f and h, not compiled (plugin)", size)
        elif solver in ("auto", "fatrop-c"):
            compiled = compile_functions(
                (step, *loops),
                name=f"nmpc_{self.system.name}_N{self.horizon}",
                cache_dir=cache_dir,
                libraries=("fatrop", "blasfeo"),
            )
            if compiled is not None:
                return "fatrop-c", compiled[0], (compiled[1], compiled[2])
            if solver == "fatrop-c":
                raise ShapeError(
                    "solver 'fatrop-c' needs a working C compiler (gcc) and a cache folder only "
                    "you can write (the warning above says which is missing); use solver='fatrop'"
                )
        return "fatrop", step, loops

    def _step_function(self, nlpsol: ca.Function) -> ca.Function:
        guess = ca.MX.sym("guess", self._nw)
        params = ca.MX.sym("params", nlpsol.size1_in("p"))
        plan = nlpsol(
            x0=guess, p=params, lbx=self._lbx, ubx=self._ubx, lbg=self._zeros_g, ubg=self._zeros_g
        )["x"]
        return ca.Function("nmpc_step", [guess, params], [plan], ["guess", "params"], ["plan"])

    def _loop_functions(self, step: ca.Function) -> tuple[ca.Function, ca.Function]:
        """The compiled loop around one call of ``step``, written as :meth:`__call__` on a
        successful solve: first state of the guess replaced by ``x``, parameters ``(x, rows
        t … t+N)``, ``u_0`` applied, the plan shifted (:meth:`_shifted`) for the next guess."""
        nx, nu, nw = self.system.n_x, self.system.n_u, self._nw
        guess = ca.MX.sym("guess", nw)
        x = ca.MX.sym("x", nx)
        window = ca.MX.sym("window", self._n_ref * (self.horizon + 1))
        w = step(ca.vertcat(x, guess[nx:]), ca.vertcat(x, window))
        first, last = int(self._u_index[0, 0]), int(self._u_index[-1, 0])
        shifted = ca.vertcat(w[nx + nu :], w[last : last + nu], w[nw - nx :])
        finite = ca.sum1(ca.fabs(w)) < np.inf  # false if any entry is nan or ±inf
        policy = ca.Function(
            "nmpc_policy", [guess, x, window], [w[first : first + nu], shifted, finite]
        )
        return loop_functions(self.system, policy, name="nmpc_loop")

    # ------------------------------------------------------------------ the controller
    def reset(self, reference: np.ndarray, x0: np.ndarray) -> None:
        nx, N = self.system.n_x, self.horizon
        self._reference = as_matrix(
            reference, self._n_ref, f"NMPC reference (one target per {self.track})"
        )
        x = as_vector(x0, nx, "NMPC x0")
        # rows past the end repeat the last one: rows t … t+N of step t are one slice
        self._windows = np.concatenate(
            [self._reference, np.repeat(self._reference[-1:], N, axis=0)]
        ).ravel()
        stage = np.concatenate([x, self.u_eq])
        self._guess = np.concatenate([np.tile(stage, N), x])
        self._plan = None
        self._since_plan = 0

    def __call__(self, t: int, x: np.ndarray) -> ControlStep:
        if self._reference is None:
            raise ShapeError("NMPC called before reset(reference, x0)")
        N, width = self.horizon, self._n_ref
        first = min(t, self._reference.shape[0] - 1) * width  # rows t … t+N, clamped at T−1
        params = np.concatenate([x, self._windows[first : first + (N + 1) * width]])
        self._guess[: self.system.n_x] = x
        start, start_cpu = time.perf_counter(), time.process_time()
        status, w = self._solve_once(params)
        elapsed = time.perf_counter() - start
        times = {"solve_time": elapsed, "solve_cpu": time.process_time() - start_cpu}
        if w is not None:
            self._plan = w[self._u_index]
            self._since_plan = 0
            self._guess = self._shifted(w)
            return ControlStep(u=self._plan[0].copy(), info={"status": status, **times})
        # fall back on the previous plan, shifted
        if self._plan is None:
            u = self.u_eq.copy()
        else:
            self._since_plan += 1
            u = self._plan[min(self._since_plan, N - 1)].copy()
            self._guess = self._shifted(self._guess)
        return ControlStep(u=u, ok=False, info={"status": status, **times})

    def _initial_guess(self, reference: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """The warm start of a new flight (what :meth:`reset` sets)."""
        self.reset(reference, x0)
        return self._guess.copy()

    def compiled_loop(self) -> CompiledLoop | None:
        return self._loop

    def _solve_once(self, params: np.ndarray) -> tuple[str, np.ndarray | None]:
        if self.hessian == "gauss-newton":
            return self._sqp(params)
        try:
            with casadi_dump_captured() as dump:
                w = self._solve_buffered(self._guess, params)
        except RuntimeError as exc:  # error_on_fail: failed or non-converged
            log.debug("NMPC solve failed: %s\n%s", exc, dump.getvalue())
            return f"{self.solver_used} failed", None
        if not np.all(np.isfinite(w)):
            return "non-finite plan", None
        return "ok", w

    def _sqp(self, params: np.ndarray) -> tuple[str, np.ndarray | None]:
        """The Gauss-Newton SQP from the warm start (see the module docstring)."""
        w = self._guess.copy()
        step, previous = 1.0, np.inf
        for iteration in range(1, self.sqp_max_iter + 1):
            try:
                new = self._condensed_step(w, params)
            except RuntimeError as exc:
                log.debug("NMPC quadratic programme failed: %s", exc)
                return f"{self.solver_used} failed (SQP iteration {iteration})", None
            if not np.all(np.isfinite(new)):
                return "non-finite plan", None
            moved = float(np.max(np.abs(new - w) / (1.0 + np.abs(new))))
            if moved <= self.sqp_tol:
                return f"ok (SQP, {iteration} QPs)", new
            if moved > 0.5 * previous:  # not contracting (GN oscillates): half steps from now on
                step = 0.5
            w, previous = w + step * (new - w), moved
        return f"ok (SQP iteration limit, {self.sqp_max_iter} QPs)", w

    def _shifted(self, w: np.ndarray) -> np.ndarray:
        """Drop stage 0 of a plan and repeat the last stage: ``(x1,u1,…,x_{N-1},u_{N-1},x_N,
        u_{N-1},x_N)``."""
        nx, nu = self.system.n_x, self.system.n_u
        last_u = w[self._u_index[-1]]
        return np.concatenate([w[nx + nu :], last_u, w[-nx:]])

    def settings(self) -> dict[str, Any]:
        return {
            "type": self.name,
            "solver": self.solver_used,
            "track": self.track,
            "horizon": self.horizon,
            f"{self.track}_weights": np.diag(self.Q).tolist(),
            "input_weights": np.diag(self.R).tolist(),
            "u_eq": self.u_eq.tolist(),
            "x_eq": self.x_eq.tolist(),
            "terminal": self.terminal,
            "terminal_weight": self.P.tolist(),
            "input_bounds": self.system.U.to_dict(),
            "tol": self.tol,
            "mu_init": self.mu_init,
            "max_iter": self.max_iter,
            "hessian": self.hessian,
            **(
                {"sqp_max_iter": self.sqp_max_iter, "sqp_tol": self.sqp_tol}
                if self.hessian == "gauss-newton"
                else {}
            ),
            "formulation": "multiple shooting, x_{k+1} - f(x_k, u_k) = 0, warm start by shift",
            "fallback": "failed solve: next input of the shifted previous plan (u_eq if none)",
        }
