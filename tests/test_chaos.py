"""Chaos indicators: maximal Lyapunov exponent and MEGNO on orbits whose
character is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.analysis.chaos import lyapunov, megno
from hamrkq.analysis.energy_surface import energy_orbits
from hamrkq.catalogue.problems import load_problem

pytest.importorskip("numba")  # the interpreted sweep over thousands of nodes is minutes

q, p = sp.symbols("q p", real=True)
W = 1.7
#: A harmonic oscillator of frequency W: the flow is linear and periodic, so
#: |v(t)| stays bounded and oscillates (it is not a pure rotation for W != 1).
OSC = hamrkq.Hamiltonian(p**2 / 2 + W**2 * q**2 / 2, q=[q], p=[p])


def test_harmonic_lyapunov_decays_like_one_over_t_and_megno_to_zero():
    lam = lyapunov(OSC, [1.0], [0.0], (0.0, 400.0), atol=1e-10)
    assert lam.success
    # The exact tangent flow: v(t) = M(t) v0 with |M| <= W (1/W), so
    # log|v| stays within log W of zero at all times: lambda t is bounded.
    assert np.max(np.abs(lam.value[1:] * (lam.t[1:] - lam.t[0]))) < math.log(W) + 1e-6
    assert abs(lam.value[-1]) < math.log(W) / 400.0
    y = megno(OSC, [1.0], [0.0], (0.0, 400.0), atol=1e-10)
    # <Y> of a bounded log|v| decays like 1/t to 0.
    assert abs(y.value[-1]) < 0.02
    assert repr(y) == (
        f"ChaosIndicator(t=400.0, value={y.value[-1]:.6g}, nodes={len(y.t)}, status=SUCCESS)"
    )


def test_the_tangent_map_takes_the_quencher_s_own_steps():
    # On the linear oscillator the tangent map is the flow itself: log|v(t)|
    # is exact.  auto at atol 1e-2 runs rk67q9 with three quencher steps a
    # step; one quencher step over each interval read 1.3e-2 off at t =
    # 2000, the quencher's three 3.2e-7 (found by QA).
    from hamrkq.analysis.chaos import tangent_growth

    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 2000.0), atol=1e-2, method="auto")
    assert sol.options["z_substeps"] > 1
    c, s = math.cos(W * 2000.0), math.sin(W * 2000.0)
    exact = math.log(math.hypot(c + s / W, -W * s + c) / math.sqrt(2.0))  # v0 = (1, 1)/sqrt 2
    for backend in ("python", "numba"):
        assert abs(tangent_growth(sol, OSC, backend=backend).sum() - exact) < 1e-5


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_an_orbit_at_an_equilibrium_has_the_linearised_flows_exponents(backend):
    """At the pendulum's rest point the orbit does not move, its steps grew
    to 694 time units, and the tangent map of such a step read lambda =
    1.57 and <Y> = 78.7 at t = 100 (QA), where the linearised flow is a
    rotation: both are 0.  At the saddle (pi, 0) the exponents are exactly
    -1 and +1 along (1, -1) and (1, 1) (it read -0.575 and 1.0018)."""
    pendulum = load_problem("pendulum")
    run = {"atol": 1e-10, "backend": backend}
    lam = lyapunov(pendulum, [0.0], [0.0], (0.0, 100.0), v0=[1.0, 0.0], **run)
    y = megno(pendulum, [0.0], [0.0], (0.0, 100.0), v0=[1.0, 0.0], **run)
    assert lam.success and y.success
    assert abs(lam.value[-1]) < 1e-10 and abs(y.value[-1]) < 1e-8
    saddle = {"gamma_limit": math.inf, **run}
    stable = lyapunov(pendulum, [math.pi], [0.0], (0.0, 10.0), v0=[1.0, -1.0], **saddle)
    unstable = lyapunov(pendulum, [math.pi], [0.0], (0.0, 20.0), v0=[1.0, 1.0], **saddle)
    assert abs(stable.value[-1] + 1.0) < 1e-8 and abs(unstable.value[-1] - 1.0) < 1e-8


def test_megno_regular_henon_heiles_orbit_tends_to_two():
    hh = load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 8, 5)
    y = megno(hh, q0[2], p0[2], (0.0, 2000.0), atol=1e-10, gamma_limit=math.inf)
    # measured 1.84 (t = 500), 1.92 (1000), 1.96 (2000): 2 - O(1/t)
    assert abs(y.value[-1] - 2.0) < 0.1
    lam = lyapunov(hh, q0[2], p0[2], (0.0, 2000.0), atol=1e-10, gamma_limit=math.inf)
    assert lam.value[-1] < 0.005  # measured 0.0030 and falling like log(t)/t


def test_an_indicator_whose_orbit_stops_says_how_to_run_it_to_the_end():
    # A chaotic orbit's error cannot be certified for long: the default
    # gamma_limit stops the orbit, and with it the indicator.  Its message
    # names the estimate's exponential growth (not "method='auto', which runs
    # again with more quencher steps", which only delays the stop) and the
    # option the docs use for indicators.
    hh = load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 6, 5)
    y = megno(hh, q0[0], p0[0], (0.0, 500.0), atol=1e-8)
    assert y.status is hamrkq.Status.TOLERANCE_UNATTAINABLE and y.t[-1] < 400
    assert "faster than any power of t" in y.message
    assert "method='auto', which" not in y.message  # auto (the default) ran it already
    assert "MEGNO ends with the orbit" in y.message and "gamma_limit=numpy.inf" in y.message


@pytest.mark.slow
def test_megno_grows_linearly_on_a_chaotic_orbit():
    hh = load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 6, 5)
    y = megno(hh, q0[0], p0[0], (0.0, 2000.0), atol=1e-10, gamma_limit=math.inf)
    lam = lyapunov(hh, q0[0], p0[0], (0.0, 2000.0), atol=1e-10, gamma_limit=math.inf)
    # <Y> ~ lambda t / 2: 35.8, 68.0, 128.3 at t = 500, 1000, 2000 (the same orbit in
    # docs/figures/make_events_figures.txt).
    late = y.t > 500
    slope = np.polyfit(y.t[late], y.value[late], 1)[0]
    assert y.value[-1] > 50
    assert 0.25 * lam.value[-1] < slope < 1.0 * lam.value[-1]
    assert lam.value[-1] > 0.05  # 0.133 (docs/figures/make_events_figures.txt)


@pytest.mark.slow
def test_lyapunov_exponent_of_the_henon_heiles_sea_agrees_with_the_published_value():
    """Sprott, Chaos and Time-Series Analysis (2003), Appendix A.6.5: 0.0450
    for the orbit (x, y, px, py) = (0.499, 0, 0, 0.03160676) at E = 1/8.  One
    orbit's finite-time value wanders (on Sprott's orbit 0.0504 at t = 1e5,
    0.0487 at 2.5e5, 0.0459 at 1e6: benchmarks/lyapunov.txt), so the check is
    the median over four orbits of the same chaotic sea to t = 5e4, the first
    four of benchmarks/lyapunov.txt's eight (0.0482, 0.0155, 0.0491, 0.0454:
    0.0468).  The median, not the mean: an orbit that sticks to the islands
    for most of its interval (the second, since the weights sum to 1) has a
    finite-time value far below the sea's and pulls the mean 12 % down."""
    hh = load_problem("henon_heiles")
    x0, py0 = 0.499, 0.03160676
    energy = 0.5 * (x0**2 + py0**2)
    finals = []
    for k in range(4):
        x = x0 - 0.002 * k
        py = math.sqrt(2 * energy - x * x)
        lam = lyapunov(hh, [x, 0.0], [0.0, py], (0.0, 5e4), atol=1e-9, method="auto",
                       gamma_limit=math.inf, max_steps=10**7)  # fmt: skip
        assert lam.success
        finals.append(lam.value[-1])
    assert abs(np.median(finals) / 0.0450 - 1) < 0.10


