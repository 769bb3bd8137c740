"""heyoka's adaptive Taylor steps, bounded: the integration under
:mod:`hamrkq.analysis.extended_reference`.

heyoka sizes a step from the solution's
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
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hamrkq.errors import InputError, IntegrationError

__all__ = ["MAX_STEPS", "STEP_GROWTH", "propagate"]

#: No step is more than this many times the one before.  heyoka's own steps
#: grew at most 1.31 times on the catalogue's cases and 1.39 on the q^10
#: oscillator at 1e-18; a bound of 1.3 made that run's error 4.1e-13 (1.1e-13
#: at 1.5), one of 2 no longer kept a run at 1e-19 right (3.4e-11).
STEP_GROWTH = 1.5
#: A run stops with an IntegrationError after this many steps rather than
#: chase a blow-up with ever shorter steps: the three runs' 274 169 steps on
#: the q^10 oscillator over [0, 1000] took 0.84 s, so some half a minute.
MAX_STEPS = 10_000_000


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


def propagate(
    equations,
    y0,
    t0: float,
    t: np.ndarray,
    tol: float,
    fp_type: Any = np.longdouble,
    pars: np.ndarray | None = None,
) -> np.ndarray:
    """The states at ``t`` from ``y0`` at ``t0``: heyoka's adaptive Taylor
    steps in ``fp_type``, each at most :data:`STEP_GROWTH` times the one
    before (the first at most :func:`_first_step_bound`), at most
    :data:`MAX_STEPS` of them.  heyoka's ``propagate_grid`` takes the steps
    (its dense output gives the states between them) and stops at a step
    longer than that; the step is then taken again, bounded.  ``pars``: the
    values of the equations' runtime parameters (``hy.par[i]``)."""
    import heyoka as hy

    ta = hy.taylor_adaptive(
        equations,
        np.array([fp_type(float(v)) for v in y0]),
        time=fp_type(float(t0)),
        fp_type=fp_type,
        tol=fp_type(tol),
        pars=np.zeros(0, dtype=fp_type) if pars is None else pars,
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
