"""Hamilton's equations as a tape of elementary operations, for Taylor series.

The Taylor coefficients of a solution, ``y(t0 + h) = sum_k Y_k h^k``, follow
from ``Y_{k+1} = F_k / (k + 1)``, where ``F_k`` is the k-th coefficient of
``f(t, y(t))`` along the solution.  ``F_k`` is computed by automatic
differentiation in Taylor mode: ``f`` is broken into elementary operations
(``+``, ``*``, ``/``, powers, ``exp``, ``sin`` and ``cos``, ...), each with a
recurrence that gives its k-th coefficient from the lower ones of its
arguments (Moore 1966; Jorba & Zou, Experiment. Math. 14 (2005) 99, section
3; the decomposition heyoka makes, Biscani & Izzo, MNRAS 504 (2021) 2614).

:func:`taylor_tape` makes that decomposition once per
:class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`, as data: a
:class:`TaylorTape` of integer instructions and float constants, which one
compiled interpreter (:mod:`hamrkq.rkq.taylor`) runs for every system.  No
source text is generated, so nothing is compiled per system.

Slots: the state's ``n`` components are slots ``0 .. n-1``, the time is slot
``n``, and every operation writes one slot (two for a sine-cosine pair or a
tangent and its square).  Identical subexpressions share a slot, and a
``sin`` and a ``cos`` of the same argument share one instruction.
Operations on constants only (numbers, parameters) are *setup* instructions,
run once at order 0: their higher coefficients are zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from hamrkq.errors import CodegenError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["OPCODES", "TaylorTape", "tape_of", "taylor_tape"]

# The instruction set.  Each row of TaylorTape.code is (op, out, a, b, c):
# the operation, the slot it writes, its arguments' slots and one more slot or
# a function number.  The k-th coefficient of ``out`` needs only coefficients
# of order <= k of its arguments, and of order < k of ``out`` itself.
CONST = 0  # out = consts[row]
PARAM = 1  # out = params[a]
ADD = 2  # out = a + b
SUB = 3  # out = a - b
MUL = 4  # out = a * b (Cauchy product)
DIV = 5  # out = a / b
ADDC = 6  # out = a + b, b constant
MULC = 7  # out = a * b, b constant
SQUARE = 8  # out = a * a
SQRT = 9  # out = sqrt(a)
POW = 10  # out = a ** b, b constant
EXP = 11  # out = exp(a)
LOG = 12  # out = log(a)
SINCOS = 13  # out = sin(a), b = cos(a)
SINHCOSH = 14  # out = sinh(a), b = cosh(a)
TAN = 15  # out = tan(a), b = out * out
TANH = 16  # out = tanh(a), b = out * out
INTEGRAL = 17  # out = F(a) with F' = g, g's series in slot b, F = INVERSE[c]
ABS = 18  # out = |a| (the series of sign(a_0) a)
SIGN = 19  # out = sign(a_0), constant along the series

#: Names of the operations, by code (for messages and tests).
OPCODES = {
    CONST: "const", PARAM: "param", ADD: "add", SUB: "sub", MUL: "mul", DIV: "div",
    ADDC: "addc", MULC: "mulc", SQUARE: "square", SQRT: "sqrt", POW: "pow",
    EXP: "exp", LOG: "log", SINCOS: "sincos", SINHCOSH: "sinhcosh", TAN: "tan",
    TANH: "tanh", INTEGRAL: "integral", ABS: "abs", SIGN: "sign",
}  # fmt: skip

# The inverse functions INTEGRAL integrates (c of the row), with the
# expression of their derivative's factor g in terms of the argument a.
ASIN, ACOS, ATAN, ASINH, ACOSH, ATANH = range(6)
_INVERSE = {
    sp.asin: (ASIN, lambda a: (1 - a**2) ** sp.Rational(-1, 2)),
    sp.acos: (ACOS, lambda a: -((1 - a**2) ** sp.Rational(-1, 2))),
    sp.atan: (ATAN, lambda a: 1 / (1 + a**2)),
    sp.asinh: (ASINH, lambda a: (1 + a**2) ** sp.Rational(-1, 2)),
    sp.acosh: (ACOSH, lambda a: (a**2 - 1) ** sp.Rational(-1, 2)),
    sp.atanh: (ATANH, lambda a: 1 / (1 - a**2)),
}


@dataclass(frozen=True)
class TaylorTape:
    """A system's right-hand side as elementary operations (see the module).

    Attributes
    ----------
    code : ndarray of int64, shape (rows, 5)
        The instructions ``(op, out, a, b, c)``, setup rows first.
    consts : ndarray of float64, shape (rows,)
        The number a ``CONST`` row writes (zero on other rows).
    setup : int
        How many leading rows are setup rows (run at order 0 only).
    outputs : ndarray of int64, shape (n,)
        The slot holding each component of ``f``.
    slots : int
        How many slots the coefficients array needs.
    """

    code: np.ndarray
    consts: np.ndarray
    setup: int
    outputs: np.ndarray
    slots: int

    @property
    def n(self) -> int:
        """The state's dimension."""
        return int(self.outputs.shape[0])

    def operations(self) -> dict[str, int]:
        """How many rows of each operation the tape holds (setup included)."""
        counts: dict[str, int] = {}
        for row in self.code:
            name = OPCODES[int(row[0])]
            counts[name] = counts.get(name, 0) + 1
        return counts


