"""Gamma, the estimated global error of the RK8 track, against its true error.

The paper's method, ``rk34q8`` (named: the default is ``auto``).
"tangent" (the exact linearisation of the RK8 step) is compared with the
paper's "(I + h J)" propagation.  The measured behaviour, documented in
docs/algorithm.md: on the harmonic oscillator det(I + h J) = 1 + h^2 > 1 and
the paper's estimate grows without bound; on prentice2011 the orbit spends
long times where det J < 0 (its mean over a period is about -0.16), so the
paper's estimate is damped and understates the true error by orders of
magnitude.  "tangent" follows the truth on both.
"""

import numpy as np
import pytest

from hamrkq.analysis.reference import periodic_reference
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problems import load_problem
from hamrkq.solve import solve


def gamma_and_true(sol, reference):
    return np.linalg.norm(sol.gamma, axis=1), np.linalg.norm(sol.z - reference, axis=1)


def test_tangent_gamma_within_a_factor_ten_on_the_pendulum():
    pr = load_problem("pendulum")
    sol = solve(pr, atol=1e-3, method="rk34q8")
    estimate, true = gamma_and_true(sol, pr.exact(sol.t))
    where = true > 1e-12
    assert where.mean() > 0.9
    ratio = estimate[where] / true[where]
    assert 0.1 < ratio.min() and ratio.max() < 10
    # In fact it is within a per cent here.
    assert 0.99 < ratio.min() and ratio.max() < 1.01


def test_cooper_verner_track_estimated_as_well():
    pr = load_problem("pendulum")
    sol = solve(pr, atol=1e-3, method="rk34q8", z_method="cooper_verner")
    assert sol.options["z_method"] == "cooper_verner"
    assert sol.options["nfev_per_step"] == 5 + 11 + 21
    estimate, true = gamma_and_true(sol, pr.exact(sol.t))
    where = true > 1e-12
    ratio = estimate[where] / true[where]
    assert 0.5 < ratio.min() and ratio.max() < 2
    assert np.abs(sol.y - pr.exact(sol.t)).max() <= 1.05e-3


def test_options_name_the_quencher_a_member_ran():
    pr = load_problem("pendulum")
    assert solve(pr, t_span=(0, 1), method="rk78q12").options["z_method"] == "feagin12"
    assert solve(pr, t_span=(0, 1), method="rk67q9").options["z_method"] == "vern98"
    assert solve(pr, t_span=(0, 1), method="rk34q8").options["z_method"] == "dop853"


def test_paper_propagation_grows_on_the_harmonic_oscillator():
    pr = load_problem("harmonic")
    runs = {
        mode: solve(
            pr,
            atol=1e-4,
            t_span=(0, 40 * np.pi),
            global_error_estimate=mode,
            gamma_limit=np.inf,
            method="rk34q8",
        )
        for mode in ("tangent", "paper")
    }
    tangent, true = gamma_and_true(runs["tangent"], pr.exact(runs["tangent"].t))
    paper, _ = gamma_and_true(runs["paper"], pr.exact(runs["paper"].t))
    assert np.abs(tangent[-1] / true[-1] - 1) < 0.01
    # Euler's propagator amplifies by sqrt(1 + h^2) per step: exp(T h / 2) overall.
    assert paper[-1] / true[-1] > 1e3
    half = runs["paper"].t.size // 2
    assert paper[-1] / true[-1] > 10 * paper[half] / true[half]


def test_gamma_off_leaves_no_estimate_and_costs_less():
    pr = load_problem("pendulum")
    sol = solve(pr, atol=1e-6, global_error_estimate="off", method="rk34q8")
    assert sol.gamma is None and sol.z is not None
    assert sol.options["nfev_per_step"] == 17 and sol.stats["njev"] == 0
    assert np.abs(sol.y - pr.exact(sol.t)).max() <= 1.05e-6
    assert "Nothing certified the tolerance: global_error_estimate='off'" in sol.message


def test_a_run_nothing_certified_says_so():
    """QA (2026-11-27): Kepler at e = 0.9, atol 1e-12 over ten periods with
    the estimate off returned SUCCESS 13.8 tolerances off (``rk34q8``), its
    message saying only that it reached the end.  Such a run, and one with
    ``gamma_limit=inf``, says that nothing certified the tolerance."""
    kepler = load_problem("kepler", e=0.9)
    sol = solve(kepler, atol=1e-12, t_span=(0, 20 * np.pi), global_error_estimate="off")
    assert sol.success
    assert np.abs(sol.y - kepler.exact(sol.t)).max() > 2e-12  # what the note is for
    assert "Nothing certified the tolerance" in sol.message
    assert "the promise is yours to check" in sol.message
    unchecked = solve(kepler, atol=1e-8, t_span=(0, 2 * np.pi), gamma_limit=np.inf)
    assert "gamma_limit=inf leaves the quencher's estimated error unchecked" in unchecked.message
    certified = solve(kepler, atol=1e-8, t_span=(0, 2 * np.pi))
    assert "Nothing certified" not in certified.message
    assert "Nothing certified" not in solve(kepler, method="rk34", t_span=(0, 1)).message


@pytest.mark.slow
def test_paper_propagation_understates_on_prentice2011():
    pr = load_problem("prentice2011")
    numeric = numeric_of(pr.hamiltonian)
    runs = {
        mode: solve(
            pr, t_span=(0, 1000), global_error_estimate=mode, gamma_limit=np.inf, method="rk34q8"
        )
        for mode in ("tangent", "paper")
    }
    ref = periodic_reference(numeric.rhs, pr.y0, runs["tangent"].t, pr.parameter_array)
    # Same mesh: the estimate does not feed back into the step sizes.
    np.testing.assert_array_equal(runs["tangent"].t, runs["paper"].t)
    tangent, true = gamma_and_true(runs["tangent"], ref.y)
    paper, _ = gamma_and_true(runs["paper"], ref.y)
    assert 0.5 < tangent[-1] / true[-1] < 2
    assert paper.max() < 0.05 * true.max()
    # The paper's estimate saturates while the true error keeps growing
    # (quadratically in t: a phase error from energy errors).
    half = runs["paper"].t.size // 2
    assert paper[half:].max() < 1.5 * paper[:half].max()
    assert true.max() > 2.5 * true[:half].max()
