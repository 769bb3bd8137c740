"""The RKQ step kernel (hamrkq.rkq) on plain NumPy right-hand sides.

Everything here is checked against an exact solution or an independent
computation: the Richardson estimate against the true local error of one RK8
step, the tangent propagation against a finite difference of the step, the
global error estimate Gamma against the true error of the RK8 track, the
evaluation count against the documented formula.
"""

import numpy as np
import pytest

import hamrkq
from hamrkq.catalogue import exact
from hamrkq.methods.tableaus import DOP853_RK8
from hamrkq.rkq import layout, steps
from hamrkq.rkq.config import Settings
from hamrkq.rkq.driver import Integration, python_functions
from hamrkq.rkq.family import get_member
from hamrkq.rkq.layout import DINC, INC


def harmonic_f(t, y, params):
    return np.array([y[1], -y[0]])


def harmonic_j(t, y, params):
    return np.array([[0.0, 1.0], [-1.0, 0.0]])


def pendulum_f(t, y, params):
    return np.array([y[1], -np.sin(y[0])])


def pendulum_j(t, y, params):
    return np.array([[0.0, 1.0], [-np.cos(y[0]), 0.0]])


def inplace(f):
    def g(t, y, params, out):
        out[...] = f(t, y, params)

    return g


def run(
    f,
    J,
    y0,
    t0,
    t_end,
    tol=1e-6,
    rk8=DOP853_RK8,
    budget=2000,
    buffer_rows=4096,
    quench=layout.QUENCH_NODE,
    gamma=layout.GAMMA_TANGENT,
    **options,
):
    """The kernel, interpreted, on ``f`` and ``J`` (RK34Q8, or RK34 with ``rk8=None``)."""
    y0 = np.asarray(y0, float)
    dim = y0.size
    member = get_member("rk34q8" if rk8 is not None else "rk34")
    settings = Settings(quench=quench, rule=layout.RULE_COMPONENTWISE, gamma=gamma, **options)
    integration = Integration(
        python_functions(inplace(f), inplace(J)),
        member,
        np.zeros(0),
        t0,
        y0,
        t_end,
        np.full(dim, tol),
        np.zeros(dim),
        settings,
    )
    with np.errstate(all="ignore"):
        return integration.run(budget=budget, buffer_rows=buffer_rows)


def _work(y):
    member = get_member("rk34q8")
    return member.tableaus, layout.allocate_work(y, 5, 12)


def rk8_step(f, y, h):
    """One DOP853 step by the kernel; returns the new state."""
    tableaus, work = _work(y)
    steps.explicit_increment(
        inplace(f), 0.0, y, np.zeros_like(y), h, tableaus, None, work, work.V[INC], False
    )
    return y + work.V[INC]


def test_richardson_estimates_the_true_local_error_of_one_rk8_step():
    y0 = np.array([0.3, 0.8])
    for h in (0.4, 0.8):
        true = rk8_step(harmonic_f, y0, h) - exact.harmonic(h, y0)[0]
        two_halves = rk8_step(harmonic_f, rk8_step(harmonic_f, y0, h / 2), h / 2)
        estimate = (rk8_step(harmonic_f, y0, h) - two_halves) * 256 / 255
        # The h^10 term of the error is not removed: a few per cent at h = 0.8.
        np.testing.assert_allclose(estimate, true, rtol=0.05 * h)


def test_tangent_propagation_is_the_linearisation_of_the_rk8_step():
    y = np.array([1.1, -0.4])
    v = np.array([0.7, 0.2])
    h = 0.3
    tableaus, work = _work(y)
    functions = python_functions(inplace(pendulum_f), inplace(pendulum_j))
    njev = steps.tangent_increment(
        functions.tangent, 0.0, y, np.zeros(2), h, tableaus, None, work, v
    )
    inc, dinc = work.V[INC], work.V[DINC]
    eps = 1e-5
    central = (rk8_step(pendulum_f, y + eps * v, h) - rk8_step(pendulum_f, y - eps * v, h)) / (
        2 * eps
    )
    assert njev == 12
    np.testing.assert_allclose(y + inc, rk8_step(pendulum_f, y, h), rtol=0, atol=1e-15)
    np.testing.assert_allclose(dinc, central, rtol=1e-8)


