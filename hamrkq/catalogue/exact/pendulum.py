"""The pendulum's exact libration, through Jacobi elliptic functions, and
the accuracy it states.

References
----------
.. [1] M. Abramowitz and I.A. Stegun, *Handbook of Mathematical Functions*,
   Chapter 16 (Jacobi elliptic functions).
.. [2] R. Bulirsch, Numerical calculation of elliptic integrals and elliptic
   functions, Numer. Math. 7 (1965) 78-90 (sncndn, in the complementary
   parameter).
"""

from __future__ import annotations

from collections.abc import Mapping

import mpmath
import numpy as np

from hamrkq._floats import EPS
from hamrkq.catalogue.exact._common import CONSTANT_DIGITS, as_state, elapsed, reduced_phase
from hamrkq.errors import InputError

__all__ = ["PENDULUM_PHASE", "PENDULUM_ROUNDING", "pendulum", "pendulum_accuracy"]


# Near the separatrix (m = k**2 -> 1) the shape of the orbit depends on m
# like 1/(1 - m): m rounded to double, which scipy's ellipj needs, moved the
# solution by eps/(2 (1 - m)) times its scale (1.9e4 eps at q0 = 3.14, the
# whole amplitude at q0 = 3.14159, where ellipj's approximation for m within
# 1e-9 of 1 holds only for small u).  So the modulus is carried as its
# complement m1 = 1 - m, computed from the double initial state in mpmath,
# and sn, cn, dn come from Bulirsch's algorithm in m1 ([2]_), whose
# backward recurrence needs no arcsine near 1; q/2 = atan2(k sn, dn), not
# asin(k sn), whose conditioning 1/dn reaches 1/sqrt(m1) at the turning
# points.


def _pendulum_modulus(
    q0: float, p0: float, turns: float
) -> tuple[mpmath.MPContext, object, object]:
    """``(ctx, m, m1)``: the modulus ``m = k**2 = (1 + H)/2`` of the libration
    through ``(q0, p0)`` and its complement ``m1 = 1 - m``, in an mpmath
    context whose precision resolves ``m1`` to 20 digits at least (a state
    within 1e-14 of the separatrix needs more than the default digits).

    Raises
    ------
    InputError
        The exact state is on the separatrix or beyond (``m1 <= 0``), or so
        near it that 136 digits do not resolve ``m1``.
    """
    ctx = mpmath.MPContext()
    for digits in (CONSTANT_DIGITS, 2 * CONSTANT_DIGITS, 4 * CONSTANT_DIGITS):
        ctx.dps = digits
        half_angle = (ctx.mpf(q0) - 2 * ctx.pi * turns) / 2
        half_momentum = ctx.mpf(p0) / 2
        m1 = ctx.cos(half_angle) ** 2 - half_momentum**2
        if m1 > ctx.mpf(10) ** (20 - digits):
            return ctx, ctx.sin(half_angle) ** 2 + half_momentum**2, m1
    raise InputError(
        f"the 'pendulum' exact solution covers only librations, H = p**2/2 - cos(q) < 1; "
        f"y0 = ({q0!r}, {p0!r}) has 1 - H = {float(2 * m1)!r} (the separatrix, "
        "or too near it to be resolved)"
    )


def _sncndn(fraction: np.ndarray, m1: object, ctx: mpmath.MPContext) -> tuple[np.ndarray, ...]:
    """``sn, cn, dn`` of ``u = fraction K(m)`` for ``m = 1 - m1`` by Bulirsch's
    algorithm ([2]_): the arithmetic-geometric mean of ``1`` and ``sqrt(m1)``
    in mpmath (rounded to double), ``u`` times the mean as the exact
    ``(pi/2) fraction``, and the backward recurrence in doubles."""
    a, b2 = ctx.mpf(1), m1
    means, roots = [], []
    while True:
        b = ctx.sqrt(b2)
        means.append(float(a))
        roots.append(float(b))
        mean = (a + b) / 2
        if abs(a - b) <= 1e-9 * a:  # the next mean is the limit to 1e-18
            break
        a, b2 = mean, a * b
    x = (0.5 * np.pi) * fraction
    sn, cn = np.sin(x), np.cos(x)
    zero = sn == 0.0
    a = cn / np.where(zero, 1.0, sn)
    c = float(mean) * a
    dn = np.ones_like(x)
    for mean_i, root_i in zip(reversed(means), reversed(roots), strict=True):
        a = a * c
        c = c * dn
        dn = (root_i + a) / (mean_i + a)
        a = c / mean_i
    size = 1.0 / np.sqrt(c * c + 1.0)
    sn_new = np.where(sn >= 0.0, size, -size)
    return (
        np.where(zero, sn, sn_new),
        np.where(zero, cn, c * sn_new),
        np.where(zero, 1.0, dn),
    )


