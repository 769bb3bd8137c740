"""hamrkq.ensemble on this machine: every member equals the same member solved
alone (bit for bit), members that fail are marked and never stop the others,
parameters bind by name, the request is validated before any member runs."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.catalogue import exact
from hamrkq.errors import HamrkqWarning, InputError, InputTypeError, OptionError
from hamrkq.result import Status

q, p, w = sp.symbols("q p w")
OSCILLATOR = hamrkq.Hamiltonian(p**2 / 2 + w**2 * q**2 / 2, q=[q], p=[p], parameters={w: 1.0})
#: Attractive 1/q potential: from rest at q = 1 the fall reaches q = 0 at
#: t = pi/(2 sqrt 2) ~ 1.11; with p0 > sqrt(2) the orbit escapes instead.
FALL = hamrkq.Hamiltonian(p**2 / 2 - 1 / q, q=[q], p=[p])


def _assert_member_equals_solve(ens, i, system, **kwargs):
    n = ens.n
    sol = hamrkq.solve(system, q0=ens.y0[i, :n], p0=ens.y0[i, n:], **kwargs)
    assert ens.member_status(i) is sol.status
    assert ens.t_last[i] == sol.t[-1]
    for name in ("steps", "rejected", "quenches", "nfev", "njev"):
        assert ens.stats[name][i] == sol.stats.get(name, 0), name
    if ens.t.size == 1 and kwargs.get("t_eval") is None:
        np.testing.assert_array_equal(ens.y[i, 0], sol.y[-1])
    else:
        np.testing.assert_array_equal(ens.y[i, : sol.t.size], sol.y)
    if sol.global_error is None:  # a pair without a quencher
        assert np.isnan(ens.max_global_error[i])
    else:
        assert ens.max_global_error[i] == np.abs(sol.global_error).max()
    if sol.t[0] == sol.options["t_span"][0]:
        assert ens.energy0[i] == sol.energy[0]
    assert ens.energy_drift[i] == np.abs(sol.energy - ens.energy0[i]).max()
    return sol


def test_1000_pendulum_members_equal_solve_alone_bitwise():
    pend = hamrkq.load_problem("pendulum")
    rng = np.random.default_rng(7)
    q0 = rng.uniform(-3.0, 3.0, (1000, 1))
    p0 = rng.uniform(-2.0, 2.0, (1000, 1))
    ens = hamrkq.ensemble(pend, q0=q0, p0=p0, t_span=(0, 3), workers=2, progress=False)
    assert ens.y.shape == (1000, 1, 2) and ens.t.tolist() == [3.0]
    assert ens.all_success and ens.success.all()
    np.testing.assert_array_equal(ens.y0, np.hstack([q0, p0]))
    for i in range(1000):
        sol = _assert_member_equals_solve(ens, i, pend, t_span=(0, 3))
        assert ens.energy0[i] == sol.energy[0]
        assert ens.energy_drift[i] == np.abs(sol.energy - sol.energy[0]).max()
    # And the numbers are right: energy is conserved to the tolerance's order
    # (atol 1e-8 from the problem file), and the error estimate is honest
    # against the RK8 track (|y - z| within the tolerance).
    assert ens.energy_drift.max() < 1e-7
    assert ens.max_global_error.max() <= 1.05e-8


def test_t_eval_keeps_every_member_at_those_times_and_matches_the_exact_solution():
    t_eval = np.linspace(0.0, 10.0, 11)
    y0 = np.array([[0.5, 0.0], [0.0, 1.0], [-1.0, 0.25]])
    ens = hamrkq.ensemble(
        hamrkq.load_problem("harmonic"), q0=y0[:, :1], p0=y0[:, 1:], t_span=(0, 10),
        t_eval=t_eval, atol=1e-9, workers=1,
    )  # fmt: skip
    assert ens.y.shape == (3, 11, 2)
    np.testing.assert_array_equal(ens.t, t_eval)
    for i in range(3):
        assert np.abs(ens.y[i] - exact.harmonic(t_eval, y0[i])).max() <= 1.05e-9
        _assert_member_equals_solve(
            ens, i, hamrkq.load_problem("harmonic"), t_span=(0, 10), t_eval=t_eval, atol=1e-9
        )


def test_parameters_per_member_by_name_against_the_exact_solution():
    # q(t) = q0 cos(w t): one member per frequency, bound by name.
    freqs = np.array([0.5, 1.0, 2.0, 3.0])
    ens = hamrkq.ensemble(
        OSCILLATOR, q0=[1.0], p0=[0.0], t_span=(0, 5), parameters={"w": freqs}, atol=1e-9,
        workers=2, scheduler="threads",
    )  # fmt: skip
    np.testing.assert_array_equal(ens.parameters["w"], freqs)
    np.testing.assert_allclose(ens.q[:, 0, 0], np.cos(5 * freqs), atol=2e-9, rtol=0)
    for i, value in enumerate(freqs):
        sol = hamrkq.solve(OSCILLATOR, [1.0], [0.0], (0, 5), parameters={w: value}, atol=1e-9)
        np.testing.assert_array_equal(ens.y[i, 0], sol.y[-1])


def test_a_problem_s_initial_values_follow_each_member_s_parameters():
    kepler = hamrkq.load_problem("kepler")
    ens = hamrkq.ensemble(
        kepler, t_span=(0, 2), parameters={"e": [0.1, 0.5, 0.1]}, workers=1, progress=False
    )
    for i, e in enumerate([0.1, 0.5, 0.1]):
        moved = kepler.with_parameters(e=e)
        np.testing.assert_array_equal(ens.y0[i], moved.y0)
        # Kepler's exact solution for that eccentricity, at the problem's tolerance.
        assert np.abs(ens.y[i, 0] - moved.exact(np.array([2.0]))[0]).max() < 1e-5


def test_a_member_that_fails_is_marked_and_never_stops_the_others():
    p0 = np.array([0.0, 2.0, 0.1, 3.0])  # 0 and 0.1 fall into q = 0; 2 and 3 escape
    ens = hamrkq.ensemble(
        FALL, q0=[1.0], p0=p0[:, None], t_span=(0, 2), atol=1e-8, workers=2, chunk_size=1,
        scheduler="threads",
    )  # fmt: skip
    assert ens.success.tolist() == [False, True, False, True]
    assert ens.failed.tolist() == [0, 2] and not ens.all_success
    for i in range(4):
        sol = _assert_member_equals_solve(ens, i, FALL, t_span=(0, 2), atol=1e-8)
        if not sol.success:
            assert ens.message(i) == sol.message
        else:
            assert ens.message(i) == "The integration reached the end of the interval (t = 2.0)."
    # The fall from rest reaches q = 0 at pi / (2 sqrt 2): the failure is there.
    assert ens.t_last[0] == pytest.approx(np.pi / (2 * np.sqrt(2)), abs=1e-3)
    assert ens.member_status(0) is not Status.SUCCESS and "t = " in ens.message(0)
    # Escaping members conserve energy: H = p0**2/2 - 1.
    h = ens.p[[1, 3], 0, 0] ** 2 / 2 - 1 / ens.q[[1, 3], 0, 0]
    np.testing.assert_allclose(h, p0[[1, 3]] ** 2 / 2 - 1, atol=1e-7, rtol=0)


def test_threads_processes_and_serial_give_the_same_bits():
    pend = hamrkq.load_problem("pendulum")
    q0 = np.linspace(-3, 3, 24)[:, None]
    runs = [
        hamrkq.ensemble(pend, q0=q0, p0=[0.3], t_span=(0, 2), scheduler=s, workers=2)
        for s in ("serial", "threads", "processes")
    ]
    for other in runs[1:]:
        np.testing.assert_array_equal(other.y, runs[0].y)
        np.testing.assert_array_equal(other.stats["nfev"], runs[0].stats["nfev"])


def test_progress_callable_sees_every_member_once():
    calls = []
    ens = hamrkq.ensemble(
        hamrkq.load_problem("pendulum"), q0=np.linspace(0, 1, 10)[:, None], p0=[0.0],
        t_span=(0, 1), workers=1, chunk_size=3, progress=lambda *args: calls.append(args),
    )  # fmt: skip
    assert calls == [(3, 10), (6, 10), (9, 10), (10, 10)] and len(ens) == 10


def test_names_bind_q0_and_p0_by_name_and_the_rest_comes_from_the_problem():
    hh = hamrkq.load_problem("henon_heiles")
    ens = hamrkq.ensemble(hh, q0={"q1": [0.0, 0.1]}, t_span=(0, 1), workers=1)
    np.testing.assert_array_equal(ens.y0, [[0.0, 0.18, 0.18, 0.18], [0.1, 0.18, 0.18, 0.18]])
    assert ens.names == ("q1", "q2", "p1", "p2")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"q0": np.zeros((3, 1)), "p0": np.zeros((4, 1))}, InputError, "q: 3, p: 4"),
        (
            {"q0": [[0.0], [np.nan]]},
            InputError,
            r"initial value q of member 1 is not finite \(nan\)",
        ),
        ({"q0": np.zeros((2, 2))}, InputError, r"shape \(1,\) or \(M, 1\)"),
        ({"q0": "0.5"}, InputTypeError, "string"),
        ({"parameters": {"zeta": [1.0]}}, InputError, "unknown parameter zeta"),
        ({"parameters": [1.0]}, InputTypeError, "mapping"),
        ({"keep_every": 2}, OptionError, "keep_every"),
        ({"atol": -1.0}, InputError, "atol"),
        ({"method": "rk99"}, OptionError, "rk99"),
        ({"t_eval": [0.5, 0.2]}, InputError, "monotonic"),
        ({"t_eval": [0.5, 7.0]}, InputError, "within t_span"),
        ({"workers": 0}, InputError, "workers"),
        ({"scheduler": "gpu"}, OptionError, "scheduler='gpu'"),
        ({"chunk_size": 0}, OptionError, "chunk_size"),
        ({"progress": "yes"}, InputTypeError, "progress"),
        ({"dense_output": True}, OptionError, "a continuous solution would be thrown away"),
        ({"events": ["q"]}, OptionError, "events 'q' do not end their member"),
    ],
)
def test_bad_requests_fail_before_any_member_runs(kwargs, error, match):
    base = {"q0": [[0.1], [0.2]], "p0": [0.0], "t_span": (0, 1), "workers": 1}
    with pytest.raises(error, match=match):
        hamrkq.ensemble(hamrkq.load_problem("pendulum"), **{**base, **kwargs})


def test_a_terminal_event_ends_each_member_where_solve_alone_ends_it():
    # q = q0 cos t: q + 0.05 falls through zero (down) a little after t = pi/2.
    event = {"expression": "q + 0.05", "terminal": True, "direction": -1}
    starts = [0.1, 0.2, 0.3]
    ens = hamrkq.ensemble(OSCILLATOR, q0=[[x] for x in starts], p0=[0.0], t_span=(0, 10),
                          atol=1e-12, events=[event], workers=1)  # fmt: skip
    for i, x in enumerate(starts):
        alone = hamrkq.solve(OSCILLATOR, q0=[x], p0=[0.0], t_span=(0, 10), atol=1e-12,
                             events=[event])  # fmt: skip
        assert ens.member_status(i) is Status.TERMINAL_EVENT is alone.status
        assert ens.t_last[i] == alone.t[-1] and np.array_equal(ens.y[i, -1], alone.y[-1])
        assert ens.t_last[i] == pytest.approx(np.arccos(-0.05 / x), abs=1e-10)


@pytest.mark.parametrize("span", [(0.0, 10.0), (0.0, -10.0)])
def test_with_t_eval_t_last_is_the_terminal_events_time(span):
    # QA: t_last was the last output time before the event (0.0 where the
    # event was at t = 1.43): the time reached is the event's.
    event = {"expression": "q + 0.05", "terminal": True}
    starts = [0.1, 0.3]
    grid = np.linspace(*span, 5)  # 0, +-2.5, ...: the event comes before the second
    ens = hamrkq.ensemble(OSCILLATOR, q0=[[x] for x in starts], p0=[0.0], t_span=span,
                          t_eval=grid, atol=1e-12, events=[event], workers=1)  # fmt: skip
    for i, x in enumerate(starts):
        assert ens.member_status(i) is Status.TERMINAL_EVENT
        # q = x cos t: q = -0.05 at |t| = arccos(-0.05 / x)
        assert abs(ens.t_last[i]) == pytest.approx(np.arccos(-0.05 / x), abs=1e-10)
        assert np.isnan(ens.y[i, 1:]).all() and ens.y[i, 0, 0] == x


EVENT_FILE = """name = "oscillator_events"
coordinates = ["q"]
momenta = ["p"]
hamiltonian = "p**2/2 + q**2/2"
[initial]
q = 1
p = 0
[integration]
t_span = [0, 7]
[[events]]
expression = "q"
terminal = true
[[events]]
expression = "p"
"""


def test_a_problem_files_terminal_events_end_the_members_as_in_solve(tmp_path):
    # QA: the file's [[events]] were ignored: every member SUCCESS at t = 7,
    # where solve of the same member ends TERMINAL_EVENT at t = pi/2.
    path = tmp_path / "oscillator_events.toml"
    path.write_text(EVENT_FILE)
    problem = hamrkq.load_problem(path)
    starts = [[0.5], [1.0], [1.5]]
    with pytest.warns(HamrkqWarning, match=r"'p'\) are not located"):
        ens = hamrkq.ensemble(problem, q0=starts, workers=1)
    for i, start in enumerate(starts):
        alone = hamrkq.solve(problem, q0=start)  # locates p too, and stops at q = 0
        assert ens.member_status(i) is Status.TERMINAL_EVENT is alone.status
        assert ens.t_last[i] == alone.t[-1] == pytest.approx(np.pi / 2, abs=1e-9)
        np.testing.assert_array_equal(ens.y[i, 0], alone.y[-1])
    assert ens.options["events"] == [{"label": "q", "terminal": 1, "direction": 0.0}]
    assert "'p'" in ens.options["events_not_located"]
    saved = ens.save(tmp_path / "ensemble.npz")
    assert hamrkq.EnsembleSolution.load(saved).options == ens.options
    # events=[] runs without the file's events, and without the warning
    ens = hamrkq.ensemble(problem, q0=starts, events=[], workers=1)
    assert ens.all_success and np.all(ens.t_last == 7.0)


def test_an_ensemble_with_a_callable_event_saves(tmp_path):
    # QA (found while fixing the above): TypeError, a function is not JSON
    def crossing(t, y):
        return y[0] + 0.05

    crossing.terminal = True
    ens = hamrkq.ensemble(OSCILLATOR, q0=[[0.1], [0.2]], p0=[0.0], t_span=(0, 10),
                          events=[crossing], workers=1)  # fmt: skip
    loaded = hamrkq.EnsembleSolution.load(ens.save(tmp_path / "ens.npz"))
    assert loaded.options["events"] == [{"label": "crossing", "terminal": 1, "direction": 0.0}]
    np.testing.assert_array_equal(loaded.t_last, ens.t_last)


def test_a_hamiltonian_needs_initial_values_and_span():
    with pytest.raises(InputError, match="p0, t_span must be given"):
        hamrkq.ensemble(FALL, q0=[1.0])
    with pytest.raises(InputTypeError, match=r"Hamiltonian or a hamrkq\.Problem"):
        hamrkq.ensemble("pendulum", q0=[1.0], p0=[0.0], t_span=(0, 1))


def test_an_empty_ensemble_is_empty():
    ens = hamrkq.ensemble(FALL, q0=np.zeros((0, 1)), p0=[0.0], t_span=(0, 1))
    assert len(ens) == 0 and ens.y.shape == (0, 1, 2) and ens.all_success


def test_threads_in_a_fresh_process_do_not_race_to_compile(tmp_path):
    # Each thread's first solve used to prepare (compile or load) the kernel's
    # signature for t_eval itself; two at once made numba raise "compilation
    # disabled".  The request's probe now prepares it once, before the pool.
    import subprocess
    import sys

    script = (
        "import numpy as np, hamrkq\n"
        "ens = hamrkq.ensemble(hamrkq.load_problem('henon_heiles'), q0=np.full((8, 2), 0.1),\n"
        "    t_span=(0, 2), t_eval=[1.0, 2.0], workers=2, scheduler='threads', chunk_size=1)\n"
        "print(len(ens), ens.failed.size)\n"
    )
    for _ in range(3):
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-2000:]
        assert done.stdout.split() == ["8", "0"]


def test_ctrl_c_inside_a_member_stops_the_whole_ensemble(monkeypatch):
    # solve turns Ctrl-C into Status.INTERRUPTED for its own run; an ensemble
    # run member by member (the interpreted backend) must not carry on with
    # the next member as if nothing happened.  It returns what it has, as
    # solve does: the chunks finished (here one member each), the other
    # members INTERRUPTED (it raised KeyboardInterrupt, and hamrkq ensemble
    # wrote nothing).
    from hamrkq.ensemble import chunk, request

    real, calls = request.solve, []

    def solve(*args, **kwargs):
        sol = real(*args, **kwargs)
        calls.append(1)
        return sol.replace(status=Status.INTERRUPTED) if len(calls) == 3 else sol

    monkeypatch.setattr(request, "solve", solve)
    monkeypatch.setattr(chunk, "solve", solve)
    ens = hamrkq.ensemble(FALL, q0=[1.0], p0=np.linspace(2, 3, 6)[:, None], t_span=(0, 1),
                          workers=1, backend="python")  # fmt: skip
    assert len(calls) == 3  # the probe, members 0 and 1; members 2..5 never ran
    assert ens.status.tolist() == [Status.SUCCESS.code] + [Status.INTERRUPTED.code] * 5
    assert ens.failed.tolist() == [1, 2, 3, 4, 5] and not ens.all_success
    assert np.isnan(ens.y[1:]).all() and np.isfinite(ens.y[0]).all()


def test_compiled_rkq_members_run_in_the_batch_loop_and_the_rest_member_by_member(monkeypatch):
    """The batch loop is what runs an RKQ ensemble on the compiled backend
    (solve_members is never called), with the bits of solve alone, also for
    method="auto" and for members whose y0 decides an option differently
    (they run as batched groups); the interpreted backend and a baseline
    method run member by member."""
    from hamrkq.ensemble import chunk

    real, used = chunk.solve_members, []

    def solve_members(request):
        used.append(request.size)
        return real(request)

    monkeypatch.setattr(chunk, "solve_members", solve_members)
    pend = hamrkq.load_problem("pendulum")
    q0 = np.linspace(-2.5, 2.5, 7)[:, None]
    t_eval = np.linspace(0.0, 4.0, 5)
    for method in ("rk34q8", "rk78q12", "rk34", "auto"):
        ens = hamrkq.ensemble(pend, q0=q0, p0=[[0.5]], t_span=(0, 4), t_eval=t_eval,
                              method=method, workers=1)  # fmt: skip
        assert used == [] and ens.all_success
        for i in range(q0.shape[0]):
            _assert_member_equals_solve(ens, i, pend, t_span=(0, 4), t_eval=t_eval, method=method)
    oscillator = hamrkq.Hamiltonian((p**2 + q**2) / 2, q=[q], p=[p])
    for system, how in (
        (pend, {"backend": "python"}),
        (oscillator, {"method": "verlet", "step": 0.01}),
    ):
        used.clear()
        hamrkq.ensemble(system, q0=q0[:2], p0=[[0.5]], t_span=(0, 0.5), workers=1, **how)
        assert sum(used) == 2, how
    # Where y0 decides an option, the chunk runs as groups that agree, each
    # batched.  The rounding witness: the tightest tolerance max(1e-12,
    # 1e-9 |y|) is 2e-9 at p = 2 (no witness) and 1e-12 at p = 0 (the
    # witness).  auto's member: atol 2e-7 reads as 2e-7 / max(1, |y0|),
    # loose (rk67q9) at |y0| <= 2 and tight (rk78q12) above.
    from hamrkq.ensemble.request import build_request

    cases = (
        ({"method": "auto", "rtol": 1e-9, "atol": 1e-12}, [[2.0], [1.0], [2.0]], [3]),
        ({"method": "auto", "rtol": 1e-9, "atol": 1e-12}, [[2.0], [0.0], [2.0]], [2, 1]),
        ({"method": "auto", "rtol": 0.0, "atol": 2e-7}, [[1.0], [3.0], [1.5]], [2, 1]),
    )
    for auto, p0, sizes in cases:
        used.clear()
        request = build_request(pend, [[2.0]], p0, (0, 0.5), None, None, auto)
        assert sorted(map(len, chunk.batch_groups(request)), reverse=True) == sizes
        ens = hamrkq.ensemble(pend, q0=[[2.0]], p0=p0, t_span=(0, 0.5), workers=1,
                              chunk_size=3, **auto)  # fmt: skip
        assert used == [] and ens.all_success
        methods = set()
        for i in range(3):
            sol = _assert_member_equals_solve(ens, i, pend, t_span=(0, 0.5), **auto)
            methods.add(sol.method)
        if auto["atol"] == 2e-7:  # both members of the family ran, each batched
            assert methods == {"rk67q9", "rk78q12"}


def test_members_with_the_rounding_witness_run_in_the_batch_loop(monkeypatch):
    # At 1e-11 auto runs the rounding witness, with the parameters moved by an
    # ulp: the batch loop must move each member's, or the witness of a member
    # runs another oscillator, stops it, and it is solved again alone.
    from hamrkq.ensemble import chunk

    real, alone = chunk.solve, []

    def solve(*args, **kwargs):
        alone.append(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(chunk, "solve", solve)
    freqs = np.tile([0.5, 1.0, 2.0], 8)  # enough members for chunks of several
    kwargs = {"t_span": (0, 20), "method": "auto", "atol": 1e-11, "rtol": 0.0}
    ens = hamrkq.ensemble(
        OSCILLATOR, q0=[1.0], p0=[0.0], parameters={"w": freqs}, workers=1, **kwargs
    )
    assert ens.all_success and alone == []
    for i, value in enumerate(freqs[:3]):
        sol = _assert_member_equals_solve(ens, i, OSCILLATOR, parameters={w: value}, **kwargs)
        assert sol.options["rounding_witness"] is True


def test_members_that_differ_on_the_witness_run_as_batched_groups(monkeypatch):
    # (They ran one solve per member before chunk.batch_groups.)
    from hamrkq.ensemble import chunk

    used = []
    real = chunk.solve_members
    monkeypatch.setattr(chunk, "solve_members", lambda r: used.append(r.size) or real(r))
    # atol 1e-9: the witness runs for |y0| above 3.3 only
    q0 = np.tile([[1.0], [10.0]], (16, 1))
    ens = hamrkq.ensemble(
        OSCILLATOR, q0=q0, p0=[0.0], t_span=(0, 5), method="rk78q12",
        atol=1e-9, rtol=0.0, workers=1,
    )  # fmt: skip
    assert used == [] and ens.all_success
    for i in (0, 1, 30, 31):
        _assert_member_equals_solve(ens, i, OSCILLATOR, t_span=(0, 5), method="rk78q12",
                                    atol=1e-9, rtol=0.0)  # fmt: skip


@pytest.mark.parametrize("t_eval", [True, False])
def test_a_member_whose_estimate_grew_exponentially_is_solved_alone_again(monkeypatch, t_eval):
    # The batch loop returned SUCCESS for these members, where solve alone
    # measures the estimate's growth, runs them again with the rounding
    # witness and stops them (docs/algorithm.md): the ensemble disagreed
    # with its own definition of a member.
    from hamrkq.ensemble import chunk

    real, alone = chunk.solve, []
    monkeypatch.setattr(chunk, "solve", lambda *a, **k: alone.append(k) or real(*a, **k))
    problem = hamrkq.load_problem("arenstorf")
    span = (0.0, 3 * problem.t_span[1])
    kwargs = {"t_span": span, "method": "rk45q12", "atol": 1e-8}
    if t_eval:
        kwargs["t_eval"] = np.linspace(*span, 121)[1:]
    q0 = np.array([problem.q0, problem.q0 * (1 + 1e-9)])
    ens = hamrkq.ensemble(problem, q0=q0, p0=problem.p0, workers=1, **kwargs)
    assert len(alone) == 2
    for i in range(2):
        assert ens.member_status(i) is Status.TOLERANCE_UNATTAINABLE
        sol = _assert_member_equals_solve(ens, i, problem, **kwargs)
        assert sol.options["rounding_witness"]


def test_a_member_whose_shadow_saturated_in_the_batch_loop_is_solved_alone(monkeypatch):
    # rk78q12 with eight quencher steps on a chaotic Henon-Heiles orbit: the
    # batch loop ran it to t = 1000 with SUCCESS; solve alone cuts it where
    # its shadow track passes half the orbit's size and runs it again with
    # the witness (tests/test_family.py).  Eight quencher steps now run the
    # witness from the start, which stops these members in the batch loop
    # (TOLERANCE_UNATTAINABLE), so they are solved alone as failures; members
    # whose shadow saturates in a run that succeeded there:
    # tests/test_ensemble_rules.py (the FPU chain).
    import math

    from hamrkq.ensemble import chunk

    real, alone = chunk.solve, []
    monkeypatch.setattr(chunk, "solve", lambda *a, **k: alone.append(k) or real(*a, **k))
    problem = hamrkq.load_problem("henon_heiles")
    q2 = np.array([-0.25, -0.2501])
    p1 = np.sqrt(2 * (1 / 6 - q2**2 / 2 + q2**3 / 3))
    kwargs = {"t_span": (0.0, 1000.0), "method": "rk78q12", "z_substeps": 8, "atol": 1e-8}
    ens = hamrkq.ensemble(problem, q0=np.column_stack([np.zeros(2), q2]),
                          p0=np.column_stack([p1, np.zeros(2)]), workers=1, **kwargs)  # fmt: skip
    assert len(alone) == 2 and not math.isnan(ens.t_last[0])
    for i in range(2):
        assert ens.member_status(i) is Status.TOLERANCE_UNATTAINABLE
        _assert_member_equals_solve(ens, i, problem, **kwargs)


def test_the_members_bar_is_drawn_on_a_bare_pseudo_terminal(monkeypatch):
    # A pseudo-terminal that reports a size of 0 x 0 (script(1), some CI
    # runners): tqdm drew nothing there, as hamrkq run's bar did before it got
    # a fallback size; the ensemble's bar lacked it.
    import os
    import pty
    import time

    from hamrkq.ensemble.api import _Progress

    master, slave = pty.openpty()
    assert os.get_terminal_size(slave) == (0, 0)
    stream = os.fdopen(slave, "w")
    monkeypatch.setattr("sys.stderr", stream)
    with _Progress(None, 10) as advance:
        advance(4)
        time.sleep(1.2)  # the bar waits a second before it is drawn
        advance(6)
    stream.flush()
    text = os.read(master, 4096).decode()
    stream.close()
    os.close(master)
    assert "10/10" in text and "member" in text


def test_fixed_step_ensemble_of_a_problem_whose_file_sets_tolerances():
    """The pendulum's file sets atol under [integration]: a default, which
    means nothing to verlet.  The ensemble passed it on as a keyword and
    every fixed-step ensemble of such a problem raised OptionError."""
    pend = hamrkq.load_problem("pendulum")
    assert "atol" in pend.integration
    for method, step in (("verlet", 0.1), ("gauss4", 0.2)):
        ens = hamrkq.ensemble(pend, q0=[[0.5], [1.0]], p0=[0.0], t_span=(0, 2),
                              method=method, step=step, progress=False)  # fmt: skip
        assert ens.all_success
        alone = hamrkq.solve(pend, q0=[1.0], p0=[0.0], t_span=(0, 2), method=method, step=step)
        assert np.array_equal(ens.y[1, 0], alone.y[-1])


def test_a_files_settings_for_another_method_apply_where_they_can(tmp_path):
    """A file whose [integration] names gauss4 with its step, or an
    8th-order z_method, runs with any method in solve; ensemble passed the
    file's step and z_method on as keywords and refused auto, rk78q12,
    rk34, verlet and scipy:DOP853 (found by QA)."""
    text = (
        'name = "{name}"\ncoordinates = ["x"]\nmomenta = ["v"]\nhamiltonian = "(v**2 + x**2)/2"\n'
        "[initial]\nx = [1]\nv = [0]\n[integration]\nt_span = [0, 2]\n{settings}\n"
    )
    files = {
        "fixed": 'method = "gauss4"\nstep = 0.05',
        # (with the method it applies to: a file's own method must use its settings)
        "quencher": 'method = "rk34q8"\nz_method = "cooper_verner"',
    }
    for name, settings in files.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(text.format(name=name, settings=settings))
        problem = hamrkq.load_problem(path)
        for method in ("auto", "rk78q12", "rk34", "rk34q8", "scipy:DOP853"):
            ens = hamrkq.ensemble(problem, q0=[[0.5], [1.0]], method=method, progress=False)
            alone = hamrkq.solve(problem, q0=[1.0], method=method)
            assert ens.all_success and np.array_equal(ens.y[1, -1], alone.y[-1]), method
