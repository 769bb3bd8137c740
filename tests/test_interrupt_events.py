"""Ctrl-C and SIGTERM outside the step loop: while events are located, in
numba's call of a first-class function, between the orbits of a section and
the chunks of an ensemble.

Before, only the step loop turned an interrupt into a status: a run with
events lost everything when the interrupt landed while its events were
located (``hamrkq run`` of a problem file with two events wrote no file at
all), a signal landing while numba unpickled a function's signature ended in
``TypeError: remembered() missing 1 required positional argument: 'sig'``,
``hamrkq poincare`` went on with the next orbit, and ``hamrkq ensemble``
wrote nothing and waited 6.5 s for its running chunks.  The interrupts here
are raised at a chosen moment (an event function, numba's unpickling, the
child process signalling itself), so each test hits the moment it is about.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import hamrkq
import hamrkq.cli.interrupts
from hamrkq.cli import EXIT_FAILED
from hamrkq.result import Solution, Status
from hamrkq.solve import event_check

ROOT = Path(__file__).resolve().parent.parent

posix_only = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

#: A run long enough to be interrupted: an oscillator with two events that
#: are not terminal, as QA's p/oscm.toml.
OSCILLATOR = """\
name = "{name}"
coordinates = ["x"]
momenta = ["v"]
hamiltonian = "v**2/2 + w**2*x**2/2 + eps*x**4"

[parameters]
w = 2
eps = "1/100"

[initial]
x = "1/w"
v = 0

[[events]]
expression = "x"
direction = 1
terminal = {terminal}

[[events]]
expression = "v - 0.5"
direction = 0
terminal = false

[integration]
t_span = [0, {t_end}]
atol = 1e-9
rtol = 0
"""


def _oscillator(tmp_path: Path, name: str = "oscm", t_end: float = 100000, terminal=False):
    path = tmp_path / f"{name}.toml"
    text = OSCILLATOR.format(name=name, t_end=t_end, terminal=str(terminal).lower())
    path.write_text(text)
    return path


def _raising_once(at_call: int):
    """``g = q`` that raises KeyboardInterrupt on its ``at_call``-th call: an
    interrupt landing while the events are located (a callable event is
    called at the nodes and along the dense output, never in the step loop
    when it is not terminal)."""
    calls = [0]

    def g(t, y):
        calls[0] += 1
        if calls[0] == at_call:
            raise KeyboardInterrupt
        return y[0]

    return g


def _plain(t, y):
    return y[0]


RUN = {"t_span": (0.0, 200.0), "method": "rk78q12", "z_substeps": 2, "atol": 1e-9}


@pytest.fixture(scope="module")
def harmonic():
    return hamrkq.load_problem("harmonic")


@pytest.fixture(scope="module")
def uninterrupted(harmonic):
    return hamrkq.solve(harmonic, events=[_plain], **RUN)


def test_an_interrupt_while_events_are_located_keeps_every_node_and_event(harmonic, uninterrupted):
    """Before: the KeyboardInterrupt left solve, and with it every node."""
    sol = hamrkq.solve(harmonic, events=[_raising_once(40)], **RUN)
    assert sol.status is Status.INTERRUPTED and sol.partial
    np.testing.assert_array_equal(sol.t, uninterrupted.t)
    np.testing.assert_array_equal(sol.y, uninterrupted.y)
    # A short run: every event is located again within the time allowed.
    assert uninterrupted.t_events[0].size == 63  # q = cos t crosses 0 at pi/2 + k pi
    np.testing.assert_array_equal(sol.t_events[0], uninterrupted.t_events[0])
    np.testing.assert_array_equal(sol.y_events[0], uninterrupted.y_events[0])
    assert "events_not_located" not in sol.options
    assert sol.message.startswith("Interrupted (KeyboardInterrupt) near t = 200.0.")


class _Clock:
    """``time.perf_counter`` for event_check: one second a reading."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self) -> float:
        self.now += 1.0
        return self.now


