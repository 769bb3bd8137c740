"""States of extreme size, and the runs they end: ``solve`` returns a status
and a message that names the true cause, never raises; and a fixed step
longer than the interval, which the message states as taken.

The harmonic oscillator ``H = (p^2 + q^2)/2`` is linear, so any scale of its
state is exact (``q = q0 cos t + p0 sin t``): the nodes kept are checked
against it.
"""

import math

import numpy as np
import pytest
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


HUGE_STATE_MESSAGE = (
    "At t = 10.0 the quencher's modelled rounding is no longer finite, so the tolerance can "
    "no longer be certified; the run ends at the last node where it held. The model sums the "
    "squares of eps times the quencher's increments, and a square overflows a double once "
    "that passes 1.34e+154: from a state of about 1e169 on, and the state's largest "
    "component here is 4e+199. It is the state's size, not the orbit or the tolerance: a "
    "looser tolerance or another estimate of the quencher's error does not help. What works: "
    "variables rescaled to bring the state well below 1e169 (q = s Q and p = s P, with "
    "H(s Q, s P) / s^2 as the Hamiltonian: the same t). The 1 node computed so far is kept."
)


@pytest.mark.parametrize(
    "options",
    [
        {"method": "auto"},
        {"method": "rk34q8"},
        {"method": "rk78q12", "global_error_estimate": "tangent"},
        {"method": "rk34q8", "global_error_estimate": "off"},
    ],
)
def test_a_state_whose_rounding_model_overflows_is_named_as_the_cause(options):
    # |y| = 5e199, atol = 1e199: f and the exact solution are finite, Gamma
    # too (4e186 at the first step), but eps times an increment is 1e184,
    # whose square overflows.  The message blamed Gamma ("no longer finite"),
    # with auto a diverged shadow "near an unstable equilibrium or a
    # separatrix, or on a chaotic orbit", and named a looser tolerance and
    # global_error_estimate='tangent', with 'off' (no Gamma at all) too.
    sol = hamrkq.solve(
        OSCILLATOR, q0=[3e199], p0=[4e199], t_span=(10.0, 0.0), atol=1e199, **options
    )
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    assert sol.t.tolist() == [10.0]
    assert sol.message == HUGE_STATE_MESSAGE


@pytest.mark.parametrize("method", ["auto", "rk34q8", "rk34"])
def test_a_state_near_the_largest_double_gets_a_finite_first_step(method):
    # QA: at |y| = 1e307..1e308 with atol 1e-8, |y| / delta overflowed, the
    # first-step heuristic's inf / inf gave a NaN step, and every attempt
    # was rejected without shrinking it: MAX_STEPS after a million
    # rejections at t = 0, the cause unnamed.
    sol = hamrkq.solve(OSCILLATOR, [1e308], [0.0], (0.0, 1.0), atol=1e-8, method=method)
    assert math.isfinite(sol.options["first_step"]) and sol.options["first_step"] > 0
    assert sol.status is Status.NON_FINITE and sol.stats["rejected"] < 1000
    assert "within a factor 1.8 of the largest double" in sol.message
    assert "rescaled" in sol.message
    if method != "rk34":  # (without a quencher it crawls at its tolerance: MAX_STEPS)
        # the quencher's rounding model overflows first, or a stage value
        sol = hamrkq.solve(OSCILLATOR, [1e307], [0.0], (0.0, 1.0), atol=1e-8, method=method)
        assert sol.status in (Status.TOLERANCE_UNATTAINABLE, Status.NON_FINITE)
        assert sol.t.tolist() == [0.0] and sol.stats["rejected"] < 1000
        assert "1e+307" in sol.message and "rescaled" in sol.message


def test_the_rescaled_state_that_the_message_names_succeeds():
    # s = 1e190: Q0 = 3e9, P0 = 4e9, H(s Q, s P) / s^2 is the same oscillator;
    # s Q is within the tolerance of the exact solution at 5e199 (0.015 of it).
    sol = hamrkq.solve(OSCILLATOR, q0=[3e9], p0=[4e9], t_span=(10.0, 0.0), atol=1e9)
    assert sol.success
    exact = oscillator_exact(sol.t - 10.0, 3e199, 4e199)
    assert np.max(np.abs(1e190 * sol.y - exact)) / 1e199 < 1.05


def test_a_diverged_shadow_at_a_small_state_still_says_so():
    # H = p^2/2 + exp(q^2) from p = 30 at atol 10: rk78q12's shadow, one step
    # a step, evaluates exp(q^2) beyond a double at t0.  The state is 30: no
    # overflow of the rounding model, and the message names the shadow.
    ham = hamrkq.Hamiltonian(p**2 / 2 + sp.exp(q**2), q=[q], p=[p])
    sol = hamrkq.solve(ham, q0=[0.0], p0=[30.0], t_span=(0.0, 3.0), atol=10.0, method="rk78q12")
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    assert sol.t.tolist() == [0.0]
    assert sol.message.startswith(
        "At t = 0.0 the estimate of the quencher's global error (Gamma) is no longer finite"
    )
    assert "it diverged" in sol.message
    assert "modelled rounding" not in sol.message


def test_a_fixed_step_longer_than_the_interval_is_stated_as_taken():
    # step=20 over (10, 0): one step of -10, which said "in 1 steps of 20.0".
    sol = hamrkq.solve(
        OSCILLATOR, q0=[0.3], p0=[0.4], t_span=(10.0, 0.0), method="gauss4", step=20.0
    )
    assert sol.success
    assert sol.t.tolist() == [10.0, 0.0]
    assert sol.message == "gauss4 reached t=0.0 in 1 step of -10.0"
    # several steps: signed, and the last where it was shortened to land on t1
    for span, step, taken in [
        ((1.0, 0.0), 0.1, "10 steps of -0.1"),
        ((10.0, 0.0), 3.0, "4 steps of -3.0, the last -1.0"),
        ((0.0, 10.0), 3.0, "4 steps of 3.0, the last 1.0"),
    ]:
        sol = hamrkq.solve(
            OSCILLATOR, q0=[0.3], p0=[0.4], t_span=span, method="midpoint", step=step
        )
        assert sol.message == f"midpoint reached t={span[1]!r} in {taken}"
        # the last step as stated: -0.1 up to the rounding of t_9 = 1 - 9 x 0.1
        assert np.diff(sol.t)[-1] == pytest.approx(float(taken.split()[-1]), rel=1e-15)
