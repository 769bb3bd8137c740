"""Events (solve(..., events=)): roots located on the dense output, SciPy's
semantics for terminal and direction, catalogue [[events]] and hostile text."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.catalogue.problems import catalogue_dir, load_problem
from hamrkq.errors import ExpressionError, InputError, ProblemFileError
from hamrkq.result import Status

q, p = sp.symbols("q p", real=True)
OSC = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2, q=[q], p=[p])


def test_harmonic_zero_crossings_at_exact_times():
    # q = cos t: zeros at (k + 1/2) pi.
    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-13, events="q")
    times = sol.t_events[0]
    exact = (np.arange(times.size) + 0.5) * math.pi
    assert times.size == 6
    assert np.max(np.abs(times - exact)) < 1e-12  # measured 1.0e-13
    # The state at each event: q = 0 and p = -sin(t) = -+1.
    np.testing.assert_allclose(sol.y_events[0][:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(sol.y_events[0][:, 1], -np.sin(exact), atol=1e-12)
    np.testing.assert_allclose(sol.event_bound[0], 1e-13)


def test_events_survive_save_and_load(tmp_path):
    """Before, Solution.load returned t_events = None: the file kept no events."""
    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-10, events=["q", "p - 2"])
    again = hamrkq.Solution.load(sol.save(tmp_path / "s.npz"))
    assert again.event_labels == sol.event_labels == ("q", "p - 2")
    for name in ("t_events", "y_events", "event_bound"):
        mine, theirs = getattr(sol, name), getattr(again, name)
        assert len(theirs) == len(mine) == 2
        for a, b in zip(mine, theirs, strict=True):
            assert np.array_equal(a, b) and a.shape == b.shape and not b.flags.writeable
    assert again.t_events[1].size == 0  # p never reaches 2: an empty list of roots
    assert again.sol is None  # the dense output is not saved (docstring of save)
    plain = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 1.0))
    assert hamrkq.Solution.load(plain.save(tmp_path / "p.npz")).t_events is None


def test_direction_filters_crossings_like_scipy():
    def g(t, y):
        return y[0]

    g.direction = 1.0  # q increasing through 0: t = 3 pi / 2, 7 pi / 2, ...
    up = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-12, events=[g, "q"])
    np.testing.assert_allclose(up.t_events[0], [1.5 * math.pi, 3.5 * math.pi, 5.5 * math.pi])
    assert up.t_events[1].size == 6
    down = hamrkq.solve(
        OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-12, events={"expression": q, "direction": -1}
    )
    np.testing.assert_allclose(down.t_events[0], [0.5 * math.pi, 2.5 * math.pi, 4.5 * math.pi])


def test_kepler_pericentre_passages_match_the_period():
    # q.p = r dr/dt rises through zero at every pericentre: t = 2 pi k (a = 1),
    # the start (a pericentre, q.p = 0 at t0) not counted.
    problem = load_problem("kepler", e=0.6)
    sol = hamrkq.solve(
        problem,
        t_span=(0.0, 200 * math.pi + 1.0),
        atol=1e-12,
        method="auto",
        gamma_limit=math.inf,
        events={"expression": "q1*p1 + q2*p2", "direction": 1},
    )
    times = sol.t_events[0]
    k = np.arange(1, times.size + 1)
    assert times.size == 100
    assert np.max(np.abs(times - 2 * math.pi * k)) < 1e-10  # measured 5.2e-12
    assert abs(np.polyfit(k, times, 1)[0] - 2 * math.pi) < 1e-12  # measured 5e-14


def test_terminal_event_stops_the_run_with_status():
    def hits_zero(t, y):
        return y[0]

    hits_zero.terminal = 2  # the second zero of q = cos t, at 3 pi / 2
    sol = hamrkq.solve(
        OSC, [1.0], [0.0], (0.0, 20.0), atol=1e-12, events=[hits_zero], dense_output=True
    )
    assert sol.status is Status.TERMINAL_EVENT
    assert sol.success and not sol.partial
    assert "terminal event 0" in sol.message
    assert sol.t[-1] == sol.t_events[0][-1]
    assert abs(sol.t[-1] - 1.5 * math.pi) < 1e-11
    np.testing.assert_allclose(sol.y[-1], [0.0, 1.0], atol=1e-11)
    assert sol.t_events[0].size == 2
    assert np.all(np.diff(sol.t) > 0)
    # the rows stay consistent after the truncation
    assert sol.z.shape == sol.y.shape == sol.gamma.shape
    assert abs(sol.energy[-1] - 0.5) < 1e-11
    assert sol.sol.t[-1] == sol.t[-1]


def test_terminal_event_backward_in_time():
    def g(t, y):
        return y[0]

    g.terminal = True
    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, -10.0), atol=1e-12, events=g)
    assert sol.status is Status.TERMINAL_EVENT
    assert abs(sol.t[-1] + 0.5 * math.pi) < 1e-11


def _copy_harmonic(tmp_path, extra: str):
    path = tmp_path / "harmonic.toml"
    shutil.copy(catalogue_dir() / "harmonic.toml", path)
    with path.open("a") as handle:
        handle.write(extra)
    return path


def test_events_from_a_problem_file(tmp_path):
    path = _copy_harmonic(
        tmp_path, '\n[[events]]\nexpression = "p"\ndirection = -1\nterminal = true\n'
    )
    problem = load_problem(path)
    assert len(problem.events) == 1
    sol = hamrkq.solve(problem, atol=1e-12)  # q = sin t, p = cos t: p falls through 0
    assert sol.status is Status.TERMINAL_EVENT
    assert abs(sol.t[-1] - 0.5 * math.pi) < 1e-11
    assert sol.event_labels == ("p",)


def test_a_problem_files_events_do_not_stop_other_methods(tmp_path, capsys):
    """Before, a file with [[events]] could not be run with SciPy's or the
    symplectic methods, nor compared: solve raised InputError for events
    nobody had passed to it.  The file's events are a default: left out,
    with a warning, where they cannot be located; given to solve, refused."""
    from hamrkq.analysis.comparison import compare
    from hamrkq.cli import main
    from hamrkq.errors import HamrkqWarning

    path = _copy_harmonic(tmp_path, '\n[[events]]\nexpression = "q"\n')
    problem = load_problem(path)
    with pytest.warns(HamrkqWarning, match=r"events of problem 'harmonic' \('q'\) are not"):
        sol = hamrkq.solve(problem, method="scipy:DOP853", t_span=(0, 5), atol=1e-10)
    assert sol.success and sol.t_events is None
    exact = problem.exact(sol.t)
    assert np.abs(sol.y - exact).max() < 1e-8  # it really ran, to the end
    with pytest.raises(InputError, match=r"run auto, rk34q8 or another family member"):
        hamrkq.solve(problem, method="gauss4", step=0.01, t_span=(0, 1), events=["q"])
    # a family member with nodes left out is told to keep them, under the name given
    with pytest.raises(InputError, match=r"\(method='auto', keep_every=2\).*keep every node"):
        hamrkq.solve(problem, t_span=(0, 1), keep_every=2, dense_output=True)
    # RKQ with every node kept still finds them: q = sin t vanishes at pi
    assert hamrkq.solve(problem, t_span=(0, 4), atol=1e-12).t_events[0] == pytest.approx(
        [math.pi], abs=1e-11
    )
    code = main(["run", str(path), "--method", "scipy:DOP853", "--t-end", "2", "--no-plots",
                 "--out", str(tmp_path / "run")])  # fmt: skip
    assert code == 0
    assert "hamrkq: warning: the events of problem 'harmonic'" in capsys.readouterr().err
    result = compare(problem, ["scipy:DOP853", "gauss4"], t_end=2.0, quick=True)
    assert all(run.success for run in result.runs)


@pytest.mark.parametrize(
    "text",
    ["__import__('os').system('true')", "q.__class__", "lambda: 0", "open('x')", "q; p"],
)
def test_hostile_event_text_is_rejected(tmp_path, text):
    path = _copy_harmonic(tmp_path, f"\n[[events]]\nexpression = '''{text}'''\n")
    with pytest.raises(ExpressionError):
        load_problem(path)
    with pytest.raises(ExpressionError):
        hamrkq.solve(OSC, [1.0], [0.0], (0.0, 1.0), events=text)


def test_bad_event_tables_are_rejected(tmp_path):
    path = _copy_harmonic(tmp_path, '\n[[events]]\nexpression = "q"\nwhen = 1\n')
    with pytest.raises(ProblemFileError, match="events"):
        load_problem(path)
    # The refusals name the line, like every other key's (they had none; QA).
    lines = path.read_text().splitlines()
    header = len(lines) - 2  # the 1-based line of the [[events]] just appended
    assert lines[header - 1] == "[[events]]"
    with pytest.raises(ProblemFileError, match=rf"harmonic.toml:{header}, key 'events\[0\]'"):
        load_problem(path)
    second = _copy_harmonic(
        tmp_path, '\n[[events]]\nexpression = "q"\n[[events]]\nexpression = "y"\n'
    )
    last = len(second.read_text().splitlines())
    with pytest.raises(ExpressionError, match=rf":{last}, key 'events\[1\].expression'"):
        load_problem(second)
    with pytest.raises(InputError, match="not coordinates"):
        hamrkq.solve(OSC, [1.0], [0.0], (0.0, 1.0), events=sp.Symbol("x"))
    # The system's q is real=True; a plain Symbol("q") is another symbol to
    # SymPy: the message said q was "not a coordinate" (QA).
    with pytest.raises(InputError, match=r"uses q, a symbol with other assumptions \(none\)"):
        hamrkq.solve(OSC, [1.0], [0.0], (0.0, 1.0), events=sp.Symbol("q") - 0.3)


def test_summary_json_lists_the_events():
    from hamrkq.io.report import summary_dict

    sol = hamrkq.solve(OSC, [1.0], [0.0], (0.0, 7.0), atol=1e-10, events=["q", "p"])
    summary = summary_dict(sol, None)
    assert [e["label"] for e in summary["events"]] == ["q", "p"]
    assert summary["events"][0]["t"] == pytest.approx([0.5 * math.pi, 1.5 * math.pi], abs=1e-9)
    assert summary["events"][1]["error_bound"] == [[1e-10, 1e-10], [1e-10, 1e-10]]


def test_a_terminal_event_ends_the_integration_itself_not_only_the_output():
    # The first zero of q on the oscillator (q0 = 1) is at pi/2; the run must
    # stop there, not integrate to t = 1000 and cut afterwards.
    problem = hamrkq.load_problem("harmonic")
    ham = problem.hamiltonian
    name = ham.q[0].name
    sol = hamrkq.solve(ham, [1.0], [0.0], (0.0, 1000.0), atol=1e-10, events=[
        {"expression": name, "terminal": True}])  # fmt: skip
    full = hamrkq.solve(ham, [1.0], [0.0], (0.0, 1000.0), atol=1e-10)
    assert sol.status is hamrkq.Status.TERMINAL_EVENT
    assert abs(sol.t[-1] - np.pi / 2) < 1e-9
    # pi/2 is 0.16 % of the interval; auto's first steps are short (64 of 4055)
    assert sol.stats["steps"] < 0.05 * full.stats["steps"]


def test_the_run_summary_lists_each_event_functions_roots(tmp_path, capsys):
    # Before, `hamrkq run` wrote the events to summary.json and solution.npz
    # but its table said nothing of them.
    from hamrkq.cli import main

    path = _copy_harmonic(tmp_path, '\n[[events]]\nexpression = "q"\n')
    out = tmp_path / "run"
    code = main(["run", str(path), "--t-end", "20", "--atol", "1e-10", "--no-plots",
                 "--reference", "none", "--out", str(out)])  # fmt: skip
    assert code == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("event q"))
    # q = sin t vanishes at k pi: six roots in (0, 20]; the first four shown
    count, times = line.split(None, 2)[2].split(" at t = ")
    assert count == "6"
    shown = [float(x) for x in times.removesuffix(", ...").split(", ")]
    assert shown == pytest.approx([math.pi * k for k in range(1, 5)], rel=5e-6)  # 6 digits
    assert times.endswith(", ...")


def _event_state_ratio(problem, sol):
    """The largest true error of an event state over its bound, against
    heyoka in 113-bit floats at the event times."""
    from helpers import multiprecision_states

    times = sol.t_events[0]
    grid = np.concatenate([[0.0], times])
    reference = multiprecision_states(
        problem.hamiltonian, problem.parameter_array, problem.y0, grid, bits=113
    )[1:]
    return float(np.max(np.abs(sol.y_events[0] - reference) / sol.event_bound[0]))


@pytest.mark.parametrize(("name", "event"), [("pendulum", "q"), ("toda", "p1")])
def test_event_states_where_a_component_crosses_zero_keep_the_promise(name, event):
    """Under rtol, an event where a component crosses zero sits where that
    component's tolerance is atol alone (1e-12 here, against rtol |y| ~ 1e-7
    at the nodes around it).  Before, nothing checked the event states: auto
    returned them up to 135 (pendulum: the quencher's own error, 1e-11 at
    t = 20) and 8.7 (Toda: the dense value's one quencher step over half a
    step that the quencher had taken in six) times their bound."""
    problem = load_problem(name)
    sol = hamrkq.solve(problem, method="auto", events=event, atol=1e-12, rtol=1e-6)
    assert sol.status is Status.SUCCESS
    assert sol.t_events[0].size > 10
    assert _event_state_ratio(problem, sol) <= 1.05  # measured 0.018 and 0.002
    # auto ran again: the first run stopped before an event state
    assert "stopped before the state of event" in sol.message


def test_a_member_stops_before_an_event_state_it_cannot_certify():
    """A named member does not run again: it ends at the last node before
    the event state whose estimated error exceeds gamma_limit of the
    tolerance there, and says so, and which component passes zero."""
    problem = load_problem("pendulum")
    sol = hamrkq.solve(problem, method="rk78q12", events="q", atol=1e-12, rtol=1e-6)
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    t_fail = float(sol.message.split("at t = ")[1].split(" ")[0])
    assert sol.t[-1] < t_fail
    assert np.all(sol.t_events[0] < t_fail)
    assert "At the state of event 'q'" in sol.message
    assert "passes zero at the event" in sol.message and "atol = 1e-12" in sol.message
    # the first zero of q, the pendulum's quarter period (3.3715 for this amplitude)
    assert t_fail == pytest.approx(3.3715, abs=1e-4)
    # with the certificate off, the same run goes to the end
    off = hamrkq.solve(
        problem, method="rk78q12", events="q", atol=1e-12, rtol=1e-6, gamma_limit=np.inf
    )
    assert off.status is Status.SUCCESS


def test_dense_values_take_the_quenchers_own_steps():
    """sol.sol(t) steps the quencher from the nearer node in steps no longer
    than the run's own: with six quencher steps a step, one step over half a
    step was (3)^13 times a quencher step's truncation error."""
    problem = load_problem("toda")
    sol = hamrkq.solve(
        problem, method="rk78q12", z_substeps=6, atol=1e-12, rtol=1e-6, dense_output=True
    )
    from helpers import multiprecision_states

    mid = 0.5 * (sol.t[:-1] + sol.t[1:])[::4]
    reference = multiprecision_states(
        problem.hamiltonian, problem.parameter_array, problem.y0, np.concatenate([[0.0], mid]),
        bits=113,
    )[1:]  # fmt: skip
    z_dense = sol.sol.through(sol.t, sol.z, None)
    error = np.max(np.abs(z_dense.values(mid) - reference))
    assert error < 1e-14  # measured 1.1e-15; 1e-11 with one quencher step


