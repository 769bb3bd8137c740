"""Built-in analytic solutions, referenced by name from problem files.

A problem file may say ``[exact] builtin = "kepler"``; the catalogue then
looks the name up in :data:`BUILTIN_EXACT` (a lookup, never an evaluation of
text).  Each entry is a function ::

    exact(t, y0, params, t0=0.0) -> ndarray, shape (N, 2n)

that returns the exact state at the times ``t`` of the trajectory through
``y0`` at time ``t0``.  It raises :class:`~hamrkq.errors.InputError` when
``y0`` is outside the family of states it covers, so an exact solution is
never silently wrong.

Entries
-------
``"harmonic"``
    ``H = (p**2 + q**2)/2``, any initial state.
``"pendulum"``
    ``H = p**2/2 - cos(q)``, libration (``H < 1``), through Jacobi elliptic
    functions.
``"kepler"``
    ``H = (p1**2 + p2**2)/2 - 1/sqrt(q1**2 + q2**2)``, any bound (``H < 0``),
    non-collision planar state, through Kepler's equation and the Lagrange
    ``f`` and ``g`` coefficients.

References
----------
.. [1] E. Hairer, C. Lubich and G. Wanner, *Geometric Numerical Integration*,
   2nd ed., Springer, 2006, Sections I.1 and I.2.
.. [2] R.H. Battin, *An Introduction to the Mathematics and Methods of
   Astrodynamics*, AIAA, 1999, Section 4.3 (f and g in the eccentric anomaly).
.. [3] J.M.A. Danby, *Fundamentals of Celestial Mechanics*, 2nd ed., 1988,
   Section 6.6 (the starting value ``M + 0.85 e`` for Kepler's equation).
.. [4] M. Abramowitz and I.A. Stegun, *Handbook of Mathematical Functions*,
   Chapter 16 (Jacobi elliptic functions).
.. [5] R. Bulirsch, Numerical calculation of elliptic integrals and elliptic
   functions, Numer. Math. 7 (1965) 78-90 (sncndn, in the complementary
   parameter).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

import mpmath
import numpy as np

from hamrkq._floats import EPS
from hamrkq.errors import InputError, OptionError

__all__ = [
    "BUILTIN_ASSUMES",
    "BUILTIN_EXACT",
    "ExactSolution",
    "builtin_exact_of",
    "exact_accuracy",
    "get_exact",
    "harmonic",
    "kepler",
    "pendulum",
    "pendulum_accuracy",
    "solve_kepler_equation",
]

#: Signature of a built-in exact solution.
ExactSolution = Callable[..., np.ndarray]

#: Newton iterations allowed for Kepler's equation.  The safeguarded iteration
#: converges quadratically from Danby's start; 8 iterations suffice for
#: e < 0.999999, the rest is margin for the bisection fallback.
_KEPLER_MAX_ITER = 60

#: Below this |E| the series of E - sin E is used: the direct difference
#: loses all digits when E ~ e sin E (e near 1, E near 0).
_SERIES_LIMIT = 0.5


def _times(t: object) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(t, dtype=float))
    if arr.ndim != 1:
        raise InputError(f"t must be a scalar or a 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("t must be finite")
    return arr


def _state(y0: object, dim: int, name: str) -> np.ndarray:
    arr = np.asarray(y0, dtype=float)
    if arr.shape != (dim,):
        raise InputError(
            f"the {name!r} exact solution needs y0 of shape ({dim},) "
            f"(q's then p's), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"y0 must be finite, got {arr.tolist()}")
    return arr


# -- the phase of a periodic motion, without growing rounding --------------------
#
# A flow evaluated as (a phase that grows like t) mod (a period) in doubles
# loses eps |t| of its phase: Kepler's mean anomaly n (t - t0) with n from a
# rounded energy was 1.8e-13 off after ten orbits at e = 0.6 (6.8e-12 at
# e = 0.9), a sixth of the tolerance a run at 1e-12 is measured against.
# The constants come from the double initial state in mpmath, and the phase
# is carried in double-double (Knuth's TwoSum, Dekker's product with
# Veltkamp's splitting; hamrkq.rkq.ddarith has the kernel's scalar forms),
# so the reduced phase is accurate to a few ulps for any t.

#: Digits of the constants computed in mpmath from the initial state.
_CONSTANT_DIGITS = 34


def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``p + e == a b`` exactly, for ``|a|, |b| <= 2**996``."""
    p = a * b

    def split(x):
        c = 134217729.0 * x  # 2**27 + 1
        hi = c - (c - x)
        return hi, x - hi

    a1, a2 = split(a)
    b1, b2 = split(b)
    return p, ((a1 * b1 - p) + a1 * b2 + a2 * b1) + a2 * b2


def _hi_lo(value: mpmath.mpf) -> tuple[float, float]:
    """An mpmath number as a double-double ``(hi, lo)``."""
    hi = float(value)
    return hi, float(value - hi)


