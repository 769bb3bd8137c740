"""``t_eval`` with events or dense output (SciPy's ``solve_ivp`` allows both):
every node kept for the dense output, the output times' values from it and
checked as the kernel checks an output time (``hamrkq.solve.output_times``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hamrkq
from hamrkq.catalogue.problems import load_problem
from hamrkq.result import Status

ATOL = 1e-8


@pytest.fixture(scope="module")
def harmonic():
    return load_problem("harmonic")


def _over_tolerance(sol, exact) -> float:
    """Largest true error over max(atol, rtol |y|) at the rows."""
    truth = exact(sol.t)
    return float(np.max(np.abs(sol.y - truth) / np.maximum(sol.atol, sol.rtol * np.abs(truth))))


def test_rows_are_the_output_times_and_events_are_found_between_them(harmonic):
    times = np.linspace(0.0, 20.0, 41)
    sol = hamrkq.solve(
        harmonic, t_span=(0.0, 20.0), t_eval=times, atol=ATOL, dense_output=True,
        events={"expression": "q", "direction": 1},
    )  # fmt: skip
    assert sol.status is Status.SUCCESS
    np.testing.assert_array_equal(sol.t, times)
    assert _over_tolerance(sol, harmonic.exact) <= 1.05
    # q = sin t rises through zero at 2 pi k
    np.testing.assert_allclose(sol.t_events[0], 2 * np.pi * np.arange(1, 4), atol=ATOL)
    assert sol.options["t_eval"] == times.tolist()
    # the continuous solution covers the whole run, between the output times too
    between = np.linspace(0.1, 19.9, 37)
    assert np.max(np.abs(sol.sol(between).T - harmonic.exact(between))) <= 1.05 * ATOL
    assert sol.gamma.shape == sol.z.shape == sol.y.shape
    np.testing.assert_array_equal(sol.global_error, sol.y - sol.z)
    np.testing.assert_allclose(sol.energy, 0.5, atol=10 * ATOL)


def test_output_values_agree_with_the_kernels_t_eval(harmonic):
    times = np.linspace(0.0, 20.0, 41)
    kernel = hamrkq.solve(harmonic, t_span=(0.0, 20.0), t_eval=times, atol=ATOL)
    sampled = hamrkq.solve(harmonic, t_span=(0.0, 20.0), t_eval=times, atol=ATOL,
                           dense_output=True)  # fmt: skip
    np.testing.assert_array_equal(sampled.t, kernel.t)
    # two runs within the tolerance of one exact solution, over other steps
    assert np.max(np.abs(sampled.y - kernel.y)) <= 2.1 * ATOL
    # the values at the output times are evaluations too
    plain = hamrkq.solve(harmonic, t_span=(0.0, 20.0), atol=ATOL, dense_output=True)
    assert sampled.stats["nfev"] > plain.stats["nfev"]


def test_a_terminal_event_ends_the_output_times_as_scipy_does(harmonic):
    times = np.linspace(0.0, 20.0, 41)
    sol = hamrkq.solve(
        harmonic, t_span=(0.0, 20.0), t_eval=times, atol=ATOL,
        events={"expression": "q", "direction": 1, "terminal": 2},
    )  # fmt: skip
    assert sol.status is Status.TERMINAL_EVENT
    np.testing.assert_allclose(sol.t_events[0], [2 * np.pi, 4 * np.pi], atol=ATOL)
    np.testing.assert_array_equal(sol.t, times[times <= 4 * np.pi])
    assert sol.sol is None
    assert _over_tolerance(sol, harmonic.exact) <= 1.05


def test_backward_run_with_a_terminal_event(harmonic):
    times = np.linspace(20.0, 0.0, 41)
    sol = hamrkq.solve(
        harmonic, t_span=(20.0, 0.0), t_eval=times, atol=ATOL,
        events={"expression": "q", "direction": 1, "terminal": True},
    )  # fmt: skip
    # from q = 0, p = 1 at t = 20, q = sin(t - 20): going back, it rises through
    # zero at 20 - pi
    assert sol.status is Status.TERMINAL_EVENT
    np.testing.assert_allclose(sol.t_events[0], [20.0 - np.pi], atol=ATOL)
    np.testing.assert_array_equal(sol.t, times[times >= 20.0 - np.pi])
    exact = np.column_stack([np.sin(sol.t - 20.0), np.cos(sol.t - 20.0)])
    assert np.max(np.abs(sol.y - exact)) <= 1.05 * ATOL


@pytest.fixture(scope="module")
def kepler():
    return load_problem("kepler")


def _pericentre_times(kepler) -> np.ndarray:
    start, end = kepler.t_span
    pericentres = 2 * np.pi * np.arange(1, 11)
    return np.unique(np.concatenate([pericentres, np.linspace(start, end, 201)]))


def test_an_output_time_that_cannot_be_certified_ends_the_run_as_the_kernels_does(kepler):
    # Kepler under rtol: at a pericentre p1 = 0 and its tolerance is atol alone
    # (docs/events.md); rk67q10's quencher cannot certify it at 4 pi.
    times = _pericentre_times(kepler)
    options = {"method": "rk67q10", "atol": 1e-9, "rtol": 1e-6, "t_eval": times}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kernel = hamrkq.solve(kepler, **options)
        sampled = hamrkq.solve(kepler, **options, events={"expression": "p1"})
    assert kernel.status is sampled.status is Status.TOLERANCE_UNATTAINABLE
    assert "At t = 12.566370614359172" in kernel.message
    assert "At t = 12.566370614359172" in sampled.message
    np.testing.assert_array_equal(sampled.t, kernel.t)
    assert _over_tolerance(sampled, kepler.exact) <= 1.05


def test_auto_runs_again_where_an_output_time_fails(kepler):
    times = _pericentre_times(kepler)
    sol = hamrkq.solve(kepler, atol=1e-9, rtol=1e-6, t_eval=times, dense_output=True)
    assert sol.status is Status.SUCCESS
    assert sol.stats["discarded_evaluations"] > 0
    np.testing.assert_array_equal(sol.t, times)
    assert _over_tolerance(sol, kepler.exact) <= 1.05


def test_a_problem_files_events_are_still_left_out_with_t_eval(kepler, tmp_path):
    # A file's events are a default: with t_eval they would keep every node.
    text = (
        'name = "osc"\ncoordinates = ["x"]\nmomenta = ["v"]\n'
        'hamiltonian = "v**2/2 + x**2/2"\n\n[initial]\nx = 0\nv = 1\n\n'
        '[[events]]\nexpression = "x"\n\n[integration]\nt_span = [0, 10]\n'
    )
    path = tmp_path / "osc.toml"
    path.write_text(text)
    problem = hamrkq.load_problem(path)
    with pytest.warns(hamrkq.errors.HamrkqWarning, match="not located"):
        sol = hamrkq.solve(problem, t_eval=[0.0, 5.0, 10.0])
    assert sol.t_events is None
    np.testing.assert_array_equal(sol.t, [0.0, 5.0, 10.0])


def test_an_interrupted_run_returns_the_output_times_it_can_certify(kepler):
    """An interrupted run is neither cut nor run again: its output times
    are kept up to the first whose value fails the check (4 pi, above)."""
    calls = [0]

    def raising(t, y):
        calls[0] += 1
        if calls[0] == 1:  # at the nodes, once the run has finished
            raise KeyboardInterrupt
        return y[3]

    times = _pericentre_times(kepler)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = hamrkq.solve(kepler, method="rk67q10", atol=1e-9, rtol=1e-6, t_eval=times,
                           events=raising)  # fmt: skip
    assert sol.status is Status.INTERRUPTED
    np.testing.assert_array_equal(sol.t, times[times < 4 * np.pi])
    assert _over_tolerance(sol, kepler.exact) <= 1.05
