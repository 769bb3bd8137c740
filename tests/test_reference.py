"""Accuracy of the independent reference trajectories (hamrkq.analysis.reference).

Each reference is checked against something computed another way: closed
forms (harmonic oscillator, Kepler's equation), a quadrature of the period,
and a 25-digit Taylor integration (mpmath.odefun).
"""

import mpmath as mp
import numpy as np
import pytest
from scipy.optimize import brentq

from hamrkq.analysis.reference import (
    TIGHTEST_RTOL,
    Reference,
    integrate_reference,
    periodic_reference,
)
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue import exact
from hamrkq.errors import InputError

Q0_PRENTICE = float(np.arccos(-0.8))


def prentice_rhs(t, y, params):
    q, p = y
    return np.array([p + np.cos(q) / 6, (p / 6 - 1) * np.sin(q)])


def prentice_energy(q, p):
    return p**2 / 2 - (1 - p / 6) * np.cos(q)


def harmonic_rhs(t, y, params):
    (omega,) = params
    return np.array([y[1], -(omega**2) * y[0]])


def pendulum_rhs(t, y, params):
    return np.array([y[1], -np.sin(y[0])])


def kepler_rhs(t, y, params):
    q1, q2, p1, p2 = y
    r3 = (q1 * q1 + q2 * q2) ** 1.5
    return np.array([p1, p2, -q1 / r3, -q2 / r3])


def kepler_exact(t, e):
    """Kepler's equation E - e sin E = t solved by Newton (period 2 pi)."""
    big_e = np.array(t, dtype=float)
    for _ in range(50):
        big_e -= (big_e - e * np.sin(big_e) - t) / (1 - e * np.cos(big_e))
    c, s = np.cos(big_e), np.sin(big_e)
    root = np.sqrt(1 - e * e)
    rate = 1 / (1 - e * c)  # dE/dt
    return np.column_stack([c - e, root * s, -s * rate, root * c * rate])


def prentice_period_by_quadrature(nodes=512):
    """Period of the H = 0.8 orbit as the integral of dt over the polar angle.

    Around the centre (0, -1/6) the orbit is star-shaped; with r(theta) from
    H = 0.8, dt = r / (u_perp . f) dtheta, a smooth periodic integrand, so the
    trapezoidal rule converges geometrically.
    """
    centre = np.array([0.0, -1.0 / 6.0])
    total = 0.0
    for theta in 2 * np.pi * np.arange(nodes) / nodes:
        u = np.array([np.cos(theta), np.sin(theta)])

        def level(r, u=u):
            q, p = centre + r * u
            return prentice_energy(q, p) - 0.8

        r = brentq(level, 0.1, 3.0, xtol=1e-16, rtol=4 * np.finfo(float).eps)
        f = prentice_rhs(0.0, centre + r * u, None)
        total += r / (-u[1] * f[0] + u[0] * f[1])
    return abs(total * 2 * np.pi / nodes)


def test_harmonic_over_long_time_matches_sin_cos():
    t = np.linspace(0.0, 4000.0, 20001)
    ref = periodic_reference(harmonic_rhs, [0.0, 1.0], t, params=np.array([1.0]))
    exact = np.column_stack([np.sin(t), np.cos(t)])
    error = np.max(np.abs(ref.y - exact))
    assert abs(ref.details["period"] - 2 * np.pi) < 2e-14
    assert error < 2e-12
    # The estimate is honest (not below the truth) and still useful.
    assert error <= ref.estimated_error < 1e-10
    assert ref.y.shape == (t.size, 2)


def test_prentice_period_agrees_with_quadrature():
    quadrature = prentice_period_by_quadrature()
    # the 30-digit value of the same quadrature in mpmath (512 and 1024 nodes agree)
    assert abs(quadrature - 10.470517315591804695782) < 1e-14
    ref = periodic_reference(prentice_rhs, [Q0_PRENTICE, 0.0], [4000.0])
    assert abs(ref.details["period"] - quadrature) < 5e-14
    assert ref.details["period_error"] < 1e-13