@pytest.mark.parametrize("tol", [1e-3, 1e-4])
def test_gamma_tracks_the_true_error_of_the_rk8_track(tol):
    y0 = np.array([0.0, 1.0])
    out = run(pendulum_f, pendulum_j, y0, 0.0, 60.0, tol=tol, gamma_limit=np.inf)
    true = np.linalg.norm(out.z - exact.pendulum(out.t, y0), axis=1)
    estimate = np.linalg.norm(out.gamma, axis=1)
    where = true > 1e-12
    assert where.sum() > 0.3 * out.t.size
    ratio = estimate[where] / true[where]
    assert 0.9 < ratio.min() and ratio.max() < 1.1


def test_reported_solution_within_tolerance_and_g_within_delta():
    y0 = np.array([0.0, 1.0])
    for tol in (1e-5, 1e-8):
        out = run(pendulum_f, pendulum_j, y0, 0.0, 30.0, tol=tol)
        assert out.status == 0
        assert np.abs(out.y - out.z).max() <= tol
        assert np.abs(out.y - exact.pendulum(out.t, y0)).max() <= 1.05 * tol
        assert out.quenched.sum() == out.stats["quenches"] > 0


def test_evaluation_counts_follow_the_documented_formula():
    # Tight tolerance from a large first step forces some rejections.
    out = run(pendulum_f, pendulum_j, [0.0, 1.0], 0.0, 10.0, tol=1e-8, first_step=2.0)
    s = out.stats
    assert s["rejected"] > 0
    nfev, njev = get_member("rk34q8").evaluations_per_step("tangent")
    assert (nfev, njev) == (40, 12)
    # f(t0, y0) serves as the first attempt's k1; a rejected attempt keeps k1.
    assert s["nfev"] == 40 * s["steps"] + 4 * s["rejected"]
    assert s["njev"] == 12 * s["steps"]
    out34 = run(pendulum_f, pendulum_j, [0.0, 1.0], 0.0, 10.0, tol=1e-8, rk8=None)
    s = out34.stats
    # Plus one evaluation for the initial-step heuristic's probe.
    assert s["nfev"] == 1 + 5 * s["steps"] + 4 * s["rejected"]
    assert out34.z is None and s["quenches"] == 0


def test_chunks_and_buffers_do_not_change_the_result():
    y0 = [0.0, 1.0]
    whole = run(pendulum_f, pendulum_j, y0, 0.0, 12.0, tol=1e-6)
    pieces = run(pendulum_f, pendulum_j, y0, 0.0, 12.0, tol=1e-6, budget=7, buffer_rows=3)
    for name in ("t", "y", "z", "gamma", "quenched"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(pieces, name))
    assert whole.stats == pieces.stats


def test_keep_every_keeps_a_subset_of_the_same_nodes():
    y0 = [0.0, 1.0]
    full = run(pendulum_f, pendulum_j, y0, 0.0, 12.0, tol=1e-6)
    thin = run(pendulum_f, pendulum_j, y0, 0.0, 12.0, tol=1e-6, keep_every=10)
    n = full.t.size
    index = np.r_[np.arange(0, n, 10), n - 1] if (n - 1) % 10 else np.arange(0, n, 10)
    np.testing.assert_array_equal(thin.t, full.t[index])
    np.testing.assert_array_equal(thin.y, full.y[index])
    np.testing.assert_array_equal(thin.gamma, full.gamma[index])


def test_t_eval_lands_exactly_on_the_requested_times():
    y0 = np.array([0.0, 1.0])
    times = np.array([0.0, 0.001, 1.0, 2.5, 2.5000001, 7.0, 9.75])
    out = run(pendulum_f, pendulum_j, y0, 0.0, 10.0, tol=1e-7, t_eval=times)
    np.testing.assert_array_equal(out.t, times)
    assert np.abs(out.y - exact.pendulum(times, y0)).max() <= 1.05e-7
    later = run(pendulum_f, pendulum_j, y0, 0.0, 10.0, tol=1e-7, t_eval=times[2:])
    np.testing.assert_array_equal(later.t, times[2:])


