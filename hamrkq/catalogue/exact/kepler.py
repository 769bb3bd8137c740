"""The Kepler problem's exact flow, through Kepler's equation and the
Lagrange ``f`` and ``g`` coefficients.

References
----------
.. [1] E. Hairer, C. Lubich and G. Wanner, *Geometric Numerical Integration*,
   2nd ed., Springer, 2006, Sections I.1 and I.2.
.. [2] R.H. Battin, *An Introduction to the Mathematics and Methods of
   Astrodynamics*, AIAA, 1999, Section 4.3 (f and g in the eccentric anomaly).
.. [3] J.M.A. Danby, *Fundamentals of Celestial Mechanics*, 2nd ed., 1988,
   Section 6.6 (the starting value ``M + 0.85 e`` for Kepler's equation).
"""

from __future__ import annotations

from collections.abc import Mapping

import mpmath
import numpy as np

from hamrkq._floats import EPS
from hamrkq.catalogue.exact._common import CONSTANT_DIGITS, as_state, elapsed, reduced_phase
from hamrkq.errors import InputError

__all__ = ["kepler", "solve_kepler_equation"]


#: Newton iterations allowed for Kepler's equation.  The safeguarded iteration
#: converges quadratically from Danby's start; 8 iterations suffice for
#: e < 0.999999, the rest is margin for the bisection fallback.
_KEPLER_MAX_ITER = 60

#: Below this |E| the series of E - sin E is used: the direct difference
#: loses all digits when E ~ e sin E (e near 1, E near 0).
_SERIES_LIMIT = 0.5


def _x_minus_sin(x: np.ndarray) -> np.ndarray:
    """``x - sin(x)`` without cancellation for small ``|x|``."""
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < _SERIES_LIMIT
    out = x - np.sin(x)
    xs = x[small]
    x2 = xs * xs
    # Taylor series x^3/3! - x^5/5! + ...; 9 terms reach 1e-17 relative at 0.5.
    term = xs * x2 / 6.0
    acc = np.zeros_like(xs)
    for j in range(9):
        acc += term
        term = -term * x2 / ((2 * j + 4) * (2 * j + 5))
    out[small] = acc
    return out


def solve_kepler_equation(mean_anomaly: object, e: float) -> np.ndarray:
    """Solve Kepler's equation ``E - e sin(E) = M`` for the eccentric anomaly.

    Vectorised safeguarded Newton iteration from Danby's starting value
    ``M + 0.85 e`` ([3]_), with the residual written as
    ``(1 - e) E + e (E - sin E) - M`` so that it keeps its digits for ``e``
    near 1 and small ``E``.  The root is bracketed in ``[M, M + e]`` (after
    reducing to ``0 <= M <= pi`` by symmetry), and any Newton iterate that
    leaves the bracket is replaced by bisection, so the iteration converges
    for every ``0 <= e < 1``.

    Parameters
    ----------
    mean_anomaly : float or array_like
        ``M``; any real values (reduced modulo ``2 pi`` internally).
    e : float
        Eccentricity, ``0 <= e < 1``.

    Returns
    -------
    ndarray
        ``E`` with ``E - M`` in ``[-pi, pi]``, i.e. on the same revolution as
        ``M``; same shape as ``mean_anomaly``.
    """
    e = float(e)
    if not 0.0 <= e < 1.0:
        raise InputError(f"eccentricity e must satisfy 0 <= e < 1, got {e!r}")
    M = np.asarray(mean_anomaly, dtype=float)
    if not np.all(np.isfinite(M)):
        raise InputError("mean_anomaly must be finite")
    two_pi = 2.0 * np.pi
    turns = np.round(M / two_pi)
    reduced = M - two_pi * turns  # in [-pi, pi]
    sign = np.where(reduced < 0.0, -1.0, 1.0)
    target = np.abs(reduced)  # in [0, pi]; the root is odd in M
    lo = target.copy()
    hi = np.minimum(target + e, np.pi)
    E = np.clip(target + 0.85 * e, lo, hi)
    one_minus_e = 1.0 - e
    tiny = 4.0 * EPS
    for _ in range(_KEPLER_MAX_ITER):
        residual = one_minus_e * E + e * _x_minus_sin(E) - target
        # F is increasing: the sign of the residual moves one end of the bracket.
        lo = np.where(residual < 0.0, E, lo)
        hi = np.where(residual > 0.0, E, hi)
        slope = one_minus_e + 2.0 * e * np.sin(0.5 * E) ** 2  # 1 - e cos E
        newton = E - residual / slope
        inside = (newton >= lo) & (newton <= hi)
        new = np.where(inside, newton, 0.5 * (lo + hi))
        step = np.abs(new - E)
        E = new
        if np.all(step <= tiny * np.maximum(1.0, E)):
            break
    return sign * E + two_pi * turns


