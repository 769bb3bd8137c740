"""Initial values on a Poincare section at a given energy.

:func:`energy_orbits` seeds the orbits of a two-degree-of-freedom system on
a section ``"q_k = c"``: the other coordinate spread over the interval of
the section's line where ``H(q, p = 0) <= E``, the section's momentum from
``H = E`` -- the classic way of drawing a section (Henon & Heiles 1964;
``hamrkq poincare --energy``).  The sections themselves:
:mod:`hamrkq.analysis.poincare`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from hamrkq.analysis.poincare import split_section
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError
from hamrkq.symbolic.expressions import parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["energy_orbits"]


def energy_orbits(
    ham: Hamiltonian,
    energy: float,
    orbits: int,
    section: str = "q1 = 0",
    parameters: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Initial values of ``orbits`` orbits on ``section`` at energy ``energy``
    (two degrees of freedom).

    The section must fix a coordinate, ``"q_k = c"``.  The other coordinate
    runs evenly over an interval of the section line where
    ``H(q, p = 0) <= E`` (the other momentum 0), and ``p_k >= 0`` is solved
    from ``H = E``.  The interval is the one containing the other
    coordinate's 0 when ``H <= E`` there, else the one around the lowest
    minimum of ``H(q, p = 0)`` found on the line; its ends are roots of
    ``H(q, p = 0) = E`` to rounding.

    ``q_k`` is the float at which the section's event function, evaluated
    as :func:`poincare`'s event evaluates it, is exactly 0: an orbit starts
    on the section, and its start is not a crossing.

    Returns
    -------
    q0, p0 : ndarrays of shape (orbits, 2)

    Raises
    ------
    InputError
        No point of the section line has ``H(q, p = 0) <= E``, or the
        interval is unbounded (the energy is above the escape energy on this
        section: orbits started there can leave to infinity, or an angle can
        go all the way round).
    """
    if ham.n != 2:
        raise InputError(f"energy_orbits needs two degrees of freedom, got n = {ham.n}")
    lhs, rhs = split_section(section)
    names = {s.name: k for k, s in enumerate(ham.q)}
    key = lhs.strip()
    if key not in names:
        raise InputError(
            f"the section must fix a coordinate ({', '.join(names)}), got {section!r}"
        )
    constant = _section_constant(ham, section, key, rhs)
    energy = float(energy)
    if not np.isfinite(energy):
        raise InputError(f"the energy must be a finite number, got {energy!r}")
    k = names[key]
    other = 1 - k
    params = ham.parameter_values(parameters)
    value = _on_section(ham, section, k, constant, params)
    name = ham.q[other].name
    H = numeric_of(ham).energy

    def h_line(xs: np.ndarray) -> np.ndarray:
        # H on the section line at p = 0; NaN (an overflow far out) counts
        # as not allowed.
        Y = np.zeros((xs.size, 4))
        Y[:, k], Y[:, other] = value, xs
        with np.errstate(all="ignore"):
            h = H(0.0, Y, params)
        return np.where(np.isnan(h), np.inf, h)

    lo, hi = _allowed_interval(h_line, energy, name, section)

    def h_at(q_other: float, p_k: float) -> float:
        y = np.zeros(4)
        y[k], y[other], y[2 + k] = value, q_other, p_k
        return float(H(0.0, y, params))

    from scipy.optimize import brentq  # 0.1 s to import: only when seeding orbits

    xs = _seeds(h_line, lo, hi, orbits, name, section)
    q0 = np.zeros((orbits, 2))
    p0 = np.zeros((orbits, 2))
    for j, x in enumerate(xs):
        top = 1.0
        while h_at(x, top) < energy and top < 1e300:
            top *= 2.0
        if not h_at(x, top) >= energy:
            raise InputError(
                f"no momentum {ham.p[k].name} >= 0 gives H = {energy!r} at {name} = {x!r} "
                f"on the section {section!r}"
            )
        pk = brentq(lambda s, x=x: h_at(x, s) - energy, 0.0, top, xtol=1e-15, rtol=1e-15)
        q0[j, k], q0[j, other], p0[j, k] = value, x, pk
    return q0, p0


def _seeds(h_line: Any, lo: float, hi: float, orbits: int, name: str, section: str) -> np.ndarray:
    """``orbits`` points spread evenly inside ``(lo, hi)``; one where ``H`` is
    singular (Kepler's centre, where ``H(q, p = 0) = -inf``: the middle one
    of an odd number on its section through the centre, whose momentum
    solve failed with a traceback, found by QA) moved half a spacing up."""
    xs = np.linspace(lo, hi, orbits + 2)[1:-1]
    singular = ~np.isfinite(h_line(xs))
    xs[singular] += 0.5 * (hi - lo) / (orbits + 1)
    still = ~np.isfinite(h_line(xs))
    if np.any(still):
        raise InputError(
            f"H is singular at {name} = {float(xs[still][0])!r} on the section {section!r} "
            "and half a spacing from it: choose another number of orbits"
        )
    return xs


