"""hamrkq.RK34Q8 as a SciPy OdeSolver: solve_ivp round trips, dense output, events,
the global error on the solver, and identity with hamrkq.solve's RKQ."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import hamrkq
from hamrkq import RK34Q8
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import HamrkqWarning, InputError, OptionError


def harmonic(t, y):
    return np.array([y[1], -y[0]])


def harmonic_jac(t, y):
    return np.array([[0.0, 1.0], [-1.0, 0.0]])


def harmonic_exact(t):
    return np.array([np.sin(t), np.cos(t)])


@pytest.fixture(scope="module")
def kepler():
    problem = hamrkq.load_problem("kepler")
    num, params = numeric_of(problem.hamiltonian), problem.parameter_array
    return (
        problem,
        lambda t, y: num.rhs(t, y, params),
        lambda t, y: num.jac(t, y, params),
    )


@pytest.mark.parametrize("atol", [1e-6, 1e-8, 1e-10])
def test_round_trip_nodes_and_dense_output_within_tolerance(atol):
    sol = solve_ivp(harmonic, (0.0, 30.0), [0.0, 1.0], method=RK34Q8, atol=atol,
                    dense_output=True)  # fmt: skip
    assert sol.success and sol.status == 0
    assert sol.t[0] == 0.0 and sol.t[-1] == 30.0
    # Every node is within atol of the RK8 track, whose own error is ~1e-14 here.
    node_error = np.abs(sol.y - harmonic_exact(sol.t)).max()
    assert node_error <= 1.01 * atol
    # Between nodes the nodes' bound holds (measured 0.9994-0.9997 x atol;
    # the cubic Hermite interpolant it replaced, 1.001-1.003).
    tt = np.linspace(0.0, 30.0, 30001)
    dense_error = np.abs(sol.sol(tt) - harmonic_exact(tt)).max()
    assert dense_error <= 1.0 * atol
    assert dense_error >= 0.5 * atol  # the tolerance is used, not wasted


def test_events_located_on_the_dense_output():
    def crossing(t, y):  # q = 1/2 on the way up: t = pi/6 + 2 pi k
        return y[0] - 0.5

    crossing.direction = 1.0

    def stop(t, y):  # p = -1/2 for the third time
        return y[1] + 0.5

    stop.terminal = 3
    sol = solve_ivp(harmonic, (0.0, 50.0), [0.0, 1.0], method=RK34Q8, atol=1e-9,
                    events=[crossing, stop])  # fmt: skip
    assert sol.status == 1  # a terminal event
    # p = cos t = -1/2 at 2pi/3, 4pi/3, 8pi/3: the run stops at 8pi/3, after two
    # upward crossings of q = 1/2 (pi/6 and pi/6 + 2pi).
    stops = np.array([2 * np.pi / 3, 4 * np.pi / 3, 8 * np.pi / 3])
    expected = np.pi / 6 + 2 * np.pi * np.arange(2)
    assert sol.t_events[0] == pytest.approx(expected, abs=5e-9)
    assert sol.t_events[1] == pytest.approx(stops, abs=5e-9)
    assert sol.t[-1] == pytest.approx(stops[-1], abs=5e-9)
    assert sol.y_events[0][:, 0] == pytest.approx(0.5, abs=2e-9)


def test_t_eval_and_args_pass_through():
    def oscillator(t, y, omega):
        return np.array([y[1], -(omega**2) * y[0]])

    t_eval = np.linspace(0.0, 10.0, 11)
    sol = solve_ivp(oscillator, (0.0, 10.0), [0.0, 2.0], method=RK34Q8, args=(2.0,),
                    t_eval=t_eval, atol=1e-9)  # fmt: skip
    assert np.array_equal(sol.t, t_eval)
    assert sol.y[0] == pytest.approx(np.sin(2 * t_eval), abs=1.1e-9)


def test_backward_integration():
    sol = solve_ivp(harmonic, (0.0, -30.0), [0.0, 1.0], method=RK34Q8, atol=1e-8)
    assert sol.success and sol.t[-1] == -30.0
    assert np.all(np.diff(sol.t) < 0)
    assert np.abs(sol.y - harmonic_exact(sol.t)).max() <= 1.01e-8


def test_max_step_and_first_step_are_honoured():
    sol = solve_ivp(harmonic, (0.0, 10.0), [0.0, 1.0], method=RK34Q8, max_step=0.05,
                    first_step=1e-3)  # fmt: skip
    steps = np.diff(sol.t)
    assert steps[0] == pytest.approx(1e-3)
    assert steps.max() <= 0.05 * (1 + 1e-12)


def test_same_nodes_as_hamrkq_solve(kepler):
    """The SciPy form runs the same loop (rkq.advance): identical nodes, bit for bit."""
    problem, fun, jac = kepler
    t_span = (0.0, 2 * np.pi)
    ref = hamrkq.solve(problem, t_span=t_span, atol=1e-8, rtol=0.0, method="rk34q8")
    track = []
    sol = solve_ivp(fun, t_span, problem.y0, method=RK34Q8, jac=jac, atol=1e-8,
                    on_step=lambda s: track.append((s.z, s.gamma, s.quenched)))  # fmt: skip
    assert np.array_equal(sol.t, ref.t)
    assert np.array_equal(sol.y.T, ref.y)
    assert np.array_equal(np.array([z for z, _, _ in track]), ref.z[1:])
    assert np.array_equal(np.array([g for _, g, _ in track]), ref.gamma[1:])
    assert [q for _, _, q in track] == list(ref.quenched[1:])
    assert sol.nfev == ref.nfev
    assert sol.njev == ref.stats["njev"]


def test_global_error_on_the_solver_bounds_and_matches_the_truth(kepler):
    problem, fun, jac = kepler
    solver = RK34Q8(fun, 0.0, problem.y0, 2 * np.pi, jac=jac, atol=1e-8)
    rows = []
    while solver.status == "running":
        solver.step()
        rows.append((solver.t, solver.y.copy(), solver.z, solver.global_error, solver.gamma))
    assert solver.status == "finished"
    t = np.array([r[0] for r in rows])
    y, z, G, gamma = (np.array([r[k] for r in rows]) for k in (1, 2, 3, 4))
    exact = problem.exact(t)
    assert np.array_equal(G, y - z)
    assert np.abs(G).max() <= 1e-8  # the paper's promise, at every node
    assert np.abs(G).max() > 0.5e-8
    # The RK8 track is far more accurate, and Gamma says so: true 6.8e-15, Gamma 9.9e-15.
    z_error = np.abs(z - exact).max()
    assert z_error < 1e-13
    assert np.abs(gamma).max() == pytest.approx(z_error, rel=1.0)
    # So G is the true error of y to ~1e-13.
    assert np.abs((y - exact) - G).max() < 1e-13
    stats = solver.stats
    assert stats["steps"] == len(rows) and stats["quenches"] >= 1
    assert stats["nfev"] == solver.nfev


def test_without_jac_gamma_is_off_but_the_quench_works():
    solver = RK34Q8(harmonic, 0.0, [0.0, 1.0], 20.0, atol=1e-7)
    while solver.status == "running":
        solver.step()
        assert np.abs(solver.global_error).max() <= 1e-7
    assert solver.gamma is None and solver.njev == 0


def test_constant_jacobian_matrix():
    solver = RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, jac=harmonic_jac(0, None))
    solver.step()
    assert solver.gamma is not None and solver.njev > 0


def van_der_pol(t, y, mu=5.0):
    return [y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]]


def test_dense_output_keeps_the_nodes_bound_where_cubic_hermite_did_not():
    """Between nodes, the values are the RK8 track's plus y - z interpolated:
    within the tolerance wherever the nodes are.  The cubic Hermite
    interpolant of the end values and slopes it replaced was 5.3 times the
    tolerance off on the van der Pol oscillator (mu = 5, atol 1e-6; 11 times
    at 1e-8), its nodes within it (benchmarks/scipy_dense.txt)."""
    t_span, y0, atol = (0.0, 20.0), [2.0, 0.0], 1e-6
    reference = solve_ivp(van_der_pol, t_span, y0, method="DOP853", rtol=1e-13, atol=1e-14,
                          dense_output=True)  # fmt: skip
    sol = solve_ivp(van_der_pol, t_span, y0, method=RK34Q8, atol=atol, dense_output=True,
                    global_error_estimate="off")  # fmt: skip
    assert sol.success
    assert np.abs(sol.y - reference.sol(sol.t)).max() <= atol
    tt = np.linspace(*t_span, 4001)
    assert np.abs(sol.sol(tt) - reference.sol(tt)).max() <= atol
    # At the nodes the dense output is the node.
    assert np.array_equal(sol.sol(sol.t[5]), sol.y[:, 5])


def test_dense_values_cost_one_rk8_step_each():
    solver = RK34Q8(harmonic, 0.0, np.array([0.0, 1.0]), 10.0, atol=1e-8,
                    global_error_estimate="off")  # fmt: skip
    solver.step()
    solver.step()
    interpolant = solver.dense_output()
    before = solver.nfev
    values = interpolant(np.linspace(solver.t_old, solver.t, 7)[1:-1])
    assert values.shape == (2, 5)
    assert solver.nfev - before == 5 * 12  # DOP853: 12 stages
    assert interpolant(solver.t_old) == pytest.approx(harmonic_exact(solver.t_old), abs=1e-8)


def test_failure_is_a_solver_status_with_a_message():
    # y' = y^2, y(0) = 1 blows up at t = 1.
    sol = solve_ivp(lambda t, y: y**2, (0.0, 2.0), [1.0], method=RK34Q8)
    assert sol.status == -1 and not sol.success
    assert "RK34Q8" in sol.message and "t = 0.99" in sol.message
    assert 0.99 < sol.t[-1] < 1.0


def test_non_finite_initial_derivative_fails_on_the_first_step():
    with np.errstate(divide="ignore"):
        sol = solve_ivp(lambda t, y: y / 0.0 if t == 0 else y, (0.0, 1.0), [1.0],
                        method=RK34Q8)  # fmt: skip
    assert sol.status == -1 and "non-finite" in sol.message


def test_non_finite_message_ends_with_one_full_stop():
    # QA: "... became non-finite (inf or nan). (t = 0.99...)"
    sol = solve_ivp(lambda t, y: [np.nan if t > 1 else 1.0], (0.0, 2.0), [0.0],
                    method=RK34Q8, global_error_estimate="off")  # fmt: skip
    assert sol.status == -1 and "non-finite" in sol.message
    assert ".." not in sol.message and ". (" not in sol.message and sol.message.endswith(").")


def test_dense_output_extrapolates_outside_the_interval_as_scipys_methods():
    # QA: sol(t) one ulp past the end raised, naming the last step as "the
    # integrated interval"; SciPy's methods extrapolate their end steps.
    sol = solve_ivp(harmonic, (0.0, 10.0), [0.0, 1.0], method=RK34Q8, jac=harmonic_jac,
                    atol=1e-8, dense_output=True)  # fmt: skip
    for t, bound in ((np.nextafter(10.0, 11.0), 1.01e-8), (10.5, 1e-7), (-0.5, 1e-7)):
        # the RK8 track stepped on from the end node: as accurate as a node
        assert np.abs(sol.sol(t) - harmonic_exact(t)).max() <= bound
    with pytest.raises(ValueError, match=r"outside|finite"):
        sol.sol(np.nan)


def plain_harmonic(t, y):  # module level: picklable, as solve_ivp's fun must be for pickle
    return np.array([y[1], -y[0]])


def plain_harmonic_columns(t, y):
    return np.vstack([y[1], -y[0]])


@pytest.mark.parametrize("fun, vectorized", [(plain_harmonic, False),
                                             (plain_harmonic_columns, True)])  # fmt: skip
def test_a_result_with_dense_output_pickles(fun, vectorized):
    # QA: "Can't pickle local object 'check_arguments.<locals>.fun_wrapped'"
    import pickle

    sol = solve_ivp(fun, (0.0, 10.0), [0.0, 1.0], method=RK34Q8, jac=harmonic_jac,
                    atol=1e-8, dense_output=True, vectorized=vectorized)  # fmt: skip
    copy = pickle.loads(pickle.dumps(sol))
    tt = np.linspace(0.0, 10.0, 101)
    np.testing.assert_array_equal(copy.sol(tt), sol.sol(tt))
    assert np.abs(copy.sol(tt) - harmonic_exact(tt)).max() <= 1.0e-8


def test_tolerances_and_max_step_are_attributes_as_scipys():
    solver = RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, atol=1e-8, rtol=1e-6, max_step=0.1,
                    jac=harmonic_jac)  # fmt: skip
    np.testing.assert_array_equal(solver.atol, [1e-8, 1e-8])
    np.testing.assert_array_equal(solver.rtol, [1e-6, 1e-6])
    assert solver.max_step == 0.1


def test_validation_names_the_parameter():
    with pytest.raises(InputError, match="atol"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, atol=-1.0)
    with pytest.raises(InputError, match="rtol must be a scalar or have 2 entries"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, rtol=[1e-6, 1e-6, 1e-6])
    with pytest.raises(InputError, match="needs jac"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, global_error_estimate="tangent")
    with pytest.raises(OptionError, match="quench"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, quench="sometimes")
    with pytest.raises(InputError, match="first_step"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, first_step=2.0)
    with pytest.raises(InputError, match="jac must have shape"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, jac=np.eye(3))
    with pytest.warns(HamrkqWarning, match="no effect"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, min_step=1e-3)
    with pytest.warns(HamrkqWarning, match="raised"):
        RK34Q8(harmonic, 0.0, [0.0, 1.0], 1.0, rtol=1e-17)


def test_relative_tolerance_and_paper_gamma():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = solve_ivp(harmonic, (0.0, 10.0), [0.0, 10.0], method=RK34Q8, jac=harmonic_jac,
                        atol=1e-12, rtol=1e-8, global_error_estimate="paper")  # fmt: skip
    exact = 10 * harmonic_exact(sol.t)
    delta = np.maximum(1e-12, 1e-8 * np.abs(sol.y))
    assert np.all(np.abs(sol.y - exact) <= 1.05 * delta + 1e-12)


def test_fun_and_jac_get_arrays_of_their_own():
    """A fun memoised on (t, y) that keeps y by reference (a SciPy idiom for
    sharing work with jac) must see the same y later: the solver's stages
    were one reused buffer, and stage 3 (same t as stage 2) got stage 2's
    cached f -- SUCCESS with an error of 16 without jac."""
    cache = {"t": None, "y": None, "f": None}
    kept = []

    def fun(t, y):
        kept.append((t, y))
        if cache["t"] == t and np.array_equal(cache["y"], y):
            return cache["f"]
        f = harmonic(t, y)
        cache.update(t=t, y=y, f=f)
        return f

    def jac(t, y):
        kept.append((t, y))
        return harmonic_jac(t, y)

    for use_jac in (True, False):
        cache.update(t=None, y=None, f=None)
        kept.clear()
        kwargs = {"jac": jac} if use_jac else {"global_error_estimate": "off"}
        sol = solve_ivp(fun, (0.0, 10.0), [0.0, 1.0], method=RK34Q8, atol=1e-8, **kwargs)
        assert sol.status == 0
        assert np.max(np.abs(sol.y - harmonic_exact(sol.t))) < 1.05e-8
        # every y handed out still holds the value it was called with
        values = np.array([y for _, y in kept])
        assert len({id(y) for _, y in kept}) == len(kept)
        assert np.all(np.isfinite(values))


def test_quench_redo_steps_on():
    """quench="redo" restarts a step from the quencher's value; the kernel
    reported that restart as the end of its call, which the OdeSolver,
    stepping once, read as the end of the run: KeyError: -1 (found by QA)."""
    sol = solve_ivp(harmonic, (0.0, 20.0), [0.0, 1.0], method=RK34Q8, atol=1e-6,
                    quench="redo", jac=harmonic_jac)  # fmt: skip
    assert sol.status == 0
    assert np.abs(sol.y - harmonic_exact(sol.t)).max() <= 1.05e-6
    alone = hamrkq.solve(hamrkq.load_problem("harmonic"), method="rk34q8", quench="redo",
                         t_span=(0.0, 20.0), atol=1e-6)  # fmt: skip
    assert alone.stats["quenches"] > 0
