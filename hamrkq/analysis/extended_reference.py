"""A reference in extended precision, from an independent Taylor integrator.

The independent reference (:func:`hamrkq.analysis.reference.hamiltonian_reference`,
SciPy's DOP853 in double) is good to 7e-11 on prentice2011 over [0, 4000],
and to 2e-8 on the Pleiades' close encounters: too coarse to measure a true error at
the tolerances RKQ certifies (a run at atol 1e-12, or the Pleiades at their
default 1e-8).  With heyoka installed (the ``bench`` extra, also part of
``test``), :func:`extended_reference` integrates Hamilton's equations by
heyoka's Taylor method in x86 extended precision (``numpy.longdouble``, a
64-bit mantissa, eps = 1.1e-19) at a tolerance of 1e-18 (heyoka's order 22).
The equations are hamrkq's own symbolic right-hand side, translated by
``heyoka.from_sympy`` (heyoka's code, not hamrkq's generated code, evaluates
them), with the parameters, the initial state and the rational constants as
extended-precision numbers, so that the problem integrated is the
mathematical one, not its rounding to double.  Its own error is estimated by
the same integration at two looser tolerances, 1e-17 and 1e-16 (orders 21
and 20): :data:`ROUNDING_SAFETY` times the largest difference from either
(see :func:`extended_reference`).

Its steps are heyoka's, bounded.  heyoka sizes a step from the solution's
Taylor coefficients of the two highest orders, p - 1 and p; where the series
has no terms of those orders the step is far too long, or infinite.  The
series of ``H = p**2/2 + q**10/10`` at q = 0 has terms of orders 0 and 1
modulo 10 only: at 1e-19 (order 23, the tolerance used before) the energy
drifted by 80 times itself over [0, 200] from (q, p) = (2, 0) (a step
starting near q = 0), and was inf from (0, 1).  No order escapes every
such H (``p**2/2 + q**8/8`` from (0, 1) went wrong at every order from 20 to
23), so the first step is at most heyoka's rule applied to the coefficients
of every order from p/2 to p, and no later step is more than
:data:`STEP_GROWTH` times the one before: heyoka is stopped at a longer one,
which is taken again, bounded.  On the catalogue's cases no step was taken
again (heyoka's own steps grew at most 1.31 times) and only the first step
was shortened, in some (``benchmarks/extended_reference_accuracy.txt``,
which also has the energy drifts).  A run heyoka cannot finish (its state
overflows, or it needs more than :data:`MAX_STEPS` steps) raises an
:class:`~hamrkq.errors.IntegrationError` that says so.

Limits: x86 extended precision only (on a platform whose ``longdouble`` is
double, :func:`available` is false and asking for it is an error that says
so); heyoka compiles each system with LLVM before it runs (0.24 s for the
forced oscillator of the tests); functions heyoka cannot translate (``Abs``,
``sign``) make the reference unavailable, with heyoka's reason.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.analysis.reference import Reference, _state, _times
from hamrkq.errors import InputError, IntegrationError

__all__ = [
    "EXTENDED_TOLERANCE",
    "available",
    "extended_reference",
    "extended_states",
    "unavailable_reason",
]

#: heyoka's tolerance for the reference run.  heyoka derives the Taylor
#: method's order from it (22 here) and sizes the steps by that order alone.
#: 1e-19 (order 23) went wrong on the q^10 oscillator by heyoka's own steps
#: (see the module's docstring); with the steps bounded it is right there
#: too, but checked only by runs at 1e-17 and 1e-18 it stated 0.4 times its
#: actual error on prentice2011 over [0, 4000] (their rounding drifts alike).
EXTENDED_TOLERANCE = 1e-18
#: The check runs' tolerances, over the reference run's (1e-16 and 1e-17):
#: each is a Taylor method of another order, so its rounding in long double is
#: another sample, and the run at 1e-16 adds its truncation error.
CHECK_FACTORS = (100.0, 10.0)
#: The stated accuracy is this many times the largest difference from a check
#: run.  Over a long run every run's error is long double's rounding (a phase
#: drift that grows with t), of much the same size at every tolerance: one
#: check run's difference, which sees the spread of two such samples, can
#: fall below the actual error.  Three times the larger of the two is 1.3 to
#: 297 times the actual error on the catalogue's cases of
#: ``benchmarks/extended_reference_accuracy.txt`` (1.3 where the rounding of
#: the states to double dominates) and 2.7 to 1044 on the q^n oscillators.
ROUNDING_SAFETY = 3.0
#: No step is more than this many times the one before.  heyoka's own steps
#: grew at most 1.31 times on the catalogue's cases and 1.39 on the q^10
#: oscillator at 1e-18; a bound of 1.3 made that run's error 4.1e-13 (1.1e-13
#: at 1.5), one of 2 no longer kept a run at 1e-19 right (3.4e-11).
STEP_GROWTH = 1.5
#: A run stops with an IntegrationError after this many steps rather than
#: chase a blow-up with ever shorter steps: the three runs' 274 169 steps on
#: the q^10 oscillator over [0, 1000] took 0.84 s, so some half a minute.
MAX_STEPS = 10_000_000


def unavailable_reason() -> str:
    """Why the extended reference cannot be had here, or ``""`` if it can."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        return "it needs heyoka: pip install 'hamrkq[bench]'"
    if np.finfo(np.longdouble).eps >= 1e-18:
        return "numpy.longdouble is no wider than double on this platform"
    return ""


