"""Assumptions declared on a state's symbols hold at every node, not only at t0.

QA's report: ``Symbol("x", positive=True)`` in ``p**2/2 + sqrt(x**2)`` (an
``|x|`` potential) is simplified by SymPy to ``p**2/2 + x``; from x0 = 1 the
run fell through x = 0 and ended at x(4) = -7 with ``SUCCESS``, where the
``|x|`` dynamics bounces back to x(4) = -0.3137.  ``q0 = -1`` was refused
for the same reason (:func:`hamrkq.symbolic.values.bind_state`); now every
run, of every method, ends at the last node before the first that
contradicts a declared assumption, with ``Status.ASSUMPTION_VIOLATED`` and a
message naming the variable, the assumption, the time, the value and the
remedy.
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.errors import HamrkqWarning, InputError
from hamrkq.result import Solution, Status
from hamrkq.symbolic.assumptions import (
    CHECKED_ASSUMPTIONS,
    assumption_conflict,
    declares_checked,
    first_conflict,
    state_conflicts,
)

try:  # a member of an ensemble is the same run as solve alone
    from test_ensemble import _assert_member_equals_solve
except ImportError:  # pragma: no cover - run from another directory
    from tests.test_ensemble import _assert_member_equals_solve

X = sp.Symbol("x", positive=True)
XR = sp.Symbol("x", real=True)
P = sp.Symbol("p", real=True)
#: QA's |x| potential: SymPy makes sqrt(x**2) x under positive=True.
BOUNCE = hamrkq.Hamiltonian(P**2 / 2 + sp.sqrt(X**2), [X], [P])
#: The same H as SymPy simplified it, without the assumption: the run the
#: declared one is, node for node, until x leaves x > 0.
FALLING = hamrkq.Hamiltonian(P**2 / 2 + XR, [XR], [P])
SPAN = (0.0, 4.0)

METHODS = [
    pytest.param({"method": "auto"}, id="auto"),
    pytest.param({"method": "rk34q8", "backend": "python", "max_step": 0.1}, id="rk34q8"),
    pytest.param({"method": "rk34", "backend": "python"}, id="rk34"),
    pytest.param({"method": "verlet", "step": 0.01}, id="verlet"),
    pytest.param({"method": "gauss4", "step": 0.05}, id="gauss4"),
    pytest.param({"method": "scipy:DOP853"}, id="scipy:DOP853"),
    pytest.param({"method": "scipy:RK34Q8"}, id="scipy:RK34Q8"),
]


def test_qa_example_ends_before_x_leaves_its_declared_sign():
    """Before: SUCCESS, x(4) = -7, min x = -7, no warning."""
    sol = hamrkq.solve(BOUNCE, [1.0], [0.0], SPAN)
    assert sol.status is Status.ASSUMPTION_VIOLATED
    assert not sol.success and sol.partial
    assert np.all(sol.q[:, 0] > 0) and sol.t[-1] < np.sqrt(2.0)  # x = 1 - t^2/2 > 0
    message = sol.message
    assert "contradicts the assumption positive=True declared on the symbol x" in message
    assert f"the run ends at the last node before it (t = {float(sol.t[-1])!r})" in message
    assert re.search(r"At t = \S+ the run reached x = -[0-9.e-]+,", message)
    assert "declare its symbol real (Symbol('x', real=True))" in message
    assert (
        "SymPy simplified H under it when the Hamiltonian was built (sqrt(x**2), say, became x)"
        in (message)
    )
    assert "Abs(x)" in message
    assert message.endswith(f"The {len(sol)} nodes computed so far are kept.")
    # The remedy works: the |x| dynamics, x(4) = -0.3137.  Certified, the run
    # ends before the kink at x = 0 (hamrkq.solve.smoothness); without the
    # certificate it goes on, as the message says.
    with pytest.warns(HamrkqWarning, match="not differentiable"):  # at the kink, as said
        remedied = hamrkq.Hamiltonian(P**2 / 2 + sp.Abs(XR), [XR], [P])
    certified = hamrkq.solve(remedied, [1.0], [0.0], SPAN, atol=1e-9)
    assert certified.status is Status.TOLERANCE_UNATTAINABLE
    assert "where H is not smooth (Abs(x))" in certified.message
    assert "gamma_limit=numpy.inf" in message
    sol = hamrkq.solve(remedied, [1.0], [0.0], SPAN, atol=1e-9, gamma_limit=np.inf)
    assert sol.success
    s = 4.0 - np.sqrt(2.0)  # x = -sqrt(2) s + s^2/2 after the kink at t = sqrt(2)
    assert sol.y[-1, 0] == pytest.approx(-np.sqrt(2.0) * s + s**2 / 2, abs=1e-6)


@pytest.mark.parametrize("options", METHODS)
def test_every_method_keeps_the_nodes_before_the_first_breach_bit_for_bit(options):
    """The RKQ family, the fixed-step baselines and SciPy's solvers alike:
    the nodes kept are the first nodes of the same run without the
    assumption, and the next one of that run has x <= 0."""
    sol = hamrkq.solve(BOUNCE, [1.0], [0.0], SPAN, **options)
    free = hamrkq.solve(FALLING, [1.0], [0.0], SPAN, **options)
    assert free.success and free.y[-1, 0] < -6  # what used to come back
    k = len(sol)
    assert sol.status is Status.ASSUMPTION_VIOLATED, sol.message
    assert 1 <= k < len(free) and free.y[k, 0] <= 0 < free.y[k - 1, 0]
    np.testing.assert_array_equal(sol.t, free.t[:k])
    np.testing.assert_array_equal(sol.y, free.y[:k])
    np.testing.assert_array_equal(sol.energy, free.energy[:k])
    for name in ("z", "global_error", "gamma", "quenched"):
        ours, theirs = getattr(sol, name), getattr(free, name)
        assert (ours is None) == (theirs is None), name
        if ours is not None:
            np.testing.assert_array_equal(ours, theirs[:k])
    assert f"At t = {float(free.t[k])!r} the run reached x = {float(free.y[k, 0])!r}" in (
        sol.message
    )


def test_a_momentum_and_a_nonzero_assumption_are_checked_too():
    # p declared negative: H = sqrt(p**2) + x**2/2 became -p + x**2/2, so
    # dx/dt = -1 and dp/dt = -x: p = -1 + t^2/2... reaches 0 at t = sqrt(2).
    x = sp.Symbol("x", real=True)
    p = sp.Symbol("p", negative=True)
    ham = hamrkq.Hamiltonian(sp.sqrt(p**2) + x**2 / 2, [x], [p])
    assert ham.H == -p + x**2 / 2
    sol = hamrkq.solve(ham, [0.0], [-1.0], (0, 3), backend="python", max_step=0.05)
    assert sol.status is Status.ASSUMPTION_VIOLATED
    assert np.all(sol.p < 0) and "declared on the symbol p" in sol.message
    assert "negative=True" in sol.message and "(sqrt(p**2), say, became -p)" in sol.message
    # nonzero: a zero value is the breach, either sign is allowed
    y = sp.Symbol("y", nonzero=True)
    assert first_conflict([y], np.array([[-1.0], [2.0], [0.0], [3.0]])) == (2, 0, "nonzero", True)


def test_t_eval_runs_end_at_the_last_output_time_before_the_breach():
    t_eval = np.linspace(0.0, 4.0, 41)
    sol = hamrkq.solve(BOUNCE, [1.0], [0.0], SPAN, t_eval=t_eval, backend="python")
    assert sol.status is Status.ASSUMPTION_VIOLATED
    # x = 1 - t^2/2: positive up to t = 1.4, negative from 1.5
    np.testing.assert_array_equal(sol.t, t_eval[:15])
    assert "At t = 1.5 the run reached x = " in sol.message


def test_events_and_dense_output_end_with_the_nodes_kept():
    events = ["x - 0.5", "p + 1.45"]  # x = 0.5 at t = 1; p = -1.45 at t = 1.45 > sqrt(2)
    sol = hamrkq.solve(
        BOUNCE, [1.0], [0.0], SPAN, events=events, dense_output=True, max_step=0.1,
        backend="python",
    )  # fmt: skip
    assert sol.status is Status.ASSUMPTION_VIOLATED
    assert sol.t_events[0] == pytest.approx([1.0], abs=1e-6)
    assert sol.t_events[1].size == 0  # after the breach: not reported
    assert sol.sol.t[-1] == sol.t[-1]  # the dense output ends with the nodes
    np.testing.assert_array_equal(sol.sol(sol.t[-1]), sol.y[-1])
    # A terminal event before the breach still ends the run, as before.
    terminal = {"expression": "x - 0.5", "terminal": True}
    sol = hamrkq.solve(BOUNCE, [1.0], [0.0], SPAN, events=terminal, max_step=0.1)
    assert sol.status is Status.TERMINAL_EVENT
    assert sol.t[-1] == pytest.approx(1.0, abs=1e-6) and np.all(sol.q > 0.5 - 1e-9)


def test_an_interrupted_run_stays_interrupted_its_nodes_cut_at_the_breach():
    """An ensemble stops on INTERRUPTED, so that status is kept; the nodes
    after the breach still go, and the message says both."""
    x = sp.Symbol("x", positive=True)
    ham = hamrkq.Hamiltonian(P**2 / 2 + x**2 / 2, [x], [P])  # x = cos t: x < 0 from pi/2

    def stop(fraction, t):
        if t > 3.0:
            raise KeyboardInterrupt

    sol = hamrkq.solve(
        ham, [1.0], [0.0], (0, 1000), method="rk34", backend="python", max_step=1e-3,
        progress=stop,
    )  # fmt: skip
    assert sol.status is Status.INTERRUPTED
    assert np.all(sol.q > 0) and sol.t[-1] < np.pi / 2
    assert sol.message.startswith("Interrupted (KeyboardInterrupt) near t = ")
    assert "contradicts the assumption positive=True" in sol.message


def test_the_status_saves_and_loads(tmp_path):
    sol = hamrkq.solve(BOUNCE, [1.0], [0.0], SPAN, method="verlet", step=0.01)
    back = Solution.load(sol.save(tmp_path / "bounce"))
    assert back.status is Status.ASSUMPTION_VIOLATED and back.message == sol.message
    assert Status.ASSUMPTION_VIOLATED.code == 10 and not Status.ASSUMPTION_VIOLATED.success


def test_ensemble_members_solved_alone_equal_solve():
    """Members run by solve (here the interpreted backend) end as solve alone does."""
    ens = hamrkq.ensemble(
        BOUNCE, q0=[[1.0], [2.0], [50.0]], p0=[[0.0], [0.0], [0.0]], t_span=SPAN,
        backend="python", workers=1, progress=False,
    )  # fmt: skip
    codes = Status.ASSUMPTION_VIOLATED.code, Status.ASSUMPTION_VIOLATED.code, 0
    assert ens.status.tolist() == list(codes)
    for i in range(3):
        _assert_member_equals_solve(ens, i, BOUNCE, t_span=SPAN, backend="python")


def test_ensemble_members_in_the_batch_loop_equal_solve():
    ens = hamrkq.ensemble(
        BOUNCE, q0=[[1.0], [50.0]], p0=[[0.0], [0.0]], t_span=SPAN, workers=1, progress=False
    )
    for i in range(2):
        _assert_member_equals_solve(ens, i, BOUNCE, t_span=SPAN)


# -- the check itself: hamrkq.symbolic.values ------------------------------------------


def test_the_message_names_the_assumption_as_it_was_declared():
    """Before: "c is declared negative=False" for Symbol("c", nonnegative=True)."""
    c = sp.Symbol("c", nonnegative=True)
    assert assumption_conflict(c, -1.0).startswith(
        "c is declared nonnegative=True but is given the value -1.0;"
    )
    assert assumption_conflict(c, 0.0) is None
    n = sp.Symbol("n", odd=True)
    assert assumption_conflict(n, 2.0).startswith("n is declared odd=True")
    assert assumption_conflict(sp.Symbol("q", positive=False), 1.0).startswith(
        "q is declared positive=False"
    )
    assert assumption_conflict(sp.Symbol("q", real=True), -1.0) is None


VALUES = [0.0, 1.0, -1.0, 2.0, -2.0, 3.0, 4.0, -4.0, 0.5, -1.5, 9.0, 97.0, 91.0, 1e300, -1e300,
          5e-324, 2.0**53 + 2]  # fmt: skip


@pytest.mark.parametrize("name", CHECKED_ASSUMPTIONS)
def test_each_checked_assumption_decides_as_sympy_does(name):
    """The vectorised check of a run and the check of one value read one
    table; it agrees with SymPy's own answer for the exact rational."""
    symbol = sp.Symbol("s", **{name: True})
    bad = state_conflicts([symbol], np.array(VALUES)[:, None])
    for value, flagged in zip(VALUES, bad, strict=True):
        holds = getattr(sp.Rational(*value.as_integer_ratio()), f"is_{name}")
        assert flagged == (not holds), (name, value)
        assert (assumption_conflict(symbol, value) is not None) == (not holds), (name, value)


