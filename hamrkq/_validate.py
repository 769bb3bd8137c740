"""Small validators shared by the public entry points.

Each checks one argument and raises an error from :mod:`hamrkq.errors` whose
message names the parameter and shows the offending value.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError, OptionError

__all__ = ["MAX_COUNT", "choice", "count", "positive", "real", "show", "span", "tolerance"]

#: The largest count (``max_steps``, ``keep_every``, ``z_substeps``) accepted.
#: Counts end in int64 fields of the compiled kernel's configuration, and the
#: loop adds to and multiplies them; 2**62 leaves a factor of two of headroom
#: below int64's 2**63 - 1 (a larger count failed deep in the run with
#: NumPy's OverflowError instead of a message naming the option).
MAX_COUNT = 2**62


def show(value: Any) -> str:
    """``repr(value)``, cut to 80 characters for error messages."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def real(name: str, value: Any) -> float:
    """A float from a real number or a SymPy number (never from a string)."""
    if isinstance(value, str | bytes):
        raise InputTypeError(f"{name} must be a number, not the string {value!r}")
    if isinstance(value, sp.Basic):
        if value.free_symbols:
            raise InputError(f"{name}={value} has free symbols")
        value = complex(sp.N(value, 17))
        if value.imag != 0:
            raise InputError(f"{name}={value} is not real")
        value = value.real
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a real number, got {show(value)}")
    try:
        return float(value)
    except OverflowError:  # an int beyond the float range
        raise InputError(f"{name} is too large for a float, got {show(value)}") from None


def span(t_span: Any) -> tuple[float, float]:
    """``t_span`` as two finite floats ``(t0, t_end)``."""
    if type(t_span) is tuple and len(t_span) == 2:
        # two floats, the common case, without the checks below (every solve pays this)
        t0, t_end = t_span
        if type(t0) is float and type(t_end) is float and math.isfinite(t0 + t_end):
            return t0, t_end
    try:
        length = None if isinstance(t_span, str | bytes) else len(t_span)
    except TypeError:  # a 0-d array has __len__ but no length
        length = None
    if length != 2:
        raise InputError(f"t_span must be two numbers (t0, t_end), got {show(t_span)}")
    # (a float is its own float: real() is for the rest)
    t0, t_end = (v if type(v) is float else real(f"t_span[{i}]", v) for i, v in enumerate(t_span))
    if not (math.isfinite(t0) and math.isfinite(t_end)):
        raise InputError(f"t_span must be finite, got {show(t_span)}")
    return t0, t_end


def plain_number(value: Any) -> float | None:
    """``value`` as a float where it is one number that converts exactly (a
    float, or an int below 2**53: ``rtol = 0`` in a problem file), else
    None: the common case of a tolerance, checked without arrays."""
    if isinstance(value, float) or (type(value) is int and abs(value) < 2**53):
        return float(value)
    return None


def tolerance(name: str, value: Any, dim: int, positive: bool) -> np.ndarray:
    """A tolerance as an array of ``dim`` finite values (> 0, or >= 0 if not ``positive``)."""
    number = plain_number(value)
    if number is not None:
        # one number, the common case, without the arrays below (every solve pays this)
        if math.isfinite(number) and (number > 0.0 if positive else number >= 0.0):
            return np.full(dim, number)
    if isinstance(value, str | bytes):
        raise InputTypeError(f"{name} must be a number or {dim} numbers, got {value!r}")
    items = np.ravel(np.asarray(value, dtype=object)) if np.ndim(value) else [value]
    if np.ndim(value) > 1 or len(items) not in (1, dim):
        raise InputError(f"{name} must be a scalar or have {dim} entries, got {show(value)}")
    array = np.array([real(name, v) for v in items], dtype=float)
    bad = ~np.isfinite(array) | ((array <= 0) if positive else (array < 0))
    if np.any(bad):
        need = "positive" if positive else "zero or positive"
        why = ""
        if positive and np.all(np.isfinite(array)) and np.all(array >= 0):
            # SciPy takes atol=0 for a purely relative tolerance; RKQ's
            # promise needs a tolerance above zero where a component is zero.
            why = (
                f" (a zero {name} leaves no tolerance where a component passes "
                "through zero; for a relative tolerance give rtol with a tiny "
                f"{name}, 1e-20 say)"
            )
        raise InputError(f"{name} must be finite and {need}, got {show(value)}{why}")
    return np.broadcast_to(array, (dim,)).copy()


def choice(name: str, value: Any, valid: Any) -> str:
    """``value`` if it is one of ``valid``, else an OptionError listing them."""
    if not isinstance(value, str) or value not in valid:
        listing = ", ".join(repr(v) for v in valid)
        raise OptionError(f"{name}={show(value)} is not valid; valid values: {listing}")
    return value


def positive(name: str, value: Any, *, inf: bool = False, upper: float | None = None) -> float:
    """A positive float (infinity only if ``inf``; at most ``upper`` if given)."""
    number = real(name, value)
    if not (number > 0) or (math.isinf(number) and not inf) or math.isnan(number):
        raise InputError(f"{name} must be a positive number, got {show(value)}")
    if upper is not None and number > upper:
        raise InputError(f"{name} must be at most {upper}, got {show(value)}")
    return number


def count(name: str, value: Any) -> int:
    """A positive integer, at most :data:`MAX_COUNT` (2**62)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {show(value)}")
    if value > MAX_COUNT:
        raise InputError(f"{name} must be at most 2**62 = {MAX_COUNT}, got {show(value)}")
    return int(value)
