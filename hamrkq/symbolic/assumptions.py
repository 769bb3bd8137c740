"""Assumptions declared on a Hamiltonian's symbols, against numbers.

SymPy simplifies H under a symbol's assumptions (``sqrt(q**2)`` is ``q`` for
a positive ``q``), so a value that breaks one gives a silently wrong answer.
:func:`assumption_conflict` says why a value breaks an assumption declared on
its symbol, and :func:`first_conflict` (:func:`state_conflicts`) finds the
first node of a run (every state) that does: the reason holds at every node,
not only at ``t0`` (:mod:`hamrkq.solve.assumptions` ends the run there).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
import sympy as sp

__all__ = [
    "CHECKED_ASSUMPTIONS",
    "Conflict",
    "assumption_conflict",
    "declares_checked",
    "first_conflict",
    "state_conflicts",
]


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
    if _declared(symbol) is None:  # nothing checked is declared (remembered per symbol)
        return None
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
