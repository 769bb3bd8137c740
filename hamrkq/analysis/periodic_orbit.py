"""One period of a periodic orbit: what a periodic reference is read from.

:func:`find_return` integrates roughly until the orbit returns to the
Poincare section through its start (normal to the flow) and gives the
approximate period; :func:`periodic_orbit` refines the period by Newton's
method on that section and keeps one period as a dense interpolant, from
which :class:`Orbit` reads the state at any time (``t`` reduced modulo the
period, plus the shift of an orbit that is periodic only up to one, such as
a pendulum's rotation).  SciPy's DOP853 does the integrating;
:func:`~hamrkq.analysis.reference.periodic_reference` uses all three.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hamrkq._floats import EPS
from hamrkq.errors import InputError, IntegrationError

__all__ = ["MAX_NEWTON", "PILOT_RTOL", "RETURN_RADIUS", "Orbit", "find_return", "periodic_orbit"]


#: The pilot runs (period search, component scales) need only a few digits.
PILOT_RTOL = 1e-10
#: A crossing of the Poincare section counts as a return only this close to
#: the start, relative to the orbit's extent: other crossings are far away.
RETURN_RADIUS = 1e-2
MAX_NEWTON = 8


@dataclass(frozen=True)
class Orbit:
    t0: float
    period: float
    shift: np.ndarray
    dense: Any  # scipy OdeSolution over one period
    closure: float  # |y(T) - y0 - shift| left after Newton (max-norm)
    nfev: int
    steps: int
    speed: float  # max-norm of f over the period's nodes

    def rounding_floor(self, periods: float) -> float:
        """Random-walk rounding of the states plus its effect on the phase."""
        walk = np.sqrt(self.steps) * EPS
        scale = float(np.max(np.abs(self.dense(self.dense.ts))))
        return float(walk * scale + periods * walk * self.period * self.speed)

    def evaluate(self, t: np.ndarray) -> np.ndarray:
        tau = t - self.t0
        # The reduction t mod T loses eps*|t| of phase; that is the accuracy
        # with which the node time itself is known, so nothing better exists.
        k = np.floor(tau / self.period)
        s = np.clip(tau - k * self.period, 0.0, self.period)
        return self.dense(self.t0 + s).T + k[:, None] * self.shift


def find_return(fun, t0, y0, shift, max_period, atol) -> tuple[float, np.ndarray, int]:
    """First return to the section through ``y0 + shift`` normal to the flow.

    Returns the approximate period, the per-component scales seen on the way,
    and the number of function evaluations.
    """
    # scipy.integrate takes 0.3 s to import: only when an orbit is computed
    # (a report whose reference is cached never needs it).
    from scipy.integrate import DOP853
    from scipy.optimize import brentq

    normal = fun(t0, y0)
    target = y0 + shift
    solver = DOP853(fun, t0, y0, t0 + max_period, rtol=PILOT_RTOL, atol=atol)
    g_old, extent, peak = 0.0, 0.0, np.abs(y0)
    while solver.status == "running":
        t_old = solver.t
        message = solver.step()
        if solver.status == "failed":
            raise IntegrationError(f"period search failed at t={float(solver.t)!r}: {message}")
        extent = max(extent, float(np.max(np.abs(solver.y - y0))))
        peak = np.maximum(peak, np.abs(solver.y))
        g_new = float(normal @ (solver.y - target))
        if g_old < 0.0 <= g_new:
            dense = solver.dense_output()

            def section(s: float, dense=dense) -> float:
                return float(normal @ (dense(s) - target))

            t_cross = brentq(section, t_old, solver.t, xtol=1e-15)
            if np.max(np.abs(dense(t_cross) - target)) <= RETURN_RADIUS * extent:
                return t_cross - t0, peak, solver.nfev
        g_old = g_new
    raise InputError(
        f"the orbit does not return to y0 within max_period={max_period!r}; it may not "
        "be periodic (use integrate_reference) or its period is longer (pass max_period)"
    )


def periodic_orbit(fun, t0, y0, shift, guess, rtol, atol, steps_per_period) -> Orbit:
    """Refine the period by Newton's method on the section and keep one period."""
    from scipy.integrate import solve_ivp  # see find_return

    normal = fun(t0, y0)
    period, nfev, closure = guess, 0, np.inf
    for _ in range(MAX_NEWTON):
        sol = solve_ivp(
            fun, (t0, t0 + period), y0, method="DOP853", rtol=rtol, atol=atol,
            max_step=period / steps_per_period, dense_output=True,
        )  # fmt: skip
        nfev += sol.nfev
        if not sol.success:
            raise IntegrationError(f"reference integration failed: {sol.message}")
        end = sol.y[:, -1]
        mismatch = end - y0 - shift
        flow = fun(t0 + period, end)
        # The return time T solves normal . (y(T) - y0 - shift) = 0; its
        # derivative in T is normal . f(y(T)).
        correction = -float(normal @ mismatch) / float(normal @ flow)
        period += correction
        closure = float(np.max(np.abs(mismatch + correction * flow)))
        if abs(correction) <= 8 * EPS * period:
            break
    # The interpolant was built over [t0, t0 + T_previous]; the last correction
    # is a few ulp of T, so reading it at T_final is a negligible extrapolation.
    speed = max(float(np.max(np.abs(fun(t0, y)))) for y in sol.y.T)
    return Orbit(t0, period, shift, sol.sol, closure, nfev, sol.t.size - 1, speed)