def test_the_events_of_an_interrupted_run_are_located_window_by_window_until_the_time_is_up(
    harmonic, uninterrupted, monkeypatch
):
    """Two windows of 50 nodes in the time allowed: every event up to the
    100th node, the same bits as the uninterrupted run's, and a note that
    says where they stop (in the message and in the options, which
    summary.json and Solution.save keep)."""
    monkeypatch.setattr(event_check, "time", _Clock())
    monkeypatch.setattr(event_check, "INTERRUPTED_LOCATE_S", 2.5)  # readings 2, 3: two windows
    monkeypatch.setattr(event_check, "INTERRUPTED_WINDOW", 50)
    sol = hamrkq.solve(harmonic, events=[_raising_once(40)], **RUN)
    assert sol.status is Status.INTERRUPTED
    np.testing.assert_array_equal(sol.t, uninterrupted.t)
    until = sol.t[100]
    expected = uninterrupted.t_events[0][uninterrupted.t_events[0] <= until]
    assert 0 < expected.size < uninterrupted.t_events[0].size
    np.testing.assert_array_equal(sol.t_events[0], expected)
    note = (
        f"Its events were located up to t = {float(until)!r} only (the run was interrupted); "
        "later ones are not reported."
    )
    assert sol.options["events_not_located"] == note
    assert sol.message.endswith(note)


def test_no_time_left_means_no_event_and_a_note(harmonic, monkeypatch, tmp_path):
    monkeypatch.setattr(event_check, "INTERRUPTED_LOCATE_S", 0.0)
    sol = hamrkq.solve(harmonic, events=[_raising_once(40)], **RUN)
    assert sol.status is Status.INTERRUPTED and sol.t[-1] == 200.0
    assert sol.t_events[0].size == 0
    assert sol.options["events_not_located"].startswith(
        "Its events were located up to t = 0.0 only (the run was interrupted)"
    )
    saved = Solution.load(sol.save(tmp_path / "s.npz"))
    assert saved.options["events_not_located"] == sol.options["events_not_located"]


def test_an_interrupt_in_the_step_loop_keeps_the_events_among_the_nodes_so_far(harmonic):
    """The progress callback raises after the first chunk of steps: the
    events among the nodes kept are located (before: all of them, however
    long that took; after SIGTERM the command line must end within about a
    second)."""
    long = {**RUN, "t_span": (0.0, 4000.0)}
    full = hamrkq.solve(harmonic, events=[_plain], **long)

    def progress(fraction, t):
        raise KeyboardInterrupt

    sol = hamrkq.solve(harmonic, events=[_plain], progress=progress, **long)
    assert sol.status is Status.INTERRUPTED and 1 < len(sol) < len(full)
    np.testing.assert_array_equal(sol.y, full.y[: len(sol)])
    expected = full.t_events[0][full.t_events[0] <= sol.t[-1]]
    assert expected.size > 10
    np.testing.assert_array_equal(sol.t_events[0], expected)
    assert "events_not_located" not in sol.options


def test_a_terminal_event_found_after_the_interrupt_still_ends_the_run(harmonic):
    """The terminal event is among the nodes when the interrupt lands: the
    run ended there, the result is complete (TERMINAL_EVENT)."""

    def terminal(t, y):
        return y[0]

    terminal.terminal = True
    terminal.direction = 1
    g = _raising_once(10**9)  # never raises: the reference
    ref = hamrkq.solve(harmonic, events=[g, terminal], **RUN)
    sol = hamrkq.solve(harmonic, events=[_raising_once(3), terminal], **RUN)
    assert ref.status is sol.status is Status.TERMINAL_EVENT
    np.testing.assert_array_equal(sol.t, ref.t)
    for mine, theirs in zip(sol.t_events, ref.t_events, strict=True):
        np.testing.assert_array_equal(mine, theirs)


numba = pytest.importorskip("numba")