def test_an_event_state_below_double_precisions_floor_stops_the_run_honestly():
    """atol 1e-16 where p2 crosses zero: the state there is stepped in double
    from a node stored in double, an ulp of the state's size (2e-16) off
    before any truncation.  Before, auto returned SUCCESS with such states
    up to 2.3 (Arenstorf) and 10.8 (prentice2011) times their bound; now it
    stops before the first, says that rounding is the limit and that a
    larger atol is what works, and does not run again for it."""
    kepler = load_problem("kepler")
    sol = hamrkq.solve(kepler, method="auto", events="p2", atol=1e-16, rtol=1e-10)
    assert sol.status is Status.TOLERANCE_UNATTAINABLE
    assert sol.t[-1] < 0.971 and sol.t_events[0].size == 0  # p2's first zero: t = 0.9708
    assert (
        "the value's own rounding" in sol.message and "A larger atol is what works" in sol.message
    )
    # no rerun: neither more quencher steps nor double-double go below it
    assert "the run with" not in sol.message
    assert "discarded_evaluations" not in sol.stats


def _grazing_times(level: float, t_end: float) -> np.ndarray:
    """Where q = sin t reaches ``level`` (< 1): twice near each maximum."""
    k = np.arange(int(t_end / (2 * math.pi)) + 1)
    times = np.concatenate(
        [math.asin(level) + 2 * math.pi * k, math.pi - math.asin(level) + 2 * math.pi * k]
    )
    return np.sort(times[times <= t_end])