_TWO_OUTPUTS = (SINCOS, SINHCOSH, TAN, TANH)


class _Builder:
    """Walks the expressions, one slot per distinct subexpression."""

    def __init__(self, state: Sequence[sp.Symbol], params: Sequence[sp.Symbol], t: sp.Symbol):
        self.slot_of: dict[sp.Expr, int] = {y: i for i, y in enumerate(state)}
        self.slot_of[t] = len(state)
        self.moving = {*state, t}
        self.param_index = {p: j for j, p in enumerate(params)}
        self.slots = len(state) + 1
        self.constant: set[int] = set()
        self.numbers: dict[float, int] = {}
        self.setup_rows: list[tuple[int, int, int, int, int, float]] = []
        self.rows: list[tuple[int, int, int, int, int, float]] = []
        self.shared: dict[tuple[int, int], tuple[int, int]] = {}

    # -- slots and rows --------------------------------------------------------
    def new_slot(self) -> int:
        self.slots += 1
        return self.slots - 1

    def emit(self, op: int, a: int = -1, b: int = -1, c: int = -1, value: float = 0.0) -> int:
        out = self.new_slot()
        self.emit_into(op, out, a, b, c, value)
        return out

    def emit_into(self, op: int, out: int, a: int, b: int, c: int, value: float = 0.0) -> None:
        """A row; a setup row where every argument is constant (its outputs
        are then constant too)."""
        inputs = [a] if op in _TWO_OUTPUTS else [s for s in (a, b) if s >= 0]
        row = (op, out, a, b, c, value)
        if op in (CONST, PARAM) or all(s in self.constant for s in inputs):
            self.constant.add(out)
            if op in _TWO_OUTPUTS:
                self.constant.add(b)
            self.setup_rows.append(row)
        else:
            self.rows.append(row)

    def number(self, value: float) -> int:
        """The slot of a float constant, one per value."""
        if value not in self.numbers:
            self.numbers[value] = self.emit(CONST, value=value)
        return self.numbers[value]

    # -- expressions -----------------------------------------------------------
    def moves(self, expr: sp.Expr) -> bool:
        """Whether ``expr`` depends on the state or the time."""
        return not self.moving.isdisjoint(expr.free_symbols)

    def slot(self, expr: sp.Expr) -> int:
        if expr not in self.slot_of:
            self.slot_of[expr] = self._build(expr)
        return self.slot_of[expr]

    def _build(self, expr: sp.Expr) -> int:
        if expr in self.param_index:
            return self.emit(PARAM, a=self.param_index[expr])
        if expr.is_Number or isinstance(expr, (type(sp.pi), type(sp.E))):
            value = float(expr)
            if not np.isfinite(value):
                raise CodegenError(f"cannot make a Taylor tape of the number {expr}")
            return self.number(value)
        if isinstance(expr, sp.Symbol):
            raise CodegenError(f"cannot make a Taylor tape: undeclared symbol {expr}")
        if isinstance(expr, sp.Add):
            return self._sum(expr.args)
        if isinstance(expr, sp.Mul):
            return self._product(expr.args)
        if isinstance(expr, sp.Pow):
            return self._power(*expr.args)
        return self._function(expr)

    def _sum(self, terms: Sequence[sp.Expr]) -> int:
        moving = [term for term in terms if self.moves(term)]
        constants = [term for term in terms if not self.moves(term)]
        if not moving or not constants:
            return self._chain_sum(terms)
        # the constant part once, in setup, added last
        return self.emit(ADDC, self._chain_sum(moving), self.slot(sp.Add(*constants)))

    def _chain_sum(self, terms: Sequence[sp.Expr]) -> int:
        # one ADD or SUB per term, a term -x (Mul(-1, x)) as a subtraction
        acc = -1
        for term in terms:
            negated = isinstance(term, sp.Mul) and term.args[0] == -1
            slot = self.slot(-term if negated else term)
            if acc >= 0:
                acc = self.emit(SUB if negated else ADD, acc, slot)
            else:
                acc = self.emit(MULC, slot, self.number(-1.0)) if negated else slot
        return acc

    def _product(self, factors: Sequence[sp.Expr]) -> int:
        numerator: list[sp.Expr] = []
        denominator: list[sp.Expr] = []
        for factor in factors:
            if isinstance(factor, sp.Pow) and factor.exp.is_Number and factor.exp < 0:
                denominator.append(factor.base ** (-factor.exp))
            else:
                numerator.append(factor)
        moving = [f for f in numerator if self.moves(f)]
        constants = [f for f in numerator if not self.moves(f)]
        if moving and constants:
            acc = self.emit(MULC, self._chain_product(moving), self.slot(sp.Mul(*constants)))
        else:
            acc = self._chain_product(numerator) if numerator else self.number(1.0)
        if not denominator:
            return acc
        below = self._chain_product(denominator)
        if below in self.constant and acc not in self.constant:
            # a / c as a * (1 / c): the reciprocal once, in setup
            return self.emit(MULC, acc, self.emit(DIV, self.number(1.0), below))
        return self.emit(DIV, acc, below)

    def _chain_product(self, factors: Sequence[sp.Expr]) -> int:
        acc = -1
        for factor in factors:
            slot = self.slot(factor)
            if acc < 0:
                acc = slot
            elif slot in self.constant and acc not in self.constant:
                acc = self.emit(MULC, acc, slot)
            elif acc in self.constant and slot not in self.constant:
                acc = self.emit(MULC, slot, acc)
            else:
                acc = self.emit(MUL, acc, slot)
        return acc

    def _power(self, base: sp.Expr, exponent: sp.Expr) -> int:
        if self.moves(exponent):
            # b ** e = exp(e log b), defined where b > 0
            return self.slot(sp.exp(exponent * sp.log(base), evaluate=False))
        a = self.slot(base)
        if exponent.is_Integer and exponent > 0:
            return self._integer_power(a, int(exponent))
        if exponent == sp.S.Half:
            return self.emit(SQRT, a)
        return self.emit(POW, a, self.slot(exponent))

    def _integer_power(self, a: int, n: int) -> int:
        # by squaring: exact where a_0 = 0, where the general power's
        # recurrence divides by a_0
        if n == 1:
            return a
        if (a, n) not in self.shared:
            if n % 2 == 0:
                result = self.emit(SQUARE, self._integer_power(a, n // 2))
            else:
                result = self.emit(MUL, self._integer_power(a, n - 1), a)
            self.shared[a, n] = (result, -1)
        return self.shared[a, n][0]

    def _function(self, expr: sp.Expr) -> int:
        func = expr.func
        if func in (sp.sin, sp.cos, sp.sinh, sp.cosh):
            a = self.slot(expr.args[0])
            trig = func in (sp.sin, sp.cos)
            key = (a, -1 if trig else -2)
            if key not in self.shared:
                first, second = self.new_slot(), self.new_slot()
                self.emit_into(SINCOS if trig else SINHCOSH, first, a, second, -1)
                self.shared[key] = (first, second)
            first, second = self.shared[key]
            return first if func in (sp.sin, sp.sinh) else second
        if func in (sp.tan, sp.tanh):
            out, square = self.new_slot(), self.new_slot()
            self.emit_into(
                TAN if func is sp.tan else TANH, out, self.slot(expr.args[0]), square, -1
            )
            return out
        if func is sp.exp:
            return self.emit(EXP, self.slot(expr.args[0]))
        if func is sp.log:
            return self.emit(LOG, self.slot(expr.args[0]))
        if func in _INVERSE:
            number, factor = _INVERSE[func]
            argument = expr.args[0]
            return self.emit(INTEGRAL, self.slot(argument), self.slot(factor(argument)), number)
        if func is sp.Abs:
            return self.emit(ABS, self.slot(expr.args[0]))
        if func is sp.sign:
            return self.emit(SIGN, self.slot(expr.args[0]))
        raise CodegenError(
            f"cannot make a Taylor tape of {func.__name__}: no Taylor recurrence for it "
            "(supported: + * / **, sqrt, exp, log, sin, cos, tan, sinh, cosh, tanh, "
            "asin, acos, atan, asinh, acosh, atanh, Abs, sign)"
        )


def tape_of(
    rhs: Sequence[sp.Expr],
    state: Sequence[sp.Symbol],
    params: Sequence[sp.Symbol],
    t: sp.Symbol,
) -> TaylorTape:
    """The tape of ``dy/dt = rhs(t, y, params)`` (see the module).

    Parameters
    ----------
    rhs : sequence of sympy.Expr
        The right-hand side, one expression per state component.
    state, params : sequence of sympy.Symbol
        The state's symbols (slots ``0 .. n-1``) and the parameters' (read
        from the ``params`` array by index at run time).
    t : sympy.Symbol
        The time (slot ``n``).

    Raises
    ------
    CodegenError
        Where an expression holds an operation with no Taylor recurrence
        (``atan2``) or an undeclared symbol.
    """
    builder = _Builder(state, params, t)
    outputs = np.array([builder.slot(f) for f in rhs], dtype=np.int64)
    rows = builder.setup_rows + builder.rows
    code = np.array([row[:5] for row in rows], dtype=np.int64).reshape(-1, 5)
    consts = np.array([row[5] for row in rows], dtype=np.float64)
    return TaylorTape(
        code=code, consts=consts, setup=len(builder.setup_rows), outputs=outputs,
        slots=builder.slots,
    )  # fmt: skip


def taylor_tape(system: Hamiltonian) -> TaylorTape:
    """The tape of Hamilton's equations of ``system`` (see :func:`tape_of`)."""
    return tape_of(list(system.rhs), system.state, system.parameters, system.t)
