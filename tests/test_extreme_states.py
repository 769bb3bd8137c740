"""States of extreme size, and the runs they end: ``solve`` returns a status
and a message that names the true cause, never raises.

The harmonic oscillator ``H = (p^2 + q^2)/2`` is linear, so any scale of its
state is exact (``q = q0 cos t + p0 sin t``): the nodes kept are checked
against it.
"""

import math

import numpy as np
import sympy as sp

import hamrkq
from hamrkq.result import Status

q, p = sp.symbols("q p", real=True)
OSCILLATOR = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2, q=[q], p=[p])


def oscillator_exact(t, q0, p0):
    """The oscillator's exact (q, p) at the times ``t`` from ``(q0, p0)`` at 0."""
    t = np.asarray(t, dtype=float)
    return np.stack([q0 * np.cos(t) + p0 * np.sin(t), p0 * np.cos(t) - q0 * np.sin(t)], axis=-1)


def test_auto_rules_turn_no_infinite_estimate_into_quencher_steps():
    from hamrkq.rkq.auto_rules import AUTO_MAX_SUBSTEPS, auto_retry_substeps

    # A stop on an estimate that is not finite is no truncation error that
    # more quencher steps shrink: None (it raised OverflowError).
    assert auto_retry_substeps(2, 9, math.inf, 0.05, 0.227) is None
    assert auto_retry_substeps(2, 9, math.nan, 0.05, 0.227) is None
    # a finite ratio whose projection overflows gets the most, as a large one does
    assert auto_retry_substeps(3, 12, 1e300, 0.05, 1e-6) == AUTO_MAX_SUBSTEPS
    assert auto_retry_substeps(3, 12, 1e9, 0.05, 1e-6) == AUTO_MAX_SUBSTEPS


def test_auto_returns_the_runs_own_status_where_its_estimate_stops_being_finite():
    # |y| = 5e169, atol = 3e169: the run stops at t = 2.27 where the estimate
    # is no longer finite; auto raised OverflowError: cannot convert float
    # infinity to integer (auto_rules._grown_substeps), forwards and backwards.
    for span, stop in [((0.0, 10.0), 2.2746), ((10.0, 0.0), 7.7554)]:
        sol = hamrkq.solve(OSCILLATOR, q0=[3e169], p0=[4e169], t_span=span, atol=3e169)
        assert sol.status is Status.TOLERANCE_UNATTAINABLE
        assert sol.t.shape == (3,)
        assert abs(sol.t[-1] - stop) < 1e-4
        # the run is auto's first (rk67q9 at this loose tolerance), not run again
        assert sol.options["z_substeps"] == 2
        assert "method='auto' ran" not in sol.message
        assert "discarded_evaluations" not in sol.stats
        # and its nodes are right: within 3e-4 of the tolerance
        exact = oscillator_exact(sol.t - span[0], 3e169, 4e169)
        assert np.max(np.abs(sol.y - exact)) / 3e169 < 3e-4