def test_an_interrupt_while_numba_unpickles_a_signature_is_raised_as_itself(harmonic, monkeypatch):
    """numba's compiled code unpickles a first-class function's signature
    and calls the address lookup with it; an interrupt landing in the
    unpickling left the argument NULL, and hamrkq's remembering lookup
    (hamrkq.backends.kernel) raised ``TypeError: remembered() missing 1
    required positional argument: 'sig'`` in its place (QA's traceback from
    ``hamrkq poincare`` under SIGTERM)."""
    import numba.core.serialize as serialize
    from numba.experimental import function_type

    sol = hamrkq.solve(harmonic, t_span=(0, 10), dense_output=True, backend="numba")
    sol.sol(np.linspace(0, 10, 3))  # compiled and remembered

    class Trap(dict):
        armed = True

        def __getitem__(self, key):
            if Trap.armed:
                Trap.armed = False
                raise KeyboardInterrupt("landed in numba's unpickling")
            return super().__getitem__(key)

    monkeypatch.setattr(serialize, "_unpickled_memo", Trap(serialize._unpickled_memo))
    with pytest.raises(KeyboardInterrupt, match="landed in numba's unpickling"):
        sol.sol(np.linspace(0, 10, 3))
    assert not Trap.armed
    np.testing.assert_allclose(sol.sol(10.0), sol.y[-1], rtol=1e-12)  # works again
    with pytest.raises(TypeError, match="needs a signature"):
        function_type._get_wrapper_address(len)  # called without one, nothing pending


# -- the command line -------------------------------------------------------------
#: ``python -m hamrkq ARGS`` where the child sends itself SIGTERM at a chosen
#: moment (HOOK, Python run before the command), and prints how long after
#: it the process ended.
CHILD = """\
import atexit, os, signal, sys, threading, time
sent = []
def sigterm():
    sent.append(time.perf_counter())
    os.kill(os.getpid(), signal.SIGTERM)
atexit.register(lambda: sent and print(f"EXIT_AFTER {{time.perf_counter() - sent[0]:.3f}}",
                                      file=sys.stderr))
{hook}
from hamrkq.cli import entry_point
sys.argv = ["hamrkq", *sys.argv[1:]]
entry_point()
"""


def _child(hook: str, args: list[str], cwd: Path, timeout: float = 600):
    code = CHILD.format(hook=textwrap.dedent(hook))
    proc = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    after = [float(line.split()[1]) for line in proc.stderr.splitlines() if "EXIT_AFTER" in line]
    return proc, (after[0] if after else None)


#: The most a test allows between SIGTERM and the end of the process (the
#: command line's aim is about a second; a loaded CI machine gets slack).
PROMPT = 5.0


