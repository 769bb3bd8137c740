"""Dense output and events for the RKQ family: what ``solve(dense_output=,
events=)`` adds to a finished run.

- :func:`dense_output` builds :class:`hamrkq.rkq.dense.DenseOutput` (one
  quencher step from the node before ``t``) on the backend the run used.
- :func:`event_specs` turns ``events=`` into :class:`EventSpec`: SciPy-style
  callables ``g(t, y)`` (their ``terminal`` and ``direction`` attributes as in
  :func:`scipy.integrate.solve_ivp`), SymPy expressions, or strings in the
  system's own names (q's, p's, parameters, ``t``), parsed by the safe parser
  of :mod:`hamrkq.symbolic.expressions` -- never ``eval``/``sympify``.
- :func:`locate` finds every root: ``g`` on all nodes, sign changes in the
  requested direction bracketed, the roots refined on ``g(t, sol(t))`` to
  a few ulps of ``t``, every bracket at once (:func:`hamrkq.rkq.roots.bracketed_roots`);
  and the pairs of roots inside one step that node signs cannot see (an
  orbit grazing a Poincare section: ``g`` turns back between two nodes of
  the same sign), found from ``dg/dt`` at the nodes (:func:`grazing_roots`).
- :func:`apply` puts ``t_events``/``y_events``/``event_bound`` and ``sol``
  on the :class:`~hamrkq.result.Solution` and, for a terminal event, ends it
  there (``Status.TERMINAL_EVENT``).

A zero of ``g`` at the initial time is not an event (the sign must change
after ``t0``), unlike SciPy, so that an orbit started on a Poincare section
does not count its starting point.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from hamrkq._tolerance import component_tolerance
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, InputTypeError
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import DenseOutput, dense_tableaus, evaluate, prepare_work
from hamrkq.rkq.family import Member
from hamrkq.rkq.roots import bracketed_roots, hermite_extreme
from hamrkq.symbolic.expressions import parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "EventSpec",
    "Found",
    "apply",
    "dense_output",
    "event_specs",
    "locate",
    "locate_all",
    "terminal_cut",
    "terminal_watch",
]

#: Each event function's roots along a run: ``(times, states)``, in the order
#: of the specifications (:func:`locate_all`).
Found = list[tuple[np.ndarray, np.ndarray]]


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
    stray = sorted(str(s) for s in expr.free_symbols - allowed)
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


def dense_output(
    ham: Hamiltonian,
    member: Member,
    backend: str,
    params: np.ndarray,
    t: np.ndarray,
    y: np.ndarray,
    z: np.ndarray | None = None,
    tolerance: tuple | None = None,
    certificate: tuple | None = None,
) -> DenseOutput:
    """The continuous solution through the nodes ``(t, y)`` of a run of
    ``member`` on ``backend`` (``"numba"`` compiles the evaluation), stepped
    from the quencher track ``z`` at the same nodes where there is one
    (:mod:`hamrkq.rkq.dense`); ``tolerance``: the run's ``(atol, rtol,
    rule)``, ``certificate`` its ``(gamma, rounding, gamma_limit)``
    (:class:`~hamrkq.rkq.dense.DenseOutput`)."""
    tab = dense_tableaus(member)
    params = np.require(params, np.float64, ("C", "W"))
    t = np.array(t, dtype=np.float64)
    y = np.array(y, dtype=np.float64)
    recipe = (_rebuilt, (ham, member, backend, params, tolerance))
    if backend == "numba":
        from hamrkq.backends import compiled, extras

        rhs = compiled.compile_system(ham).rhs
        d = y.shape[1]
        work = prepare_work(d, tab)
        args = (rhs, tab, params, t, y, y, np.zeros(1, np.int64), np.zeros(1),
                np.ones(d), np.zeros(d), np.zeros(3), work, np.zeros((1, d)))  # fmt: skip
        fast = extras.compiled_helper(evaluate, ("rhs",), *args)
        return DenseOutput(t, y, z, rhs, tab, params, fast, recipe, tolerance, certificate)
    numeric = numeric_of(ham)

    def rhs(t, y, params, out):
        out[:] = numeric.rhs(t, y, params)

    return DenseOutput(t, y, z, rhs, tab, params, None, recipe, tolerance, certificate)


def _rebuilt(ham, member, backend, params, tolerance, t, y, z, certificate=None) -> DenseOutput:
    """A pickled :func:`dense_output` rebuilt (its recipe)."""
    return dense_output(ham, member, backend, params, t, y, z, tolerance, certificate)


def locate(spec: EventSpec, dense: DenseOutput) -> tuple[np.ndarray, np.ndarray]:
    """Every root of ``spec`` along ``dense`` (in the direction of
    integration, a zero at the first node excluded): times and states."""
    t, y = dense.t, dense.y
    g = spec.rows(t, y)
    if t.size < 2:
        return np.empty(0), np.empty((0, y.shape[1]))
    hits = np.flatnonzero(_crossings(spec, g))
    on_node = g[hits + 1] == 0.0
    roots = list(t[hits[on_node] + 1])
    inside = hits[~on_node]
    roots += list(
        bracketed_roots(_along(spec, dense), t[inside], t[inside + 1], g[inside], g[inside + 1])
    )
    roots += grazing_roots(spec, dense, g)
    key = 1.0 if t[-1] >= t[0] else -1.0
    times = np.array(sorted(roots, key=lambda r: key * r), dtype=float)
    states = dense.values_unchecked(times) if times.size else np.empty((0, y.shape[1]))
    return times, states


def _along(spec: EventSpec, dense: DenseOutput) -> Callable[[np.ndarray], np.ndarray]:
    """``g(t, sol(t))`` at an array of times, in one call of each."""

    def values(times: np.ndarray) -> np.ndarray:
        return spec.rows(times, dense.values_unchecked(times))

    return values


#: A step where ``g`` turns back toward zero and away again is searched for
#: two roots when the cubic through the nodes' ``g`` and ``dg/dt`` comes
#: within this fraction of ``g``'s variation over the step of zero.  The
#: cubic's own error over a step is a few thousandths of that variation even
#: for a step of a radian of the motion (``(omega h)^4 / 384``): the margin
#: is wide, and only steps where the orbit nearly grazes the surface pay.
GRAZING_MARGIN = 0.1


def grazing_roots(spec: EventSpec, dense: DenseOutput, g: np.ndarray) -> list[float]:
    """The pairs of roots inside one step between two nodes where ``g`` has
    the same sign: ``g`` heads toward zero at the first node and away at the
    second (``dg/dt`` from ``spec.slopes``) and the cubic Hermite through
    the two nodes comes near zero (:data:`GRAZING_MARGIN`).  Then the turning
    point is found on the dense output (a root of ``dg/dt``), and where ``g``
    there has the other sign both roots are refined, those in ``spec``'s
    direction kept.  Node signs alone missed them: on the harmonic
    oscillator ``q = sin t``, the section ``q = 0.99`` had 12 of its 20
    crossings found at atol 1e-6.  Two turns inside one step (a step longer
    than half an oscillation of ``g``) are not looked for."""
    if spec.slopes is None or g.size < 2:
        return []
    t, y = dense.t, dense.y
    # |g| falls to the turn and rises after it, so among the nodes it is
    # smallest at one end of the step that holds the turn: only the steps
    # beside a node where |g| is smallest of its neighbours are looked at,
    # and dg/dt is evaluated there alone (a callable g pays two calls a
    # node for it).
    size = np.abs(g)
    padded = np.concatenate([[np.inf], size, [np.inf]])
    lows = np.flatnonzero((size <= padded[:-2]) & (size <= padded[2:]))
    steps = np.unique(np.concatenate([lows - 1, lows]))
    steps = steps[(steps >= 0) & (steps < g.size - 1)]
    side = np.sign(g[steps])
    steps = steps[(side != 0) & (np.sign(g[steps + 1]) == side)]
    if steps.size == 0:
        return []
    ends = np.unique(np.concatenate([steps, steps + 1]))
    rates = np.empty(g.size)
    rates[ends] = spec.slopes(t[ends], y[ends])
    h = t[steps + 1] - t[steps]
    # values and slopes over each step's unit interval
    g0, g1 = g[steps], g[steps + 1]
    d0, d1 = rates[steps] * h, rates[steps + 1] * h
    side = np.sign(g0)
    turning = np.flatnonzero((side * d0 < 0) & (side * d1 > 0))
    from scipy.optimize import brentq

    along = _along(spec, dense)

    def f(s: float) -> float:
        return float(along(np.array([s]))[0])

    def rate(s: float) -> float:
        return spec.slope(s, dense.values_unchecked(s)[0])

    brackets: list[tuple[float, float, float, float]] = []
    for j in turning:
        lowest = side[j] * hermite_extreme(g0[j], g1[j], d0[j], d1[j])
        variation = abs(g0[j]) + abs(g1[j]) + abs(d0[j]) + abs(d1[j])
        if lowest > GRAZING_MARGIN * variation:
            continue
        a, b = float(t[steps[j]]), float(t[steps[j] + 1])
        if not rate(a) * rate(b) < 0:
            continue
        turn = brentq(rate, a, b, rtol=1e-12, maxiter=200)
        g_turn = f(turn)
        if not side[j] * g_turn < 0:
            continue  # g turns back before it reaches zero
        # The first root leaves side[j], the second returns to it.
        if spec.direction in (0, -side[j]):
            brackets.append((a, turn, g0[j], g_turn))
        if spec.direction in (0, side[j]):
            brackets.append((turn, b, g_turn, g1[j]))
    if not brackets:
        return []
    return list(bracketed_roots(along, *(np.array(c) for c in zip(*brackets, strict=True))))


def _crossings(spec: EventSpec, g: np.ndarray) -> np.ndarray:
    """Where ``g`` changes sign between consecutive nodes, in ``spec``'s
    direction (a zero at the earlier node does not count)."""
    g0, g1 = g[:-1], g[1:]
    up = (g0 < 0) & (g1 >= 0)
    down = (g0 > 0) & (g1 <= 0)
    if spec.direction > 0:
        return up
    if spec.direction < 0:
        return down
    return up | down


def terminal_watch(
    specs: list[EventSpec],
) -> Callable[[], Callable[[np.ndarray, np.ndarray], bool]] | None:
    """A maker of ``stop(t, y)`` for the driver, one for each run: ``stop``
    is True once a terminal event has occurred as often as it ends the run
    (it sees the nodes chunk by chunk, in order).  None when no event is
    terminal.  The event itself is located afterwards by :func:`apply`, on
    the nodes the run kept.  A new ``stop`` for each run because it counts:
    one shared by ``method="auto"``'s runs counted the crossings its
    discarded runs had seen (Kepler at e = 0.9 with a terminal event at
    t = 626.4 stopped with TERMINAL_EVENT at t = 12.6 and no event; QA)."""
    terminal = [spec for spec in specs if spec.terminal]
    if not terminal:
        return None
    return functools.partial(_terminal_stop, terminal)


def _terminal_stop(terminal: list[EventSpec]) -> Callable[[np.ndarray, np.ndarray], bool]:
    """:func:`terminal_watch`'s ``stop`` for one run, its counts at zero."""
    counts = [0] * len(terminal)
    last: list[tuple[np.ndarray, np.ndarray]] = []

    def stop(t: np.ndarray, y: np.ndarray) -> bool:
        if last:
            t = np.concatenate([last[0][0], t])
            y = np.vstack([last[0][1], y])
        last[:] = [(t[-1:], y[-1:])]
        for k, spec in enumerate(terminal):
            counts[k] += int(np.count_nonzero(_crossings(spec, spec.rows(t, y))))
            if counts[k] >= spec.terminal:
                return True
        return False

    return stop


