"""The paper's experiment: prentice2011 on [0, 4000] with atol = 1e-6
(Prentice, arXiv:1111.6996, Section 4), against an independent reference.

The reference is hamrkq.analysis.reference.periodic_reference: SciPy's DOP853 over one
period at rtol = 100 eps with the period refined by Newton's method, read off
modulo the period; its own estimated error (8.5e-11, benchmarks/reproduce/summary.json) is
checked to be at least
100 times below the tolerance.  The pure-Python loop takes ~30 s for the
~62 000 steps, so the runs are shared through module-scoped fixtures.
"""

import numpy as np
import pytest

from hamrkq.analysis.reference import periodic_reference
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problems import load_problem
from hamrkq.solve import solve

pytestmark = pytest.mark.slow

TOL = 1e-6


@pytest.fixture(scope="module")
def problem():
    return load_problem("prentice2011")


def _with_reference(problem, sol):
    numeric = numeric_of(problem.hamiltonian)
    ref = periodic_reference(numeric.rhs, problem.y0, sol.t, problem.parameter_array)
    assert ref.estimated_error <= TOL / 100
    return sol, ref.y


@pytest.fixture(scope="module")
def rkq_run(problem):
    sol = solve(problem)  # the file's settings: rk34q8, atol 1e-6, rtol 0
    return _with_reference(problem, sol)


@pytest.fixture(scope="module")
def rk34_run(problem):
    return _with_reference(problem, solve(problem, method="rk34"))


def test_settings_are_the_papers(rkq_run):
    sol, _ = rkq_run
    assert sol.success, sol.message
    assert sol.method == "rk34q8" and sol.t[0] == 0.0 and sol.t[-1] == 4000.0
    np.testing.assert_array_equal(sol.atol, [TOL, TOL])
    np.testing.assert_array_equal(sol.rtol, [0.0, 0.0])


def test_estimated_global_error_within_tolerance_at_every_node(rkq_run):
    sol, _ = rkq_run
    assert np.abs(sol.global_error).max() <= TOL
    assert sol.stats["quenches"] > 100  # the bound is enforced, not idle


def test_true_error_within_tolerance_at_every_node(rkq_run):
    sol, reference = rkq_run
    true = np.abs(sol.y - reference)
    assert true.max() < 1.05 * TOL
    # The paper's trajectory bound: sqrt(2) delta in the Euclidean norm.
    assert np.linalg.norm(sol.y - reference, axis=1).max() <= np.sqrt(2) * TOL


def test_node_count_matches_the_paper_within_a_factor_of_two(rkq_run):
    sol, _ = rkq_run
    assert 48_000 <= sol.t.size <= 192_000  # the paper: about 96 000


def test_energy_error_within_the_papers_bound(rkq_run, problem):
    sol, _ = rkq_run
    numeric = numeric_of(problem.hamiltonian)
    gradient = numeric.gradient(sol.t, sol.y, problem.parameter_array)
    bound = np.abs(gradient).sum(axis=1) * TOL
    assert np.all(np.abs(sol.energy - 0.8) <= 1.05 * bound + 1e-15)


def test_gamma_estimates_the_true_error_of_the_rk8_track(rkq_run):
    sol, reference = rkq_run
    true = np.linalg.norm(sol.z - reference, axis=1)
    estimate = np.linalg.norm(sol.gamma, axis=1)
    where = true > 1e-12
    assert where.mean() > 0.8
    ratio = estimate[where] / true[where]
    assert 0.1 < ratio.min() and ratio.max() < 10
    # The track's error (~1e-9 at t = 4000) is far below the tolerance.
    assert 1e-10 < true.max() < 1e-8


def test_work_budget(rkq_run):
    sol, _ = rkq_run
    s = sol.stats
    per_step = sol.options["nfev_per_step"]
    assert per_step == 40
    assert s["nfev"] <= 1.2 * (s["steps"] + s["rejected"]) * per_step
    assert s["njev"] == sol.options["njev_per_step"] * s["steps"]


def test_rk34_alone_drifts_as_the_paper_reports(rk34_run):
    sol, reference = rk34_run
    assert sol.success and sol.z is None
    assert np.abs(sol.y - reference).max() > 1e-3  # the paper: about 0.02
    drift = np.abs(sol.energy - 0.8).max()
    assert 1e-7 <= drift <= 1e-4  # the paper: about 3e-6
    # The drift is secular: it grows along the run.
    quarter = sol.t.size // 4
    assert (
        np.abs(sol.energy[-quarter:] - 0.8).mean() > 3 * np.abs(sol.energy[:quarter] - 0.8).mean()
    )


def test_save_and_load_round_trip_is_bit_exact(rkq_run, tmp_path):
    sol, _ = rkq_run
    back = type(sol).load(sol.save(tmp_path / "prentice.npz"))
    for name in ("t", "y", "z", "global_error", "gamma", "energy", "quenched"):
        np.testing.assert_array_equal(getattr(back, name), getattr(sol, name))
    assert back.stats == sol.stats and back.options == sol.options
    assert back.status is sol.status and back.message == sol.message