@pytest.mark.slow
def test_prentice_states_agree_with_taylor_integration():
    """Reference at t = 4000 (382 periods) against a 25-digit Taylor solution."""
    times = np.array([4000.0, 3000.0, 1000.5, 2096.2])  # phases 0.19 .. 2.2 in the period
    truth = []
    with mp.workdps(25):
        period = mp.mpf("10.47051731559180469578204")
        taylor = mp.odefun(
            lambda t, y: [y[1] + mp.cos(y[0]) / 6, (y[1] / 6 - 1) * mp.sin(y[0])],
            0,
            [mp.acos(mp.mpf("-0.8")), mp.mpf(0)],
        )
        for t in times:
            tt = mp.mpf(float(t))
            phase = tt - mp.floor(tt / period) * period
            truth.append([float(v) for v in taylor(phase)])
    ref = periodic_reference(prentice_rhs, [Q0_PRENTICE, 0.0], times)
    error = np.max(np.abs(ref.y - np.array(truth)))
    assert error < 1e-11  # target in the brief: 1e-10
    assert error <= ref.estimated_error < 1e-10


def test_prentice_long_grid_conserves_energy_and_is_self_consistent():
    t = np.linspace(0.0, 4000.0, 62001)
    ref = periodic_reference(prentice_rhs, [Q0_PRENTICE, 0.0], t)
    assert np.max(np.abs(prentice_energy(ref.y[:, 0], ref.y[:, 1]) - 0.8)) < 1e-13
    other = periodic_reference(prentice_rhs, [Q0_PRENTICE, 0.0], t, steps_per_period=400)
    assert np.max(np.abs(other.y - ref.y)) <= ref.estimated_error
    assert ref.y[0].tolist() == pytest.approx([Q0_PRENTICE, 0.0], abs=1e-15)


def test_pendulum_period_is_four_complete_elliptic_integrals():
    from scipy.special import ellipk

    # q0 = 0, p0 = 1: H = -1/2 = -cos(q_max), so q_max = pi/3, k = sin(pi/6) = 1/2
    ref = periodic_reference(pendulum_rhs, [0.0, 1.0], [100.0])
    assert abs(ref.details["period"] - 4 * ellipk(0.25)) < 2e-14


def test_kepler_two_degrees_of_freedom_against_keplers_equation():
    e = 0.6
    y0 = [1 - e, 0.0, 0.0, np.sqrt((1 + e) / (1 - e))]
    t = np.linspace(0.0, 100 * np.pi, 4001)  # 50 orbits
    ref = periodic_reference(kepler_rhs, y0, t)
    assert abs(ref.details["period"] - 2 * np.pi) < 1e-13
    # The truth is the flow of the double y0 (its period is 2 pi only to
    # rounding): the catalogue's formula, checked against mpmath in
    # tests/test_exact.py; measured 7.2e-13 on one machine and 2.3e-12 on
    # another (SciPy's DOP853 rounds with the CPU's NumPy and BLAS kernels;
    # 4.3e-13 from the ideal orbit through the exact y0).
    error = np.max(np.abs(ref.y - exact.kepler(t, y0)))
    assert error < 5e-12
    assert error <= ref.estimated_error < 1e-9
    assert np.max(np.abs(ref.y - kepler_exact(t, e))) < 1e-11


def test_rotating_pendulum_with_shift_matches_direct_integration():
    y0 = [0.0, 2.5]  # H = 2.125 > 1: the pendulum goes over the top
    t = np.linspace(0.0, 60.0, 301)
    ref = periodic_reference(pendulum_rhs, y0, t, shift=[2 * np.pi, 0.0])
    direct = integrate_reference(pendulum_rhs, y0, t)
    assert np.max(np.abs(ref.y - direct.y)) < 1e-10
    assert ref.y[-1, 0] > 30.0  # q keeps growing by 2 pi per period


def test_backward_times_and_t0():
    t = np.array([-7.0, -1.0, 3.0, 12.5])
    ref = periodic_reference(harmonic_rhs, [1.0, 0.0], t, params=[2.0], t0=1.0)
    exact = np.column_stack([np.cos(2 * (t - 1)), -2 * np.sin(2 * (t - 1))])
    assert np.max(np.abs(ref.y - exact)) < 1e-13


