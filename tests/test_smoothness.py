"""Certified runs end before the first step across a kink of H
(``hamrkq.solve.smoothness``).

QA: ``H = p^2/2 + |q|`` with ``auto`` at 1e-8 returned SUCCESS with nodes 84
times the tolerance off (140 of 172 nodes above it), and an ``atan2(y, x)``
term in a Kepler problem, whose value jumps by 2 pi across the negative
x-axis, 562 times; the Hamiltonian only warned that the error estimates of a
step across a kink are not reliable.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import hamrkq
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError
from hamrkq.result import Status

q, p = sp.symbols("q p", real=True)


@pytest.fixture(scope="module")
def v_well():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), [q], [p])


def _v_well_exact(t):
    """From q = 1, p = 0, before the crossing at t = sqrt 2: q = 1 - t^2/2."""
    return np.column_stack([1 - t**2 / 2, -t])


START = {"q0": [1.0], "p0": [0.0], "t_span": (0.0, 20.0)}


@pytest.mark.parametrize("method", ["auto", "rk34q8", "rk67q9", "scipy:RK34Q8"])
def test_a_certified_run_ends_before_the_first_step_across_a_kink(v_well, method):
    sol = hamrkq.solve(v_well, **START, atol=1e-8, method=method)
    assert sol.t[-1] < np.sqrt(2.0)
    if "RK34Q8" in method.upper():
        # the paper's tangent Gamma, 5e7 times the tolerance across the kink,
        # stops it first (SciPy's wrapper reports that as its failure)
        assert sol.status in (Status.TOLERANCE_UNATTAINABLE, Status.EXTERNAL_FAILURE)
    else:
        assert sol.status is Status.TOLERANCE_UNATTAINABLE
        assert "crosses q = 0, where H is not smooth (Abs(q))" in sol.message
    assert np.max(np.abs(sol.y - _v_well_exact(sol.t))) <= 1.05e-8


def test_without_the_certificate_the_run_goes_on(v_well):
    sol = hamrkq.solve(v_well, **START, atol=1e-8, gamma_limit=np.inf)
    assert sol.status is Status.SUCCESS
    assert sol.t[-1] == 20.0


def test_output_times_keep_every_node_to_see_the_crossing(v_well):
    # 0, 2, 4, ...: no output time falls between the crossing's nodes
    times = np.linspace(0.0, 20.0, 11)
    sol = hamrkq.solve(v_well, **START, atol=1e-8, t_eval=times)
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    np.testing.assert_array_equal(sol.t, [0.0])
    with pytest.raises(InputError, match="keep_every=3 would hide where the run crosses"):
        hamrkq.solve(v_well, **START, atol=1e-8, keep_every=3)


def test_an_orbit_that_never_reaches_the_kink_succeeds():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + sp.Abs(q - 5), [q], [p])
    # |q - 5| = 5 - q on the orbit: q = 1 - 0.5 cos t, p = 0.5 sin t
    sol = hamrkq.solve(ham, q0=[0.5], p0=[0.0], t_span=(0.0, 20.0), atol=1e-8)
    assert sol.status is Status.SUCCESS
    exact = np.column_stack([1 - 0.5 * np.cos(sol.t), 0.5 * np.sin(sol.t)])
    assert np.max(np.abs(sol.y - exact)) <= 1.05e-8


def test_the_branch_cut_of_atan2_is_a_kink():
    x, y, px, py = sp.symbols("x y p_x p_y", real=True)
    r = sp.sqrt(x**2 + y**2)
    ham = hamrkq.Hamiltonian(
        (px**2 + py**2) / 2 - 1 / r + sp.atan2(y, x) * px / 50, [x, y], [px, py]
    )
    sol = hamrkq.solve(ham, q0=[1.0, 0.0], p0=[0.0, 1.1], t_span=(0.0, 30.0), atol=1e-8)
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    assert "crosses y = 0 with x < 0" in sol.message
    # before the cut the equations are smooth: a tight DOP853 run is the truth
    numeric = numeric_of(ham)
    params = np.zeros(0)
    truth = solve_ivp(
        lambda t, s: numeric.rhs(t, s, params), (0.0, sol.t[-1]), sol.y[0],
        method="DOP853", rtol=1e-13, atol=1e-15, t_eval=sol.t,
    ).y.T  # fmt: skip
    assert np.max(np.abs(sol.y - truth)) <= 1.05e-8
    assert sol.y[-1, 1] > 0 or sol.y[-1, 0] > 0  # still before the cut


def test_ensemble_members_are_cut_as_solve_cuts_them(v_well):
    q0 = np.array([[1.0], [2.0]])
    ens = hamrkq.ensemble(v_well, q0=q0, p0=np.zeros((2, 1)), t_span=(0.0, 20.0), atol=1e-8)
    for m in range(2):
        alone = hamrkq.solve(v_well, q0=q0[m], p0=[0.0], t_span=(0.0, 20.0), atol=1e-8)
        assert ens.member_status(m) is alone.status is Status.TOLERANCE_UNATTAINABLE
        assert ens.t_last[m] == alone.t[-1]
        assert "where H is not smooth" in ens.message(m)
