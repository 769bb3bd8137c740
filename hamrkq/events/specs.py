"""What ``events=`` may be, as :class:`EventSpec`: SciPy-style callables
``g(t, y)``, SymPy expressions, strings in the system's own names (parsed by
the safe parser of :mod:`hamrkq.symbolic.expressions`, never
``eval``/``sympify``) or mappings with ``expression``, ``terminal`` and
``direction`` (a catalogue file's ``[[events]]``), each with ``dg/dt`` along
the flow where it can be had."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, InputTypeError
from hamrkq.symbolic.expressions import parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian
from hamrkq.symbolic.values import assumptions_twin

__all__ = ["EventSpec", "event_specs"]


@dataclass(frozen=True)
class EventSpec:
    """One event function, ready to evaluate.

    ``rows(t, Y)`` gives ``g`` at the rows of ``Y`` (times ``t``);
    ``terminal`` is the number of occurrences that end the run (0: never);
    ``direction`` > 0 counts only upward crossings, < 0 only downward, 0 both.
    ``label`` names it in messages and summaries; ``slopes(t, Y)`` gives
    ``dg/dt`` along the flow at the rows of ``Y`` (None: not known, and
    roots that node signs miss are not looked for).
    """

    rows: Callable[[np.ndarray, np.ndarray], np.ndarray]
    terminal: int
    direction: float
    label: str
    slopes: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None

    def scalar(self, t: float, y: np.ndarray) -> float:
        return float(self.rows(np.array([t]), y[None, :])[0])

    def slope(self, t: float, y: np.ndarray) -> float:
        return float(self.slopes(np.array([t]), y[None, :])[0])


def _terminal(value: Any, where: str) -> int:
    if isinstance(value, bool | np.bool_):
        return int(value)
    if isinstance(value, int | np.integer) and value >= 0:
        return int(value)
    raise InputTypeError(f"{where}: terminal must be a bool or a count >= 0, got {value!r}")


def _direction(value: Any, where: str) -> float:
    try:
        d = float(value)
    except (TypeError, ValueError):
        raise InputTypeError(f"{where}: direction must be a number, got {value!r}") from None
    if not math.isfinite(d):
        raise InputError(f"{where}: direction must be finite, got {value!r}")
    return float(np.sign(d))


def _symbols(ham: Hamiltonian) -> dict[str, sp.Symbol]:
    names = {s.name: s for s in (*ham.state, *ham.parameters)}
    names.setdefault("t", ham.t)
    return names


def _expression_rows(ham: Hamiltonian, expr: sp.Expr, params: np.ndarray, label: str):
    allowed = {*ham.state, *ham.parameters, ham.t}
    strays = sorted(expr.free_symbols - allowed, key=str)
    for symbol in strays:
        twin = assumptions_twin(symbol, (*ham.state, *ham.parameters, ham.t))
        if twin is not None:
            raise InputError(
                f"event {label!r} uses {symbol!s}, {twin}: write the event as a string "
                "in the system's names or with the Hamiltonian's own symbols"
            )
    stray = [str(s) for s in strays]
    if stray:
        raise InputError(
            f"event {label!r} uses {', '.join(stray)}, which are not coordinates, momenta, "
            f"parameters or t of the system"
        )
    f = sp.lambdify((ham.t, ham.state, ham.parameters), expr, modules="numpy")
    dim = ham.dim

    def rows(t: np.ndarray, Y: np.ndarray) -> np.ndarray:
        cols = [Y[:, k] for k in range(dim)]
        return np.broadcast_to(np.asarray(f(t, cols, params), dtype=float), t.shape).copy()

    return rows


def _expression_slopes(ham: Hamiltonian, expr: sp.Expr, params: np.ndarray):
    """``dg/dt = dg/dt|_y + grad g . f`` along Hamilton's flow, symbolically
    (only the state components ``g`` depends on)."""
    rate = sp.diff(expr, ham.t) + sum(
        (
            sp.diff(expr, s) * f
            for s, f in zip(ham.state, ham.rhs, strict=True)
            if s in expr.free_symbols
        ),
        sp.Integer(0),
    )
    return _expression_rows(ham, rate, params, f"d/dt {expr}")


def _callable_rows(g: Callable) -> Callable:
    def rows(t: np.ndarray, Y: np.ndarray) -> np.ndarray:
        return np.array([float(g(float(ti), yi.copy())) for ti, yi in zip(t, Y, strict=True)])

    return rows


def _callable_slopes(rows: Callable, ham: Hamiltonian, params: np.ndarray) -> Callable:
    """``dg/dt`` of a callable ``g`` along the flow, by a central difference
    over a short time ``e`` along ``f`` (about 1e-10 relative: enough to see
    where ``g`` turns).

    ``e`` is 1e-5 of the orbit's time scale at the node, ``max|y| / max|f|``
    (the time the flow takes to move the state by its own size), and of
    ``max(1, |t|)`` where that is shorter: 1e-5 ``|t|`` alone was 10 time
    units at t = 1e6, longer than the harmonic oscillator's turn at a
    maximum, every slope's sign there was wrong, and the pairs of roots
    inside a step near the maxima were missed (80 crossings found 60 times,
    found by QA).  At least 64 ulps of ``t``, so that ``t +- e`` differ.
    """
    numeric = numeric_of(ham)

    def slopes(t: np.ndarray, Y: np.ndarray) -> np.ndarray:
        F = np.atleast_2d(numeric.rhs_many(t, Y, params))
        size, speed = np.abs(Y).max(axis=1), np.abs(F).max(axis=1)
        moving = (size > 0.0) & (speed > 0.0) & np.isfinite(speed)
        scale = np.where(moving, size / np.where(moving, speed, 1.0), np.inf)
        e = 1e-5 * np.minimum(np.maximum(1.0, np.abs(t)), scale)
        e = np.maximum(e, 64.0 * np.spacing(np.abs(t)))
        ahead = rows(t + e, Y + e[:, None] * F)
        behind = rows(t - e, Y - e[:, None] * F)
        return (ahead - behind) / (2.0 * e)

    return slopes


def event_specs(events: Any, ham: Hamiltonian, params: np.ndarray) -> list[EventSpec]:
    """``events=`` as a list of :class:`EventSpec`.

    Each item is a callable ``g(t, y)`` (``y`` the state, q's then p's; the
    attributes ``terminal`` and ``direction`` as in SciPy), a SymPy
    expression or a string in the system's names, or a mapping with
    ``expression`` and optional ``terminal`` (bool or count) and
    ``direction`` (the form of a catalogue file's ``[[events]]``).
    A single item may be given without a list.
    """
    if events is None:
        return []
    if callable(events) or isinstance(events, str | sp.Basic | Mapping):
        events = [events]
    if not isinstance(events, Sequence):
        raise InputTypeError(
            f"events must be a callable, an expression, a string or a list of them, "
            f"got {type(events).__name__}"
        )
    specs = []
    for k, item in enumerate(events):
        where = f"events[{k}]"
        terminal, direction = 0, 0.0
        if isinstance(item, Mapping):
            unknown = sorted(set(item) - {"expression", "terminal", "direction"})
            if unknown or "expression" not in item:
                raise InputError(
                    f"{where}: a mapping needs 'expression' and may have 'terminal' and "
                    f"'direction' (got keys {sorted(item)})"
                )
            terminal = _terminal(item.get("terminal", False), where)
            direction = _direction(item.get("direction", 0.0), where)
            item = item["expression"]
        if isinstance(item, str | sp.Basic):
            label = item if isinstance(item, str) else str(item)
            expr = (
                parse_expression(item, _symbols(ham), key=where) if isinstance(item, str) else item
            )
            rows = _expression_rows(ham, expr, params, label)
            slopes = _expression_slopes(ham, expr, params)
            specs.append(EventSpec(rows, terminal, direction, label, slopes))
        elif callable(item):
            terminal = _terminal(getattr(item, "terminal", False), where)
            direction = _direction(getattr(item, "direction", 0.0), where)
            label = getattr(item, "__name__", f"event {k}")
            rows = _callable_rows(item)
            specs.append(
                EventSpec(rows, terminal, direction, label, _callable_slopes(rows, ham, params))
            )
        else:
            raise InputTypeError(
                f"{where} must be a callable, a SymPy expression or a string, "
                f"got {type(item).__name__}"
            )
    return specs