def test_first_conflict_is_the_earliest_node_then_the_first_column():
    a, b = sp.Symbol("a", positive=True), sp.Symbol("b", nonpositive=True)
    y = np.array([[1.0, 0.0], [1.0, 0.5], [-1.0, 1.0], [np.nan, 0.0]])
    assert first_conflict([a, b], y) == (1, 1, "nonpositive", True)
    assert first_conflict([a, sp.Symbol("b")], y) == (2, 0, "positive", True)
    assert first_conflict([a, b], y[:1]) is None
    assert first_conflict([sp.Symbol("a"), sp.Symbol("b", real=True)], y) is None
    assert declares_checked([sp.Symbol("a"), b]) and not declares_checked([P, sp.Symbol("a")])
    # NaN is never a breach: a non-finite state has its own status
    assert not state_conflicts([a], np.array([[np.nan], [np.inf]])).any()


def test_the_check_costs_microseconds_on_a_run_of_1e5_nodes():
    """One comparison per column that declares a sign (about 0.1 ms for
    1e5 nodes): far below H at the nodes.  A bound a per-node Python or
    SymPy loop would exceed many times over."""
    y = np.random.default_rng(1).uniform(0.1, 2.0, (100_000, 4))
    symbols = [X, sp.Symbol("y", nonnegative=True), P, sp.Symbol("py")]
    first_conflict(symbols, y)  # the symbols' assumptions read once
    started = time.perf_counter()
    for _ in range(10):
        assert first_conflict(symbols, y) is None
    assert (time.perf_counter() - started) / 10 < 0.01