def _reduced_phase(
    tau: np.ndarray, tau_lo: np.ndarray, rate: mpmath.mpf, start: mpmath.mpf, period: mpmath.mpf
) -> np.ndarray:
    """``start + rate (tau + tau_lo)`` reduced modulo ``period``, in
    ``[-period/2, period/2]``, accurate to a few ulps of ``period`` for any
    ``tau``."""
    rate_hi, rate_lo = _hi_lo(rate)
    start_hi, start_lo = _hi_lo(start)
    period_hi, period_lo = _hi_lo(period)
    product, product_lo = _two_prod(np.full_like(tau, rate_hi), tau)
    product_lo = product_lo + (rate_hi * tau_lo + rate_lo * tau)
    total, total_lo = _two_sum(np.full_like(tau, start_hi), product)
    total_lo = total_lo + (start_lo + product_lo)
    turns = np.round(total / period_hi)
    off, off_lo = _two_prod(turns, np.full_like(tau, period_hi))
    off_lo = off_lo + turns * period_lo
    phase, phase_lo = _two_sum(total, -off)
    return phase + (phase_lo + (total_lo - off_lo))


def _elapsed(t: object, t0: float) -> tuple[np.ndarray, np.ndarray]:
    """``t - t0`` as a double-double (exact)."""
    return _two_sum(_times(t), np.float64(-float(t0)))


# -- harmonic oscillator -------------------------------------------------------


def harmonic(
    t: object, y0: object, params: Mapping[str, float] | None = None, t0: float = 0.0
) -> np.ndarray:
    """Exact flow of ``H = (p**2 + q**2)/2``: a rotation of the phase plane.

    Parameters
    ----------
    t : float or array_like, shape (N,)
        Times.
    y0 : array_like, shape (2,)
        ``(q, p)`` at time ``t0``.
    params : mapping, optional
        Unused (the oscillator has unit frequency); accepted for a uniform
        signature.
    t0 : float, optional
        Time of ``y0``.

    Returns
    -------
    ndarray, shape (N, 2)
        ``q = q0 cos(t - t0) + p0 sin(t - t0)``, ``p = p0 cos(t - t0) - q0 sin(t - t0)``.
    """
    tau, tau_lo = _elapsed(t, t0)
    q0, p0 = _state(y0, 2, "harmonic")
    # cos and sin of tau + tau_lo to first order in tau_lo (below an ulp of
    # tau): t - t0 rounded to double lost eps |t - t0| / 2 of the phase,
    # 3.7e-11 at t = 1e6 from t0 = 1/3 (benchmarks/exact_accuracy.txt).
    c, s = np.cos(tau), np.sin(tau)
    c, s = c - s * tau_lo, s + c * tau_lo
    return np.column_stack([q0 * c + p0 * s, p0 * c - q0 * s])


# -- pendulum ------------------------------------------------------------------
#
# Near the separatrix (m = k**2 -> 1) the shape of the orbit depends on m
# like 1/(1 - m): m rounded to double, which scipy's ellipj needs, moved the
# solution by eps/(2 (1 - m)) times its scale (1.9e4 eps at q0 = 3.14, the
# whole amplitude at q0 = 3.14159, where ellipj's approximation for m within
# 1e-9 of 1 holds only for small u).  So the modulus is carried as its
# complement m1 = 1 - m, computed from the double initial state in mpmath,
# and sn, cn, dn come from Bulirsch's algorithm in m1 ([5]_), whose
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
    for digits in (_CONSTANT_DIGITS, 2 * _CONSTANT_DIGITS, 4 * _CONSTANT_DIGITS):
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
    algorithm ([5]_): the arithmetic-geometric mean of ``1`` and ``sqrt(m1)``
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
    ``phi0 = atan2(sin(q0/2), p0/2)`` ([4]_, 16.1).  The libration may be about
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
    tau, tau_lo = _elapsed(t, t0)
    q0, p0 = _state(y0, 2, "pendulum")
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
    fraction = _reduced_phase(tau, tau_lo, 1 / quarter, u0 / quarter, ctx.mpf(4))
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
    q0, p0 = _state(y0, 2, "pendulum")
    scale = float(np.max(np.abs(np.asarray(states, dtype=float)), initial=0.0))
    if q0 == 0.0 and p0 == 0.0:
        return 0.0  # the equilibrium, exactly
    turns = float(np.round(q0 / (2.0 * np.pi)))
    ctx, exact_m, _m1 = _pendulum_modulus(float(q0), float(p0), turns)
    phase = float(ctx.sqrt(exact_m) * ctx.ellipk(exact_m))
    return EPS * (PENDULUM_ROUNDING * scale + PENDULUM_PHASE * phase)


# -- Kepler problem --------------------------------------------------------------


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
    tau, tau_lo = _elapsed(t, t0)
    y0 = _state(y0, 4, "kepler")
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
    ctx.dps = _CONSTANT_DIGITS
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
    mean = _reduced_phase(tau, tau_lo, exact_a ** ctx.mpf(-1.5), mean0, 2 * ctx.pi)
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


#: The registry, by name.  Read-only.
BUILTIN_EXACT: Mapping[str, ExactSolution] = MappingProxyType(
    {"harmonic": harmonic, "kepler": kepler, "pendulum": pendulum}
)