def _cut(certificate: tuple | None, keep: np.ndarray) -> tuple | None:
    """A dense output's certificate for its nodes ``keep`` and a terminal
    event's state after them (Gamma and rounding of the last node kept,
    carried, as the solution's ``gamma``)."""
    if certificate is None:
        return None
    gamma, rounding, limit = certificate
    gamma = np.vstack([gamma[keep], gamma[keep][-1:]])
    if rounding is not None:
        rounding = np.vstack([rounding[keep], rounding[keep][-1:]])
    return gamma, rounding, limit


def _bound(sol: Solution, states: np.ndarray) -> np.ndarray:
    """RKQ's promise at the event states: delta_k = max(atol_k, rtol_k |y_k|)."""
    return component_tolerance(sol.atol, sol.rtol, states)


def locate_all(specs: list[EventSpec], dense: DenseOutput) -> tuple[Found, int]:
    """Every root of every event function along ``dense`` (:func:`locate`),
    those after the terminal event that ends the run left out, and the index
    of that event function (-1: none ends it)."""
    found = [locate(spec, dense) for spec in specs]
    return terminal_cut(specs, found, 1.0 if dense.t[-1] >= dense.t[0] else -1.0)


def terminal_cut(specs: list[EventSpec], found: Found, key: float) -> tuple[Found, int]:
    """``found`` without the roots after the terminal occurrence that ends
    the run first, and the index of its event function (-1: none ends it);
    ``key`` is +1 for a run forward in time, -1 backward."""
    stop_at, stop_by = math.inf, -1
    for k, (spec, (times, _)) in enumerate(zip(specs, found, strict=True)):
        if spec.terminal and times.size >= spec.terminal:
            at = key * times[spec.terminal - 1]
            if at < stop_at:
                stop_at, stop_by = at, k
    if stop_by < 0:
        return found, -1
    return [(t[key * t <= stop_at], y[key * t <= stop_at]) for t, y in found], stop_by