def test_t_eval_times_as_dense_as_the_steps_do_not_double_them():
    """A step shortened to land on a t_eval time has a small error; the PI
    controller used to remember it and hold back the next steps' growth, so
    output times spaced like the natural steps took two steps each (the
    harmonic oscillator with as many times as steps: 293 steps for 146;
    the outer solar system with 2001 times over 500 000 days: 4004 for
    1931).  The landing step no longer counts as the controller's memory."""
    import hamrkq

    harmonic = hamrkq.load_problem("harmonic")
    free = hamrkq.solve(harmonic, method="auto", atol=1e-8)
    steps = free.stats["steps"]
    grid = np.linspace(free.t[0], free.t[-1], steps + 1)
    landed = hamrkq.solve(harmonic, method="auto", atol=1e-8, t_eval=grid)
    np.testing.assert_array_equal(landed.t, grid)
    assert landed.stats["steps"] <= 1.2 * steps
    exact_y = harmonic.exact(grid)
    assert np.abs(landed.y - exact_y).max() <= 1.05e-8


def test_compensated_track_beats_plain_summation():
    # Harmonic oscillator, 10 periods at 1e-10: the RK8 truncation error is
    # ~1e-17 per step, so the track's error is its rounding.
    y0 = np.array([0.0, 1.0])
    out = run(harmonic_f, harmonic_j, y0, 0.0, 20 * np.pi, tol=1e-10)
    ts = np.asarray(out.t)
    z_err = np.abs(out.z - exact.harmonic(ts, y0)).max()
    steps = out.stats["steps"]
    # Plain summation would random-walk to ~sqrt(steps) eps; the track stays
    # within a few ulps of the exact rotation.
    assert steps > 9000
    assert z_err < 2e-14 < np.sqrt(steps) * 2.2e-16
    # Node times are the compensated sums of the steps: the last is exact.
    assert out.t[-1] == 20 * np.pi


def test_backward_integration_mirrors_forward():
    y0 = np.array([0.5, 0.0])
    fwd = run(pendulum_f, pendulum_j, y0, 0.0, 8.0, tol=1e-8)
    bwd = run(pendulum_f, pendulum_j, y0, 0.0, -8.0, tol=1e-8)
    assert bwd.t[-1] == -8.0 and np.all(np.diff(bwd.t) < 0)
    # The pendulum is reversible: y(-t) = (q(t), -p(t)) for p0 = 0.
    np.testing.assert_allclose(bwd.t, -fwd.t, rtol=0, atol=1e-13)
    np.testing.assert_allclose(bwd.y, fwd.y * [1, -1], rtol=0, atol=1e-14)
    assert np.abs(bwd.y - exact.pendulum(bwd.t, y0)).max() <= 1.05e-8


def test_finite_time_blow_up_stops_when_the_rk8_track_is_no_longer_exact_enough():
    # y' = y^2, y(0) = 1: y = 1/(1 - t) blows up at t = 1; errors grow like y^2.
    # The run must stop once the RK8 track's own error (Gamma) is no longer
    # small against the tolerance: beyond that the bound cannot be promised.
    f = lambda t, y, p: y**2  # noqa: E731
    J = lambda t, y, p: np.array([[2 * y[0]]])  # noqa: E731
    out = run(f, J, [1.0], 0.0, 2.0, tol=1e-6)
    assert out.status == 5
    assert 0.05 < out.max_ratio < 0.06
    assert out.t[-1] == out.t_last < 1.0
    exact_y = 1 / (1 - out.t)
    # Gamma was right: the track's true error had reached ~5 % of the tolerance.
    z_err = out.z[-1, 0] - exact_y[-1]
    assert 0.8 < out.gamma[-1, 0] / z_err < 1.25 and abs(z_err) > 3e-8
    assert np.abs(out.y[:, 0] - exact_y).max() <= 1.05e-6


