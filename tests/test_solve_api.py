"""hamrkq.solve as a user meets it: time spans, defaults, options, output
selection, interruption and the Solution it returns, checked against exact
solutions where numbers are involved."""

import io
import re
import sys

import numpy as np
import pytest
import sympy as sp
from helpers import counters

from hamrkq.catalogue import exact
from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import HamrkqWarning
from hamrkq.result import Solution, Status
from hamrkq.solve import MIN_RTOL, solve
from hamrkq.symbolic.hamiltonian import Hamiltonian

q, p = sp.symbols("q p")
HARMONIC = Hamiltonian((p**2 + q**2) / 2, q=[q], p=[p])


def test_nonzero_t0():
    y0 = [0.3, -0.2]
    sol = solve(HARMONIC, [y0[0]], [y0[1]], (5.0, 17.5), atol=1e-7)
    assert sol.t[0] == 5.0 and sol.t[-1] == 17.5 and np.all(np.diff(sol.t) > 0)
    np.testing.assert_array_equal(sol.y[0], y0)
    assert np.abs(sol.y - exact.harmonic(sol.t, y0, t0=5.0)).max() <= 1.05e-7


def test_backward_integration_from_nonzero_t0():
    pr = load_problem("pendulum")
    y0 = pr.exact(np.array([3.0]))[0]
    sol = solve(pr, q0=y0[:1], p0=y0[1:], t_span=(3.0, -12.0), atol=1e-7)
    assert sol.success and sol.t[-1] == -12.0 and np.all(np.diff(sol.t) < 0)
    assert np.abs(sol.y - pr.exact(sol.t)).max() <= 1.05e-7
    assert np.abs(sol.global_error).max() <= 1e-7


def test_t0_equal_to_t_end_returns_the_initial_node():
    sol = solve(HARMONIC, [0.1], [0.2], (2.0, 2.0))
    assert sol.success and sol.t.tolist() == [2.0]
    np.testing.assert_array_equal(sol.y, [[0.1, 0.2]])
    assert sol.energy.tolist() == [0.025000000000000005] and sol.stats["steps"] == 0
    assert sol.quenched.tolist() == [False] and sol.gamma.tolist() == [[0.0, 0.0]]


def test_solution_fields_are_consistent():
    pr = load_problem("pendulum")
    sol = solve(pr, atol=1e-6, method="rk34q8")
    assert isinstance(sol, Solution) and sol.names == ("q", "p") and sol.n == 1
    np.testing.assert_array_equal(sol.global_error, sol.y - sol.z)
    assert np.all(sol.global_error[sol.quenched] == 0)
    np.testing.assert_allclose(sol.energy, 0.5 * sol.p[:, 0] ** 2 - np.cos(sol.q[:, 0]))
    assert sol.stats["quenches"] == sol.quenched.sum() > 0
    assert set(sol.stats) >= {"steps", "rejected", "quenches", "nfev", "njev"}
    assert sol.options["first_step_rule"] == "hairer-norsett-wanner"
    assert 0 < sol.options["first_step"] < 1
    # SciPy's result fields (QA: njev and nlu were missing)
    assert (sol.nfev, sol.njev, sol.nlu) == (sol.stats["nfev"], sol.stats["njev"], 0)
    assert sol.njev > 0  # rk34q8's tangent Gamma: one Jacobian product a stage


@pytest.mark.parametrize("method", ["auto", "scipy:DOP853"])
def test_events_given_as_an_empty_list_give_empty_lists(method):
    # As SciPy's solve_ivp: None without events=, [] with events=[] (QA: None,
    # and a loop over sol.t_events raised TypeError)
    pr = load_problem("harmonic")
    assert solve(pr, t_span=(0.0, 1.0), method=method).t_events is None
    sol = solve(pr, t_span=(0.0, 1.0), method=method, events=[])
    assert sol.t_events == [] and sol.y_events == []
    assert Solution.load(_saved(sol)).t_events == []


def _saved(sol):
    import tempfile
    from pathlib import Path

    path = Path(tempfile.mkdtemp()) / "run.npz"
    sol.save(path)
    return path