@pytest.mark.parametrize("direction", [0, 1, -1])
def test_two_crossings_inside_one_step_are_found(direction):
    # q = sin t grazes q = 0.99 near each maximum: the two crossings, 0.28
    # apart, often fall between the same two nodes, where g has one sign at
    # both.  Node signs alone found 12 of the 20 at atol 1e-6.
    t_end = 20 * math.pi
    exact = _grazing_times(0.99, t_end)
    sol = hamrkq.solve(OSC, [0.0], [1.0], (0.0, t_end), atol=1e-6,
                       events={"expression": "q - 0.99", "direction": direction})  # fmt: skip
    want = {0: exact, 1: exact[0::2], -1: exact[1::2]}[direction]
    times = sol.t_events[0]
    assert times.size == want.size
    # |dg/dt| = 0.14 at the crossings: a time within delta / 0.14
    assert np.max(np.abs(times - want)) < 2e-5
    np.testing.assert_allclose(sol.y_events[0][:, 0], 0.99, atol=1.05e-6)
    # ... and where the orbit turns back short of the surface, nothing.
    short = hamrkq.solve(OSC, [0.0], [1.0], (0.0, t_end), atol=1e-6, events="q - 1.001")
    assert short.t_events[0].size == 0


def test_two_crossings_inside_one_step_of_a_callable_event_backward_in_time():
    # A Python g has no symbolic derivative: dg/dt by a central difference
    # along f.  Backward in time the roots come in the run's order.
    def g(t, y):
        return y[0] - 0.999

    t_end = 20 * math.pi
    exact = _grazing_times(0.999, t_end)
    sol = hamrkq.solve(OSC, [math.sin(t_end)], [math.cos(t_end)], (t_end, 0.0), atol=1e-9,
                       events=g)  # fmt: skip
    times = sol.t_events[0]
    assert times.size == exact.size  # node signs alone: 2 of 20
    np.testing.assert_allclose(times, exact[::-1], atol=1e-6)