def apply(
    sol: Solution,
    specs: list[EventSpec],
    dense: DenseOutput,
    energy: Callable[[np.ndarray, np.ndarray], np.ndarray],
    z_dense: DenseOutput | None,
    keep_dense: bool,
    located: tuple[Found, int] | None = None,
) -> Solution:
    """Events (and ``sol``) on the solution; a terminal event ends it.
    ``located``: :func:`locate_all` on ``dense`` already."""
    found, stop_by = located if located is not None else locate_all(specs, dense)
    changes: dict[str, Any] = {}
    if stop_by >= 0:
        t_stop = found[stop_by][0][specs[stop_by].terminal - 1]
        key = 1.0 if dense.t[-1] >= dense.t[0] else -1.0
        stop_at = key * t_stop
        keep = key * sol.t < stop_at
        y_stop = dense.values_unchecked([t_stop])
        t_new = np.append(sol.t[keep], t_stop)
        y_new = np.vstack([sol.y[keep], y_stop])
        changes.update(t=t_new, y=y_new, energy=energy(t_new, y_new))
        if sol.z is not None and z_dense is not None:
            z_new = np.vstack([sol.z[keep], z_dense.values_unchecked([t_stop])])
            changes.update(z=z_new, global_error=y_new - z_new)
        if sol.gamma is not None:
            # Gamma is not re-stepped: the last node's estimate, carried.
            changes["gamma"] = np.vstack([sol.gamma[keep], sol.gamma[keep][-1:]])
        if sol.quenched is not None:
            changes["quenched"] = np.append(sol.quenched[keep], False)
        changes.update(
            status=Status.TERMINAL_EVENT,
            message=(
                f"stopped by terminal event {stop_by} ({specs[stop_by].label}) "
                f"at t = {float(t_stop)!r}"
            ),
        )
        if keep_dense:
            dense = dense.through(t_new, y_new, changes.get("z"), _cut(dense.certificate, keep))
    changes.update(
        t_events=[times for times, _ in found],
        y_events=[states for _, states in found],
        event_bound=[_bound(sol, states) for _, states in found],
        event_labels=[spec.label for spec in specs],
    )
    if keep_dense:
        changes["sol"] = dense
    return sol.replace(**changes)