def test_indicator_of_a_finished_run_needs_every_node():
    from hamrkq.analysis.chaos import indicator_of

    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-10)
    again = megno(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-10)
    assert np.array_equal(indicator_of("megno", sol, OSC).value, again.value)
    thinned = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-10, keep_every=4)
    with pytest.raises(ValueError, match="every node"):
        indicator_of("lyapunov", thinned, OSC)
    with pytest.raises(ValueError, match="kind must be one of"):
        indicator_of("fli", sol, OSC)


def test_a_backward_run_measures_the_time_reversed_orbits_exponent():
    # (q, p, t) -> (q, -p, -t) maps the forward run of a reversible
    # Hamiltonian onto the backward one: the same growth of |v| over the same
    # elapsed time.  The exponent was divided by t - t0 < 0: Henon-Heiles'
    # chaotic orbit read -0.193 backward where it reads +0.193 forward.
    hh = load_problem("henon_heiles")
    energy, q2 = 1 / 6, -0.25
    p1 = math.sqrt(2 * (energy - (q2**2 / 2 - q2**3 / 3)))
    options = {"atol": 1e-12, "gamma_limit": math.inf}
    forward = lyapunov(hh, [0, q2], [-p1, 0], (0, 100), v0=[1, 1, 1, 1], **options)
    backward = lyapunov(hh, [0, q2], [p1, 0], (0, -100), v0=[1, 1, -1, -1], **options)
    assert forward.value[-1] > 0.1  # chaotic: measured 0.193
    assert backward.value[-1] == pytest.approx(forward.value[-1], rel=1e-3)
    y_forward = megno(hh, [0, q2], [-p1, 0], (0, 100), v0=[1, 1, 1, 1], **options)
    y_backward = megno(hh, [0, q2], [p1, 0], (0, -100), v0=[1, 1, -1, -1], **options)
    assert y_backward.value[-1] == pytest.approx(y_forward.value[-1], rel=1e-3)