def test_two_crossings_inside_one_step_of_a_callable_event_at_a_large_time():
    # QA: the central difference stepped 1e-5 |t|, 10 time units at t = 1e6,
    # longer than the turn at a maximum: every slope there had the wrong
    # sign and 60 of 80 crossings were found, SUCCESS.  Now 1e-5 of the
    # orbit's own time scale.
    def g(t, y):  # nonlinear in q: a linear g's difference is exact for any e
        return np.sin(3.0 * y[0]) - math.sin(3.0 * 0.99)

    t0 = 1e6
    span = 20 * math.pi
    # q = sin t on the exact orbit; g = 0 at q = 0.99 (twice near each
    # maximum, inside one step) and at q = (pi - 2.97) / 3 (steeply)
    k = np.arange(math.floor(t0 / (2 * math.pi)) - 1, math.ceil((t0 + span) / (2 * math.pi)) + 1)
    roots = []
    for a in (math.asin(0.99), math.asin((math.pi - 2.97) / 3)):
        roots += [a + 2 * math.pi * k, math.pi - a + 2 * math.pi * k]
    roots = np.sort(np.concatenate(roots))
    exact = roots[(roots > t0) & (roots <= t0 + span)]
    sol = hamrkq.solve(OSC, [math.sin(t0)], [math.cos(t0)], (t0, t0 + span), atol=1e-6,
                       events=g)  # fmt: skip
    assert sol.t_events[0].size == exact.size == 40
    # |dg/dt| >= 3 |cos 2.97| 0.14 at the crossings: a time within delta / 0.4
    assert np.max(np.abs(sol.t_events[0] - exact)) < 1e-5