def test_dense_output_takes_a_time_an_ulp_past_either_end():
    # QA: np.arange(4) * 0.1 ends at 0.30000000000000004, which SciPy's
    # dense output evaluates and hamrkq's refused for a run to 0.3
    pr = load_problem("harmonic")  # q = sin t, p = cos t
    for span in ((0.0, 0.3), (0.3, 0.0)):
        sol = solve(pr, t_span=span, atol=1e-10, dense_output=True)
        t0 = span[0]
        times = np.array([np.nextafter(0.3, 1.0), np.nextafter(0.0, -1.0), 0.15])
        exact_q = np.sin(times - t0)
        assert np.abs(sol.sol(times)[0] - exact_q).max() <= 1.05e-10
        with pytest.raises(ValueError, match="outside the integrated interval"):
            sol.sol(0.3 + 1e-9)


def test_problem_defaults_and_keyword_overrides():
    pr = load_problem("kepler")
    assert solve(pr, t_span=(0, 1)).atol.tolist() == [1e-8] * 4  # from the file
    sol = solve(pr, t_span=(0, 1), atol=1e-5, rtol=1e-6)
    assert sol.atol.tolist() == [1e-5] * 4 and sol.rtol.tolist() == [1e-6] * 4


def test_parameters_move_the_initial_values_of_a_problem():
    sol = solve(load_problem("kepler"), parameters={"e": 0.9}, t_span=(0, 2 * np.pi), atol=1e-7)
    np.testing.assert_allclose(sol.y[0], [0.1, 0.0, 0.0, np.sqrt(19.0)], rtol=1e-15)
    assert sol.options["parameters"] == {"e": 0.9}
    # One full period later the orbit closes.
    assert np.abs(sol.y[-1] - sol.y[0]).max() < 2e-7


def test_parameters_of_a_hamiltonian_bind_by_symbol_and_by_name():
    k = sp.Symbol("k")
    ham = Hamiltonian(p**2 / 2 + k * q**2 / 2, q=[q], p=[p], parameters={k: 1.0})
    for params in ({k: 4.0}, {"k": 4.0}):
        sol = solve(ham, [0], [1], (0, 10), atol=1e-8, parameters=params)
        # omega = 2: q = sin(2t)/2, p = cos(2t).
        reference = np.column_stack([np.sin(2 * sol.t) / 2, np.cos(2 * sol.t)])
        assert np.abs(sol.y - reference).max() <= 1.05e-8


def test_sympy_initial_values():
    pr = load_problem("prentice2011")
    sol = solve(pr.hamiltonian, [sp.acos(sp.Rational(-4, 5))], [sp.Integer(0)], (0, 1))
    np.testing.assert_array_equal(sol.y[0], pr.y0)


def test_prentice_tolerance_rule_uses_the_smallest_component_tolerance():
    pr = load_problem("kepler")
    sol = solve(pr, atol=1e-9, rtol=1e-7, tolerance_rule="prentice", t_span=(0, 4 * np.pi))
    delta = np.maximum(1e-9, 1e-7 * np.abs(sol.y)).min(axis=1, keepdims=True)
    assert np.all(np.abs(sol.global_error) <= delta)
    assert np.all(np.abs(sol.y - pr.exact(sol.t)) <= 1.05 * delta)
    looser = solve(pr, atol=1e-9, rtol=1e-7, t_span=(0, 4 * np.pi))
    assert sol.stats["steps"] > looser.stats["steps"]


def test_redo_quench():
    pr = load_problem("pendulum")
    sol = solve(pr, atol=1e-6, quench="redo", method="rk34q8")
    assert sol.options["quench"] == "redo" and sol.stats["quenches"] > 0
    assert np.abs(sol.y - pr.exact(sol.t)).max() <= 1.05e-6


def test_keep_every_and_t_eval_select_nodes():
    pr = load_problem("pendulum")
    full = solve(pr, atol=1e-6)
    thin = solve(pr, atol=1e-6, keep_every=50)
    assert thin.t.size == 1 + (full.t.size - 2) // 50 + 1
    np.testing.assert_array_equal(thin.t[:-1], full.t[::50][: thin.t.size - 1])
    assert thin.t[-1] == full.t[-1] and counters(thin.stats) == counters(full.stats)
    times = np.linspace(0, pr.t_span[1], 7)
    picked = solve(pr, atol=1e-6, t_eval=times)
    np.testing.assert_array_equal(picked.t, times)
    assert np.abs(picked.y - pr.exact(times)).max() <= 1.05e-6
    assert picked.options["t_eval"] == times.tolist()


