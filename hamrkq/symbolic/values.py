"""Numbers given for a Hamiltonian's symbols: parameter and initial values.

:func:`as_number` makes a finite float of a number or of a SymPy expression
without free symbols; :func:`assumption_conflict` says why a value breaks an
assumption declared on its symbol (SymPy has already simplified H under it).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError

__all__ = ["CHECKED_ASSUMPTIONS", "as_number", "assumption_conflict", "show_value"]


def as_number(value: Any, what: str) -> float:
    """A finite float from a number or a SymPy expression without free symbols."""
    if isinstance(value, str | bytes):
        raise InputTypeError(f"{what} must be a number, not the string {value!r}")
    if isinstance(value, sp.Basic):
        if value.free_symbols:
            names = ", ".join(sorted(str(s) for s in value.free_symbols))
            raise InputError(f"{what} = {value} has free symbols ({names})")
        try:
            number = complex(sp.N(value, 17))
        except (TypeError, ValueError):
            raise InputError(f"{what} = {value} is not a number") from None
        if number.imag != 0:
            raise InputError(f"{what} = {value} is not real")
        value = number.real
    elif isinstance(value, bool) or not isinstance(value, numbers.Real | np.floating):
        raise InputTypeError(f"{what} must be a real number, not {type(value).__name__}")
    try:
        value = float(value)
    except OverflowError:
        raise InputError(f"{what} must be finite, got a number too large for a float") from None
    if not math.isfinite(value):
        raise InputError(f"{what} must be finite, got {value}")
    return value


#: Assumptions a symbol may carry that a real number can be checked against.
#: SymPy simplifies H under them (``sqrt(q**2)`` is ``q`` for a positive
#: ``q``), so a value that breaks one gives a silently wrong answer.  Others
#: (``rational``, ``algebraic``, ...) say nothing a float can honestly decide.
CHECKED_ASSUMPTIONS = (
    "positive",
    "negative",
    "nonnegative",
    "nonpositive",
    "zero",
    "nonzero",
    "integer",
    "noninteger",
    "even",
    "odd",
    "prime",
    "composite",
    "extended_positive",
    "extended_negative",
    "extended_nonnegative",
    "extended_nonpositive",
    "extended_nonzero",
)


def assumption_conflict(symbol: Any, value: float) -> str | None:
    """Why ``value`` contradicts an assumption declared on ``symbol``, or None."""
    declared = getattr(symbol, "assumptions0", {})
    if not any(name in declared for name in CHECKED_ASSUMPTIONS):
        return None
    number = sp.Rational(*float(value).as_integer_ratio())  # the float, exactly
    for name in CHECKED_ASSUMPTIONS:
        wanted = declared.get(name)
        if wanted is None:
            continue
        actual = getattr(number, f"is_{name}")
        if actual is not None and actual != wanted:
            return (
                f"{symbol} is declared {name}={wanted} but is given the value {value!r}; "
                "SymPy has already simplified H under that assumption, so the result "
                "would be wrong. Give a value that satisfies it, or declare the symbol "
                "without the assumption"
            )
    return None


def show_value(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