def _section_constant(ham: Hamiltonian, section: str, coordinate: str, rhs: str) -> sp.Expr:
    """The constant ``c`` of the section ``"q_k = c"``.

    The right side goes through the safe parser with the system's names, so
    that a side naming a state component or a parameter (``"q1 = q2"``) is
    refused for what it is: not a constant.  Parsed with no names at all, it
    read "unknown name 'q2'" of a coordinate of the problem (found by QA).
    """
    symbols = {s.name: s for s in (*ham.state, *ham.parameters)}
    symbols["t"] = ham.t
    constant = parse_expression(rhs, symbols, key="section")
    if constant.free_symbols:
        named = ", ".join(sorted(s.name for s in constant.free_symbols))
        raise InputError(
            f"the section {section!r} sets {coordinate} to {rhs.strip()!r}, which depends on "
            f"{named}: orbits seeded at an energy need a section that fixes a coordinate "
            f"to a constant, '{coordinate} = c' with c a number or an expression of numbers, "
            "pi and E (1/10, sqrt(2)/20); hamrkq.poincare(problem, section, q0, p0, t_span) "
            "takes any surface 'lhs = rhs' of the state, the parameters and t, with "
            "initial values of your own"
        )
    return constant


def _on_section(
    ham: Hamiltonian, section: str, k: int, constant: sp.Expr, params: np.ndarray
) -> float:
    """The float ``q_k`` at which the event function of ``"q_k = c"`` is 0
    (``constant``, :func:`_section_constant`).

    The event evaluates ``q_k - c`` with NumPy (lambdified like
    :mod:`hamrkq.events`' expression events), whose rounding of ``c`` may
    differ from SymPy's by an ulp (``sqrt(2)/10``): the start would then sit
    3e-17 off the section and count as a crossing at t ~ 1e-16.
    ``dg/dq_k = 1``, so ``q_k -= g(q_k)`` lands on NumPy's ``c``.
    """
    # The event's expression, section_expression's ``lhs - rhs``, from the
    # constant already parsed rather than parsing the section again: its lhs
    # is the symbol q_k itself, so this is the same SymPy expression.
    expr = ham.q[k] - constant
    g = sp.lambdify((ham.t, ham.state, ham.parameters), expr, modules="numpy")
    guess = float(sp.N(constant))

    def g_at(x: float) -> float:
        # The event's call: columns of the state rows, t as an array.
        columns = [np.zeros(1) for _ in range(ham.dim)]
        columns[k] = np.array([x])
        values = np.asarray(g(np.zeros(1), columns, params), dtype=float)
        return float(np.broadcast_to(values, (1,))[0])

    value, residual = guess, g_at(guess)
    for _ in range(3):
        if residual == 0.0:
            return value
        value -= residual
        residual = g_at(value)
    if residual != 0.0:
        raise InputError(
            f"no float puts the orbits exactly on the section {section!r} (the event "
            f"function is {residual!r} at {ham.q[k].name} = {value!r})"
        )
    return value


# The section line is searched every 1e-3 out to |x| = 10 (the fixed grid
# of the first versions), then, only while the interval reaches the grid's
# edge or none is found, decade by decade (10000 points each) out to 1e6:
# an interval cut at the edge would seed orbits at an arbitrary point of a
# region they can leave.
_FINE_REACH = 10.0
_MAX_REACH = 1e6


def _line_grid(reach: float) -> np.ndarray:
    """Symmetric points out to ``reach``, 0 among them exactly."""
    side = [np.linspace(0.0, _FINE_REACH, 10001)]
    edge = _FINE_REACH
    while edge < reach:
        side.append(np.linspace(edge, 10.0 * edge, 10001)[1:])
        edge *= 10.0
    right = np.concatenate(side)
    return np.concatenate([-right[:0:-1], right])


def _local_minima(h: np.ndarray) -> np.ndarray:
    """Indices of the grid's interior local minima (the edges' values say
    nothing of what lies beyond)."""
    inner = h[1:-1]
    return np.flatnonzero((inner <= h[:-2]) & (inner <= h[2:])) + 1


def _end(h_line: Any, energy: float, blocked: float, allowed: float) -> float:
    """The root of ``h_line = energy`` between a blocked and an allowed grid
    point; the allowed point where brentq cannot run (an overflow beyond
    it), off the root by less than one grid step."""
    from scipy.optimize import brentq  # 0.1 s to import: only when seeding orbits

    def excess(s: float) -> float:
        return float(h_line(np.array([s]))[0]) - energy

    if not np.isfinite(excess(blocked)):
        return float(allowed)
    return float(brentq(excess, blocked, allowed, xtol=1e-15))