def test_not_periodic_or_equilibrium_is_refused():
    def two_frequencies(t, y, params):
        return np.array([y[2], np.sqrt(2) * y[3], -y[0], -np.sqrt(2) * y[1]])

    with pytest.raises(InputError, match=r"(does not close|does not return)"):
        periodic_reference(two_frequencies, [1.0, 1.0, 0.0, 0.0], [10.0], max_period=60.0)
    with pytest.raises(InputError, match="equilibrium"):
        periodic_reference(pendulum_rhs, [0.0, 0.0], [1.0])
    with pytest.raises(InputError, match="y0"):
        periodic_reference(pendulum_rhs, [0.0, 0.0, 1.0], [1.0])
    with pytest.raises(InputError, match="rtol"):
        periodic_reference(pendulum_rhs, [0.0, 1.0], [1.0], rtol=1e-16)


def test_integrate_reference_error_estimate_is_honest():
    t = np.linspace(0.0, 200.0, 1001)
    ref = integrate_reference(harmonic_rhs, [0.0, 1.0], t, params=[1.0])
    error = np.max(np.abs(ref.y - np.column_stack([np.sin(t), np.cos(t)])))
    assert error <= ref.estimated_error < 1e-10
    assert ref.y[0].tolist() == [0.0, 1.0]  # the first node is y0 exactly


@pytest.mark.parametrize("amplitude", [1e-6, 1e6])
def test_integrate_reference_atol_follows_the_scale(amplitude):
    t = np.linspace(0.0, 50.0, 201)
    ref = integrate_reference(harmonic_rhs, [0.0, amplitude], t, params=[1.0])
    relative = np.max(np.abs(ref.y / amplitude - np.column_stack([np.sin(t), np.cos(t)])))
    assert relative < 1e-11
    assert ref.estimated_error / amplitude < 1e-10


def test_integrate_reference_backward_and_validation():
    t = np.array([0.0, -1.0, -5.0])
    ref = integrate_reference(pendulum_rhs, [0.3, 0.0], t, rtol=TIGHTEST_RTOL)
    forward = integrate_reference(pendulum_rhs, ref.y[-1], [-5.0, 0.0])
    assert np.max(np.abs(forward.y[-1] - [0.3, 0.0])) < 1e-12
    with pytest.raises(InputError, match="one side"):
        integrate_reference(pendulum_rhs, [0.3, 0.0], [-1.0, 1.0], t0=0.0)
    with pytest.raises(InputError, match="atol"):
        integrate_reference(pendulum_rhs, [0.3, 0.0], [0.0, 1.0], atol=0.0)
    with pytest.raises(InputError, match="finite"):
        integrate_reference(pendulum_rhs, [np.nan, 0.0], [0.0, 1.0])


def test_reference_is_frozen_and_describes_itself():
    ref = integrate_reference(pendulum_rhs, [0.3, 0.0], [0.0, 1.0])
    assert isinstance(ref, Reference)
    with pytest.raises(ValueError, match="read-only"):
        ref.y[0, 0] = 1.0
    assert "DOP853" in ref.describe() and "accurate to ~" in ref.describe()
    assert isinstance(ref.details["nfev"], int)


def test_components_at_rounding_level_do_not_stall_the_reference():
    """Toda from a symmetric start: q2 and p2 stay zero up to rounding noise.

    A scale-aware atol built from that noise (~1e-17) asked DOP853 to resolve
    rounding and never finished; such components now borrow the largest scale.
    """
    import hamrkq
    from hamrkq.analysis.reference import hamiltonian_reference

    problem = hamrkq.load_problem("toda")
    t = np.linspace(0.0, 50.0, 201)
    ref = hamiltonian_reference(problem, problem.y0, t)
    assert ref.estimated_error < 1e-9
    ham, params = problem.hamiltonian, problem.parameter_array
    energy = numeric_of(ham).energy(t, ref.y, params)
    assert np.max(np.abs(energy - energy[0])) < 1e-10
    np.testing.assert_allclose(ref.y[:, [1, 4]], 0.0, atol=1e-12)  # symmetry kept