def test_non_finite_right_hand_side_ends_with_status_and_keeps_the_nodes():
    # f is nan beyond y = 0.5: steps into it are rejected until the step size
    # underflows; the status says why.
    f = lambda t, y, p: np.where(y < 0.5, 1.0, np.nan)  # noqa: E731
    J = lambda t, y, p: np.zeros((1, 1))  # noqa: E731
    out = run(f, J, [0.0], 0.0, 2.0, tol=1e-6)
    assert out.status == 2
    assert 0.5 - 1e-9 < out.t_last < 0.5 and out.t[-1] == out.t_last
    np.testing.assert_allclose(out.y[:, 0], out.t, rtol=0, atol=1e-15)


def test_max_steps_stops_and_keeps_the_last_node_with_keep_every():
    out = run(pendulum_f, pendulum_j, [0.0, 1.0], 0.0, 100.0, tol=1e-6, max_steps=25, keep_every=7)
    assert out.status == 3
    assert out.stats["steps"] + out.stats["rejected"] == 25
    assert out.t[-1] == out.t_last and out.t.size == 1 + 25 // 7 + 1


def test_tolerance_below_rounding_is_unattainable():
    # delta = 1e-17 is below one ulp of |y| ~ 1: no double can be that close.
    out = run(harmonic_f, harmonic_j, [0.0, 1.0], 0.0, 1.0, tol=1e-17)
    assert out.status == 5
    # The first step would break the promise: only the initial node is kept.
    assert out.max_ratio > 1 and out.t.size == 1


def test_redo_mode_restarts_from_the_track():
    y0 = np.array([0.0, 1.0])
    node = run(pendulum_f, pendulum_j, y0, 0.0, 30.0, tol=1e-6)
    redo = run(pendulum_f, pendulum_j, y0, 0.0, 30.0, tol=1e-6, quench=layout.QUENCH_REDO)
    assert redo.stats["quenches"] > 0
    assert np.abs(redo.y - redo.z).max() <= 1e-6
    assert np.abs(redo.y - exact.pendulum(redo.t, y0)).max() <= 1.05e-6
    # A redo re-uses the cached RK8 step: only the RK3/RK4 stages are repeated.
    s = redo.stats
    assert s["nfev"] == 1 + 40 * s["steps"] + 4 * s["rejected"] + 5 * s["quenches"]
    assert node.stats["nfev"] == 1 + 40 * node.stats["steps"] + 4 * node.stats["rejected"]


def _one_component_at_a_time(base, lo, h, A, A_low, j, K, reverse, compensated):
    """Reference stage values: one component's sum at a time over every
    coefficient, the order of the kernel's first release."""
    out = np.empty(base.shape[0])
    for i in range(out.shape[0]):
        acc, low = 0.0, 0.0
        for k in range(j):
            m = j - 1 - k if reverse else k
            acc += A[j, m] * K[m, i]
            low += A_low[j, m] * K[m, i]
        if compensated:
            out[i] = base[i] + (lo[i] + (acc + low) * h if j else lo[i])
        else:
            out[i] = acc * h + base[i] if j else base[i]
    return out


@pytest.mark.parametrize("compiled", [False, True])
def test_stage_sums_side_by_side_keep_every_bit(compiled):
    """The quencher's stage sums run several components at once and skip
    zero coefficients (arith.stage_value_compensated): each component's sum
    must be the same sequence of roundings as one at a time, bit for bit,
    for every count of components (the blocks of four and two and the last
    one) and both orders of summation; the pair's plain sums
    (arith.stage_value) likewise."""
    from hamrkq.rkq import arith

    compensated, plain = arith.stage_value_compensated, arith.stage_value
    if compiled:
        numba = pytest.importorskip("numba")

        @numba.njit
        def compensated(base, lo, h, A, A_low, j, K, out, reverse):
            arith.stage_value_compensated(base, lo, h, A, A_low, j, K, out, reverse)

        @numba.njit
        def plain(base, h, A, j, K, out):
            arith.stage_value(base, h, A, j, K, out)

    tab = get_member("rk78q12").tableaus  # Feagin 12: 130 zero coefficients of 300
    A, A_low = tab.Az, tab.Az_low
    zeros = np.zeros_like(A)
    rng = np.random.default_rng(7)
    for d in (1, 2, 3, 4, 5, 6, 7, 9, 12):
        K = rng.standard_normal((25, d)) * 10.0 ** rng.integers(-6, 6, (25, d))
        base, lo = rng.standard_normal(d), rng.standard_normal(d) * 1e-17
        h = rng.uniform(0.01, 1.0)
        for j in range(25):
            for reverse in (False, True):
                out = np.empty(d)
                compensated(base, lo, h, A, A_low, j, K, out, reverse)
                expected = _one_component_at_a_time(base, lo, h, A, A_low, j, K, reverse, True)
                assert out.tobytes() == expected.tobytes(), (d, j, reverse)
            plain(base, h, A, j, K, out)
            expected = _one_component_at_a_time(base, lo, h, A, zeros, j, K, False, False)
            assert out.tobytes() == expected.tobytes(), (d, j)


