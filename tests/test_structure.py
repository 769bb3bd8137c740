"""Hamiltonian structure of every catalogue problem, checked symbolically and
against finite differences."""

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends.numeric import numeric_of
from hamrkq.symbolic.hamiltonian import is_zero

NAMES = hamrkq.list_problems()


@pytest.fixture(scope="module", params=NAMES)
def problem(request):
    return hamrkq.load_problem(request.param)


def test_catalogue_has_the_promised_entries():
    promised = {
        "prentice2011",
        "harmonic",
        "pendulum",
        "kepler",
        "henon_heiles",
        "outer_solar_system",
        "fpu",
        "toda",
        "double_pendulum",
        "arenstorf",
        "pleiades",
    }
    assert promised <= set(NAMES)


def test_jacobian_matches_central_differences(problem):
    ham = problem.hamiltonian
    numeric, params = numeric_of(ham), problem.parameter_array
    rng = np.random.default_rng(20111130)
    y0 = problem.y0
    for _ in range(3):
        # random states near the initial one, scaled to each component's size
        scale = 0.05 * np.maximum(np.abs(y0), 0.1 * np.max(np.abs(y0)) + 1e-3)
        y = y0 + scale * rng.standard_normal(y0.size)
        t = float(rng.uniform(*problem.t_span))
        J = numeric.jac(t, y, params)
        fd = np.empty_like(J)
        for k in range(y.size):
            h = 1e-6 * max(abs(y[k]), 1e-2)
            e = np.zeros_like(y)
            e[k] = h
            fd[:, k] = (numeric.rhs(t, y + e, params) - numeric.rhs(t, y - e, params)) / (2 * h)
        np.testing.assert_allclose(J, fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(J)))


def test_liouville_trace_of_jacobian_is_zero(problem):
    assert is_zero(problem.hamiltonian.jacobian.trace())


def test_jacobian_is_hamiltonian_matrix(problem):
    """S^T J is symmetric (it is the Hessian of H), S the symplectic matrix."""
    ham = problem.hamiltonian
    n = ham.n
    S = sp.zeros(2 * n, 2 * n)
    S[:n, n:] = sp.eye(n)
    S[n:, :n] = -sp.eye(n)
    M = S.T * ham.jacobian
    for i in range(2 * n):
        for j in range(i + 1, 2 * n):
            assert is_zero(M[i, j] - M[j, i]), (i, j)


def test_energy_is_conserved_symbolically(problem):
    ham = problem.hamiltonian
    assert not ham.time_dependent
    assert is_zero((ham.gradient.T * ham.rhs)[0])  # dH/dt along the flow


def test_problem_loads_with_sensible_values(problem):
    ham = problem.hamiltonian
    assert problem.y0.shape == (2 * ham.n,) and np.all(np.isfinite(problem.y0))
    t0, t1 = problem.t_span
    assert t1 > t0
    assert problem.references, "every entry cites its sources"
    assert problem.title and problem.description
    H0 = numeric_of(ham).energy(t0, problem.y0, problem.parameter_array)
    assert np.isfinite(H0)