def _lowest(h_line: Any, x: np.ndarray, h: np.ndarray, indices: np.ndarray) -> tuple[float, float]:
    """Where and what the lowest of ``h[indices]`` is, refined between its
    grid neighbours (the messages quote it)."""
    from scipy.optimize import minimize_scalar

    i = indices[np.argmin(h[indices])]
    if i == 0 or i == x.size - 1:
        return float(x[i]), float(h[i])
    best = minimize_scalar(
        lambda s: float(h_line(np.array([s]))[0]),
        bounds=(x[i - 1], x[i + 1]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    return (float(best.x), float(best.fun)) if best.fun < h[i] else (float(x[i]), float(h[i]))


def _allowed_interval(h_line: Any, energy: float, name: str, section: str) -> tuple[float, float]:
    """The ends of the interval of the section line where ``h_line <= energy``:
    the one containing 0 when 0 is in one, else the one around the lowest
    local minimum of ``h_line`` found.

    Raises
    ------
    InputError
        No point is allowed, or the interval is unbounded.
    """
    reach = _FINE_REACH
    while True:
        x = _line_grid(reach)
        h = h_line(x)
        allowed = h <= energy
        zero = x.size // 2
        if allowed[zero]:
            centre: int | None = zero
        else:
            minima = _local_minima(h)
            minima = minima[allowed[minima]]
            centre = int(minima[np.argmin(h[minima])]) if minima.size else None
        if centre is not None:
            blocked = np.flatnonzero(~allowed)
            left, right = blocked[blocked < centre], blocked[blocked > centre]
            lo = left[-1] + 1 if left.size else 0
            hi = right[0] - 1 if right.size else x.size - 1
            if lo > 0 and hi < x.size - 1:
                return _end(h_line, energy, x[lo - 1], x[lo]), _end(
                    h_line, energy, x[hi + 1], x[hi]
                )
        if reach >= _MAX_REACH:
            break
        reach *= 10.0
    interval = (lo, hi) if centre is not None else None
    raise _refusal(h_line, energy, name, section, x, h, interval)


def _refusal(
    h_line: Any,
    energy: float,
    name: str,
    section: str,
    x: np.ndarray,
    h: np.ndarray,
    interval: tuple[int, int] | None,
) -> InputError:
    """Why no orbit is seeded: no point of the line allowed; the chosen
    interval reaching the grid's edge (grid indices ``interval``); or, with
    no minimum allowed, allowed points only on stretches reaching it."""
    allowed = h <= energy
    reach = f"{x[-1]:.0e}".replace("e+0", "e")
    if not allowed.any():
        at, least = _lowest(h_line, x, h, np.arange(x.size))
        return InputError(
            f"no point of the section {section!r} has H(q, p = 0) <= E = {energy!r}: the "
            f"lowest energy found on it is {least:.6g}, at {name} = {at:.6g} (searched out "
            f"to |{name}| = {reach}); choose an energy above it or another section"
        )

    def stretch(lo: int, hi: int) -> str:
        if lo > 0:
            return f"from {name} = {_end(h_line, energy, x[lo - 1], x[lo]):.6g} up past {reach}"
        if hi < x.size - 1:
            return f"from below -{reach} to {name} = {_end(h_line, energy, x[hi + 1], x[hi]):.6g}"
        return "over the whole line"

    if interval is not None:
        return InputError(
            f"at E = {energy!r} the interval of the section {section!r} where "
            f"H(q, p = 0) <= E is unbounded along {name}: it runs {stretch(*interval)} "
            f"(searched out to |{name}| = {reach}). The energy is above the escape energy "
            f"on this section: orbits started there can leave to infinity (or, for an "
            f"angle, go all the way round); choose a lower energy or another section"
        )
    blocked = np.flatnonzero(~allowed)
    runs = []
    if allowed[0]:
        runs.append(stretch(0, blocked[0] - 1))
    if allowed[-1]:
        runs.append(stretch(blocked[-1] + 1, x.size - 1))
    minima = _local_minima(h)
    lowest, advice = "", "choose another section"
    if minima.size:
        at, least = _lowest(h_line, x, h, minima)
        lowest = f" (the lowest is {least:.6g}, at {name} = {at:.6g})"
        advice = "choose an energy above that minimum or another section"
    return InputError(
        f"at E = {energy!r} no interval of the section {section!r} around a minimum of "
        f"H(q, p = 0) is at or below E{lowest}; H(q, p = 0) <= E only {' and '.join(runs)}, "
        f"where orbits can leave to infinity (searched out to |{name}| = {reach}); {advice}"
    )