@pytest.mark.parametrize("method", ["rk34", "rk34q8"])
def test_safety_one_does_not_stall_a_rejected_step(method):
    """QA (2026-11-27): with ``safety=1.0`` (the top of its range) a rejected
    step shrank by ``err^(-1/4)``, which tends to 1 as ``err`` falls to 1:
    the RK3(4) pair stalled at Kepler's first pericentre (e = 0.9, atol
    1e-6: 175 steps and 19 825 rejections at t = 6.2638 when max_steps =
    20 000 ran out).  A rejection now shrinks the step by at least 10 %."""
    problem = hamrkq.load_problem("kepler", e=0.9)
    sol = hamrkq.solve(
        problem, method=method, atol=1e-6, t_span=(0.0, 4 * np.pi), safety=1.0, max_steps=20_000
    )
    assert sol.status is hamrkq.Status.SUCCESS
    assert sol.stats["rejected"] < sol.stats["steps"]


@pytest.mark.parametrize(
    "options",
    [{}, {"t_eval": np.linspace(0.0, 100.0, 401)}, {"method": "rk78q12"}, {"method": "rk34q8"}],
    ids=["auto", "t_eval", "rk78q12", "rk34q8"],
)
def test_a_force_pulse_narrower_than_the_steps_never_gives_a_wrong_success(options):
    """A free particle kicked by a narrow force pulse, H = p^2/2 - q
    exp(-((t - 50)/a)^2), a = 1/2, from rest: p is a/2 sqrt(pi) (erf(u) + 1)
    with u = (t - 50)/a, and q its integral.  At atol 1e-4 the pair's steps
    grow to tens of time units before the pulse; a step whose stages sample
    it reads thousands of tolerances and the run stops.  Retrying such a
    step shorter (tried in 89aa82f, reverted) let later steps pass the pulse
    with no stage in it: SUCCESS 4.4e5 tolerances off with output times,
    1.74 with rk78q12.  Whatever the run returns, its nodes keep the
    promise; and with a max_step below the pulse's width it reaches the end."""
    import sympy as sp
    from scipy.special import erf

    q, p, t = sp.symbols("q p t", real=True)
    a = 0.5
    pulse = hamrkq.Hamiltonian(p**2 / 2 - q * sp.exp(-(((t - 50) / sp.Rational(1, 2)) ** 2)),
                               q=[q], p=[p], t=t)  # fmt: skip

    def off(sol):
        u = (sol.t - 50) / a
        momentum = a * np.sqrt(np.pi) / 2 * (erf(u) + 1)
        position = (
            a
            * np.sqrt(np.pi)
            / 2
            * (a * (u * erf(u) + np.exp(-(u**2)) / np.sqrt(np.pi)) - 100 * a + sol.t)
        )
        return max(np.abs(sol.y[:, 0] - position).max(), np.abs(sol.y[:, 1] - momentum).max())

    run = {"q0": [0.0], "p0": [0.0], "t_span": (0.0, 100.0), "atol": 1e-4, "rtol": 0.0}
    sol = hamrkq.solve(pulse, **run, **options)
    assert off(sol) <= 1.05e-4
    bounded = hamrkq.solve(pulse, **run, **options, max_step=0.2)
    assert bounded.status is hamrkq.Status.SUCCESS and off(bounded) <= 1.05e-4
