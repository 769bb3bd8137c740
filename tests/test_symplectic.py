"""Fixed-step symplectic baselines: coefficients, orders, symplecticity, energy, failures.

Every numerical claim is checked against something independent: exact
solutions (Kepler after one period, a forced oscillator, a non-separable
rotation H = I^2/2), the exact symplectic condition M^T S M = S, and classical
RK4 (written here) as the non-symplectic foil.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.errors import InputError, OptionError
from hamrkq.fixed_step.implicit_rk import GAUSS_TABLEAUS
from hamrkq.fixed_step.symplectic import (
    FIXED_STEP_METHODS,
    SPLITTING_SCHEMES,
    integrate_fixed,
    solve_fixed,
)
from hamrkq.result import Solution, Status

ALL = sorted(FIXED_STEP_METHODS)
GAUSS = sorted(GAUSS_TABLEAUS)
ORDER_WINDOW = 0.3


# -- test problems, written out by hand (independent of the symbolic layer) ----
def kepler_rhs(t, y, p):
    q1, q2, p1, p2 = y
    r3 = (q1 * q1 + q2 * q2) ** 1.5
    return np.array([p1, p2, -q1 / r3, -q2 / r3])


def kepler_jac(t, y, p):
    q1, q2 = y[0], y[1]
    r2 = q1 * q1 + q2 * q2
    r3, r5 = r2**1.5, r2**2.5
    jac = np.zeros((4, 4))
    jac[0, 2] = jac[1, 3] = 1.0
    jac[2, 0] = -1 / r3 + 3 * q1 * q1 / r5
    jac[2, 1] = jac[3, 0] = 3 * q1 * q2 / r5
    jac[3, 1] = -1 / r3 + 3 * q2 * q2 / r5
    return jac


def kepler_y0(e):
    return np.array([1 - e, 0.0, 0.0, np.sqrt((1 + e) / (1 - e))])


def forced_rhs(t, y, p):
    # H = p^2/2 + q^2/2 - q sin(2t): separable and time-dependent
    return np.array([y[1], -y[0] + np.sin(2 * t)])


def forced_jac(t, y, p):
    return np.array([[0.0, 1.0], [-1.0, 0.0]])


def forced_exact(t):
    # q'' + q = sin 2t, q(0) = 1, q'(0) = 0
    q = np.cos(t) + 2 / 3 * np.sin(t) - np.sin(2 * t) / 3
    return np.array([q, -np.sin(t) + 2 / 3 * np.cos(t) - 2 / 3 * np.cos(2 * t)])


def rotation_rhs(t, y, p):
    # H = I^2/2 with I = (q^2 + p^2)/2: non-separable; rotation at angular speed I
    action = (y[0] ** 2 + y[1] ** 2) / 2
    return np.array([action * y[1], -action * y[0]])


def rotation_jac(t, y, p):
    q, mom = y
    action = (q * q + mom * mom) / 2
    return np.array([[q * mom, action + mom * mom], [-action - q * q, -q * mom]])


def rotation_exact(t, y0):
    omega = (y0[0] ** 2 + y0[1] ** 2) / 2
    c, s = np.cos(omega * t), np.sin(omega * t)
    return np.array([y0[0] * c + y0[1] * s, y0[1] * c - y0[0] * s])


def pendulum_rhs(t, y, p):
    return np.array([y[1], -np.sin(y[0])])


def pendulum_jac(t, y, p):
    return np.array([[0.0, 1.0], [-np.cos(y[0]), 0.0]])


def prentice_rhs(t, y, p):
    # H = p^2/2 - (1 - p/6) cos q (Prentice 2011), non-separable
    q, mom = y
    return np.array([mom + np.cos(q) / 6, (mom / 6 - 1) * np.sin(q)])


def prentice_jac(t, y, p):
    q, mom = y
    return np.array([[-np.sin(q) / 6, 1.0], [(mom / 6 - 1) * np.cos(q), np.sin(q) / 6]])


def rk4_fixed(rhs, y0, h, steps):
    """Classical RK4 with a fixed step: the non-symplectic foil."""
    out = np.empty((steps + 1, y0.size))
    out[0] = y = np.array(y0, dtype=float)
    for i in range(steps):
        t = i * h
        k1 = rhs(t, y, ())
        k2 = rhs(t + h / 2, y + h / 2 * k1, ())
        k3 = rhs(t + h / 2, y + h / 2 * k2, ())
        k4 = rhs(t + h, y + h * k3, ())
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[i + 1] = y
    return out


def fitted_order(steps, errors):
    return np.polyfit(np.log(steps), np.log(errors), 1)[0]


# -- coefficients ---------------------------------------------------------------
@pytest.mark.parametrize("name", GAUSS)
def test_gauss_coefficients_exact(name):
    tab = GAUSS_TABLEAUS[name]
    s = tab.stages
    a = sp.Matrix(tab.a_exact)
    b, c = list(tab.b_exact), list(tab.c_exact)
    # nodes: zeros of the shifted Legendre polynomial P_s(2x - 1)
    for ci in c:
        assert sp.simplify(sp.legendre(s, 2 * ci - 1)) == 0
    # B(2s): quadrature order 2s;  C(s): stage order s  => order 2s (Butcher 1964)
    for k in range(1, 2 * s + 1):
        quadrature = sum(bi * ci ** (k - 1) for bi, ci in zip(b, c, strict=True))
        assert sp.simplify(quadrature - sp.Rational(1, k)) == 0
    for i in range(s):
        for k in range(1, s + 1):
            lhs = sum(a[i, j] * c[j] ** (k - 1) for j in range(s))
            assert sp.simplify(lhs - c[i] ** k / k) == 0
    # symplecticity condition b_i a_ij + b_j a_ji = b_i b_j (Sanz-Serna 1988)
    for i in range(s):
        for j in range(s):
            assert sp.simplify(b[i] * a[i, j] + b[j] * a[j, i] - b[i] * b[j]) == 0
    assert tab.order == 2 * s
    # the floats are the correctly rounded exact values and are read-only
    for exact, floats in ((a, tab.a), (sp.Matrix(b), tab.b), (sp.Matrix(c), tab.c)):
        want = np.array([float(sp.N(v, 30)) for v in exact]).reshape(floats.shape)
        np.testing.assert_array_equal(floats, want)
        assert not floats.flags.writeable


def test_yoshida_coefficients_cancel_third_order():
    scheme = SPLITTING_SCHEMES["yoshida4"]
    w1, w0, _ = scheme.drifts
    assert 2 * w1 + w0 == pytest.approx(1.0, abs=1e-15)
    assert 2 * w1**3 + w0**3 == pytest.approx(0.0, abs=1e-14)
    for coefficients in (scheme.kicks, scheme.drifts):
        assert sum(coefficients) == pytest.approx(1.0, abs=1e-15)
        assert coefficients == coefficients[::-1]  # symmetric composition


# -- convergence orders ---------------------------------------------------------
KEPLER_STEPS = {
    "midpoint": [200, 400, 800, 1600],
    "verlet": [200, 400, 800, 1600],
    "gauss4": [100, 200, 400, 800],
    "yoshida4": [200, 400, 800, 1600],
    "gauss6": [50, 100, 200, 400],
}


@pytest.mark.parametrize("method", ALL)
def test_order_kepler_one_period(method):
    # e = 0.5: after one period (2 pi) the exact solution is back at y0
    y0 = kepler_y0(0.5)
    steps = np.array(KEPLER_STEPS[method])
    errors = []
    for n in steps:
        res = integrate_fixed(method, kepler_rhs, kepler_jac, y0, 0.0, 2 * np.pi, 2 * np.pi / n)
        assert res.success and res.steps == n
        errors.append(np.abs(res.y[-1] - y0).max())
    assert min(errors) > 1e-11  # stay above roundoff
    order = fitted_order(2 * np.pi / steps, errors)
    assert abs(order - FIXED_STEP_METHODS[method]) <= ORDER_WINDOW, (order, errors)


@pytest.mark.parametrize("method", ALL)
def test_order_time_dependent_forced_oscillator(method):
    # exercises the stage times (Gauss) and the kick/drift times (splitting)
    steps = np.array([10, 20, 40, 80])
    errors = []
    for n in steps:
        res = integrate_fixed(method, forced_rhs, forced_jac, [1.0, 0.0], 0.0, 5.0, 5.0 / n)
        errors.append(np.abs(res.y[-1] - forced_exact(5.0)).max())
    order = fitted_order(5.0 / steps, errors)
    assert abs(order - FIXED_STEP_METHODS[method]) <= ORDER_WINDOW, (order, errors)


@pytest.mark.parametrize("method", GAUSS)
def test_order_non_separable_rotation(method):
    y0 = np.array([0.6, 0.8])
    steps = np.array([20, 40, 80, 160])
    errors = []
    for n in steps:
        res = integrate_fixed(method, rotation_rhs, rotation_jac, y0, 0.0, 10.0, 10.0 / n)
        errors.append(np.abs(res.y[-1] - rotation_exact(10.0, y0)).max())
    order = fitted_order(10.0 / steps, errors)
    assert abs(order - FIXED_STEP_METHODS[method]) <= ORDER_WINDOW, (order, errors)


# -- symplecticity and symmetry ---------------------------------------------------
S = np.array([[0.0, 1.0], [-1.0, 0.0]])


def one_step_jacobian(step, y, delta=1e-3):
    """d step / d y by the 4th-order central difference (error ~ delta^4)."""
    cols = []
    for k in range(y.size):
        e = np.zeros(y.size)
        e[k] = delta
        cols.append(
            (-step(y + 2 * e) + 8 * step(y + e) - 8 * step(y - e) + step(y - 2 * e)) / (12 * delta)
        )
    return np.column_stack(cols)


def _map(method, rhs, jac, h):
    def step(y):
        res = integrate_fixed(method, rhs, jac, y, 0.0, h, h)
        assert res.success and res.steps == 1
        return res.y[-1]

    return step


@pytest.mark.parametrize("method", ALL)
def test_one_step_map_is_symplectic_on_pendulum(method):
    m = one_step_jacobian(_map(method, pendulum_rhs, pendulum_jac, 0.4), np.array([0.9, 0.7]))
    assert np.abs(m.T @ S @ m - S).max() < 1e-10
    assert np.abs(m - np.eye(2)).max() > 0.1  # a real step, not the identity


@pytest.mark.parametrize("method", GAUSS)
def test_one_step_map_is_symplectic_non_separable(method):
    m = one_step_jacobian(_map(method, prentice_rhs, prentice_jac, 0.4), np.array([2.2, 0.3]))
    assert np.abs(m.T @ S @ m - S).max() < 1e-10


def test_rk4_foil_is_not_symplectic():
    def step(y):
        return rk4_fixed(pendulum_rhs, y, 0.4, 1)[-1]

    m = one_step_jacobian(step, np.array([0.9, 0.7]))
    assert np.abs(m.T @ S @ m - S).max() > 1e-5


@pytest.mark.parametrize("method", ALL)
def test_symmetric_methods_retrace_their_steps(method):
    # all five methods are symmetric: 50 steps back from where 50 steps forward
    # ended return to the start up to roundoff, although each step errs by ~h^3
    y0 = kepler_y0(0.3)
    fwd = integrate_fixed(method, kepler_rhs, kepler_jac, y0, 0.0, 5.0, 0.1)
    back = integrate_fixed(method, kepler_rhs, kepler_jac, fwd.y[-1], 5.0, 0.0, 0.1)
    assert back.success and back.steps == 50
    np.testing.assert_allclose(back.t[[0, -1]], [5.0, 0.0])
    assert np.abs(back.y[-1] - y0).max() < 1e-13  # measured: at most 6.6e-15
    assert np.abs(fwd.y[-1] - kepler_y0(0.3)).max() > 1e-4


@pytest.fixture(scope="module")
def outer_solar_system():
    # built once: generating the 36 x 36 Jacobian's code takes about 2 s
    return hamrkq.load_problem("outer_solar_system")


@pytest.mark.parametrize("method", ALL)
def test_multiscale_state_retraced_component_by_component(method, outer_solar_system):
    # outer solar system: Pluto's momenta (~1e-11) sit 12 orders below the
    # positions (~30); Newton must converge per component, not in a global norm,
    # or the small components would lose their digits (measured: <= 4.3e-16)
    problem = outer_solar_system
    ham, y0 = problem.hamiltonian, problem.y0
    fwd = solve_fixed(ham, y0, (0.0, 500.0), method, 50.0)
    back = solve_fixed(ham, fwd.y[-1], (500.0, 0.0), method, 50.0)
    moved = np.abs(fwd.y[-1] - y0) / np.abs(np.where(y0 == 0, 1.0, y0))
    assert moved.max() > 1e-3
    nonzero = y0 != 0
    rel = np.abs(back.y[-1] - y0)[nonzero] / np.abs(y0[nonzero])
    assert rel.max() < 1e-13, rel.max()
    assert np.abs(back.y[-1] - y0)[~nonzero].max() < 1e-17  # the Sun's momentum


@pytest.mark.parametrize("method", GAUSS)
def test_components_zero_by_symmetry_do_not_stall_newton(method):
    # the catalogue's Toda lattice keeps q2 = p2 = 0 by symmetry: those components
    # carry only rounding noise (~1e-20), which a purely relative test never clears
    problem = hamrkq.load_problem("toda")
    sol = solve_fixed(problem.hamiltonian, problem.y0, (0.0, 20.0), method, 0.1)
    assert sol.success, sol.message
    assert sol.stats["newton_iterations"] < 12 * sol.stats["steps"]
    assert np.ptp(sol.energy) < 1e-2 * abs(sol.energy[0])
    assert np.abs(sol.y[:, [1, 4]]).max() < 1e-12  # the symmetry is kept


# -- long-run energy behaviour (pendulum from the catalogue, 10 000 periods) --------
PENDULUM_PERIOD = 6.743001419250385  # 4 K(1/4) for H = p^2/2 - cos q, q0 = 0, p0 = 1
T_END = 10_000 * PENDULUM_PERIOD
# Steps between 5 and 27 per period: the energy error stays well below 1e-2, and
# the Gauss runs (7 to 9 Newton iterations per step) stay within ~15 s each.
DRIFT_STEPS = {"verlet": 0.25, "yoshida4": 0.5, "midpoint": 0.5, "gauss4": 1.0, "gauss6": 1.25}
# The implicit methods run 2 500 periods (their Newton iterations made the
# suite's three longest fixed-step tests, 16 to 30 s each at 10 000): over
# 2 500 periods RK4's drift is still about 40 times its scatter (a quarter of
# the 10 000-period drift below), the implicit methods' 1e-3 to 4e-3 of it.
DRIFT_PERIODS = {"verlet": 10_000, "yoshida4": 10_000, "midpoint": 2_500, "gauss4": 2_500,
                 "gauss6": 2_500}  # fmt: skip


def drift_and_scatter(t, energy):
    """Fitted change of H over the run (the slope times the run's length) and
    the residuals' std."""
    err = energy - energy[0]
    slope, intercept = np.polyfit(t, err, 1)
    return slope * (t[-1] - t[0]), np.std(err - (slope * t + intercept))


def test_pendulum_period_value():
    from scipy.special import ellipk

    assert 4 * ellipk(0.25) == pytest.approx(PENDULUM_PERIOD, rel=1e-15)


@pytest.mark.slow
@pytest.mark.parametrize("method", ALL)
def test_no_energy_drift_over_thousands_of_periods(method):
    problem = hamrkq.load_problem("pendulum")
    sol = solve_fixed(
        problem.hamiltonian,
        problem.y0,
        (0.0, DRIFT_PERIODS[method] * PENDULUM_PERIOD),
        method,
        DRIFT_STEPS[method],
        keep_every=7,
    )
    assert sol.success
    drift, scatter = drift_and_scatter(sol.t, sol.energy)
    # measured |drift| / scatter: verlet 5.1e-4, yoshida4 1.4e-3 (10 000
    # periods), midpoint 1.2e-3, gauss4 3.7e-3, gauss6 2.2e-3 (2 500 periods);
    # RK4 below: 170 over 10 000 periods
    assert abs(drift) < 0.02 * scatter, (drift, scatter)
    # and the oscillation is as large at the end as at the start, not larger
    err = np.abs(sol.energy - sol.energy[0])
    tenth = err.size // 10
    assert err[-tenth:].max() < 1.5 * err[:tenth].max()


@pytest.mark.slow
def test_rk4_foil_drifts_over_10000_periods():
    h = 0.2
    y = rk4_fixed(pendulum_rhs, np.array([0.0, 1.0]), h, int(T_END / h))[::7]
    t = np.arange(y.shape[0]) * 7 * h
    drift, scatter = drift_and_scatter(t, y[:, 1] ** 2 / 2 - np.cos(y[:, 0]))
    # measured: drift -0.097, scatter 5.6e-4
    assert drift < -50 * scatter, (drift, scatter)


# -- failures are statuses, not exceptions ---------------------------------------------
def ramped_quartic_rhs(t, y, p):
    # H = p^2/2 + exp(t) q^4/4: the stiffness grows with t until Newton fails
    return np.array([y[1], -np.exp(t) * y[0] ** 3])


def ramped_quartic_jac(t, y, p):
    return np.array([[0.0, 1.0], [-3 * np.exp(t) * y[0] ** 2, 0.0]])


@pytest.mark.parametrize("method", GAUSS)
def test_newton_failure_is_a_status_with_partial_results(method):
    res = integrate_fixed(
        method, ramped_quartic_rhs, ramped_quartic_jac, [1.0, 0.0], 0.0, 30.0, 0.1
    )
    assert res.status is Status.NEWTON_FAILED and not res.success
    t_fail = float(res.t[-1])
    assert 3.0 < t_fail < 30.0  # a long stretch was integrated before the failure
    assert f"t={t_fail!r}" in res.message and "Newton" in res.message
    # what helps and what is kept, as every other failed run says (QA)
    assert "What works: a smaller step" in res.message
    assert res.message.endswith(f" The {res.t.size} nodes computed so far are kept.")
    assert res.steps == round(t_fail / 0.1) and res.y.shape == (res.steps + 1, 2)
    assert np.isfinite(res.y).all()
    # the partial trajectory is right: the same run stopped earlier agrees with it
    short = integrate_fixed(
        method,
        ramped_quartic_rhs,
        ramped_quartic_jac,
        [1.0, 0.0],
        0.0,
        30.0,
        0.1,
        max_steps=res.steps,
    )
    np.testing.assert_array_equal(short.y, res.y)


def test_newton_failure_on_the_first_step():
    res = integrate_fixed(
        "gauss6", ramped_quartic_rhs, ramped_quartic_jac, [10.0, 0.0], 0.0, 100.0, 10.0
    )
    assert res.status is Status.NEWTON_FAILED
    assert res.steps == 0 and res.t.tolist() == [0.0] and res.y.tolist() == [[10.0, 0.0]]
    assert "t=0.0" in res.message


def test_non_finite_state_is_a_status():
    # H = p^2/2 - q^4/4 blows up in finite time; the last good node is kept
    def rhs(t, y, p):
        return np.array([y[1], y[0] ** 3])

    with np.errstate(over="ignore", invalid="ignore"):
        res = integrate_fixed("verlet", rhs, None, [1.0, 1.0], 0.0, 50.0, 0.5, keep_every=1000)
    assert res.status is Status.NON_FINITE
    assert np.isfinite(res.y).all() and res.t[-1] < 50.0
    assert res.t.size == 2  # the first node and the last good one
    assert f"non-finite at t={float(res.t[-1]) + 0.5!r}" in res.message
    assert "What works: a smaller step" in res.message
    assert res.message.endswith(" The 2 nodes computed so far are kept.")


def test_overflow_in_an_implicit_method_is_a_status():
    # H = 3 q p: q = q0 exp(3t) overflows near t = 236; the implicit method must
    # stop with a status (whichever of Newton or the state sees the inf first)
    def rhs(t, y, p):
        return np.array([3.0 * y[0], -3.0 * y[1]])

    def jac(t, y, p):
        return np.diag([3.0, -3.0])

    with np.errstate(over="ignore", invalid="ignore"):
        res = integrate_fixed("gauss4", rhs, jac, [1.0, 1.0], 0.0, 400.0, 0.5)
    assert res.status in (Status.NON_FINITE, Status.NEWTON_FAILED)
    assert np.isfinite(res.y).all() and 200.0 < res.t[-1] < 250.0


def test_max_steps_stops_with_status():
    res = integrate_fixed("verlet", pendulum_rhs, None, [0.0, 1.0], 0.0, 10.0, 0.1, max_steps=30)
    assert res.status is Status.MAX_STEPS and res.steps == 30
    assert res.t[-1] == pytest.approx(3.0) and "max_steps=30" in res.message
    assert "What works: a larger max_steps" in res.message
    assert res.message.endswith(f" The {res.t.size} nodes computed so far are kept.")


# -- the mesh, storage and counters ------------------------------------------------
def test_last_step_is_shortened_to_land_on_t1():
    res = integrate_fixed("gauss4", forced_rhs, forced_jac, [1.0, 0.0], 0.0, 1.05, 0.1)
    assert res.steps == 11 and res.t[-1] == 1.05
    np.testing.assert_allclose(np.diff(res.t)[:-1], 0.1, rtol=1e-12)
    assert np.diff(res.t)[-1] == pytest.approx(0.05)
    # the shortened step keeps the accuracy: error as for a uniform mesh
    assert np.abs(res.y[-1] - forced_exact(1.05)).max() < 1e-5
    # h dividing the interval up to rounding gives exactly N steps, none tiny
    res = integrate_fixed("verlet", forced_rhs, None, [1.0, 0.0], 0.0, 2 * np.pi, 2 * np.pi / 7)
    assert res.steps == 7 and res.t[-1] == 2 * np.pi


def test_backward_mesh_and_empty_interval():
    res = integrate_fixed("yoshida4", forced_rhs, None, forced_exact(2.0), 2.0, -0.25, 0.1)
    assert res.steps == 23 and res.t[0] == 2.0 and res.t[-1] == -0.25
    np.testing.assert_allclose(np.diff(res.t)[:-1], -0.1, rtol=1e-12)
    assert np.abs(res.y[-1] - forced_exact(-0.25)).max() < 1e-4
    res = integrate_fixed("gauss6", forced_rhs, forced_jac, [1.0, 0.0], 3.0, 3.0, 0.1)
    assert res.success and res.steps == 0 and res.t.tolist() == [3.0]


def test_keep_every_changes_storage_not_the_result():
    full = integrate_fixed("gauss6", kepler_rhs, kepler_jac, kepler_y0(0.5), 0.0, 10.0, 0.05)
    thin = integrate_fixed(
        "gauss6", kepler_rhs, kepler_jac, kepler_y0(0.5), 0.0, 10.0, 0.05, keep_every=7
    )
    assert full.steps == thin.steps == 200
    idx = np.append(np.arange(0, 201, 7), 200)
    np.testing.assert_array_equal(thin.t, full.t[idx])
    np.testing.assert_array_equal(thin.y, full.y[idx])


def test_counters():
    for method, calls_per_step in (("verlet", 2), ("yoshida4", 6)):
        res = integrate_fixed(method, pendulum_rhs, None, [0.0, 1.0], 0.0, 3.0, 0.1)
        assert res.nfev == calls_per_step * res.steps + 1 and res.njev == 0
    for method in GAUSS:
        res = integrate_fixed(method, pendulum_rhs, pendulum_jac, [0.0, 1.0], 0.0, 3.0, 0.1)
        stages = GAUSS_TABLEAUS[method].stages
        assert res.njev == res.steps == 30
        assert res.nfev == stages * res.newton_iterations
        # extrapolated starting values: a few iterations per step, not dozens
        assert res.newton_iterations < 8 * res.steps


# -- the Hamiltonian adapter --------------------------------------------------------
def kepler_hamiltonian():
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    return hamrkq.Hamiltonian(
        (p1**2 + p2**2) / 2 - 1 / sp.sqrt(q1**2 + q2**2), q=[q1, q2], p=[p1, p2]
    )


@pytest.mark.parametrize("method", ALL)
def test_solve_fixed_matches_the_plain_driver(method):
    ham = kepler_hamiltonian()
    y0 = kepler_y0(0.6)
    sol = solve_fixed(ham, y0, (0.0, 2 * np.pi), method, 2 * np.pi / 200)
    plain = integrate_fixed(method, kepler_rhs, kepler_jac, y0, 0.0, 2 * np.pi, 2 * np.pi / 200)
    assert isinstance(sol, Solution) and sol.success and sol.method == method
    np.testing.assert_allclose(sol.y, plain.y, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sol.t, plain.t)
    assert sol.names == ("q1", "q2", "p1", "p2") and sol.n == 2
    assert sol.stats["steps"] == 200 and sol.stats["nfev"] == plain.nfev
    assert sol.z is None and sol.global_error is None and np.isnan(sol.atol).all()
    np.testing.assert_allclose(sol.energy, -0.5 * np.ones(sol.t.size), atol=0.05)
    assert sol.options["step"] == 2 * np.pi / 200


def test_solve_fixed_with_parameters():
    q, p, k = sp.symbols("q p k")
    ham = hamrkq.Hamiltonian(p**2 / 2 + k * q**2 / 2, q=[q], p=[p], parameters={k: 1.0})
    sol = solve_fixed(ham, [1.0, 0.0], (0.0, 1.0), "gauss6", 0.05, params={"k": 4.0})
    assert sol.y[-1] == pytest.approx([np.cos(2.0), -2 * np.sin(2.0)], abs=1e-10)


@pytest.mark.parametrize("method", sorted(SPLITTING_SCHEMES))
def test_splitting_refuses_a_non_separable_hamiltonian(method):
    q, p = sp.symbols("q p")
    ham = hamrkq.Hamiltonian(p**2 / 2 - (1 - p / 6) * sp.cos(q), q=[q], p=[p])
    with pytest.raises(OptionError, match=rf"'{method}'.*separable"):
        solve_fixed(ham, [2.0, 0.0], (0.0, 1.0), method, 0.1)
    # the Gauss methods take it
    assert solve_fixed(ham, [2.0, 0.0], (0.0, 1.0), "gauss4", 0.1).success


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"method": "rk4"}, "unknown fixed-step method 'rk4'"),
        ({"h": 0.0}, "step must be a positive number"),
        ({"h": float("nan")}, "step must be a positive number"),
        ({"h": float("inf")}, "step must be a positive number"),
        ({"y0": [np.inf, 0.0]}, "y0 must be finite"),
        ({"keep_every": 0}, "keep_every must be an integer >= 1"),
        ({"max_steps": -3}, "max_steps must be a positive integer"),
        ({"jac": None}, "gauss4 is implicit and needs jac"),
    ],
)
def test_bad_input_raises_naming_the_parameter(kwargs, match):
    args = {
        "method": "gauss4",
        "rhs": pendulum_rhs,
        "jac": pendulum_jac,
        "y0": [0.0, 1.0],
        "t0": 0.0,
        "t1": 1.0,
        "h": 0.1,
    } | kwargs
    with pytest.raises(InputError, match=match):
        integrate_fixed(**args)
