"""Diagnostics on data with known answers (hamrkq.analysis.diagnostics)."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import hamrkq
from hamrkq.analysis.diagnostics import (
    bound_ratio,
    diagnose,
    drift_summary,
    energy_bound,
    tolerance,
    trajectory_bound,
    trajectory_error,
)
from hamrkq.analysis.reference import integrate_reference
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, OptionError
from hamrkq.result import Solution, Status


def make_solution(t, y, energy, *, z=None, gamma=None, atol=1e-6, rtol=0.0, n=1, **extra):
    names = tuple([f"q{i + 1}" for i in range(n)] + [f"p{i + 1}" for i in range(n)])
    if n == 1:
        names = ("q", "p")
    return Solution(
        t=t, y=y, energy=energy, z=z, gamma=gamma,
        global_error=None if z is None else np.asarray(y) - np.asarray(z),
        status=extra.pop("status", Status.SUCCESS), message=extra.pop("message", "ok"),
        method=extra.pop("method", "rk34q8"), n=n, names=names, atol=atol, rtol=rtol,
        stats=extra.pop("stats", {"steps": len(t) - 1, "rejected": 0, "quenches": 0, "nfev": 1}),
        **extra,
    )  # fmt: skip


def harmonic_energy(y):
    return 0.5 * (y[:, 0] ** 2 + y[:, 1] ** 2)


def harmonic_exact(t):
    return np.column_stack([np.sin(t), np.cos(t)])


# -- array functions with answers worked out by hand --------------------------
def test_linear_drift_is_recovered_exactly():
    t = np.linspace(0.0, 50.0, 501)
    summary = drift_summary("H", t, 0.8 + 3e-7 * t)
    assert summary.drift == pytest.approx(3e-7, rel=1e-9)
    assert summary.drift_stderr < 1e-15
    assert summary.max_abs == pytest.approx(1.5e-5, rel=1e-9)
    assert summary.final == pytest.approx(1.5e-5, rel=1e-9)
    assert summary.t_max == 50.0
    assert summary.initial == 0.8
    assert summary.relative_max == pytest.approx(1.5e-5 / 0.8)


def test_drift_standard_error_matches_theory_for_white_noise():
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 100.0, 20001)
    sigma, slope = 1e-9, 2e-11
    values = 1.0 + slope * t + sigma * rng.standard_normal(t.size)
    summary = drift_summary("H", t, values)
    theory = sigma / np.sqrt(np.sum((t - t.mean()) ** 2))  # OLS slope standard error
    assert summary.drift_stderr == pytest.approx(theory, rel=0.05)
    assert abs(summary.drift - slope) < 4 * theory


def test_pure_oscillation_has_the_small_slope_least_squares_predicts():
    # a sin(t) over N whole periods (length L = 2 pi N): the least-squares slope
    # is int (t - L/2) a sin t dt / (L^3/12) = -12 a / L^2, not zero
    t = np.linspace(0.0, 20 * np.pi, 40001)
    summary = drift_summary("H", t, 0.5 + 1e-8 * np.sin(t))
    assert summary.drift == pytest.approx(-12e-8 / (20 * np.pi) ** 2, rel=1e-3)
    assert summary.max_abs == pytest.approx(1e-8, rel=1e-6)
    assert abs(summary.final) < 1e-20


def test_tolerance_rules_by_hand():
    y = np.array([[3.0, -4.0], [0.0, 1e-9]])
    componentwise = tolerance(y, 1e-6, 1e-6)
    assert componentwise.tolist() == [[3e-6, 4e-6], [1e-6, 1e-6]]
    assert trajectory_bound(componentwise)[0] == pytest.approx(5e-6)
    prentice = tolerance(y, 1e-6, 1e-6, rule="prentice")  # the paper's min over components
    assert prentice.tolist() == [[3e-6, 3e-6], [1e-6, 1e-6]]
    assert trajectory_bound(prentice) == pytest.approx([3e-6 * np.sqrt(2), 1e-6 * np.sqrt(2)])
    # absolute tolerance in 2-D: the paper's sqrt(2) delta
    assert trajectory_bound(tolerance(y, 1e-6, 0.0)) == pytest.approx([np.sqrt(2) * 1e-6] * 2)


def test_energy_bound_and_ratio_by_hand():
    # harmonic oscillator, gradient of H = (q, p); nodes on the unit circle
    y = np.array([[0.0, 1.0], [0.6, 0.8], [1.0, 0.0]])
    delta = tolerance(y, 1e-6, 0.0)
    bound = energy_bound(y, delta)  # (|q| + |p|) delta
    assert bound == pytest.approx([1e-6, 1.4e-6, 1e-6])
    observed = np.array([0.0, 0.7e-6, -0.25e-6])
    ratio, where = bound_ratio(observed, bound, np.array([0.0, 1.0, 2.0]))
    assert ratio == pytest.approx(0.5) and where == 1.0
    assert bound_ratio(np.array([0.0, 1e-9]), np.array([0.0, 0.0]), np.arange(2.0))[0] == np.inf
    # no bound at all (a fixed-step run has no tolerance): no ratio (QA: inf)
    nan = np.full(2, np.nan)
    assert np.isnan(bound_ratio(np.array([0.0, 1e-9]), nan, np.arange(2.0))[0])


def test_a_fixed_step_run_s_table_states_no_tolerance_and_no_bound():
    # QA: "tolerance delta nan .. nan" and "trajectory / bound max inf"
    problem = hamrkq.load_problem("harmonic")
    d = diagnose(hamrkq.solve(problem, method="gauss6", step=0.05), problem)
    table = d.table()
    assert "none (a fixed-step run has no tolerance)" in table
    assert "nan" not in table and "inf" not in table and "/ bound" not in table
    assert d.to_dict()["global_error"]["bound_ratio"] is None


def test_energy_error_of_a_t_eval_run_is_measured_from_the_initial_state():
    # QA: with t_eval from t = 50 on, the first returned node was the
    # baseline: the pendulum's energy error read 18 % low and its end value
    # had the wrong sign.  H(y0) is the baseline, as for a run with every node.
    problem = hamrkq.load_problem("pendulum")
    times = np.linspace(50.0, 100.0, 11)
    full = hamrkq.solve(problem, t_span=(0.0, 100.0), atol=1e-6)
    sampled = hamrkq.solve(problem, t_span=(0.0, 100.0), atol=1e-6, t_eval=times)
    q0, p0 = problem.y0
    h0 = 0.5 * p0**2 - np.cos(q0)
    energy = 0.5 * sampled.p[:, 0] ** 2 - np.cos(sampled.q[:, 0])
    d = diagnose(sampled, problem, reference="exact")
    assert d.energy.final == pytest.approx(energy[-1] - h0, rel=1e-9)
    assert d.energy.max_abs == pytest.approx(np.max(np.abs(energy - h0)), rel=1e-9)
    np.testing.assert_allclose(d.series["energy_error"], energy - h0, rtol=1e-9, atol=1e-18)
    # every node: unchanged, the first node is y0
    d_full = diagnose(full, problem, reference="exact")
    assert d_full.energy.final == pytest.approx(full.energy[-1] - full.energy[0], rel=1e-12)
    # without the system, H(y0) is unknown: the first node, with a note
    alone = diagnose(sampled, reference="none")
    assert alone.energy.final == pytest.approx(energy[-1] - energy[0], rel=1e-9)
    assert any("first returned node" in note for note in alone.notes)
    assert "measured at the 11 nodes returned (t_eval)" in " ".join(d.notes)
    assert not any("nodes returned" in note for note in d_full.notes)


def test_trajectory_error_is_euclidean():
    error = np.array([[3e-7, 4e-7], [0.0, 0.0], [-1e-6, 0.0]])
    assert trajectory_error(error) == pytest.approx([5e-7, 0.0, 1e-6])


# -- diagnose on synthetic solutions ------------------------------------------
def synthetic_run(nodes=2001):
    """Exact harmonic states plus a known error; an 'RK8 track' 1e-10 off."""
    t = np.linspace(0.0, 10.0, nodes)
    exact = harmonic_exact(t)
    error = np.column_stack([4e-7 * np.sin(3 * t), -3e-7 * np.sin(2 * t)])  # zero at t = 0
    y = exact + error
    z = exact + 1e-10
    gamma = np.full_like(y, 1e-10)
    return make_solution(t, y, harmonic_energy(y), z=z, gamma=gamma), exact, error


def test_diagnose_against_exact_known_error():
    sol, _, error = synthetic_run()
    diag = diagnose(sol, reference="exact", exact=harmonic_exact, gradient=lambda t, Y: Y.copy())
    assert diag.error.source == "exact"
    assert diag.error.max_abs == pytest.approx((4e-7, 3e-7), rel=1e-4)
    assert diag.error.max_trajectory == pytest.approx(np.max(np.hypot(error[:, 0], error[:, 1])))
    assert diag.error.bound_ratio == pytest.approx(diag.error.max_trajectory / (np.sqrt(2) * 1e-6))
    np.testing.assert_allclose(diag.series["error"], error, atol=1e-16)
    # the energy error is H(y) - H(y0) and stays within its first-order bound
    expected = harmonic_energy(sol.y) - harmonic_energy(sol.y)[0]
    np.testing.assert_allclose(diag.series["energy_error"], expected, rtol=0, atol=1e-18)
    assert 0.1 < diag.energy_bound_ratio < 1.0
    # the run's own estimate (y - z) is reported separately, with Gamma's accuracy
    assert diag.estimated.source == "rk8"
    assert diag.estimated.reference_accuracy == pytest.approx(1e-10)
    assert diag.estimated.max_abs[0] == pytest.approx(4e-7 - 1e-10, rel=1e-3)


def test_repr_is_one_line_of_the_maxima_and_str_is_the_report():
    sol, _, _ = synthetic_run(2001)
    diag = diagnose(sol, reference="exact", exact=harmonic_exact, gradient=lambda t, Y: Y.copy())
    text = repr(diag)
    # before: the generated repr printed every per-node array of ``series``
    assert "\n" not in text and len(text) < 300
    assert f"true_error_max={max(diag.error.max_abs):.3e}" in text
    assert f"estimated_max={max(diag.estimated.max_abs):.3e}" in text
    assert f"energy_max_abs={diag.energy.max_abs:.3e}" in text
    assert str(diag) == diag.table()


def test_diagnose_rk8_and_none_and_auto():
    sol, _, _ = synthetic_run(201)
    rk8 = diagnose(sol, reference="rk8")
    assert rk8.error is rk8.estimated
    np.testing.assert_array_equal(rk8.series["reference"], sol.z)
    assert rk8.gamma_max == pytest.approx(1e-10)
    none = diagnose(sol, reference="none")
    assert none.error is None and "error" not in none.series
    assert diagnose(sol).error.source == "rk8"  # auto: no exact solution given
    assert diagnose(sol, exact=harmonic_exact).error.source == "exact"
    assert np.isnan(none.energy_bound_ratio)  # no gradient, no energy bound


def test_independent_reference_object_is_accepted():
    sol, _, error = synthetic_run(401)
    ref = integrate_reference(
        lambda t, y, params: np.array([y[1], -y[0]]), sol.y[0] - error[0], sol.t
    )
    diag = diagnose(sol, reference=ref)
    assert diag.error.source == "independent"
    assert diag.error.reference_accuracy == ref.estimated_error < 1e-11
    assert diag.error.max_abs == pytest.approx((4e-7, 3e-7), rel=1e-4)


def test_invariants_are_tracked_like_the_energy():
    t = np.linspace(0.0, 10.0, 101)
    grow = 1 + 1e-9 * t  # momenta scaled up: L = q1 p2 - q2 p1 = 1 + 1e-9 t exactly
    y = np.column_stack([np.cos(t), np.sin(t), -np.sin(t) * grow, np.cos(t) * grow])
    sol = make_solution(t, y, np.zeros_like(t), n=2)
    momentum = {"angular_momentum": lambda t, Y: Y[:, 0] * Y[:, 3] - Y[:, 1] * Y[:, 2]}
    diag = diagnose(sol, invariants=momentum)
    (summary,) = diag.invariants
    assert summary.initial == pytest.approx(1.0)
    assert summary.drift == pytest.approx(1e-9, rel=1e-6)
    assert summary.max_abs == pytest.approx(1e-8, rel=1e-6)
    assert summary.t_max == 10.0


def test_bad_reference_requests():
    sol, _, _ = synthetic_run(11)
    with pytest.raises(OptionError, match="reference must be one of"):
        diagnose(sol, reference="best")
    with pytest.raises(InputError, match="exact solution"):
        diagnose(sol, reference="exact")
    with pytest.raises(InputError, match="starts at"):
        diagnose(sol, reference="exact", exact=lambda t: harmonic_exact(t + 1.0))
    with pytest.raises(InputError, match="needs a problem"):
        diagnose(sol, reference="independent")
    no_track = make_solution(sol.t, sol.y, sol.energy, method="rk34")
    with pytest.raises(InputError, match="needs a quencher track"):
        diagnose(no_track, reference="rk8")
    # A problem without an exact solution is named as such; the message said
    # "needs an exact solution (exact= or a problem)" though a problem was given (QA).
    pendulum = hamrkq.load_problem("prentice2011")
    short = hamrkq.solve(pendulum, t_span=(0.0, 0.5), method="rk34q8")
    with pytest.raises(InputError, match="problem 'prentice2011' has no exact solution; use"):
        diagnose(short, pendulum, reference="exact")
    other = integrate_reference(lambda t, y, p: np.array([y[1], -y[0]]), sol.y[0], sol.t[:5])
    with pytest.raises(InputError, match="node times"):
        diagnose(sol, reference=other)


def test_roundoff_gamma_and_partial_run_are_noted():
    sol, _, _ = synthetic_run(51)
    tiny = sol.replace(gamma=np.full_like(sol.y, 1e-17), status=Status.MAX_STEPS, message="stop")
    diag = diagnose(tiny, reference="rk8")
    assert any("roundoff" in note for note in diag.notes)
    assert any("partial run" in note for note in diag.notes)
    assert diag.status == "MAX_STEPS"


def test_the_quencher_track_is_named_by_its_order_and_the_estimate_by_its_name():
    # rk78q12's "RK8 track" is Feagin 12's, its Gamma the shadow's: the
    # report names both as they are (it said "RK8" and "Richardson" before).
    sol, _, _ = synthetic_run(51)
    tiny = sol.replace(gamma=np.full_like(sol.y, 1e-17))
    diag = diagnose(tiny, reference="rk8")
    assert "RK8 track" in diag.error.description
    assert any("the tangent estimate measures rounding" in n for n in diag.notes)
    member = tiny.replace(method="rk78q12", options={"global_error_estimate": "shadow"})
    diag = diagnose(member, reference="rk8")
    assert diag.error.description == "the run's own RK12 track (the paper's yardstick)"
    assert any("RK12 track: the shadow estimate measures rounding" in n for n in diag.notes)
    assert "RK12 track |Gamma|" in diag.table()
    # a quencher in double-double rounds some 1e-30 of its size: no such note
    extended = member.replace(
        options={"global_error_estimate": "shadow", "quencher_precision": "double-double"}
    )
    assert not any("roundoff" in n for n in diagnose(extended, reference="rk8").notes)


def test_to_dict_is_strict_json_and_table_reads_well():
    sol, _, _ = synthetic_run(101)
    diag = diagnose(sol, exact=harmonic_exact, gradient=lambda t, Y: Y.copy())
    data = diag.to_dict()
    text = json.dumps(data, allow_nan=False)  # nan/inf became None
    assert json.loads(text) == data
    assert data["global_error"]["max_abs"]["q"] == pytest.approx(4e-7, rel=1e-4)
    assert data["energy"]["max_abs"] == diag.energy.max_abs
    assert data["rk8_estimated_global_error_max"] == pytest.approx(1e-10)
    table = diag.table()
    for label in (
        "energy error",
        "energy / bound",
        "true error",
        "error / tolerance (worst component)",
        "trajectory / paper's bound",
    ):
        assert label in table
    assert diag.series["t"].flags.writeable is False


# -- with the symbolic layer ---------------------------------------------------
def test_catalogue_problem_exact_and_independent_references_agree():
    from hamrkq import load_problem

    problem = load_problem("harmonic")
    ham, params = problem.hamiltonian, problem.parameter_array
    t = np.linspace(0.0, 20.0, 401)
    run = solve_ivp(
        lambda t, y: numeric_of(ham).rhs(t, y, params), (0, 20), problem.y0, method="RK45",
        rtol=1e-8, atol=1e-8, t_eval=t,
    )  # fmt: skip
    y = run.y.T
    sol = make_solution(t, y, numeric_of(ham).energy(t, y, params), atol=1e-8)
    by_exact = diagnose(sol, problem, reference="exact")
    by_reference = diagnose(sol, problem, reference="independent")
    assert by_reference.error.reference_accuracy < 1e-11
    assert "period" in by_reference.error.description
    np.testing.assert_allclose(by_reference.series["error"], by_exact.series["error"], atol=1e-11)
    # gradient from the problem: H = (p^2 + q^2)/2 so the bound is (|q| + |p|) delta
    np.testing.assert_allclose(
        by_exact.series["energy_bound"], (np.abs(y[:, 0]) + np.abs(y[:, 1])) * 1e-8
    )


@pytest.mark.slow
def test_prentice2011_rk34q8_meets_the_papers_bounds():
    """The issue's acceptance test: RK34Q8 at 1e-6 on the paper's problem."""
    from hamrkq import load_problem
    from hamrkq.solve import solve

    problem = load_problem("prentice2011")
    sol = solve(problem)  # RK34Q8, atol 1e-6, rtol 0, t in [0, 4000]
    true = diagnose(sol, problem, reference="independent")
    paper = diagnose(sol, problem, reference="rk8")
    # the independent reference is far more accurate than the tolerance
    assert true.error.reference_accuracy < 1e-8
    assert true.error.bound_ratio <= 1.05  # trajectory error / (sqrt(2) 1e-6)
    assert true.energy_bound_ratio <= 1.05  # |H - 0.8| / ((|q'| + |p'|) 1e-6)
    # against its own RK8 track every node is within delta by construction
    assert max(paper.error.max_abs) <= 1e-6 * (1 + 1e-12)
    assert paper.error.bound_ratio <= 1.0 + 1e-12
    # the two differ by the RK8 track's own error, which Gamma estimates
    track_error = np.asarray(sol.z) - true.series["reference"]
    assert np.max(np.abs(track_error - sol.gamma)) <= 0.5 * np.max(np.abs(track_error))
    assert abs(true.energy.initial - 0.8) < 1e-15


def test_references_start_where_the_run_started_when_t_eval_omits_it():
    """A run with t_eval need not return its initial state as a node: the
    exact solution was refused ("starts at ..., not at the run's initial
    state") and the independent references started from the run's own first
    node, error included (Kepler at 1e-6 from t = 1: 3.8e-7 of it)."""
    problem = hamrkq.load_problem("kepler")
    sol = hamrkq.solve(problem, t_eval=np.linspace(1.0, 20.0, 20), atol=1e-6, method="rk34q8")
    assert sol.t[0] == 1.0 and sol.options["y0"] == problem.y0.tolist()
    exact = hamrkq.diagnose(sol, problem=problem, reference="exact")
    independent = hamrkq.diagnose(sol, problem=problem, reference="independent")
    truth = problem.exact(sol.t)
    np.testing.assert_allclose(exact.series["reference"], truth, rtol=0, atol=1e-14)
    np.testing.assert_allclose(independent.series["reference"], truth, rtol=0, atol=1e-9)
    first_error = np.abs(sol.y[0] - truth[0]).max()
    assert 1e-8 < first_error <= 1.05e-6  # the first node's own error, now measured


OSCILLATOR_FILE = """\
name = "oscillator"
coordinates = ["q"]
momenta = ["p"]
hamiltonian = "(p**2 + w**2*q**2)/2"

[parameters]
w = 1.0

[initial]
q = [0]
p = [1]

[integration]
t_span = [0, 30]
atol = 1e-8

[invariants]
I = "(p**2 + w**2*q**2)/2"

[exact]
q = ["sin(w*t)/w"]
p = ["cos(w*t)"]
"""


def test_a_run_with_other_parameters_is_diagnosed_at_them(tmp_path):
    # solve(problem, parameters={"w": 2}) measured against the problem's w = 1:
    # a true error of 1.3 and 2.0 reported as measured, the invariant H's
    # error 0.375, and the energy bound from the gradient at w = 1.
    path = tmp_path / "oscillator.toml"
    path.write_text(OSCILLATOR_FILE)
    problem = hamrkq.load_problem(path)
    sol = hamrkq.solve(problem, parameters={"w": 2.0})
    exact = np.column_stack([np.sin(2 * sol.t) / 2, np.cos(2 * sol.t)])
    own = np.abs(sol.y - exact).max(axis=0)
    energy = np.abs((sol.y[:, 1] ** 2 + 4 * sol.y[:, 0] ** 2) / 2 - 0.5)
    bound = energy / ((np.abs(4 * sol.y[:, 0]) + np.abs(sol.y[:, 1])) * 1e-8)
    for reference in ("auto", "exact", "independent"):
        diag = diagnose(sol, problem, reference=reference)
        np.testing.assert_allclose(diag.error.max_abs, own, rtol=1e-3)
        assert diag.invariants[0].max_abs == pytest.approx(energy.max(), rel=1e-9)
        assert diag.energy_bound_ratio == pytest.approx(bound.max(), rel=1e-9)
    # The same for a Hamiltonian whose default the run overrode.
    q, p, w = (
        problem.hamiltonian.q[0],
        problem.hamiltonian.p[0],
        problem.hamiltonian.parameters[0],
    )
    ham = hamrkq.Hamiltonian((p**2 + w**2 * q**2) / 2, q=[q], p=[p], parameters={w: 1.0})
    run = hamrkq.solve(ham, [0.0], [1.0], (0.0, 30.0), atol=1e-8, parameters={"w": 2.0})
    assert diagnose(run, ham, reference="rk8").energy_bound_ratio == pytest.approx(
        bound.max(), rel=0.05
    )


def test_auto_passes_over_an_exact_solution_that_does_not_apply():
    # Kepler from other initial values: the file's exact solution starts
    # elsewhere.  reference="auto" raised InputError; it takes the run's own
    # track, as its docstring says, and notes why.
    kepler = hamrkq.load_problem("kepler")
    sol = hamrkq.solve(kepler, q0=[0.5, 0.0], p0=[0.0, 1.2], t_span=(0.0, 20.0))
    diag = diagnose(sol, kepler)
    assert diag.error.source == "rk8"
    assert any("the exact solution does not apply" in note for note in diag.notes)
