"""Numbers given for a Hamiltonian's symbols: parameter and initial values.

:func:`bind_parameters` and :func:`bind_state` bind them to the symbols, by
position or by name (the homes of :meth:`hamrkq.Hamiltonian.parameter_values`
and :meth:`~hamrkq.Hamiltonian.state_values`).

:func:`as_number` makes a finite float of a number or of a SymPy expression
without free symbols; :func:`assumption_conflict` says why a value breaks an
assumption declared on its symbol (SymPy has already simplified H under it),
and :func:`first_conflict` (:func:`state_conflicts`) finds the first node of
a run (every state) that does: the reason holds at every node, not only at
``t0``.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError

__all__ = [
    "CHECKED_ASSUMPTIONS",
    "Conflict",
    "as_number",
    "assumption_conflict",
    "bind_parameters",
    "bind_state",
    "declares_checked",
    "first_conflict",
    "show_value",
    "state_conflicts",
]


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


def _integral(v: np.ndarray) -> np.ndarray:
    return np.isfinite(v) & (np.floor(v) == v)


def _prime(v: np.ndarray) -> np.ndarray:
    out = _integral(v) & (v >= 2)
    # SymPy's test, once per distinct candidate: a declared prime is rare.
    values, where = np.unique(v[out], return_inverse=True)
    verdicts = np.array([sp.isprime(int(x)) for x in values], dtype=bool)
    out[out] = verdicts[where] if values.size else False
    return out


def _composite(v: np.ndarray) -> np.ndarray:
    return _integral(v) & (v > 1) & ~_prime(v)


def _even(v: np.ndarray) -> np.ndarray:
    return _integral(v) & (np.fmod(v, 2.0) == 0)


def _odd(v: np.ndarray) -> np.ndarray:
    return _integral(v) & (np.abs(np.fmod(v, 2.0)) == 1)


#: What each of :data:`CHECKED_ASSUMPTIONS` says of finite floats, element
#: by element: the one statement of their meaning, for one value
#: (:func:`assumption_conflict`) and for every node of a run
#: (:func:`state_conflicts`).  A float is an exact rational, so each is
#: decided, as SymPy decides it for ``Rational(value)``; ``extended_*`` is
#: the same as the plain one for a finite number.
_HOLDS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "positive": lambda v: v > 0,
    "negative": lambda v: v < 0,
    "nonnegative": lambda v: v >= 0,
    "nonpositive": lambda v: v <= 0,
    "zero": lambda v: v == 0,
    "nonzero": lambda v: (v < 0) | (v > 0),
    "integer": _integral,
    "noninteger": lambda v: np.isfinite(v) & ~_integral(v),
    "even": _even,
    "odd": _odd,
    "prime": _prime,
    "composite": _composite,
    "extended_positive": lambda v: v > 0,
    "extended_negative": lambda v: v < 0,
    "extended_nonnegative": lambda v: v >= 0,
    "extended_nonpositive": lambda v: v <= 0,
    "extended_nonzero": lambda v: (v < 0) | (v > 0),
}
#: The assumptions that depend on a value's sign alone.
_SIGN_ASSUMPTIONS = frozenset(
    name
    for name in CHECKED_ASSUMPTIONS
    if "zero" in name or "positive" in name or "negative" in name
)
#: Where a value's sign is outside a set of allowed signs, as one comparison
#: (a run's check costs one pass over a column; NaN is never flagged: a
#: non-finite state has its own status).
_OUTSIDE_SIGNS: dict[frozenset, Callable[[np.ndarray], np.ndarray]] = {
    frozenset({1.0}): lambda v: v <= 0,
    frozenset({0.0, 1.0}): lambda v: v < 0,
    frozenset({-1.0}): lambda v: v >= 0,
    frozenset({-1.0, 0.0}): lambda v: v > 0,
    frozenset({-1.0, 1.0}): lambda v: v == 0,
    frozenset({0.0}): lambda v: (v < 0) | (v > 0),
    frozenset(): lambda v: v == v,  # contradictory assumptions: SymPy refuses them
}


class _Declared(NamedTuple):
    """A symbol's checked assumptions: the signs they allow (None: any)
    and the others (``integer``, ...) as ``(name, value)`` pairs."""

    signs: frozenset | None
    others: tuple[tuple[str, bool], ...]


@functools.lru_cache(maxsize=4096)
def _declared(symbol: Any) -> _Declared | None:
    """What ``symbol``'s checked assumptions (with those SymPy derives from
    them) require of a value, or None: nothing."""
    facts = getattr(symbol, "assumptions0", {})
    checked = {name: facts[name] for name in CHECKED_ASSUMPTIONS if facts.get(name) is not None}
    if not checked:
        return None
    signs = None
    if _SIGN_ASSUMPTIONS & checked.keys():
        signs = frozenset(
            s
            for s in (-1.0, 0.0, 1.0)
            if all(
                bool(_HOLDS[name](np.array([s]))[0]) == wanted
                for name, wanted in checked.items()
                if name in _SIGN_ASSUMPTIONS
            )
        )
        signs = None if len(signs) == 3 else signs
    others = tuple((n, w) for n, w in checked.items() if n not in _SIGN_ASSUMPTIONS)
    if signs is None and not others:
        return None
    return _Declared(signs, others)


def _column_conflicts(symbol: Any, values: np.ndarray) -> np.ndarray | None:
    """Where ``values`` contradict an assumption declared on ``symbol``
    (a boolean array of their shape; NaN never does), or None where
    nothing is declared."""
    declared = _declared(symbol)
    if declared is None:
        return None
    bad = None
    if declared.signs is not None:
        bad = _OUTSIDE_SIGNS[declared.signs](values)
    for name, wanted in declared.others:
        broken = (_HOLDS[name](values) != wanted) & np.isfinite(values)
        bad = broken if bad is None else bad | broken
    return bad


def _broken(symbol: Any, value: float) -> tuple[str, bool] | None:
    """The assumption on ``symbol`` that ``value`` contradicts, as the user
    wrote it where one of those is broken (``nonnegative=True`` rather than
    SymPy's derived ``negative=False``), or None."""
    declared = getattr(symbol, "assumptions0", {})
    written = getattr(symbol, "_assumptions_orig", None) or {}
    order = [n for n in CHECKED_ASSUMPTIONS if written.get(n) is not None]
    order += [n for n in CHECKED_ASSUMPTIONS if n not in order and declared.get(n) is not None]
    v = np.array([float(value)])
    for name in order:
        wanted = bool(written.get(name, declared.get(name)))
        if bool(_HOLDS[name](v)[0]) != wanted:
            return name, wanted
    return None


def assumption_conflict(symbol: Any, value: float) -> str | None:
    """Why ``value`` contradicts an assumption declared on ``symbol``, or None.

    Parameters
    ----------
    symbol : sympy.Symbol
    value : float
        A finite number.

    Returns
    -------
    str or None
        ``"c is declared nonnegative=True but is given the value -1.0; ..."``,
        naming the assumption as it was declared.
    """
    broken = _broken(symbol, value)
    if broken is None:
        return None
    name, wanted = broken
    return (
        f"{symbol} is declared {name}={wanted} but is given the value {value!r}; "
        "SymPy has already simplified H under that assumption, so the result "
        "would be wrong. Give a value that satisfies it, or declare the symbol "
        "without the assumption"
    )


class Conflict(NamedTuple):
    """The first value of a run that contradicts a declared assumption
    (:func:`first_conflict`): its ``row`` (node) and ``column``, and the
    ``assumption`` broken with its declared value."""

    row: int
    column: int
    assumption: str
    declared: bool


def declares_checked(symbols: Sequence[Any]) -> bool:
    """Whether any of ``symbols`` declares an assumption that its values are
    checked against (:func:`state_conflicts`): where none does, a run needs
    no check."""
    return any(_declared(symbol) is not None for symbol in symbols)


def state_conflicts(symbols: Sequence[Any], values: np.ndarray) -> np.ndarray:
    """Where a state contradicts an assumption declared on its symbols.

    Parameters
    ----------
    symbols : sequence of sympy.Symbol
        The state's symbols (``q`` then ``p``), one per column.
    values : ndarray, shape (..., len(symbols))
        States, the last axis ordered like ``symbols``.

    Returns
    -------
    ndarray of bool, shape ``values.shape[:-1]``
        True where any component contradicts its symbol's assumptions
        (non-finite components never do).
    """
    values = np.asarray(values, dtype=float)
    bad = np.zeros(values.shape[:-1], dtype=bool)
    for j, symbol in enumerate(symbols):
        column = _column_conflicts(symbol, values[..., j])
        if column is not None:
            bad |= column
    return bad


def first_conflict(symbols: Sequence[Any], values: np.ndarray) -> Conflict | None:
    """The first row of ``values`` that contradicts an assumption declared
    on its symbols, or None.

    Parameters
    ----------
    symbols : sequence of sympy.Symbol
        One per column of ``values``.
    values : ndarray, shape (N, len(symbols))
        The states of a run, node by node.

    Returns
    -------
    Conflict or None
        The earliest row; at that row, the first column in the order of
        ``symbols``.

    Notes
    -----
    One comparison per column whose symbol declares a sign (``positive``,
    ``nonnegative``, ...) and nothing for the others: about 0.1 ms for
    1e5 nodes, far below evaluating H at them.
    """
    first: Conflict | None = None
    for j, symbol in enumerate(symbols):
        bad = _column_conflicts(symbol, values[:, j])
        if bad is None or not bad.any():
            continue
        row = int(np.argmax(bad))
        if first is None or row < first.row:
            # _broken reads the same table as the mask: it names what broke
            name, wanted = _broken(symbol, float(values[row, j])) or ("?", True)
            first = Conflict(row, j, name, wanted)
    return first


def show_value(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _assumptions(symbol: sp.Symbol) -> str:
    """The assumptions a symbol was declared with, for messages."""
    given = getattr(symbol, "_assumptions_orig", None) or symbol.assumptions0
    # every Symbol is commutative unless told otherwise: not worth naming
    shown = {k: v for k, v in given.items() if v is not None and k != "commutative"}
    return ", ".join(f"{k}={v}" for k, v in sorted(shown.items())) or "none"


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
            twin = by_name.get(getattr(key, "name", None))
            if twin is not None:
                # Symbol("w", real=True) is not Symbol("w"): SymPy tells
                # symbols apart by their assumptions too.
                raise InputError(
                    f"parameter {key!s} is keyed by a symbol with other assumptions "
                    f"({_assumptions(key)}) than the Hamiltonian's {twin!s} "
                    f"({_assumptions(twin)}); SymPy counts them as different symbols: key "
                    f"it by name ({twin.name!r}) or by the Hamiltonian's own symbol"
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
    labels = [f"q0[{i}]" for i in range(n)] + [f"p0[{i}]" for i in range(n)]
    for symbol, value, label in zip((*q, *p), parts, labels, strict=True):
        conflict = assumption_conflict(symbol, value)
        if conflict is not None:
            raise InputError(f"{label}: {conflict}")
    return np.array(parts, dtype=float)


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