def test_keyboard_interrupt_keeps_the_nodes_so_far():
    pr = load_problem("pendulum")
    calls = []

    def progress(fraction, t):
        calls.append((fraction, t))
        raise KeyboardInterrupt

    sol = solve(pr, atol=1e-8, progress=progress, method="rk34q8")
    assert sol.status is Status.INTERRUPTED and not sol.success and sol.partial
    assert len(calls) == 1 and 0 < calls[0][0] < 1
    assert "Interrupted" in sol.message and sol.t.size > 100
    assert sol.t[-1] == pytest.approx(calls[0][1])
    assert np.abs(sol.y - pr.exact(sol.t)).max() <= 1.05e-8


def test_progress_reports_increasing_fractions():
    seen = []
    solve(
        load_problem("pendulum"), atol=1e-8, progress=lambda f, t: seen.append(f), method="rk34q8"
    )
    assert len(seen) >= 1 and all(0 < f < 1 for f in seen) and seen == sorted(seen)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_true_draws_a_bar_on_a_terminal_stderr_only(monkeypatch):
    problem = load_problem("pendulum")
    quiet = io.StringIO()
    monkeypatch.setattr(sys, "stderr", quiet)
    solve(problem, atol=1e-8, progress=True, method="rk34q8")
    assert quiet.getvalue() == ""  # not a terminal: nothing drawn
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    sol = solve(problem, atol=1e-8, progress=True, method="rk34q8")
    shown = re.findall(r"rk34q8: \[[#.]+\]\s+([0-9.]+)%, t=([0-9.eE+-]+)", terminal.getvalue())
    assert shown, terminal.getvalue()
    fractions = [float(f) for f, _ in shown]
    assert all(0 <= f < 100 for f in fractions) and fractions == sorted(fractions)
    assert 0 < float(shown[-1][1]) < sol.t[-1]  # the time reached, as the bar last showed it
    assert terminal.getvalue().endswith("\n")  # the finished bar keeps its own line


def test_the_default_method_is_auto_and_a_problem_file_may_name_the_papers():
    # auto needs 2 to 8 times fewer evaluations and as much less time on every
    # catalogue problem (benchmarks/default_method.md); prentice2011's file
    # names the paper's rk34q8
    default = solve(HARMONIC, [0], [1], (0, 10), atol=1e-8)
    auto = solve(HARMONIC, [0], [1], (0, 10), atol=1e-8, method="auto")
    np.testing.assert_array_equal(default.y, auto.y)
    assert default.options == auto.options and default.method == "rk78q12"
    assert solve(load_problem("prentice2011"), t_span=(0, 1)).method == "rk34q8"
    assert solve(load_problem("kepler"), t_span=(0, 1)).method == "rk78q12"


def test_max_steps_status_and_message():
    sol = solve(load_problem("pendulum"), atol=1e-8, max_steps=100, method="rk34q8")
    assert sol.status is Status.MAX_STEPS and sol.t.size == 101
    assert "max_steps = 100" in sol.message and f"t = {float(sol.t[-1])!r}" in sol.message


def test_unattainable_tolerance_status_and_message():
    sol = solve(HARMONIC, [0], [1], (0, 1), atol=1e-17)
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    assert "can no longer be certified" in sol.message and sol.t.size == 1


def test_rtol_below_100_eps_is_raised_with_a_warning():
    with pytest.warns(HamrkqWarning, match="rtol"):
        sol = solve(HARMONIC, [0], [1], (0, 1), atol=1e-8, rtol=1e-17)
    assert sol.rtol.tolist() == [MIN_RTOL, MIN_RTOL]


def test_rk34_solution_round_trips(tmp_path):
    sol = solve(load_problem("pendulum"), method="rk34", atol=1e-6)
    assert sol.z is None and sol.gamma is None and sol.quenched is None
    assert "quench" not in sol.options
    back = Solution.load(sol.save(tmp_path / "rk34"))
    np.testing.assert_array_equal(back.y, sol.y)
    np.testing.assert_array_equal(back.t, sol.t)
    assert back.z is None and back.options == sol.options
