"""Numbers given for a Hamiltonian's symbols: parameter and initial values.

:func:`bind_parameters` and :func:`bind_state` bind them to the symbols, by
position or by name (the homes of :meth:`hamrkq.Hamiltonian.parameter_values`
and :meth:`~hamrkq.Hamiltonian.state_values`).

:func:`as_number` makes a finite float of a number or of a SymPy expression
without free symbols.  A value that breaks an assumption declared on its
symbol is refused (:mod:`hamrkq.symbolic.assumptions`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError
from hamrkq.symbolic.assumptions import assumption_conflict

__all__ = ["as_number", "bind_parameters", "bind_state", "show_value"]


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


def show_value(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _assumptions(symbol: sp.Symbol) -> str:
    """The assumptions a symbol was declared with, for messages."""
    given = getattr(symbol, "_assumptions_orig", None) or symbol.assumptions0
    # every Symbol is commutative unless told otherwise: not worth naming
    shown = {k: v for k, v in given.items() if v is not None and k != "commutative"}
    return ", ".join(f"{k}={v}" for k, v in sorted(shown.items())) or "none"


def assumptions_twin(key: Any, symbols: tuple[sp.Symbol, ...]) -> str | None:
    """Why ``key``, a SymPy symbol not among ``symbols``, is not the one of
    them that has its name (``Symbol("q")`` beside a catalogue's
    ``Symbol("q", real=True)``: SymPy tells symbols apart by their
    assumptions too), as a clause for a message; None when no symbol of
    ``symbols`` has its name."""
    twin = next((s for s in symbols if s.name == getattr(key, "name", None)), None)
    if twin is None or not isinstance(key, sp.Symbol):
        return None
    return (
        f"a symbol with other assumptions ({_assumptions(key)}) than the declared "
        f"{twin!s} ({_assumptions(twin)}); SymPy counts them as different symbols"
    )


def bind_parameters(
    parameters: tuple[sp.Symbol, ...],
    defaults: Mapping[sp.Symbol, float],
    values: Mapping[Any, Any] | None,
) -> np.ndarray:
    """Parameter values as a float array ordered like ``parameters``: the
    ``defaults`` overridden by ``values`` (keyed by symbol or by name); see
    :meth:`hamrkq.Hamiltonian.parameter_values`."""
    chosen = dict(defaults)
    by_name = {s.name: s for s in parameters}
    for key, value in (values or {}).items():
        symbol = by_name.get(key) if isinstance(key, str) else key
        if symbol not in parameters:
            known = ", ".join(by_name) or "none"
            twin = assumptions_twin(key, parameters)
            if twin is not None:
                raise InputError(
                    f"parameter {key!s} is keyed by {twin}: key it by name ({key.name!r}) "
                    "or by the Hamiltonian's own symbol"
                )
            raise InputError(f"unknown parameter {key!s} (parameters: {known})")
        chosen[symbol] = as_number(value, f"parameter {symbol}")
        conflict = assumption_conflict(symbol, chosen[symbol])
        if conflict is not None:
            raise InputError(f"parameter {conflict}")
    missing = [s.name for s in parameters if s not in chosen]
    if missing:
        raise InputError(f"no value for parameter(s): {', '.join(missing)}")
    return np.array([chosen[s] for s in parameters], dtype=float)


def bind_state(q: tuple[sp.Symbol, ...], p: tuple[sp.Symbol, ...], q0: Any, p0: Any) -> np.ndarray:
    """Initial values as one float array ``(q0..., p0...)``, each a
    sequence in the order of ``q`` (``p``) or a mapping by name or symbol;
    see :meth:`hamrkq.Hamiltonian.state_values`."""
    n = len(q)
    state = _finite_doubles(q0, p0, n)
    parts = _state_parts(q, p, q0, p0) if state is None else state.tolist()
    for k, (symbol, value) in enumerate(zip((*q, *p), parts, strict=True)):
        conflict = assumption_conflict(symbol, value)
        if conflict is not None:
            label = f"q0[{k}]" if k < n else f"p0[{k - n}]"
            raise InputError(f"{label}: {conflict}")
    return np.array(parts, dtype=float) if state is None else state


def _finite_doubles(q0: Any, p0: Any, n: int) -> np.ndarray | None:
    """``(q0..., p0...)`` where both are arrays of n finite doubles (the
    common case, decided without a Python object per value: every solve
    pays this), else None: each value is then checked on its own, for its
    message (:func:`_state_parts`)."""
    for values in (q0, p0):
        if not (type(values) is np.ndarray and values.dtype == np.float64):
            return None
        if values.shape != (n,):
            return None
    state = np.concatenate((q0, p0))
    return state if np.isfinite(state).all() else None


def _state_parts(q: tuple[sp.Symbol, ...], p: tuple[sp.Symbol, ...], q0: Any, p0: Any) -> list:
    """The values of ``q0`` and ``p0`` as floats, one at a time, each
    checked (:func:`as_number`), or the error that names what is wrong."""
    n = len(q)
    parts: list[float] = []
    for label, values, symbols in (("q0", q0, q), ("p0", p0, p)):
        if isinstance(values, Mapping):
            other = p if label == "q0" else q
            parts.extend(_bind_by_name(label, values, symbols, other))
            continue
        if isinstance(values, str | bytes):
            raise InputTypeError(f"{label} must be a sequence of numbers, not a string")
        if isinstance(values, numbers.Number | sp.Basic) and not isinstance(values, sp.MatrixBase):
            values = [values]
        try:
            array = np.asarray(values, dtype=object)
        except (TypeError, ValueError):
            raise InputTypeError(f"{label} must be a sequence of numbers") from None
        if array.ndim > 1 and not (isinstance(values, sp.MatrixBase) and min(array.shape) == 1):
            # As SciPy's y0: flattening a (2, 1) or a transposed array hid a slip.
            raise InputError(
                f"{label} must be 1-dimensional (n values), got an array of shape {array.shape}"
            )
        seq = list(array.ravel())
        if len(seq) != n:
            raise InputError(
                f"{label} has {len(seq)} value{'s' if len(seq) != 1 else ''} but the system "
                f"has {n} degree{'s' if n != 1 else ''} of freedom"
            )
        parts.extend(as_number(v, f"{label}[{i}]") for i, v in enumerate(seq))
    return parts


def _bind_by_name(
    label: str,
    values: Mapping[Any, Any],
    symbols: tuple[sp.Symbol, ...],
    other: tuple[sp.Symbol, ...],
) -> list[float]:
    """The values of ``symbols`` from a mapping keyed by name or symbol
    (``other``: the other half's symbols, named in the message when a key
    belongs there)."""
    role = "coordinate" if label == "q0" else "momentum"
    by_name = {s.name: s for s in symbols}
    bound: dict[sp.Symbol, Any] = {}
    for key, value in values.items():
        symbol = by_name.get(key) if isinstance(key, str) else key
        if symbol not in symbols:
            shown = key if isinstance(key, str) else str(key)
            twin = assumptions_twin(key, symbols)
            if twin is not None:
                raise InputError(
                    f"{label}: {shown!r} is keyed by {twin}: key it by name ({shown!r}) "
                    "or by the Hamiltonian's own symbol"
                )
            if any(shown == s.name for s in other):
                where = "p0" if label == "q0" else "q0"
                raise InputError(
                    f"{label}: {shown!r} is not a {role} (it belongs in {where}); "
                    f"{label} binds {', '.join(by_name)}"
                )
            raise InputError(
                f"{label}: unknown {role} {shown!r} = {show_value(value)}; the "
                f"{'coordinates' if label == 'q0' else 'momenta'} are {', '.join(by_name)}"
            )
        if symbol in bound:
            raise InputError(
                f"{label}: {symbol.name} is bound twice (by name and by symbol): "
                f"{show_value(bound[symbol])} and {show_value(value)}"
            )
        bound[symbol] = value
    missing = [s.name for s in symbols if s not in bound]
    if missing:
        raise InputError(f"{label}: no value for {', '.join(missing)}")
    return [as_number(bound[s], f"{label}[{s.name!r}]") for s in symbols]
