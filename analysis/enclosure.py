"""Interval enclosures of CasADi SX functions and of their Jacobians, batched over boxes.

:class:`Enclosure` walks the algorithm of a ``casadi.Function`` built from SX (``n_instructions``,
``instruction_id/input/output/constant``) once, then evaluates it on a batch of boxes in the
interval arithmetic of :mod:`canonid.analysis.interval`. With ``wrt=k`` it also runs forward-mode
automatic differentiation in intervals and returns an enclosure of the Jacobian with respect to
input ``k``.

Non-smooth operations. The Jacobian is enclosed on the *original* expression graph, not on
CasADi's symbolic Jacobian (whose ``fmax`` derivative ``(b≤a)/((b≤a)+(a≤b))`` divides by an
interval containing 0 as soon as a box straddles the kink). ``fmax``, ``fmin`` and ``fabs``
take the interval hull of the gradients of the pieces that may be active, which contains
Clarke's generalised Jacobian; the mean-value inclusion ``f(x) − f(x') ∈ co ∂f([x, x'])(x − x')``
(Clarke, *Optimization and Nonsmooth Analysis*, Prop. 2.6.5) then makes the hull a sound
Lipschitz certificate for the clipped tank. A comparison or ``if_else`` whose outcome is not
decided on a box may jump, so its box is flagged :data:`DISCONTINUITY` rather than bounded.

Flags (bit masks per box) say why an enclosure is unusable; :func:`describe_flags` turns them
into words for error messages.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np
from flint import arb

from canonid.analysis.estimate import OutOfTime
from canonid.analysis.interval import Interval, _sum_lower, _sum_upper, arb_map
from canonid.kernel.errors import SetError, ShapeError

__all__ = [
    "DISCONTINUITY",
    "DIV_ZERO",
    "DOMAIN",
    "NONFINITE",
    "SLOPE",
    "Enclosure",
    "EnclosureResult",
    "describe_flags",
]

#: the slope of √ is infinite where its argument reaches 0
SLOPE = 1
#: a division by an expression whose enclosure contains 0
DIV_ZERO = 2
#: a comparison or if_else undecided on the box (the function may jump)
DISCONTINUITY = 4
#: √ or log of a negative number (the function is undefined there)
DOMAIN = 8
#: overflow or another non-finite enclosure
NONFINITE = 16

_FLAG_TEXT = {
    SLOPE: "√ of an expression that reaches 0, where the slope of √ is infinite",
    DIV_ZERO: "a division by an expression that reaches 0",
    DISCONTINUITY: "a comparison or if_else that changes outcome (a possible jump)",
    DOMAIN: "√ or log of a negative number (the function is undefined there)",
    NONFINITE: "an overflow (non-finite enclosure)",
}


def describe_flags(flags: int) -> str:
    """Words for a flag mask, e.g. for an error message."""
    parts = [text for bit, text in _FLAG_TEXT.items() if flags & bit]
    return "; ".join(parts) if parts else "no problem"


@dataclass(frozen=True)
class EnclosureResult:
    """Enclosures on ``B`` boxes.

    Attributes:
        values: one :class:`Interval` per output, shape ``(B, n_out)``.
        jacobians: one per output, shape ``(B, n_out, n_wrt)``, or ``None`` without ``wrt``.
        value_flags: ``(B,)`` bit mask, non-zero where the value enclosure is unusable.
        jac_flags: ``(B,)`` bit mask, non-zero where the Jacobian enclosure is unusable
            (includes ``value_flags``).
    """

    values: list[Interval]
    jacobians: list[Interval] | None
    value_flags: np.ndarray
    jac_flags: np.ndarray


_BINARY = {ca.OP_ADD, ca.OP_SUB, ca.OP_MUL, ca.OP_DIV, ca.OP_POW, ca.OP_CONSTPOW}
_COMPARE = {ca.OP_LT, ca.OP_LE, ca.OP_EQ, ca.OP_NE}
_ARB_FUN = {
    ca.OP_EXP: arb.exp,
    ca.OP_LOG: arb.log,
    ca.OP_SIN: arb.sin,
    ca.OP_COS: arb.cos,
    ca.OP_TAN: arb.tan,
    ca.OP_ATAN: arb.atan,
    ca.OP_TANH: arb.tanh,
    ca.OP_SINH: arb.sinh,
    ca.OP_COSH: arb.cosh,
}
_OP_NAMES = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
#: increasing on their domain: an interval's image is spanned by the images of its ends (one arb
#: ball over a wide interval is far looser, e.g. tanh([−10, 10]) ⊆ [−6.5e8, 2])
_INCREASING = {ca.OP_EXP, ca.OP_LOG, ca.OP_ATAN, ca.OP_TANH, ca.OP_SINH}


#: instructions walked between two looks at the clock
_CLOCK_EVERY = 4096


def _check_time(step: int, deadline: float) -> None:
    """Raise :class:`OutOfTime` past ``deadline``, looking at the clock every
    :data:`_CLOCK_EVERY` instructions (a large network has millions)."""
    if step % _CLOCK_EVERY == _CLOCK_EVERY - 1 and time.perf_counter() > deadline:
        raise OutOfTime


def _increasing(func: Callable[[arb], arb], a: Interval) -> Interval:
    """``func([lo, hi]) = [func(lo), func(hi)]`` for an increasing ``func``, each end enclosed
    by arb and rounded outward; an undefined end makes both NaN (as :func:`arb_map`)."""
    lo = arb_map(func, Interval.point(a.lo)).lo
    hi = arb_map(func, Interval.point(a.hi)).hi
    bad = np.isnan(lo) | np.isnan(hi)
    return Interval(np.where(bad, np.nan, lo), np.where(bad, np.nan, hi))


class Enclosure:
    """Interval evaluator of an SX ``casadi.Function`` (dense inputs).

    Args:
        fun: the function; it must be an SX function (``fun.is_a("SXFunction")``).
        wrt: index of the input whose Jacobian is enclosed, or ``None`` for values only.
        refine: intersect every intermediate value with its **mean-value form**
            ``v(c) + [∇v](B − c)`` (``c`` the box centre, ``[∇v]`` the gradient enclosure with
            respect to all inputs, carried along by forward-mode AD). It costs about twice the
            plain evaluation and makes enclosures converge quadratically as boxes shrink, which
            decides ``fmax``/``fabs``/comparisons and keeps √ away from 0 long before the plain
            (natural) extension would. Skipped on boxes already flagged. Off by default: on the
            shipped systems the branch-and-bound searches reach the same bounds faster without it.
        deadline: ``time.perf_counter()`` after which building the evaluator or an evaluation
            raises :class:`~canonid.analysis.estimate.OutOfTime` (a network of millions of
            instructions takes minutes per batch); default: none.
    """

    def __init__(
        self,
        fun: ca.Function,
        *,
        wrt: int | None = None,
        refine: bool = False,
        deadline: float = math.inf,
    ) -> None:
        if not fun.is_a("SXFunction"):
            raise ShapeError(f"interval evaluation needs an SX function, got {fun.class_name()}")
        for i in range(fun.n_in()):
            if not fun.sparsity_in(i).is_dense():
                raise ShapeError(f"{fun.name()}: input {i} must be dense for interval evaluation")
        if wrt is not None and not 0 <= wrt < fun.n_in():
            raise ShapeError(f"{fun.name()}: wrt={wrt} but the function has {fun.n_in()} inputs")
        self.fun = fun
        self.wrt = wrt
        self.refine = refine
        self.n_in = [fun.nnz_in(i) for i in range(fun.n_in())]
        self.offsets = np.concatenate([[0], np.cumsum(self.n_in)]).astype(int)
        if refine:
            self.n_grad = int(self.offsets[-1])
        else:
            self.n_grad = 0 if wrt is None else self.n_in[wrt]
        self.n_wrt = 0 if wrt is None else self.n_in[wrt]
        self.out_rows = [
            fun.sparsity_out(i).row() if fun.sparsity_out(i).size2() == 1 else None
            for i in range(fun.n_out())
        ]
        for i, rows in enumerate(self.out_rows):
            if rows is None:
                raise ShapeError(f"{fun.name()}: output {i} must be a column vector")
        self.n_out = [fun.size1_out(i) for i in range(fun.n_out())]
        self.deadline = deadline
        self.program: list[tuple[int, list[int], list[int], float]] = []
        for k in range(fun.n_instructions()):
            _check_time(k, deadline)
            op = fun.instruction_id(k)
            const = fun.instruction_constant(k) if op == ca.OP_CONST else 0.0
            self.program.append(
                (op, list(fun.instruction_input(k)), list(fun.instruction_output(k)), const)
            )
            if op not in _SUPPORTED:
                raise SetError(
                    f"{fun.name()}: operation {_OP_NAMES.get(op, op)} is not supported by the "
                    "interval evaluator (supported: + − × ÷, powers, √, exp, log, sin, cos, tan, "
                    "atan, tanh, sinh, cosh, fabs, fmin, fmax, comparisons, if_else)"
                )
        self.n_work = 1 + max((o[0] for _, _, o, _ in self.program if o), default=0)

    def _seed(self, k: int, nz: int, batch: int) -> Interval | None:
        """Gradient of input ``k``, entry ``nz``: a unit vector in the gradient columns."""
        if self.refine:
            col = int(self.offsets[k]) + nz
        elif k == self.wrt:
            col = nz
        else:
            return None
        g = np.zeros((batch, self.n_grad))
        g[:, col] = 1.0
        return Interval.point(g)

    # ------------------------------------------------------------------ evaluation
    def __call__(self, inputs: Sequence[Interval]) -> EnclosureResult:
        """Enclose the outputs (and the Jacobian) on a batch of boxes.

        ``inputs[i]`` is an :class:`Interval` of shape ``(B, nnz_in(i))``.
        """
        if len(inputs) != len(self.n_in):
            raise ShapeError(f"{self.fun.name()}: expected {len(self.n_in)} inputs")
        batch = inputs[0].shape[0]
        for i, (iv, n) in enumerate(zip(inputs, self.n_in)):
            if iv.shape != (batch, n):
                raise ShapeError(
                    f"{self.fun.name()}: input {i} must have shape ({batch}, {n}), got {iv.shape}"
                )
        run = _Run(batch, self.n_grad)
        w_val: list[Interval | None] = [None] * self.n_work
        w_grad: list[Interval | None] = [None] * self.n_work
        if self.refine:
            centre_run = _Run(batch, 0)
            centres = [Interval.point(iv.mid) for iv in inputs]
            offset = Interval(
                np.concatenate([_sum_lower(iv.lo, -c.lo) for iv, c in zip(inputs, centres)], 1),
                np.concatenate([_sum_upper(iv.hi, -c.lo) for iv, c in zip(inputs, centres)], 1),
            )  # B − c, per gradient column
            w_cen: list[Interval | None] = [None] * self.n_work
        values = [Interval.point(np.zeros((batch, n))) for n in self.n_out]
        grads = [Interval.point(np.zeros((batch, n, self.n_grad))) for n in self.n_out]
        for step, (op, ins, outs, const) in enumerate(self.program):
            _check_time(step, self.deadline)
            if op == ca.OP_OUTPUT:
                k, nz = outs
                row = self.out_rows[k][nz]  # type: ignore[index]
                v = w_val[ins[0]]
                assert v is not None
                values[k].lo[:, row], values[k].hi[:, row] = v.lo, v.hi
                g = w_grad[ins[0]]
                if g is not None:
                    grads[k].lo[:, row, :], grads[k].hi[:, row, :] = g.lo, g.hi
                continue
            if op == ca.OP_INPUT:
                k, nz = ins
                val, grad = inputs[k][:, nz], self._seed(k, nz, batch)
                if self.refine:
                    w_cen[outs[0]] = centres[k][:, nz]
            elif op == ca.OP_CONST:
                val, grad = Interval.point(np.full(batch, const)), None
                if self.refine:
                    w_cen[outs[0]] = val
            else:
                args = [w_val[i] for i in ins]
                val, grad = run.apply(op, args, [w_grad[i] for i in ins])  # type: ignore[arg-type]
                if self.refine:
                    cen, _ = centre_run.apply(op, [w_cen[i] for i in ins], [None] * len(ins))  # type: ignore[misc]
                    w_cen[outs[0]] = cen
                    if grad is not None:
                        val = self._mean_value(val, cen, grad, offset, run, centre_run)
            w_val[outs[0]] = val
            w_grad[outs[0]] = grad
        for v in values:
            run.flag_value(~np.all(v.finite, axis=1), NONFINITE)
        jacobians = None
        if self.wrt is not None:
            lo_col = int(self.offsets[self.wrt]) if self.refine else 0
            cols = slice(lo_col, lo_col + self.n_wrt)
            jacobians = [g[:, :, cols] for g in grads]
            for g in jacobians:
                run.flag_jac(~np.all(g.finite, axis=(1, 2)), NONFINITE)
        return EnclosureResult(values, jacobians, run.value_flags, run.value_flags | run.jac_flags)

    @staticmethod
    def _mean_value(
        val: Interval,
        cen: Interval,
        grad: Interval,
        offset: Interval,
        run: _Run,
        centre_run: _Run,
    ) -> Interval:
        """``val ∩ (v(c) + Σ_j [∂v/∂v_j](B_j − c_j))`` where no flag has been raised yet."""
        terms = grad * offset  # (B, n_grad)
        lo, hi = cen.lo, cen.hi
        for j in range(terms.lo.shape[1]):
            lo = _sum_lower(lo, terms.lo[:, j])
            hi = _sum_upper(hi, terms.hi[:, j])
        ok = (run.value_flags == 0) & (run.jac_flags == 0) & (centre_run.value_flags == 0)
        ok &= np.isfinite(lo) & np.isfinite(hi)
        return Interval(
            np.where(ok, np.maximum(val.lo, lo), val.lo),
            np.where(ok, np.minimum(val.hi, hi), val.hi),
        )


class _Run:
    """Per-call state: batch size, gradient size and the flag masks."""

    def __init__(self, batch: int, n: int) -> None:
        self.batch, self.n = batch, n
        self.value_flags = np.zeros(batch, dtype=np.int64)
        self.jac_flags = np.zeros(batch, dtype=np.int64)

    def flag_value(self, mask: np.ndarray, bit: int) -> None:
        self.value_flags |= np.where(mask, bit, 0)

    def flag_jac(self, mask: np.ndarray, bit: int) -> None:
        self.jac_flags |= np.where(mask, bit, 0)

    # gradient helpers (None is an exact zero gradient)
    def _zero(self) -> Interval:
        return Interval.point(np.zeros((self.batch, self.n)))

    @staticmethod
    def _col(d: Interval) -> Interval:
        return Interval(d.lo[:, None], d.hi[:, None])

    def chain(self, d: Interval, g: Interval | None) -> Interval | None:
        """``d · g``: a scalar derivative enclosure times a gradient enclosure."""
        return None if g is None else self._col(d) * g

    def gadd(self, g1: Interval | None, g2: Interval | None) -> Interval | None:
        if g1 is None:
            return g2
        if g2 is None:
            return g1
        return g1 + g2

    def gselect(
        self, first: np.ndarray, second: np.ndarray, g1: Interval | None, g2: Interval | None
    ) -> Interval | None:
        """Gradient ``g1`` where ``first``, ``g2`` where ``second``, their hull elsewhere."""
        if g1 is None and g2 is None:
            return None
        a = g1 if g1 is not None else self._zero()
        b = g2 if g2 is not None else self._zero()
        h = a.hull(b)
        m1, m2 = first[:, None], second[:, None]
        return Interval(
            np.where(m1, a.lo, np.where(m2, b.lo, h.lo)),
            np.where(m1, a.hi, np.where(m2, b.hi, h.hi)),
        )

    # ------------------------------------------------------------------ one operation
    def apply(
        self, op: int, args: list[Interval], gargs: list[Interval | None]
    ) -> tuple[Interval, Interval | None]:
        a = args[0]
        ga = gargs[0]
        if op == ca.OP_ASSIGN:
            return a, ga
        if op == ca.OP_NEG:
            return -a, None if ga is None else -ga
        if op == ca.OP_TWICE:
            two = Interval.point(np.full(self.batch, 2.0))
            return a * two, self.chain(two, ga)
        if op == ca.OP_SQ:
            return a.sq(), self.chain(a.scale(2.0), ga)
        if op == ca.OP_SQRT:
            self.flag_value(a.lo < 0, DOMAIN)
            v = a.sqrt()
            if ga is not None:
                self.flag_jac(v.lo <= 0, SLOPE)
            return v, self.chain(Interval.point(np.full(self.batch, 0.5)) / v, ga)
        if op == ca.OP_INV:
            self.flag_value(a.contains_zero(), DIV_ZERO)
            v = Interval.point(np.ones(self.batch)) / a
            return v, self.chain(-(v.sq()), ga)
        if op == ca.OP_FABS:
            pos, neg = a.lo > 0, a.hi < 0
            return a.abs(), self.gselect(pos, neg, ga, None if ga is None else -ga)
        if op == ca.OP_NOT:
            return self._logical((a.lo > 0) | (a.hi < 0), (a.lo == 0) & (a.hi == 0), invert=True)
        if op in _ARB_FUN:
            return self._transcendental(op, a, ga)
        b, gb = args[1], gargs[1]
        if op == ca.OP_ADD:
            return a + b, self.gadd(ga, gb)
        if op == ca.OP_SUB:
            return a - b, self.gadd(ga, None if gb is None else -gb)
        if op == ca.OP_MUL:
            return a * b, self.gadd(self.chain(b, ga), self.chain(a, gb))
        if op == ca.OP_DIV:
            self.flag_value(b.contains_zero(), DIV_ZERO)
            v = a / b
            dv = self.chain(v, gb)
            grad = self.gadd(ga, None if dv is None else -dv)  # (ga − v·gb) / b
            return v, None if grad is None else grad / self._col(b)
        if op in (ca.OP_POW, ca.OP_CONSTPOW):
            return self._power(a, b, ga, gb)
        if op == ca.OP_FMAX:
            first, second = a.lo > b.hi, b.lo > a.hi
            return a.maximum(b), self.gselect(first, second, ga, gb)
        if op == ca.OP_FMIN:
            first, second = a.hi < b.lo, b.hi < a.lo
            return a.minimum(b), self.gselect(first, second, ga, gb)
        if op in _COMPARE:
            return self._compare(op, a, b)
        if op == ca.OP_AND:
            true = ((a.lo > 0) | (a.hi < 0)) & ((b.lo > 0) | (b.hi < 0))
            false = ((a.lo == 0) & (a.hi == 0)) | ((b.lo == 0) & (b.hi == 0))
            return self._logical(true, false)
        if op == ca.OP_OR:
            true = (a.lo > 0) | (a.hi < 0) | (b.lo > 0) | (b.hi < 0)
            false = (a.lo == 0) & (a.hi == 0) & (b.lo == 0) & (b.hi == 0)
            return self._logical(true, false)
        if op == ca.OP_IF_ELSE_ZERO:
            true = (a.lo > 0) | (a.hi < 0)
            false = (a.lo == 0) & (a.hi == 0)
            self.flag_jac(~(true | false), DISCONTINUITY)
            zero = Interval.point(np.zeros(self.batch))
            val = b.where(true, b.hull(zero)).where(~false, zero)
            return val, self.gselect(true, false, gb, None)
        raise AssertionError(f"unhandled operation {op}")  # guarded in Enclosure.__init__

    def _logical(
        self, true: np.ndarray, false: np.ndarray, *, invert: bool = False
    ) -> tuple[Interval, None]:
        if invert:
            true, false = false, true
        undecided = ~(true | false)
        self.flag_jac(undecided, DISCONTINUITY)
        lo = np.where(true, 1.0, 0.0)
        hi = np.where(false, 0.0, 1.0)
        return Interval(lo, hi), None

    def _compare(self, op: int, a: Interval, b: Interval) -> tuple[Interval, None]:
        if op == ca.OP_LT:
            true, false = a.hi < b.lo, a.lo >= b.hi
        elif op == ca.OP_LE:
            true, false = a.hi <= b.lo, a.lo > b.hi
        elif op == ca.OP_EQ:
            true = (a.lo == a.hi) & (b.lo == b.hi) & (a.lo == b.lo)
            false = (a.hi < b.lo) | (b.hi < a.lo)
        else:  # OP_NE
            false = (a.lo == a.hi) & (b.lo == b.hi) & (a.lo == b.lo)
            true = (a.hi < b.lo) | (b.hi < a.lo)
        return self._logical(true, false)

    def _transcendental(
        self, op: int, a: Interval, ga: Interval | None
    ) -> tuple[Interval, Interval | None]:
        if op == ca.OP_LOG:
            self.flag_value(a.lo <= 0, DOMAIN)
        v = _increasing(_ARB_FUN[op], a) if op in _INCREASING else arb_map(_ARB_FUN[op], a)
        if ga is None:
            return v, None
        one = Interval.point(np.ones(self.batch))
        if op == ca.OP_EXP:
            d = v
        elif op == ca.OP_LOG:
            d = one / a
        elif op == ca.OP_SIN:
            d = arb_map(arb.cos, a)
        elif op == ca.OP_COS:
            d = -arb_map(arb.sin, a)
        elif op == ca.OP_TAN:
            d = one + v.sq()
        elif op == ca.OP_ATAN:
            d = one / (one + a.sq())
        elif op == ca.OP_TANH:
            d = one - v.sq()
        elif op == ca.OP_SINH:
            d = arb_map(arb.cosh, a)
        else:  # OP_COSH
            d = arb_map(arb.sinh, a)
        return v, self.chain(d, ga)

    def _power(
        self, a: Interval, b: Interval, ga: Interval | None, gb: Interval | None
    ) -> tuple[Interval, Interval | None]:
        exponent = b.lo[0] if b.lo.size else 0.0
        constant = bool(np.all(b.lo == exponent) and np.all(b.hi == exponent)) and gb is None
        if constant and float(exponent).is_integer() and exponent >= 0:
            p = int(exponent)
            v = a.power(p)
            d = a.power(p - 1).scale(float(p)) if p >= 1 else Interval.point(np.zeros(self.batch))
            return v, self.chain(d, ga)
        # general power a**b = exp(b log a), defined for a > 0
        self.flag_value(a.lo <= 0, DOMAIN)
        log_a = arb_map(arb.log, a)
        v = arb_map(arb.exp, b * log_a)
        grad = self.gadd(self.chain(b * v / a, ga), self.chain(v * log_a, gb))
        return v, grad


_SUPPORTED = (
    {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST, ca.OP_ASSIGN, ca.OP_NEG, ca.OP_TWICE, ca.OP_SQ}
    | {ca.OP_SQRT, ca.OP_INV, ca.OP_FABS, ca.OP_NOT, ca.OP_FMAX, ca.OP_FMIN, ca.OP_AND}
    | {ca.OP_OR, ca.OP_IF_ELSE_ZERO}
    | _BINARY
    | _COMPARE
    | set(_ARB_FUN)
)


class RangeEnclosure:
    """Tight enclosures of the range of ``fun(x, u)`` over boxes of ``v = (x, u)``.

    Three rigorous enclosures are intersected:

    * the natural interval extension;
    * the **mean-value form** ``f(c) + [J](B − c)`` (``c`` the box centre, ``[J]`` the Jacobian
      enclosure, which contains Clarke's generalised Jacobian for ``fmax``/``fmin``/``fabs``),
      tight near stationary points where the natural extension is not;
    * the **monotonicity test**: where ``[J]`` has a fixed sign in coordinate ``j`` for output
      ``i`` the extremes of output ``i`` lie on the corresponding face, which is evaluated instead.

    Boxes are rows of ``lo``/``hi`` over the concatenated ``v``. Besides the enclosure the call
    returns candidate points (centres of the faces of the monotonicity test): real points where
    the caller can evaluate ``fun`` to get inner estimates of the range.

    ``refine`` is passed to :class:`Enclosure`; off by default, since the outer mean-value form
    already gives most of its benefit at a fraction of the cost.
    """

    def __init__(self, fun: ca.Function, *, refine: bool = False) -> None:
        self.n_x, self.n_u = fun.nnz_in(0), fun.nnz_in(1)
        v = ca.SX.sym("v", self.n_x + self.n_u)
        g = ca.Function(f"{fun.name()}_v", [v], [fun(v[: self.n_x], v[self.n_x :])])
        self.n_out = g.size1_out(0)
        self._values = Enclosure(g, refine=refine)
        self._with_jac = Enclosure(g, wrt=0, refine=refine)

    def __call__(self, lo: np.ndarray, hi: np.ndarray) -> tuple[Interval, np.ndarray, np.ndarray]:
        """For ``B`` boxes: the enclosure ``(B, n_out)``, value flags ``(B,)`` and candidate
        points ``(B, 2·n_out + 1, dim v)`` inside the boxes."""
        res = self._with_jac([Interval(lo, hi)])
        natural = res.values[0]
        assert res.jacobians is not None
        jac = res.jacobians[0]
        batch, m, d = jac.shape
        centre = Interval.from_bounds(lo, hi).mid
        pos, neg = jac.lo >= 0, jac.hi <= 0  # (B, m, d)
        blo, bhi = lo[:, None, :], hi[:, None, :]
        # the face holding the minimum of output i, and the face holding its maximum
        min_lo, min_hi = np.where(neg, bhi, blo), np.where(pos, blo, bhi)
        max_lo, max_hi = np.where(pos, bhi, blo), np.where(neg, blo, bhi)
        face_lo = np.concatenate([min_lo, max_lo], axis=1)  # (B, 2m, d)
        face_hi = np.concatenate([min_hi, max_hi], axis=1)
        both = self._values(
            [
                Interval(
                    np.concatenate([face_lo.reshape(-1, d), centre]),
                    np.concatenate([face_hi.reshape(-1, d), centre]),
                )
            ]
        )
        vals = both.values[0]
        flags = both.value_flags
        nf = batch * 2 * m
        face_ok = (flags[:nf] == 0).reshape(batch, 2, m)
        rows = np.arange(m)
        low = vals.lo[:nf].reshape(batch, 2, m, m)[:, 0][:, rows, rows]
        high = vals.hi[:nf].reshape(batch, 2, m, m)[:, 1][:, rows, rows]
        usable = res.jac_flags == 0
        use_low = usable[:, None] & face_ok[:, 0]
        use_high = usable[:, None] & face_ok[:, 1]
        tight_lo = np.where(use_low, np.maximum(natural.lo, low), natural.lo)
        tight_hi = np.where(use_high, np.minimum(natural.hi, high), natural.hi)
        # mean-value form around the centre
        f_c = vals[nf:]
        offset = Interval(_sum_lower(lo, -centre), _sum_upper(hi, -centre))  # B − c
        mv = Interval(f_c.lo, f_c.hi)
        for j in range(d):
            mv = mv + jac[:, :, j] * offset[:, j : j + 1]
        mv_ok = (usable & (flags[nf:] == 0))[:, None] & mv.finite
        tight_lo = np.where(mv_ok, np.maximum(tight_lo, mv.lo), tight_lo)
        tight_hi = np.where(mv_ok, np.minimum(tight_hi, mv.hi), tight_hi)
        points = np.concatenate([Interval(face_lo, face_hi).mid, centre[:, None, :]], axis=1)
        return Interval(tight_lo, tight_hi), res.value_flags, points