def pendulum(
    t: object, y0: object, params: Mapping[str, float] | None = None, t0: float = 0.0
) -> np.ndarray:
    """Exact libration of the pendulum ``H = p**2/2 - cos(q)``.

    With ``k = sin(q_max/2)``, ``k**2 = (1 + H)/2``, the solution is
    ``q = 2 asin(k sn(u, k**2))``, ``p = 2 k cn(u, k**2)`` with ``u = t - t0 + u0``;
    the phase ``u0`` is the incomplete elliptic integral of the amplitude
    ``phi0 = atan2(sin(q0/2), p0/2)`` ([1]_, 16.1).  The libration may be about
    any stable equilibrium ``q = 2 pi j``; the solution keeps that branch.
    Accurate to :func:`pendulum_accuracy` at any time.

    Parameters
    ----------
    t : float or array_like, shape (N,)
        Times.
    y0 : array_like, shape (2,)
        ``(q, p)`` at ``t0``, with ``H < 1``.
    params : mapping, optional
        Unused (unit length and gravity).
    t0 : float, optional
        Time of ``y0``.

    Returns
    -------
    ndarray, shape (N, 2)

    Raises
    ------
    InputError
        If ``H >= 1``: the separatrix (``H = 1``) and the rotations
        (``H > 1``) are not covered.
    """
    tau, tau_lo = elapsed(t, t0)
    q0, p0 = as_state(y0, 2, "pendulum")
    # (1 + H)/2 written without the cancellation of 1 - cos(q).
    m = float(0.25 * p0**2 + np.sin(0.5 * q0) ** 2)
    if not m < 1.0:
        raise InputError(
            f"the 'pendulum' exact solution covers only librations, H = p**2/2 - cos(q) < 1; "
            f"y0 = ({float(q0)!r}, {float(p0)!r}) has H = {2.0 * m - 1.0!r} "
            f"(H = 1 is the separatrix, H > 1 a rotation)"
        )
    # The libration is about the equilibrium 2 pi j nearest to q0; work with
    # the angle relative to it so that sin(q/2) has the right sign.
    turns = float(np.round(q0 / (2.0 * np.pi)))
    branch = 2.0 * np.pi * turns
    if q0 == 0.0 and p0 == 0.0:
        # At rest at the bottom: the equilibrium.  (A state of 1e-300 has
        # m = 0 in doubles, not in mpmath, and librates.)
        return np.column_stack([np.zeros_like(tau), np.zeros_like(tau)])
    ctx, exact_m, m1 = _pendulum_modulus(float(q0), float(p0), turns)
    quarter = ctx.ellipk(exact_m)
    half_angle = (ctx.mpf(float(q0)) - 2 * ctx.pi * turns) / 2
    u0 = ctx.ellipf(ctx.atan2(ctx.sin(half_angle), ctx.mpf(float(p0)) / 2), exact_m)
    # The phase in quarter periods, reduced modulo the period (4 of them).
    fraction = reduced_phase(tau, tau_lo, 1 / quarter, u0 / quarter, ctx.mpf(4))
    sn, cn, dn = _sncndn(fraction, m1, ctx)
    k = float(ctx.sqrt(exact_m))
    q = branch + 2.0 * np.arctan2(k * sn, dn)
    p = 2.0 * k * cn
    return np.column_stack([q, p])


#: The pendulum's stated accuracy is ``eps (PENDULUM_ROUNDING max|y| +
#: PENDULUM_PHASE k K(m))``, see :func:`pendulum_accuracy`.
PENDULUM_ROUNDING = 2.0
PENDULUM_PHASE = 3.0


def pendulum_accuracy(y0: object, states: object) -> float:
    """What :func:`pendulum`'s values from ``y0`` are accurate to, at any
    time: ``eps (2 max|y| + 3 k K(m))`` over the ``states`` it returned.

    The phase, in quarter periods, is reduced in double-double from
    constants computed in mpmath, so its error does not grow with ``t``:
    a few ulps of the
    reduced phase ``x = (pi/2) (u/K)``, which become ``(2K/pi) dx`` in ``u``
    and ``|dy/du| (2K/pi) dx <= 2k (2K/pi) dx`` in the state; ``K``, the
    quarter period, grows like ``log(4/sqrt(1 - m))`` near the separatrix.
    The rest is the rounding of the values themselves and of the branch
    ``2 pi j``.  Every node within it against mpmath at 40 digits, the
    worst above 0.2 of it, on six librations to ``1 - m`` = 1.8e-12 over
    spans to 1e4 (``tests/test_exact_accuracy.py``).
    """
    q0, p0 = as_state(y0, 2, "pendulum")
    scale = float(np.max(np.abs(np.asarray(states, dtype=float)), initial=0.0))
    if q0 == 0.0 and p0 == 0.0:
        return 0.0  # the equilibrium, exactly
    turns = float(np.round(q0 / (2.0 * np.pi)))
    ctx, exact_m, _m1 = _pendulum_modulus(float(q0), float(p0), turns)
    phase = float(ctx.sqrt(exact_m) * ctx.ellipk(exact_m))
    return EPS * (PENDULUM_ROUNDING * scale + PENDULUM_PHASE * phase)
