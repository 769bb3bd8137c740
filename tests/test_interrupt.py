"""Ctrl-C on a real ``hamrkq run`` process: SIGINT in the middle of a long run.

The process must stop the integration, still write ``solution.npz`` and
``summary.json`` (readable, marked partial, status INTERRUPTED), print the
summary, exit with status 1 and show no traceback.  Its stderr is a
pseudo-terminal, so that the progress bar is drawn: the signal is sent once
the bar shows that the step loop is running, never blindly after a delay.
"""

import json
import os
import pty
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hamrkq.result import Solution, Status

ROOT = Path(__file__).resolve().parent.parent
BAR = re.compile(rb"\[[#.]+\]\s+([0-9.]+)%,\s+t=([0-9.eE+-]+)")

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pseudo-terminal")


def _ctrl_c_as_at_a_terminal() -> None:
    """In the child before it starts Python: SIGINT unblocked, with its
    default disposition, as a shell starts a command.

    A process inherits its parent's signal mask and an *ignored* SIGINT, and
    Python then never raises KeyboardInterrupt.  The test worker's state is
    not this test's to rely on: in the full suite under CI (twice, never when
    run alone) the child ran to the end after the signal."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Child:
    """``python -m hamrkq ARGS`` with stderr on a pseudo-terminal."""

    def __init__(self, args, cwd):
        master, slave = pty.openpty()
        self.master = master
        self.stdout_path = cwd / "stdout.txt"
        with open(self.stdout_path, "wb") as stdout:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "hamrkq", *args],
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=slave,
                cwd=cwd,
                env={**os.environ, "PYTHONPATH": str(ROOT)},
                preexec_fn=_ctrl_c_as_at_a_terminal,
            )
        os.close(slave)
        self.stderr = b""

    def read(self, timeout):
        """Read what stderr has within ``timeout`` seconds; False at its end."""
        ready, _, _ = select.select([self.master], [], [], timeout)
        if not ready:
            return True
        try:
            chunk = os.read(self.master, 65536)
        except OSError:  # the child closed the terminal
            return False
        self.stderr += chunk
        return bool(chunk)

    def wait_for_bar(self, limit):
        """Wait until the bar shows progress; returns its (fraction, t)."""
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline and self.proc.poll() is None:
            self.read(0.2)
            shown = BAR.findall(self.stderr)
            if shown and float(shown[-1][0]) > 0:
                return float(shown[-1][0]) / 100, float(shown[-1][1])
        raise AssertionError(f"no progress bar within {limit} s: {self.stderr[-500:]!r}")

    def finish(self, limit):
        """Drain stderr until the process exits; returns its exit status."""
        deadline = time.monotonic() + limit
        while self.proc.poll() is None:
            if time.monotonic() > deadline:
                self.proc.kill()
                raise AssertionError("the interrupted run did not exit")
            self.read(0.2)
        while self.read(0.1):
            pass
        os.close(self.master)
        return self.proc.returncode

    @property
    def stdout(self):
        return self.stdout_path.read_text()


@pytest.mark.slow
def test_sigint_writes_partial_results_marked_partial_and_exits_1(tmp_path):
    out = tmp_path / "run"
    # The paper's run: about 62 000 steps, far longer than it takes to see the bar.
    child = Child(["run", "prentice2011", "--backend", "python", "--out", str(out)], tmp_path)
    fraction, t_bar = child.wait_for_bar(limit=60)
    assert 0 < fraction < 0.5  # interrupted well before the end
    child.proc.send_signal(signal.SIGINT)
    status = child.finish(limit=60)
    stderr = child.stderr.decode(errors="replace")

    assert status == 1, stderr
    assert "Traceback" not in stderr + child.stdout

    # Both files are on disk, readable and marked partial.
    summary = json.loads((out / "summary.json").read_text())
    assert summary["partial"] is True and summary["success"] is False
    assert summary["status"] == "INTERRUPTED"
    saved = Solution.load(out / "solution.npz")
    assert saved.status is Status.INTERRUPTED and saved.partial and not saved.success
    assert summary["nodes"] == len(saved) > 1000
    # It stopped after the node the bar showed (printed rounded to 3 decimals),
    # long before t = 4000.
    assert t_bar - 5e-4 <= saved.t[-1] < 2000
    assert np.all(np.diff(saved.t) > 0) and np.all(np.isfinite(saved.y))
    assert saved.message.startswith("Interrupted (KeyboardInterrupt) near t = ")

    # The nodes kept are still right: within the tolerance of the RK8 track
    # and of an independent reference (computed by the run's own diagnostics).
    assert np.abs(saved.global_error).max() <= 1e-6
    true = summary["diagnostics"]["global_error"]
    assert true["source"] == "independent"
    assert max(true["max_abs"].values()) <= 1.05e-6

    # The summary table and the message reached stdout; the files are listed.
    assert "INTERRUPTED (partial results)" in child.stdout
    assert "Interrupted (KeyboardInterrupt)" in child.stdout
    assert {"solution.npz", "summary.json"} <= set(summary["files"])
    assert not list(out.glob(".*.tmp"))  # no temporary file left behind


def test_an_interrupted_runs_message_names_the_running_commands_signal_only():
    """The message names SIGTERM while the command that received it runs;
    a library call after it in the same process is told KeyboardInterrupt."""
    from hamrkq._interruption import RECEIVED, interrupted_near
    from hamrkq.cli.interrupts import sigterm_as_interrupt

    assert interrupted_near(2) == "Interrupted (KeyboardInterrupt) near t = 2.0."
    with sigterm_as_interrupt():
        RECEIVED.append("SIGTERM")  # as its handler records it
        assert interrupted_near(2.5) == "Interrupted (SIGTERM) near t = 2.5."
        RECEIVED.append("SIGINT")
        assert interrupted_near(2.5).startswith("Interrupted (KeyboardInterrupt)")
        RECEIVED.append("SIGTERM")
    assert RECEIVED[-1] == "SIGTERM"  # kept for the command's exit
    assert interrupted_near(3).startswith("Interrupted (KeyboardInterrupt)")