@posix_only
@pytest.mark.slow
def test_sigterm_while_a_run_locates_its_events_writes_the_nodes(tmp_path):
    """QA's case: SIGTERM while the events of a finished 100 000-unit
    oscillator run were located (50 s with brentq): no file at all,
    "terminated (SIGTERM)".  Now every node, the events among the first
    ones and a note, INTERRUPTED, exit 1, within about a second, no
    figure and no reference integration."""
    problem = _oscillator(tmp_path, t_end=20000)
    hook = """
        import hamrkq.events as events
        original = events.locate_all
        def locate_all(specs, dense):
            if not sent and dense.t.size > 10000:  # the finished run's own
                sigterm()
            return original(specs, dense)
        events.locate_all = locate_all
    """
    out = tmp_path / "ev"
    args = ["run", str(problem), "--method", "rk78q12", "--out", str(out)]
    proc, after = _child(hook, args, tmp_path)
    assert proc.returncode == EXIT_FAILED, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert "terminated" not in proc.stderr
    assert after is not None and after < PROMPT, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["solution.npz", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "INTERRUPTED" and summary["partial"] is True
    assert summary["t_final"] == 20000.0
    assert "stopped by SIGTERM (handled like Ctrl-C)" in summary["notes"]
    assert hamrkq.cli.interrupts.QUICK_REPORT in summary["notes"]
    assert summary["settings"]["reference"] == "none"
    saved = Solution.load(out / "solution.npz")
    assert saved.status is Status.INTERRUPTED and len(saved) == summary["nodes"]
    labels = [event["label"] for event in summary["events"]]
    assert len(labels) == 2 and labels[0] == "x"
    note = saved.options.get("events_not_located")
    if note is not None:  # not every event was located in the time allowed
        assert note.startswith("Its events were located up to t = ") and note in saved.message
        until = float(note.split("t = ")[1].split(" ")[0])
        assert 0 < until < 20000
        assert saved.t_events[0].max() <= until


@posix_only
@pytest.mark.slow
def test_sigterm_during_a_poincare_orbit_keeps_the_orbits_run(tmp_path):
    """Before: the orbit running stopped, the others ran on (a minute), and
    at some moments the command ended in a TypeError traceback."""
    hook = """
        import hamrkq.cli.poincare as command
        original = command.poincare
        orbits = []
        def poincare(*args, **kwargs):
            orbits.append(1)
            if len(orbits) == 3:  # inside the third orbit's run
                threading.Timer(0.3, sigterm).start()
            return original(*args, **kwargs)
        command.poincare = poincare
    """
    out = tmp_path / "pt"
    args = ["poincare", "henon_heiles", "--orbits", "6", "--t-end", "20000", "--out", str(out)]
    proc, after = _child(hook, args, tmp_path)
    assert proc.returncode == EXIT_FAILED, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert after is not None and after < PROMPT, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["section.npz", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == ["SUCCESS", "SUCCESS", *["INTERRUPTED"] * 4]
    assert summary["partial"] is True
    assert "stopped by SIGTERM (handled like Ctrl-C)" in summary["notes"]
    assert "orbits 3 to 5 (from 0) were not started" in summary["notes"]
    with np.load(out / "section.npz") as section:
        orbit = section["orbit"]
        assert summary["crossings"] == orbit.size
        assert set(orbit.tolist()) <= {0, 1, 2} and {0, 1} <= set(orbit.tolist())
        assert np.all(np.isfinite(section["y"]))


@posix_only
@pytest.mark.slow
def test_sigterm_during_an_ensemble_keeps_the_chunks_finished_and_does_not_wait(tmp_path):
    """Before: nothing written, and 6.5 s to exit (the running chunks were
    waited for).  Here a chunk takes seconds: the command must not wait."""
    hook = """
        import importlib
        local = importlib.import_module("hamrkq.ensemble.local")  # hamrkq.ensemble: a function
        original = local.Collector.add
        def add(self, chunk):
            members = original(self, chunk)
            if self.done == 2:  # two chunks of one member kept, two running
                sigterm()
            return members
        local.Collector.add = add
    """
    out = tmp_path / "en"
    grid = ["--grid", "q1=-0.3:0.3:4", "--grid", "p1=-0.1:0.1:4"]
    # a member takes about 10 s: the two running when SIGTERM lands would hold the exit
    args = ["ensemble", "henon_heiles", *grid, "--t-end", "100000", "--workers", "2"]
    proc, after = _child(hook, [*args, "--out", str(out)], tmp_path)
    assert proc.returncode == EXIT_FAILED, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert after is not None and after < PROMPT, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["ensemble.npz", "summary.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is True
    assert "stopped by SIGTERM (handled like Ctrl-C)" in summary["notes"]
    ens = hamrkq.EnsembleSolution.load(out / "ensemble.npz")
    interrupted = ens.status == Status.INTERRUPTED.code
    assert interrupted.sum() == 14 and (ens.status[~interrupted] == 0).all()
    assert np.isnan(ens.y[interrupted]).all() and np.isfinite(ens.y[~interrupted]).all()
    assert "interrupted: 14 of 16 members not integrated" in summary["notes"]


def test_an_interrupted_ensemble_returns_the_members_finished(monkeypatch):
    """The library: Ctrl-C between chunks (here raised by the progress
    callback after the first) returns the ensemble, the rest INTERRUPTED."""
    pendulum = hamrkq.load_problem("pendulum")
    q0 = np.linspace(-1, 1, 6)[:, None]

    def progress(done, total):
        raise KeyboardInterrupt

    started = time.perf_counter()
    ens = hamrkq.ensemble(
        pendulum, q0=q0, p0=[0.0], t_span=(0, 5), workers=1, chunk_size=2, progress=progress
    )
    assert time.perf_counter() - started < 60
    assert ens.status.tolist() == [0, 0, 4, 4, 4, 4]
    assert ens.failed.tolist() == [2, 3, 4, 5]
    assert ens.message(2).startswith("Not integrated: the ensemble was interrupted")
    assert np.isnan(ens.y[2:]).all() and np.isfinite(ens.y[:2]).all()
    assert not ens.all_success


@posix_only
@pytest.mark.slow
def test_sigterm_during_compare_ends_it_at_once(tmp_path):
    """``hamrkq compare`` keeps no partial results (docs/errors.md says why):
    before, the run SIGTERM stopped returned INTERRUPTED and the sweep went
    on with every other run; now it ends after that run, exit 1, with
    "hamrkq: terminated (SIGTERM)" and no file."""
    hook = """
        import importlib
        comparison = importlib.import_module("hamrkq.analysis.comparison")
        original = comparison.solve
        def solve(problem, *args, t_span, **kwargs):
            def progress(fraction, t):  # in the step loop, after its first chunk
                if not sent:
                    sigterm()
            if t_span[1] > 100:  # the anchor's run, not a warm-up
                kwargs["progress"] = progress
            return original(problem, *args, t_span=t_span, **kwargs)
        comparison.solve = solve
    """
    out = tmp_path / "cmp"
    args = ["compare", "prentice2011", "--methods", "rk34q8", "rk34", "--quick"]
    proc, after = _child(hook, [*args, "--out", str(out)], tmp_path)
    assert proc.returncode == EXIT_FAILED, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert proc.stderr.splitlines()[0] == "hamrkq: terminated (SIGTERM)"
    (line,) = proc.stdout.splitlines()  # the anchor's run, and no run after it
    assert line.startswith("  rk34q8 atol=1e-06 rtol=0: "), line
    assert after is not None and after < PROMPT, proc.stderr
    assert not out.exists() or not [p for p in out.iterdir() if p.name != ".hamrkq.lock"]


def _main(args: list[str]) -> tuple[int, str]:
    import contextlib
    import io

    from hamrkq.cli import main

    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(args)
    return status, stdout.getvalue() + stderr.getvalue()


@posix_only
@pytest.mark.parametrize("moment", ["solution.npz", "summary.json"])
def test_sigterm_while_the_results_are_written_still_writes_them(moment, tmp_path, monkeypatch):
    """Every file is written atomically: SIGTERM landing in a write left no
    file (writing summary.json with 10 000 events takes 0.6 s).  The signal
    is held back until the file is written, then acted on: the quick
    report, exit status 1."""
    import hamrkq.cli.run as run

    if moment == "solution.npz":
        original = Solution.save

        def save(self, path):
            os.kill(os.getpid(), signal.SIGTERM)  # handled at the next bytecode: in the write
            return original(self, path)

        monkeypatch.setattr(Solution, "save", save)
    else:
        original = run.summary_dict

        def summary_dict(*args, **kwargs):
            os.kill(os.getpid(), signal.SIGTERM)
            return original(*args, **kwargs)

        monkeypatch.setattr(run, "summary_dict", summary_dict)
    out = tmp_path / "run"
    status, text = _main(
        ["run", "harmonic", "--t-end", "2", "--backend", "python", "--out", str(out)]
    )
    assert status == EXIT_FAILED, text
    assert "Traceback" not in text and "terminated" not in text
    summary = json.loads((out / "summary.json").read_text())
    assert "stopped by SIGTERM (handled like Ctrl-C)" in summary["notes"]
    saved = Solution.load(out / "solution.npz")
    assert saved.status is Status.SUCCESS and len(saved) == summary["nodes"]
    if moment == "solution.npz":  # before the report: the quick one
        assert sorted(p.name for p in out.iterdir()) == ["solution.npz", "summary.json"]
        assert hamrkq.cli.interrupts.QUICK_REPORT in summary["notes"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