def test_bracketed_roots_all_at_once_to_four_eps_in_a_few_calls():
    from hamrkq.rkq.roots import bracketed_roots

    # Roots of sin(t) - 1/2 near 1000..2000, each in a bracket of 0.3, one
    # whose end is already the root to within an ulp (false position lands
    # on that end; bisecting from there took 30 iterations), and one whose
    # end is exactly a root.
    k = np.arange(1000, 1200)
    exact = np.arcsin(0.5) + 2 * math.pi * k
    a, b = exact - 0.1 * np.cos(k) ** 2 - 0.01, exact + 0.2 * np.sin(k) ** 2 + 0.01
    b[0] = exact[0] + 4 * np.spacing(exact[0])  # f(b) = 3e-12, f(a) = -0.04
    calls = []

    def f(t):
        calls.append(t.size)
        return np.sin(t) - 0.5

    roots = bracketed_roots(f, a, b, np.sin(a) - 0.5, np.sin(b) - 0.5)
    assert len(calls) <= 10 and calls[0] == k.size
    np.testing.assert_allclose(roots, exact, rtol=8 * np.finfo(float).eps, atol=0)
    assert (
        bracketed_roots(f, np.array([0.0]), np.array([1.0]), np.array([0.0]), np.array([1.0]))
        == 0.0
    )