def available() -> bool:
    """Whether :func:`extended_reference` can run here (heyoka, x86 extended precision)."""
    return not unavailable_reason()


def _constant(value: Any):
    import heyoka as hy

    return hy.expression(np.longdouble(value))


def _products(expr: sp.Basic) -> sp.Basic:
    """``expr`` with every integer power ``x**n`` (n >= 2) written as the
    product ``x*x*...*x``, unevaluated: heyoka differentiates ``x**3.0`` by
    a recurrence that divides by ``x``, so a coordinate starting at zero
    (the FPU chain's) made the reference NaN at once."""
    if expr.is_Atom:
        return expr
    args = [_products(arg) for arg in expr.args]
    if expr.is_Pow and expr.exp.is_Integer and int(expr.exp) >= 2:
        return sp.Mul(*([args[0]] * int(expr.exp)), evaluate=False)
    if expr.is_Add or expr.is_Mul or expr.is_Pow:
        return expr.func(*args, evaluate=False)
    return expr.func(*args)


def _equations(ham: Any, params: np.ndarray) -> list:
    """Hamilton's equations as heyoka (variable, expression) pairs."""
    import heyoka as hy

    rhs = list(ham.rhs)
    symbols: dict[sp.Basic, Any] = {s: hy.expression(f"y{k}") for k, s in enumerate(ham.state)}
    symbols[ham.t] = hy.time
    # Parameters and non-dyadic rationals (1/6) as extended-precision
    # constants, through placeholders: heyoka takes only dyadic rationals,
    # and SymPy would fold a sum of parameter Floats (1 - mu) to 53 bits.
    replacements: dict[sp.Basic, sp.Basic] = {}
    for symbol, value in zip(ham.parameters, np.asarray(params, dtype=float), strict=True):
        placeholder = sp.Dummy()
        symbols[placeholder] = _constant(value)
        replacements[symbol] = placeholder
    rhs = [e.xreplace(replacements) for e in rhs]
    rationals = set().union(*(e.atoms(sp.Rational) for e in rhs))
    replacements = {}
    for rational in rationals:
        if rational.q & (rational.q - 1):  # the denominator is not a power of two
            placeholder = sp.Dummy()
            symbols[placeholder] = hy.expression(
                np.longdouble(rational.p) / np.longdouble(rational.q)
            )
            replacements[rational] = placeholder
    rhs = [_products(e.xreplace(replacements)) for e in rhs]
    variables = [symbols[s] for s in ham.state]
    try:
        return [(v, hy.from_sympy(e, symbols)) for v, e in zip(variables, rhs, strict=True)]
    except (TypeError, ValueError) as exc:
        raise InputError(f"the extended reference cannot translate H for heyoka: {exc}") from exc


