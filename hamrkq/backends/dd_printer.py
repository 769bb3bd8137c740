"""Hamilton's right-hand side printed in double-double arithmetic.

:func:`rhs_dd_block` prints ``rhs_dd``, the right-hand side evaluated with
every quantity a double-double ``(hi, lo)`` (about 32 digits) through
:mod:`hamrkq.rkq.ddarith`.  It is what the quencher track evaluates when it
runs in double-double (``solve(..., quencher_precision="double-double")``):
where double precision's rounding floor is above the tolerance (prentice2011
at 1e-12 over [0, 4000], docs/algorithm.md), the quencher's stages and ``f``
must both be carried in extended precision.

Its signature is the fused ``rhs_jvp``'s, ``rhs_dd(t, y, params, ylo, out,
outlo, JM)``: the state's high words in ``y`` and low words in ``ylo``, the
derivative's in ``out`` and ``outlo`` (``JM`` is unused).  The kernel passes
it where it would pass ``rhs_jvp``, which a double-double quencher does not
use (its Gamma comes from the shadow track), so the kernel's signature stays
the same.

Common subexpressions are shared (:func:`sympy.cse`); parameters and time
enter as doubles (``(p, 0)``), rationals and ``pi``, ``E`` as double-double
constants computed here exactly, a SymPy Float to its own precision (one of
more than 53 bits, ``Float("0.1", 30)``, as the double-double nearest it,
not rounded to a double).  Supported: ``+ * **`` (integer and
half-integer powers exactly, others as ``exp(b log a)``), ``sin cos tan exp
log cosh Abs sign``; anything else raises :class:`~hamrkq.errors.CodegenError`
naming it (the inverse trigonometric and hyperbolic functions, ``sinh`` and
``tanh`` have no double-double form here).
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

import mpmath
import sympy as sp

from hamrkq.errors import CodegenError

__all__ = ["DD_FUNCTIONS", "rhs_dd_block"]

#: The ddarith functions the printed code calls (imported by the module).
DD_FUNCTIONS = (
    "dd_add",
    "dd_neg",
    "dd_mul",
    "dd_mul_d",
    "dd_div",
    "dd_sqrt",
    "dd_exp",
    "dd_log",
    "dd_sin",
    "dd_cos",
    "dd_sincos",
    "dd_pow_int",
    "dd_pow",
)


def _split(value: Fraction) -> tuple[float, float]:
    """The double-double nearest ``value``: ``hi`` rounded, ``lo`` the rest."""
    hi = float(value)
    return hi, float(value - Fraction(hi))


def _constant(value) -> tuple[str, str]:
    """Literal text of a double-double constant (an exact rational, an
    mpmath number or a SymPy Float; one of 53 bits or fewer has the low
    word 0.0)."""
    if not isinstance(value, Fraction):
        with mpmath.workdps(60):
            hi = float(value)
            lo = float(mpmath.mpf(value) - mpmath.mpf(hi))
    else:
        hi, lo = _split(value)
    return repr(hi), repr(lo)


class _Printer:
    """Emits one assignment per operation into ``lines``; each value is a
    pair of names (or literals) ``(hi, lo)``."""

    def __init__(
        self, state: Sequence[sp.Symbol], parameters: Sequence[sp.Symbol], time, paired=()
    ):
        #: Arguments whose sine and cosine both occur: one ``dd_sincos``.
        self.paired = frozenset(paired)
        self.values: dict[sp.Expr, tuple[str, str]] = {}
        for i, s in enumerate(state):
            self.values[s] = (f"y[{i}]", f"ylo[{i}]")
        for j, s in enumerate(parameters):
            self.values[s] = (f"params[{j}]", "0.0")
        self.values[time] = ("t", "0.0")
        self.lines: list[str] = []
        self.count = 0

    def _new(self, call: str) -> tuple[str, str]:
        hi, lo = f"h{self.count}", f"l{self.count}"
        self.count += 1
        self.lines.append(f"    {hi}, {lo} = {call}")
        return hi, lo

    def bind(self, symbol: sp.Symbol, expr: sp.Expr) -> None:
        self.values[symbol] = self.emit(expr)

    def emit(self, expr: sp.Expr) -> tuple[str, str]:
        known = self.values.get(expr)
        if known is not None:
            return known
        value = self._emit(expr)
        self.values[expr] = value
        return value

    def _emit(self, expr: sp.Expr) -> tuple[str, str]:
        if expr.is_Integer or expr.is_Rational:
            return _constant(Fraction(int(expr.p), int(expr.q)))
        if expr.is_Float:  # to its own precision: Float("0.1", 30) is not rounded to a double
            return _constant(expr)
        if expr in (sp.pi, sp.E):
            return _constant(mpmath.pi if expr == sp.pi else mpmath.e)
        if expr.is_Symbol:  # not the system's (its name is not quoted: see rhs_dd_block)
            raise CodegenError("cannot generate double-double code for a symbol not of the system")
        if expr.is_Add:
            return self._fold("dd_add", expr.args)
        if expr.is_Mul:
            return self._product(expr)
        if expr.is_Pow:
            return self._power(expr.base, expr.exp)
        return self._function(expr)

    def _fold(self, op: str, args) -> tuple[str, str]:
        hi, lo = self.emit(args[0])
        for arg in args[1:]:
            bh, bl = self.emit(arg)
            hi, lo = self._new(f"{op}({hi}, {lo}, {bh}, {bl})")
        return hi, lo

    def _product(self, expr: sp.Expr) -> tuple[str, str]:
        coefficient, factors = expr.as_coeff_Mul()
        if coefficient == 1:
            return self._fold("dd_mul", expr.args)
        value = self.emit(factors)
        if coefficient == -1:
            return self._new(f"dd_neg({value[0]}, {value[1]})")
        ch, cl = self.emit(coefficient)
        if cl == "0.0":  # an integer or a float: a double times a double-double
            return self._new(f"dd_mul_d({value[0]}, {value[1]}, {ch})")
        return self._new(f"dd_mul({value[0]}, {value[1]}, {ch}, {cl})")

    def _power(self, base: sp.Expr, exponent: sp.Expr) -> tuple[str, str]:
        bh, bl = self.emit(base)
        if exponent.is_Integer:
            return self._new(f"dd_pow_int({bh}, {bl}, {int(exponent)})")
        if exponent.is_Rational and exponent.q == 2:
            root = self._new(f"dd_sqrt({bh}, {bl})")
            k = int(exponent.p) // 2  # exponent = k + 1/2, k may be negative
            if k == 0:
                return root
            whole = self._new(f"dd_pow_int({bh}, {bl}, {k})")
            return self._new(f"dd_mul({whole[0]}, {whole[1]}, {root[0]}, {root[1]})")
        eh, el = self.emit(exponent)
        return self._new(f"dd_pow({bh}, {bl}, {eh}, {el})")

    def _function(self, expr: sp.Expr) -> tuple[str, str]:
        if expr.func in (sp.sin, sp.cos) and expr.args[0] in self.paired:
            ah, al = self.emit(expr.args[0])
            n = self.count
            self.count += 1
            self.lines.append(f"    sh{n}, sl{n}, ch{n}, cl{n} = dd_sincos({ah}, {al})")
            self.values[sp.sin(expr.args[0])] = (f"sh{n}", f"sl{n}")
            self.values[sp.cos(expr.args[0])] = (f"ch{n}", f"cl{n}")
            return self.values[expr]
        unary = {sp.sin: "dd_sin", sp.cos: "dd_cos", sp.exp: "dd_exp", sp.log: "dd_log"}
        if expr.func in unary:
            ah, al = self.emit(expr.args[0])
            return self._new(f"{unary[expr.func]}({ah}, {al})")
        if expr.func is sp.tan:
            s = self.emit(sp.sin(expr.args[0]))
            c = self.emit(sp.cos(expr.args[0]))
            return self._new(f"dd_div({s[0]}, {s[1]}, {c[0]}, {c[1]})")
        if expr.func is sp.cosh:  # (e^x + e^-x) / 2: no cancellation
            ah, al = self.emit(expr.args[0])
            up = self._new(f"dd_exp({ah}, {al})")
            down = self._new(f"dd_exp(-{ah}, -{al})")
            total = self._new(f"dd_add({up[0]}, {up[1]}, {down[0]}, {down[1]})")
            return self._new(f"dd_mul_d({total[0]}, {total[1]}, 0.5)")
        if expr.func is sp.Abs:
            ah, al = self.emit(expr.args[0])
            return self._new(f"({ah}, {al}) if {ah} >= 0.0 else (-{ah}, -{al})")
        if expr.func is sp.sign:
            ah, _ = self.emit(expr.args[0])
            return self._new(f"(1.0 if {ah} > 0.0 else (-1.0 if {ah} < 0.0 else 0.0), 0.0)")
        raise CodegenError(
            f"cannot generate double-double code for {type(expr).__name__}: "
            "supported are + * **, sin, cos, tan, exp, log, cosh, Abs and sign"
        )


def rhs_dd_block(ham) -> list[str]:
    """Lines of ``def rhs_dd(t, y, params, ylo, out, outlo, JM)`` for ``ham``.

    Every symbol is printed as its slot (``y[i]``, ``ylo[i]``, ``params[j]``,
    ``t``), whatever its class or name, and the errors name the function, not
    the expression: their text is written into the generated module
    (``DD_UNSUPPORTED``), where no user-chosen name appears.

    Raises
    ------
    CodegenError
        If the right-hand side contains a function with no double-double form.
    """
    # Temporaries equal to no symbol of the system (whose values they would replace).
    temps = sp.numbered_symbols("_d", exclude=[*ham.state, *ham.parameters, ham.t])
    replacements, reduced = sp.cse(list(ham.rhs), symbols=temps, order="none")
    exprs = [value for _, value in replacements] + list(reduced)
    sines = {a.args[0] for e in exprs for a in e.atoms(sp.sin)}
    cosines = {a.args[0] for e in exprs for a in e.atoms(sp.cos)}
    printer = _Printer(ham.state, ham.parameters, ham.t, sines & cosines)
    for symbol, value in replacements:
        printer.bind(symbol, value)
    results = [printer.emit(value) for value in reduced]
    stores = []
    for i, (hi, lo) in enumerate(results):
        stores += [f"    out[{i}] = {hi}", f"    outlo[{i}] = {lo}"]
    return [
        "def rhs_dd(t, y, params, ylo, out, outlo, JM):",
        '    """dy/dt in double-double: high words into out, low words into outlo."""',
        *printer.lines,
        *stores,
    ]
