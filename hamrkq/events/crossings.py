"""Where event functions cross zero along a run's dense output
(:func:`locate`: sign changes between nodes refined on ``g(t, sol(t))``, and
the pairs of roots inside one step that node signs miss,
:func:`grazing_roots`), and which occurrence of a terminal event ends the
run (:func:`terminal_watch` while it runs, :func:`terminal_cut` after).

A zero of ``g`` at the initial time is not an event (the sign must change
after ``t0``), unlike SciPy, so that an orbit started on a Poincare section
does not count its starting point.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from hamrkq.events.specs import EventSpec
from hamrkq.rkq.dense import DenseOutput
from hamrkq.rkq.roots import bracketed_roots, hermite_extreme

__all__ = ["Found", "grazing_roots", "locate", "locate_all", "terminal_cut", "terminal_watch"]

#: Each event function's roots along a run: ``(times, states)``, in the order
#: of the specifications (:func:`locate_all`).
Found = list[tuple[np.ndarray, np.ndarray]]


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
