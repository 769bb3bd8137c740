"""A problem file's events where the run cannot locate them (``--keep-every``,
a method outside the RKQ family).

Before, they were left out with a warning on stderr only: ``hamrkq run
osct.toml --keep-every 2 --json`` went on past the file's terminal event
(t = 2.354) to t = 20 with status SUCCESS, no ``events`` key and ``notes:
[]``, so a script could not tell.  Now a terminal event with ``--keep-every``
is refused (exit 2), and otherwise summary.json, ``--json`` and the saved
solution say, in the warning's words, that the events were not located.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

import hamrkq
from hamrkq.cli import EXIT_BAD_INPUT, main
from hamrkq.errors import HamrkqWarning
from hamrkq.result import Solution, Status

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
t_span = [0, 20]
atol = 1e-9
rtol = 0
"""

NOT_LOCATED = (
    "the events of problem '{name}' ('x', 'v - 1/2') are not located in this run: events "
    "need an RKQ-family method with every node kept (solve(..., events=[]) runs without "
    "them, and without this warning)"
)


def _problem(tmp_path: Path, terminal: bool) -> Path:
    name = "osct" if terminal else "oscn"
    path = tmp_path / f"{name}.toml"
    path.write_text(OSCILLATOR.format(name=name, terminal=str(terminal).lower()))
    return path


def _cli(args: list[str]) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(args)
    return status, stdout.getvalue(), stderr.getvalue()


def test_keep_every_with_a_terminal_event_in_the_file_is_refused(tmp_path):
    problem = _problem(tmp_path, terminal=True)
    out = tmp_path / "out"
    status, stdout, stderr = _cli(["run", str(problem), "--keep-every", "2", "--out", str(out)])
    assert status == EXIT_BAD_INPUT and stdout == ""
    assert stderr == (
        "hamrkq: error: --keep-every 2: problem 'osct' has a terminal event ('x') that ends "
        "the run where it occurs, and events are located only with every node kept: the run "
        "would go on past it to t_end. Leave out --keep-every (and thin the nodes afterwards: "
        "Solution.load(path).t[::2])\n"
    )
    assert not out.exists()
    # --keep-every 1 keeps every node: the terminal event ends the run as the file says.
    status, stdout, _ = _cli(
        ["run", str(problem), "--keep-every", "1", "--json", "--out", str(out)]
    )
    summary = json.loads(stdout)
    assert status == 0 and summary["status"] == "TERMINAL_EVENT"
    assert abs(summary["t_final"] - 2.354) < 1e-3


def test_events_left_out_by_keep_every_are_noted_in_the_summary(tmp_path):
    problem = _problem(tmp_path, terminal=False)
    out = tmp_path / "out"
    args = ["run", str(problem), "--keep-every", "2", "--json", "--no-plots", "--out", str(out)]
    status, stdout, stderr = _cli(args)
    words = NOT_LOCATED.format(name="oscn")
    assert status == 0
    assert stderr == f"hamrkq: warning: {words}\n"
    summary = json.loads(stdout)
    assert summary == json.loads((out / "summary.json").read_text())
    assert summary["status"] == "SUCCESS" and "events" not in summary
    assert summary["notes"] == [words]
    assert summary["settings"]["solve"]["events_not_located"] == words
    saved = Solution.load(out / "solution.npz")
    assert saved.options["events_not_located"] == words


def test_a_baseline_method_runs_past_the_files_terminal_event_and_says_so(tmp_path):
    """Comparing methods means running the problem with each: allowed, and noted."""
    problem = _problem(tmp_path, terminal=True)
    out = tmp_path / "out"
    args = ["run", str(problem), "--method", "scipy:DOP853", "--json", "--no-plots"]
    status, stdout, stderr = _cli([*args, "--out", str(out)])
    words = NOT_LOCATED.format(name="osct") + (
        "; the terminal event 'x' does not end it, so it runs to t_end"
    )
    assert status == 0 and stderr == f"hamrkq: warning: {words}\n"
    summary = json.loads(stdout)
    assert summary["status"] == "SUCCESS" and summary["t_final"] == 20.0
    assert summary["notes"] == [words]


def test_the_library_records_the_events_left_out(tmp_path):
    problem = hamrkq.load_problem(_problem(tmp_path, terminal=False))
    with pytest.warns(HamrkqWarning) as caught:
        sol = hamrkq.solve(problem, keep_every=3)
    (warning,) = caught
    assert sol.options["events_not_located"] == str(warning.message)
    assert sol.status is Status.SUCCESS and sol.t_events is None
    located = hamrkq.solve(problem)  # every node: located, nothing noted
    assert "events_not_located" not in located.options and len(located.t_events) == 2
    quiet = hamrkq.solve(problem, keep_every=3, events=[])  # asked for none: nothing noted
    assert "events_not_located" not in quiet.options