def _first_step_bound(ta: Any) -> float:
    """The first step by heyoka's own rule, read from the Taylor coefficients
    of every order from p/2 to p rather than p - 1 and p alone (``inf``
    where all of them vanish: the solution is a polynomial, the step exact).

    heyoka sizes a step from the coefficients of the two highest orders.
    Where the solution's series has a gap there, the step is far too long,
    or infinite: ``p**2/2 + q**10/10`` from (0, 1) has coefficients only at
    orders 0 and 1 modulo 10, so at order 23 (tol 1e-19) both top orders
    vanish and the state was inf."""
    order = ta.order
    norms = np.max(np.abs(ta.tc), axis=0)
    scale = norms[0] if norms[0] > 1 else 1
    rho = min(
        (float(scale / norms[k]) ** (1.0 / k) for k in range(max(1, order // 2), order + 1)
         if norms[k] > 0),
        default=math.inf,
    )  # fmt: skip
    return rho / math.e**2 * math.exp(-0.7 / (order - 1))


def _check_grid(grid: np.ndarray, t0: Any, sign: int) -> None:
    if np.any((grid - t0) * sign < 0) or np.any(np.diff(grid) * sign < 0):
        raise InputError("t_nodes must be monotonic and on one side of t0")


class _Steps:
    """``propagate_grid``'s callback: stops heyoka after a step more than
    :data:`STEP_GROWTH` times the one before (``previous``; the step began
    at ``start``), or after :data:`MAX_STEPS` steps (``count``)."""

    def __init__(self, ta: Any, h: Any):
        self.count = 0
        self.taken(ta, h)

    def taken(self, ta: Any, h: Any) -> None:
        self.previous = abs(float(h))
        self.start = ta.time
        self.count += 1

    def __call__(self, ta: Any) -> bool:
        h = ta.last_h
        if abs(float(h)) > STEP_GROWTH * self.previous or self.count >= MAX_STEPS:
            return False
        self.taken(ta, h)
        return True


def _failed(ta: Any, tol: float, outcome: Any) -> IntegrationError:
    return IntegrationError(
        f"heyoka's Taylor step failed in the extended reference (tol {tol:g}, order "
        f"{ta.order}) at t = {float(ta.time)!r}: {outcome}"
    )


def _checked(ta: Any, tol: float, outcome: Any, h: Any) -> Any:
    """``h``, unless the step that took it failed."""
    import heyoka as hy

    if outcome not in (hy.taylor_outcome.success, hy.taylor_outcome.time_limit) or not h:
        raise _failed(ta, tol, outcome)
    return h


def _first_step(ta: Any, end: Any, sign: int, tol: float, fp_type: Any) -> Any:
    """The first step, by heyoka's rule unless it is longer than
    :func:`_first_step_bound`, then taken again that long."""
    start = ta.time, ta.state.copy()
    remaining = (end - ta.time) * sign
    outcome, h = ta.step(sign * remaining, write_tc=True)
    bound = _first_step_bound(ta)
    if not abs(float(h)) <= bound:  # also a NaN step
        ta.time, ta.state[:] = start
        outcome, h = ta.step(sign * min(remaining, fp_type(bound)), write_tc=True)
    return _checked(ta, tol, outcome, h)


def _dense(ta: Any, grid: np.ndarray, states: np.ndarray, done: int, sign: int) -> int:
    """The states at the grid points the last step passed, from its Taylor
    polynomial; the number of grid points done."""
    while done < grid.size and (grid[done] - ta.time) * sign <= 0:
        states[done] = ta.update_d_output(grid[done])
        done += 1
    return done


def _propagate(
    equations, y0, t0: float, t: np.ndarray, tol: float, fp_type: Any = np.longdouble
) -> np.ndarray:
    """The states at ``t`` from ``y0`` at ``t0``: heyoka's adaptive Taylor
    steps in ``fp_type``, each at most :data:`STEP_GROWTH` times the one
    before (the first at most :func:`_first_step_bound`), at most
    :data:`MAX_STEPS` of them.  heyoka's ``propagate_grid`` takes the steps
    (its dense output gives the states between them) and stops at a step
    longer than that; the step is then taken again, bounded."""
    import heyoka as hy

    ta = hy.taylor_adaptive(
        equations,
        np.array([fp_type(float(v)) for v in y0]),
        time=fp_type(float(t0)),
        fp_type=fp_type,
        tol=fp_type(tol),
    )
    grid = np.array([fp_type(float(v)) for v in t])
    end = grid[-1]
    sign = 1 if end >= ta.time else -1
    _check_grid(grid, ta.time, sign)
    states = np.empty((grid.size, ta.state.size), dtype=grid.dtype)
    done = int(np.count_nonzero(grid == ta.time))
    states[:done] = ta.state
    if done == grid.size:
        return states
    steps = _Steps(ta, _first_step(ta, end, sign, tol, fp_type))
    done = _dense(ta, grid, states, done, sign)
    while done < grid.size:
        outcome, *_, part = ta.propagate_grid(np.array([ta.time, *grid[done:]]), callback=steps)
        if outcome == hy.taylor_outcome.time_limit:
            states[done:] = part[1:]
            break
        if outcome != hy.taylor_outcome.cb_stop:
            raise _failed(ta, tol, outcome)
        if steps.count >= MAX_STEPS:
            raise IntegrationError(
                f"the extended reference stopped after {MAX_STEPS} steps at t = "
                f"{float(ta.time)!r}, short of {float(end)!r}"
            )
        # the last step grew too much: keep the states before it, take it again bounded
        kept = int(np.count_nonzero((grid[done:] - steps.start) * sign <= 0))
        states[done : done + kept] = part[1 : 1 + kept]
        ta.time, ta.state[:] = steps.start, ta.tc[:, 0]
        limit = min((end - ta.time) * sign, fp_type(STEP_GROWTH * steps.previous))
        steps.taken(ta, _checked(ta, tol, *ta.step(sign * limit, write_tc=True)))
        done = _dense(ta, grid, states, done + kept, sign)
    if not np.all(np.isfinite(states)):
        raise IntegrationError(f"the extended reference (tol {tol:g}) returned non-finite states")
    return states


def extended_states(
    ham: Any,
    params: Any,
    y0: Any,
    t_nodes: Any,
    *,
    t0: float | None = None,
    tol: float = EXTENDED_TOLERANCE,
) -> np.ndarray:
    """The states of ``ham`` at ``t_nodes`` in extended precision, unrounded
    (``numpy.longdouble``, shape (N, 2n)): one heyoka run at ``tol``.  The
    arguments are :func:`extended_reference`'s; raises its errors."""
    reason = unavailable_reason()
    if reason:
        raise InputError(f"reference='extended' is not available: {reason}")
    t = _times(t_nodes)
    equations = _equations(ham, np.asarray(params, dtype=float).ravel())
    return _propagate(equations, _state(y0, "y0"), _start(t, t0), t, tol)


def _start(t: np.ndarray, t0: float | None) -> float:
    """``t0``, by default the first node's time."""
    return float(t[0]) if t0 is None else float(t0)


def extended_reference(
    ham: Any, params: Any, y0: Any, t_nodes: Any, *, t0: float | None = None
) -> Reference:
    """Reference states of ``ham`` at ``t_nodes`` in extended precision (heyoka).

    Parameters
    ----------
    ham : Hamiltonian
    params : array_like
        Parameter values, ordered like ``ham.parameters``.
    y0 : array_like, shape (2n,)
        State at ``t0``.
    t_nodes : array_like, shape (N,)
        Times wanted, monotonic, on one side of ``t0`` (a solution's ``t``).
    t0 : float, optional
        Time of ``y0``; default ``t_nodes[0]``.

    Returns
    -------
    Reference
        States rounded to double; ``component_error`` per component
        :data:`ROUNDING_SAFETY` times the largest difference from the same
        integration at 100 and at 10 times the tolerance (at least the
        rounding of the component to double), ``estimated_error`` the
        largest of those.

    Notes
    -----
    Why two check runs and a factor.  On a short run the difference from a
    looser run is that run's truncation error, larger than this one's.  On a
    long one every run's error is long double's rounding, which grows into a
    phase drift with t and is of much the same size at any tolerance: the
    difference of two runs is then the spread of two such samples, which can
    fall below either (on prentice2011 over [0, 4000] the reference is
    2.1e-14 off a quad-precision integration; checked by runs at 1e-17 and
    1e-19 alone it stated 0.3 times that).  The runs at other orders (heyoka
    chooses the order from the tolerance) round differently, the one at 1e-16
    adds its truncation error, and three times the larger difference bounded
    the actual error on every case of
    ``benchmarks/extended_reference_accuracy.py``.  A bound with high
    probability, not a certainty: rounding is sampled, not bounded.

    Raises
    ------
    InputError
        heyoka is missing, ``longdouble`` is double here, or H has a function
        heyoka cannot translate; the message says which.
    IntegrationError
        heyoka could not finish a run: a step failed (the state overflowed,
        a blow-up) or :data:`MAX_STEPS` steps did not reach the last node.
    """
    t = _times(t_nodes)
    t0 = _start(t, t0)
    y = extended_states(ham, params, y0, t, t0=t0)
    spread = np.zeros(y.shape[1])
    for factor in CHECK_FACTORS:
        check = extended_states(ham, params, y0, t, t0=t0, tol=factor * EXTENDED_TOLERANCE)
        spread = np.maximum(spread, np.max(np.abs(check - y), axis=0).astype(float))
    states = y.astype(np.float64)
    # per component, so that a component small beside the others (a
    # momentum of 1e-9 beside positions of 30 AU) is judged on its own scale
    rounding = np.max(np.abs(states), axis=0) * np.finfo(np.float64).eps / 2
    components = np.maximum(ROUNDING_SAFETY * spread, rounding)
    error = float(np.max(components))
    method = (
        f"heyoka Taylor in extended precision (tol {EXTENDED_TOLERANCE:g}) "
        f"over [{t0:g}, {float(t[-1]):g}]"
    )
    details = {
        "tol": EXTENDED_TOLERANCE,
        "check_tol": [factor * EXTENDED_TOLERANCE for factor in CHECK_FACTORS],
        "safety": ROUNDING_SAFETY,
        "step_growth": STEP_GROWTH,
    }
    return Reference(
        t=t, y=states, estimated_error=error, method=method, details=details,
        component_error=components,
    )  # fmt: skip