def kepler(
    t: object, y0: object, params: Mapping[str, float] | None = None, t0: float = 0.0
) -> np.ndarray:
    """Exact flow of the planar Kepler problem ``H = |p|**2/2 - 1/|q|``.

    Any bound, non-collision state is accepted.  The semi-major axis is
    ``a = -1/(2H)``; the eccentric anomaly relative to the initial one,
    ``dE``, solves ``n (t - t0) = dE - e cos(E0) sin(dE) + e sin(E0) (1 - cos dE)``
    with ``e cos(E0) = 1 - r0/a``, ``e sin(E0) = q0.p0/sqrt(a)``,
    ``n = a**-1.5``; then ``q = f q0 + g p0``, ``p = f' q0 + g' p0`` with the
    Lagrange coefficients in the eccentric anomaly ([2]_).  For the
    catalogue's state at pericentre, ``q0 = (1 - e, 0)``,
    ``p0 = (0, sqrt((1 + e)/(1 - e)))``, this is ``q1 = cos E - e``,
    ``q2 = sqrt(1 - e**2) sin E`` with ``E - e sin E = t - t0`` ([1]_, I.2.2).

    Parameters
    ----------
    t : float or array_like, shape (N,)
        Times.
    y0 : array_like, shape (4,)
        ``(q1, q2, p1, p2)`` at ``t0``.
    params : mapping, optional
        Unused: the Hamiltonian has ``G M = 1``.  (The catalogue's parameter
        ``e`` enters only through the initial state.)
    t0 : float, optional
        Time of ``y0``.

    Returns
    -------
    ndarray, shape (N, 4)

    Raises
    ------
    InputError
        If the state is unbound (``H >= 0``), at the origin, or on a
        collision orbit (zero angular momentum).
    """
    tau, tau_lo = elapsed(t, t0)
    y0 = as_state(y0, 4, "kepler")
    q0, p0 = y0[:2], y0[2:]
    r0 = float(np.hypot(q0[0], q0[1]))
    if r0 == 0.0:
        raise InputError("the 'kepler' exact solution needs q0 != (0, 0) (the singularity)")
    energy = 0.5 * float(p0 @ p0) - 1.0 / r0
    if not energy < 0.0:
        raise InputError(
            f"the 'kepler' exact solution covers only bound orbits (H < 0); y0 = "
            f"{y0.tolist()} has H = {energy!r} (parabolic or hyperbolic)"
        )
    ang = float(q0[0] * p0[1] - q0[1] * p0[0])
    if ang == 0.0:
        raise InputError(
            f"the 'kepler' exact solution needs non-zero angular momentum; y0 = "
            f"{y0.tolist()} lies on a collision orbit"
        )
    # The orbit's constants from the double initial state, in mpmath: the
    # mean motion n from an energy rounded to double moves the phase by
    # eps n |t - t0|, which near pericentre the velocity magnifies.
    ctx = mpmath.MPContext()
    ctx.dps = CONSTANT_DIGITS
    q1, q2, v1, v2 = (ctx.mpf(float(v)) for v in y0)
    exact_r0 = ctx.sqrt(q1**2 + q2**2)
    exact_a = -1 / (2 * ((v1**2 + v2**2) / 2 - 1 / exact_r0))
    exact_sqrt_a = ctx.sqrt(exact_a)
    exact_sigma0 = q1 * v1 + q2 * v2  # r0 dr/dt at t0
    ec = 1 - exact_r0 / exact_a  # e cos E0
    es = exact_sigma0 / exact_sqrt_a  # e sin E0
    exact_e = ctx.sqrt(ec**2 + es**2)
    exact_E0 = ctx.atan2(es, ec)
    mean0 = exact_E0 - exact_e * ctx.sin(exact_E0)
    mean = reduced_phase(tau, tau_lo, exact_a ** ctx.mpf(-1.5), mean0, 2 * ctx.pi)
    # (ec, es) = e (cos E0, sin E0) by construction; H < 0 and L != 0 give
    # e < 1, but rounding can reach 1 on extremely eccentric orbits.
    e = min(float(exact_e), float(np.nextafter(1.0, 0.0)))
    a, sqrt_a, sigma0 = float(exact_a), float(exact_sqrt_a), float(exact_sigma0)
    # The eccentric anomaly on the reduced phase (the trigonometric
    # functions below need dE only modulo 2 pi).
    dE = solve_kepler_equation(mean, e) - float(exact_E0)
    s = np.sin(dE)
    one_minus_c = 2.0 * np.sin(0.5 * dE) ** 2  # 1 - cos dE, without cancellation
    # r0 + (a - r0)(1 - cos dE), not a - (a - r0) cos dE: near pericentre of
    # an eccentric orbit the latter cancels down to r0 = a (1 - e), losing
    # eps / (1 - e) of r (at e = 0.999 the momenta were 7.5e-13 off)
    r = r0 + (a - r0) * one_minus_c + sigma0 * sqrt_a * s
    f = 1.0 - (a / r0) * one_minus_c
    g = a * sigma0 * one_minus_c + r0 * sqrt_a * s
    fdot = -sqrt_a * s / (r * r0)
    gdot = 1.0 - (a / r) * one_minus_c
    q = f[:, None] * q0 + g[:, None] * p0
    p = fdot[:, None] * q0 + gdot[:, None] * p0
    return np.hstack([q, p])