#: What each built-in solution assumes: the state's length and the
#: Hamiltonian whose flow it is (no parameter enters any of them).  A file's
#: ``[exact] builtin`` of another length is refused when the file is read; one
#: whose Hamiltonian differs is refused by the check of the solution against
#: Hamilton's equations (:func:`hamrkq.catalogue.problem.check_exact`).
BUILTIN_ASSUMES: Mapping[str, tuple[int, str]] = MappingProxyType(
    {
        "harmonic": (2, "H = (p**2 + q**2)/2 (unit mass and frequency)"),
        "kepler": (4, "H = (p1**2 + p2**2)/2 - 1/sqrt(q1**2 + q2**2) (G M = 1)"),
        "pendulum": (2, "H = p**2/2 - cos(q) (unit length and gravity), H < 1"),
    }
)


#: An exact solution's values are stated accurate to this many ulps of their
#: largest component, ``EXACT_ROUNDING * eps * max|y|``, unless it states its
#: own accuracy (:data:`BUILTIN_ACCURACY`).
EXACT_ROUNDING = 4.0

#: A solution written as expressions in ``t`` is stated accurate to
#: ``EXACT_PHASE * eps * max_i |t_i| |f(t_i, y_i)|`` more (``f`` the
#: right-hand side, max-norm): a phase such as ``w*t`` evaluated in doubles
#: loses up to ``eps |w t| / 2`` at each rounding (the product, a sum with a
#: constant), ``eps |t| |dy/dt|`` in the state over two of them.  Measured
#: against mpmath at 40 digits: ``sin(w*t)/w, cos(w*t)`` at w = 1.1, 0.3,
#: 2.7 up to t = 1e6 reach 0.46 of it (benchmarks/exact_accuracy.txt).
EXACT_PHASE = 1.0

#: The built-in solutions that state their own accuracy:
#: ``accuracy(y0, states) -> float``.  Read-only.
BUILTIN_ACCURACY: Mapping[str, Callable[[object, object], float]] = MappingProxyType(
    {"pendulum": pendulum_accuracy}
)


def exact_accuracy(
    states: object,
    builtin: str | None = None,
    y0: object = None,
    times: object = None,
    rates: object = None,
) -> float:
    """What an exact solution's ``states`` are stated accurate to (max-norm).

    ``builtin`` names the built-in solution they came from, ``y0`` its
    initial state: the pendulum states its own (:func:`pendulum_accuracy`),
    the harmonic oscillator and Kepler ``EXACT_ROUNDING * eps * max|y|``
    (their phase is carried in double-double from ``t - t0``, so their
    error does not grow with time: measured up to t = 1e6).  A solution
    written as expressions in ``t`` (``builtin`` None) evaluates its phase
    in doubles, which loses ``eps |w t|`` of a phase ``w*t``: given the
    node ``times`` and the ``rates`` ``f(t_i, y_i)`` of the Hamiltonian's
    right-hand side at the ``states`` (shape ``(N, 2n)``), it is stated
    accurate to ``eps (EXACT_ROUNDING max|y| + EXACT_PHASE max_i |t_i|
    |f(t_i, y_i)|)``; without them to ``EXACT_ROUNDING * eps * max|y|``,
    which holds only where the phase is exact (``sin(t)``) or ``|t|``
    small.  What ``hamrkq.diagnose`` and ``hamrkq compare`` report as the
    exact reference's accuracy.
    """
    if builtin in BUILTIN_ACCURACY and y0 is not None:
        return float(BUILTIN_ACCURACY[builtin](y0, states))
    states = np.asarray(states, dtype=float)
    accuracy = EXACT_ROUNDING * EPS * float(np.max(np.abs(states), initial=0.0))
    if builtin is None and times is not None and rates is not None:
        at = np.abs(np.asarray(times, dtype=float)).reshape(-1)
        rate = np.abs(np.asarray(rates, dtype=float)).reshape(at.size, -1)
        phase = float(np.max(at * np.max(rate, axis=1, initial=0.0), initial=0.0))
        accuracy += EXACT_PHASE * EPS * phase
    return accuracy


def builtin_exact_of(problem: object) -> tuple[str | None, object]:
    """``(name, y0)`` of the built-in solution that is ``problem.exact``
    (the flow of ``problem.y0``), or ``(None, None)`` for a problem whose
    exact solution is written as expressions, or that has none: the
    arguments of :func:`exact_accuracy` after the states."""
    spec = getattr(problem, "exact_spec", None) or {}
    if "builtin" not in spec:
        return None, None
    return str(spec["builtin"]), getattr(problem, "y0", None)


def get_exact(name: str) -> ExactSolution:
    """Look up a built-in exact solution by name.

    Raises
    ------
    OptionError
        If ``name`` is not in :data:`BUILTIN_EXACT`; the message lists the
        known names.
    """
    try:
        return BUILTIN_EXACT[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(BUILTIN_EXACT))
        raise OptionError(f"unknown built-in exact solution {name!r}; known: {known}") from None