@pytest.mark.parametrize("v0", [[1.0, 1.0], [1, 0, 0, 0, 9], [0, 0, 0, 0], [1, np.nan, 0, 0]])
def test_a_tangent_direction_of_the_wrong_length_or_zero_is_refused_before_the_run(v0):
    # A short v0 was accepted, the compiled sweep wrote past its end, and
    # the process later aborted (munmap_chunk(): invalid pointer); a long one
    # was cut silently, a zero one gave nan.
    hh = load_problem("henon_heiles")
    for indicator in (lyapunov, megno):
        with pytest.raises(hamrkq.errors.InputError, match="v0 must be"):
            indicator(hh, t_span=(0, 20), v0=v0)


def test_a_method_outside_the_rkq_family_is_refused_before_the_run():
    # verlet's run has no RKQ tableau to step the tangent vector with: it
    # ended in KeyError: 'method' after the whole orbit was integrated.
    with pytest.raises(hamrkq.errors.OptionError, match=r"not an RKQ method.*'rk34q8'"):
        megno(OSC, [1.0], [0.0], (0.0, 20.0), method="verlet", step=0.01)
    from hamrkq.analysis.chaos import indicator_of

    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 2.0), method="verlet", step=0.01)
    with pytest.raises(hamrkq.errors.OptionError, match="the run's method 'verlet'"):
        indicator_of("lyapunov", sol, OSC)


@pytest.mark.parametrize(("method", "before"), [("auto", 2.354), ("rk34q8", 1.607)])
def test_megno_of_a_regular_orbit_is_two_at_a_loose_tolerance_too(method, before):
    # Swept along the reported track y (the pair's steps and the quenches
    # that jump it onto z), MEGNO read `before` on Kepler e = 0.6 at atol
    # 1e-6; along the quencher's own track it reads 1.998, as at 1e-10.
    kepler = load_problem("kepler")
    y = megno(kepler, t_span=(0.0, 2000.0), atol=1e-6, method=method, gamma_limit=math.inf)
    assert abs(y.value[-1] - 2.0) < 0.01