def test_the_time_span_meets_the_time_symbols_assumptions():
    """A positive=True time symbol in sqrt(t**2), made t by SymPy, was never
    checked: from t0 = -2 the run integrated q'' = -q - t for the written
    q'' = -q + t and returned SUCCESS (found by QA)."""
    q, p = sp.symbols("q p", real=True)
    t = sp.Symbol("t", positive=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + q * sp.sqrt(t**2), q=[q], p=[p], t=t)
    for span in ((-2.0, -1.0), (1.0, -1.0)):
        with pytest.raises(InputError, match=r"t_span\[\d\]: t is declared positive=True"):
            hamrkq.solve(ham, q0=[0.0], p0=[0.0], t_span=span)
    assert hamrkq.solve(ham, q0=[0.0], p0=[0.0], t_span=(1.0, 2.0)).success
    nonzero = sp.Symbol("t", nonzero=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + q / nonzero, q=[q], p=[p], t=nonzero)
    with pytest.raises(InputError, match="passes t = 0"):
        hamrkq.solve(ham, q0=[0.0], p0=[0.0], t_span=(-1.0, 1.0))


def test_an_h_whose_equations_ignore_t_is_autonomous_for_the_witness():
    """H = (p^2 + q^2)/2 + cos(t): the equations do not depend on t, yet the
    time-rounding rule ran the witness (nfev 8833 for 5633) and refused
    double-double (found by QA)."""
    q, p, t = sp.symbols("q p t", real=True)
    shifted = hamrkq.Hamiltonian((p**2 + q**2) / 2 + sp.cos(t), q=[q], p=[p], t=t)
    plain = hamrkq.Hamiltonian((p**2 + q**2) / 2, q=[q], p=[p])
    assert shifted.time_dependent and not shifted.equations_time_dependent
    span = {"q0": [1.0], "p0": [0.0], "t_span": (1e8, 1e8 + 20.0), "atol": 1e-9}
    a, b = hamrkq.solve(shifted, **span), hamrkq.solve(plain, **span)
    assert a.options["rounding_witness"] == b.options["rounding_witness"]
    assert a.nfev == b.nfev
    assert hamrkq.solve(shifted, **span, quencher_precision="double-double").success
