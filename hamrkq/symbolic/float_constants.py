"""Constant subexpressions of a parsed expression, evaluated in double precision.

:func:`check_constants` refuses a constant that is not a finite real double
(``exp(exp(exp(1000)))``, ``acos(2)``) when the text is read, so that it does
not overflow in a run, or run SymPy's arbitrary-precision arithmetic out of
memory.  Values are computed bottom-up with Python floats, never with SymPy's
arbitrary-precision evaluation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np
import sympy as sp

from hamrkq.errors import ExpressionError

__all__ = ["MAX_MAGNITUDE", "check_constants"]

#: Largest magnitude a constant subexpression may have: the largest double.
#: Constants are evaluated in double precision when a file is read, so that
#: ``exp(exp(exp(1000)))`` is refused there (and not left to overflow, or to
#: run SymPy's arbitrary-precision arithmetic out of memory, in a run).
MAX_MAGNITUDE = float(np.finfo(float).max)

_FLOAT_FUNCTIONS: Mapping[type, Callable[..., float]] = {
    sp.sin: math.sin,
    sp.cos: math.cos,
    sp.tan: math.tan,
    sp.asin: math.asin,
    sp.acos: math.acos,
    sp.atan: math.atan,
    sp.atan2: math.atan2,
    sp.sinh: math.sinh,
    sp.cosh: math.cosh,
    sp.tanh: math.tanh,
    sp.exp: math.exp,
    sp.log: math.log,
    sp.Abs: abs,
}


def _float_value(expr: sp.Expr) -> float:
    """``expr`` (no free symbols) in double precision, bottom-up, with Python floats.

    Raises OverflowError, ValueError or ZeroDivisionError where double
    precision cannot represent a value (never calls SymPy's arbitrary-precision
    evaluation, which ``exp(exp(1000))`` would run out of memory).
    """
    if expr.is_Rational:
        value = expr.p / expr.q  # int / int: exact rounding, OverflowError if too large
    elif expr.is_Float:
        value = float(expr)
    elif expr is sp.pi:
        value = math.pi
    elif expr is sp.E:
        value = math.e
    elif expr.is_Add:
        value = math.fsum(_float_value(arg) for arg in expr.args)
    elif expr.is_Mul:
        value = 1.0
        for arg in expr.args:
            value *= _float_value(arg)
    elif expr.is_Pow:
        base, exponent = (_float_value(arg) for arg in expr.args)
        if base == 0 and exponent < 0:
            raise ZeroDivisionError("0 to a negative power")
        value = base**exponent
        if isinstance(value, complex):
            raise ValueError("not real")
    elif type(expr) is sp.exp:  # exp(x) is a Pow in some SymPy versions, a function in others
        value = math.exp(_float_value(expr.args[0]))
    elif type(expr) in _FLOAT_FUNCTIONS:
        value = _FLOAT_FUNCTIONS[type(expr)](*(_float_value(arg) for arg in expr.args))
    else:
        value = complex(sp.N(expr, 17))  # anything else SymPy built: a small known constant
        if value.imag != 0:
            raise ValueError("not real")
        value = value.real
    value = float(value)
    if not math.isfinite(value):
        raise OverflowError("not finite")
    return value


def check_constants(expr: sp.Expr, where: dict) -> None:
    """Refuse a constant subexpression that is not a finite real double."""
    if not expr.args and not expr.is_Number:
        return  # a symbol, or a named constant (pi, E)
    if expr.free_symbols:
        for arg in expr.args:
            check_constants(arg, where)
        return
    try:
        value = _float_value(expr)
    except (OverflowError, ValueError, ZeroDivisionError, TypeError):
        value = None
    if value is None or abs(value) > MAX_MAGNITUDE:
        raise ExpressionError(
            "a constant in the expression is not a finite real number in double precision "
            "(overflow, or outside the function's domain)",
            piece=str(expr)[:60],
            **where,
        )
