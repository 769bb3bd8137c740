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
them), with the initial state as extended-precision numbers and the
parameters and rational constants as heyoka's runtime parameters, each
correctly rounded (never folded into products or sums of rounded numbers),
so that the problem integrated is the mathematical one, not its rounding.
Its own error is estimated by the same integration at two looser
tolerances, 1e-17 and 1e-16 (orders 21 and 20): :data:`ROUNDING_SAFETY`
times the largest difference from either (see :func:`extended_reference`).

Its steps are heyoka's, bounded (:mod:`hamrkq.analysis.heyoka_steps`:
where the solution's Taylor series has no terms at the two highest orders,
heyoka's own step is far too long, or infinite); a run heyoka cannot finish
raises an :class:`~hamrkq.errors.IntegrationError` that says so.

Limits: x86 extended precision only (on a platform whose ``longdouble`` is
double, :func:`available` is false and asking for it is an error that says
so); heyoka compiles each system with LLVM before it runs (0.24 s for the
forced oscillator of the tests); functions heyoka cannot translate (``Abs``,
``sign``) make the reference unavailable, with heyoka's reason.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np
import sympy as sp

from hamrkq.analysis.heyoka_steps import STEP_GROWTH, propagate
from hamrkq.analysis.reference import Reference, _state, _times
from hamrkq.errors import InputError

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


class HeyokaSystem(NamedTuple):
    """Hamilton's equations for heyoka and the values of their runtime
    parameters (``hy.par[i]``): H's parameters that the equations use, then
    the rational constants
    whose denominator is not a power of two (1/6), as exact fractions, to be
    rounded to the precision of the run (:meth:`pars`)."""

    equations: list
    constants: tuple[Fraction, ...]

    def pars(self, fp_type: Any = np.longdouble, precision: int | None = None) -> np.ndarray:
        """The parameters' values in ``fp_type`` (``heyoka.real`` takes its
        ``precision`` in bits): each fraction correctly rounded."""
        import heyoka as hy

        if fp_type is hy.real:
            return np.array(
                [hy.real(c.numerator, precision) / hy.real(c.denominator, precision)
                 for c in self.constants]
            )  # fmt: skip
        return np.array(
            [fp_type(c.numerator) / fp_type(c.denominator) for c in self.constants],
            dtype=fp_type,
        )


def _equations(ham: Any, params: np.ndarray) -> HeyokaSystem:
    """Hamilton's equations as heyoka (variable, expression) pairs, with
    H's parameters and non-dyadic rationals as runtime parameters.

    Not as numbers in the expressions: heyoka folds products and sums of
    numbers as it builds them, in the numbers' precision, so ``g (m1 + m2)
    l1`` became one long double, rounded, and the problem integrated was
    not the mathematical one.  On the double pendulum over [0, 100], whose
    state at t = 96.86 moves 4.9e-4 for an ulp of its start, the reference
    so built (in 160-bit floats, with those long-double constants) was
    2.3e-7 off one with the parameters exact, and made hamrkq's nodes look
    2272 tolerances off at 1e-10 (QA, 2026-11-27; they are within 0.992:
    ``benchmarks/reference_constants.txt``).
    SymPy would likewise fold a sum of parameter Floats (1 - mu) to 53
    bits, and heyoka takes only dyadic rationals."""
    import heyoka as hy

    rhs = list(ham.rhs)
    symbols: dict[sp.Basic, Any] = {s: hy.expression(f"y{k}") for k, s in enumerate(ham.state)}
    symbols[ham.t] = hy.time
    constants: list[Fraction] = []
    replacements: dict[sp.Basic, sp.Basic] = {}

    def runtime(placeholder: sp.Basic, value: Fraction) -> None:
        symbols[placeholder] = hy.par[len(constants)]
        constants.append(value)

    used = set().union(*(e.free_symbols for e in rhs))
    for symbol, value in zip(ham.parameters, np.asarray(params, dtype=float), strict=True):
        if symbol not in used:  # (Kepler's e sets the start only: heyoka counts pars)
            continue
        placeholder = sp.Dummy()
        runtime(placeholder, Fraction(float(value)))
        replacements[symbol] = placeholder
    rhs = [e.xreplace(replacements) for e in rhs]
    rationals = set().union(*(e.atoms(sp.Rational) for e in rhs))
    replacements = {}
    for rational in sorted(rationals, key=lambda r: (r.q, r.p)):
        if rational.q & (rational.q - 1):  # the denominator is not a power of two
            placeholder = sp.Dummy()
            runtime(placeholder, Fraction(int(rational.p), int(rational.q)))
            replacements[rational] = placeholder
    rhs = [_products(e.xreplace(replacements)) for e in rhs]
    variables = [symbols[s] for s in ham.state]
    try:
        equations = [(v, hy.from_sympy(e, symbols)) for v, e in zip(variables, rhs, strict=True)]
    except (TypeError, ValueError) as exc:
        raise InputError(f"the extended reference cannot translate H for heyoka: {exc}") from exc
    return HeyokaSystem(equations, tuple(constants))


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
    system = _equations(ham, np.asarray(params, dtype=float).ravel())
    return propagate(system.equations, _state(y0, "y0"), _start(t, t0), t, tol, pars=system.pars())


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
        a blow-up) or :data:`~hamrkq.analysis.heyoka_steps.MAX_STEPS` steps did not
        reach the last node.
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
