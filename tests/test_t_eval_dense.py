"""Output times (``t_eval``) denser than the steps: passed by the steps, their
values from dense output inside the kernel (``hamrkq.rkq.loop.emit_dense``),
against the exact solution; the steps are the run's own."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.rkq.config import Settings
from hamrkq.rkq.driver import Integration
from hamrkq.rkq.family import get_member
from hamrkq.rkq.layout import GAMMA_SHADOW, QUENCH_NODE, RULE_COMPONENTWISE

KEPLER_SPAN = (0.0, 20 * np.pi)


@pytest.fixture(scope="module")
def kepler():
    return hamrkq.load_problem("kepler", e=0.6)


@pytest.mark.parametrize("method", ["auto", "rk34q8", "rk45q12"])
def test_dense_output_times_hold_the_tolerance_without_more_steps(kepler, method):
    """5001 output times over ten orbits at 1e-9: every value within the
    tolerance of the exact solution (Kepler's equation), and about the
    steps of the run without them (before, a step landed on every time:
    5000 steps for auto, whose own run takes about 400)."""
    atol = 1e-9
    own = hamrkq.solve(kepler, t_span=KEPLER_SPAN, method=method, atol=atol)
    t_eval = np.linspace(*KEPLER_SPAN, 5001)
    sol = hamrkq.solve(kepler, t_span=KEPLER_SPAN, t_eval=t_eval, method=method, atol=atol)
    assert sol.success, sol.message
    np.testing.assert_array_equal(sol.t, t_eval)
    assert np.abs(sol.y - kepler.exact(sol.t)).max() <= 1.05 * atol
    assert sol.stats["steps"] <= 1.1 * own.stats["steps"]
    # The quencher's value beside each, and its difference is within the bound
    assert np.abs(sol.global_error).max() <= 1.05 * atol


def test_backward_in_time(kepler):
    """From the exact state at t = 20 back to 0, 2001 output times."""
    y20 = kepler.exact(np.array([20.0]))[0]
    t_eval = np.linspace(20.0, 0.0, 2001)
    sol = hamrkq.solve(kepler, q0=y20[:2], p0=y20[2:], t_span=(20.0, 0.0), t_eval=t_eval,
                       method="auto", atol=1e-9)  # fmt: skip
    assert sol.success
    np.testing.assert_array_equal(sol.t, t_eval)
    exact = kepler.exact(sol.t)  # the exact flow through y20 is the one from y0
    assert np.abs(sol.y - exact).max() <= 1.05e-9


def _integration(kepler, t_eval, buffer_rows):
    ham = kepler.hamiltonian
    from hamrkq.backends.first_use import kernel_functions

    member = get_member("rk78q12", None, 2)
    settings = Settings(QUENCH_NODE, RULE_COMPONENTWISE, GAMMA_SHADOW, t_eval=t_eval)
    tolerances = (np.full(4, 1e-9), np.zeros(4))
    run = Integration(kernel_functions(ham, "shadow"), member, np.array([0.6]), 0.0,
                      kepler.y0, KEPLER_SPAN[1], *tolerances, settings)  # fmt: skip
    return run.run(buffer_rows=buffer_rows)


def test_a_full_buffer_between_dense_times_loses_nothing(kepler):
    """Many output times inside one step, a buffer of 3 rows: the kernel
    returns to grow it in the middle of a step's times and goes on where it
    stopped; the same rows as with a large buffer."""
    t_eval = np.linspace(*KEPLER_SPAN, 3001)
    small = _integration(kepler, t_eval, 3)
    large = _integration(kepler, t_eval, 10_000)
    assert small.status == large.status == 0
    for name in ("t", "y", "z", "gamma", "quenched"):
        np.testing.assert_array_equal(getattr(small, name), getattr(large, name))
    np.testing.assert_array_equal(small.t, t_eval)
    assert small.stats == large.stats


def test_python_and_numba_agree_bit_for_bit(kepler):
    t_eval = np.linspace(0.0, 3.0, 301)
    options = {"t_span": (0.0, 3.0), "t_eval": t_eval, "method": "auto", "atol": 1e-9}
    runs = [hamrkq.solve(kepler, backend=backend, **options) for backend in ("numba", "python")]
    for name in ("t", "y", "global_error", "gamma"):
        np.testing.assert_array_equal(getattr(runs[0], name), getattr(runs[1], name))
    assert runs[0].stats["nfev"] == runs[1].stats["nfev"]


def test_ensemble_members_are_the_single_runs(kepler):
    """The batch loop writes the dense times as a single run does."""
    q0 = np.array([[0.4, 0.0], [0.5, 0.0]])
    p0 = np.array([[0.0, 2.0], [0.0, 1.7]])
    t_eval = np.linspace(0.0, 10.0, 1001)
    ens = hamrkq.ensemble(kepler, q0=q0, p0=p0, t_span=(0.0, 10.0), t_eval=t_eval,
                          method="auto", atol=1e-9, workers=1)  # fmt: skip
    for m in range(2):
        single = hamrkq.solve(kepler, q0=q0[m], p0=p0[m], t_span=(0.0, 10.0), t_eval=t_eval,
                              method="auto", atol=1e-9)  # fmt: skip
        np.testing.assert_array_equal(ens.y[m], single.y)


@pytest.mark.parametrize("method", ["auto", "rk45q8"])
def test_under_rtol_output_times_near_a_zero_keep_their_tolerance(method):
    """The FPU chain at rtol 1e-6: an output time where a component passes
    near zero inside a step got y - z interpolated from the nodes, twice
    its tolerance there (tests/test_rounding_floor.py found it); it is now
    the quencher's value, quenched."""
    fpu = hamrkq.load_problem("fpu")
    times = np.linspace(0.0, 60.0, 601)[1:]
    reference = hamrkq.solve(fpu, t_span=(0.0, 60.0), method="rk78q12", atol=1e-11,
                             quencher_precision="double-double", t_eval=times)  # fmt: skip
    sol = hamrkq.solve(fpu, t_span=(0.0, 60.0), method=method, atol=1e-9, rtol=1e-6,
                       t_eval=times)  # fmt: skip
    assert sol.success and reference.success
    delta = np.maximum(1e-9, 1e-6 * np.abs(reference.y))
    assert np.max(np.abs(sol.y - reference.y) / delta) <= 1.05


@pytest.mark.parametrize("method", ["rk78q12", "rk67q10", "auto"])
def test_under_rtol_an_output_time_at_a_zero_checks_the_quenchers_error_there(method):
    """Kepler at rtol 1e-6 (atol 1e-9), asked for 201 times among which the
    pericentres, where p1 = 0 and its tolerance is atol: the output times
    inside a step were written without the check the nodes get (the
    quencher's Gamma and rounding against gamma_limit of the tolerance
    there), and rk78q12 returned the value at t = 18 pi 1.63 tolerances
    off, rk67q10 4.30 at t = 10 pi.  Now such a run ends before the time
    where the promise cannot be kept; auto runs again with more quencher
    steps and reaches the end."""
    kepler = hamrkq.load_problem("kepler")
    grid = np.linspace(*kepler.t_span, 201)
    sol = hamrkq.solve(kepler, method=method, atol=1e-9, rtol=1e-6, t_eval=grid)
    truth = kepler.exact(sol.t)
    delta = np.maximum(1e-9, 1e-6 * np.abs(truth))
    assert np.max(np.abs(sol.y - truth) / delta) <= 1.05
    if method == "auto":
        assert sol.status is hamrkq.Status.SUCCESS
    else:
        assert sol.status is hamrkq.Status.TOLERANCE_UNATTAINABLE
        assert sol.t[-1] < sol.options["t_span"][1]


def _decoupled_oscillators():
    """Two oscillators coupled by q1^2 q2^2 / 2, released with q2 = p2 = 0:
    q1 = 0.3 cos s + 0.4 sin s exactly (s = t - 10), q2 stays 0."""
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    ham = hamrkq.Hamiltonian(
        (p1**2 + q1**2) / 2 + (p2**2 + q2**2) / 2 + q1**2 * q2**2 / 2, q=[q1, q2], p=[p1, p2]
    )
    phase = np.arctan2(0.4, 0.3)
    zeros = 10.0 + np.pi / 2 + phase + np.pi * np.arange(3)  # of q1, in (10, 20)

    def exact(t):
        s = t - 10.0
        zero = np.zeros_like(s)
        return np.column_stack([0.3 * np.cos(s) + 0.4 * np.sin(s), zero,
                                0.4 * np.cos(s) - 0.3 * np.sin(s), zero])  # fmt: skip

    return ham, zeros, exact


@pytest.mark.parametrize(
    "options",
    [{}, {"method": "rk78q12", "quencher_precision": "double-double", "z_substeps": 12}],
    ids=["auto", "rk78q12-double-double"],
)
def test_an_output_time_at_a_zero_under_a_tiny_atol_is_not_certified(options):
    """QA: under rtol 1e-8 with atol 1e-20, asked for q1's zeros, auto (the
    quencher in double-double after its reruns) returned SUCCESS with values
    1120 times the tolerance off.  The value at an output time inside a
    step is stepped with the quencher's stages in double, whose rounding
    (an ulp of the state's size, 5e-18) the kernel's check counted only as
    an ulp of the value (1e-32), and the double-double quencher's modelled
    rounding is far below it.  Now the run stops there at once, naming the
    atol that works, and with it succeeds within the tolerance."""
    ham, zeros, exact = _decoupled_oscillators()
    start = {"q0": [0.3, 0.0], "p0": [0.4, 0.0], "t_span": (10.0, 20.0), "t_eval": zeros}
    sol = hamrkq.solve(ham, **start, atol=1e-20, rtol=1e-8, **options)
    assert sol.status is hamrkq.Status.TOLERANCE_UNATTAINABLE
    assert sol.t.size == 0
    assert "a larger atol (at least 8.8e-15) is what works" in sol.message
    # auto knows no rerun reduces it: one run
    assert "discarded_evaluations" not in sol.stats
    fixed = hamrkq.solve(ham, **start, atol=8.8e-15, rtol=1e-8)
    assert fixed.status is hamrkq.Status.SUCCESS
    truth = exact(fixed.t)
    assert np.max(np.abs(fixed.y - truth) / np.maximum(8.8e-15, 1e-8 * np.abs(truth))) <= 1.05


def test_an_output_time_the_quencher_fails_at_is_run_again_in_double_double():
    """The double pendulum at rtol 3e-11 (atol 1e-13) on 201 output times:
    in double the quencher stops at the output time t = 7.0 of 10, where
    p1 = -0.364 and its own rounding, measured by the witness, is 0.054 of
    the tolerance.  A rule that read the rounding from a component's largest
    size over the run named a larger atol there instead of running the
    quencher in double-double (the same stop at rtol 1e-10 before the
    weights summed to 1, t = 9.45); auto runs again in double-double and
    reaches the end within the tolerance of the extended-precision
    reference (0.936 measured; its own error 5.7e-15)."""
    ext = pytest.importorskip("hamrkq.analysis.extended_reference")
    if not ext.available():
        pytest.skip(ext.unavailable_reason())
    problem = hamrkq.load_problem("double_pendulum")
    grid = np.linspace(*problem.t_span, 201)
    sol = hamrkq.solve(problem, atol=1e-13, rtol=3e-11, t_eval=grid)
    assert sol.status is hamrkq.Status.SUCCESS, sol.message
    assert sol.options["quencher_precision"] == "double-double"
    assert "the rounding witness stopped at t = 7.0," in sol.message
    np.testing.assert_array_equal(sol.t, grid)
    ref = ext.extended_reference(problem.hamiltonian, problem.parameter_array, problem.y0, grid)
    assert ref.estimated_error < 0.1e-13
    delta = np.maximum(1e-13, 3e-11 * np.abs(ref.y))
    assert np.max(np.abs(sol.y - ref.y) / delta) <= 1.05
