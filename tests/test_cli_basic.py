"""`hamrkq list` and `hamrkq show` from the test process, and the program's exit."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

import hamrkq
from hamrkq.cli import main


def test_list_shows_every_problem(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in hamrkq.list_problems():
        assert name in out
    assert "prentice2011" in out


def test_show_prentice2011(capsys):
    assert main(["show", "prentice2011"]) == 0
    out = capsys.readouterr().out
    assert "p**2/2 - (1 - p/6)*cos(q)" in out
    assert "dq/dt = p + cos(q)/6" in out
    assert "[conserved]" in out


def test_show_latex(capsys):
    assert main(["show", "kepler", "--latex"]) == 0
    out = capsys.readouterr().out
    assert r"\frac" in out and r"\sqrt" in out


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [(["show", "no_such_problem"], "no problem named"), (["frobnicate"], "invalid choice")],
)
def test_bad_input_exits_2_without_traceback(capsys, argv, fragment):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err


def _program(argv: list[str]) -> subprocess.CompletedProcess:
    """``entry_point`` in a fresh process whose stdout is a pipe (block-buffered,
    so an exit that skipped the flush would lose output), with an ``atexit``
    handler registered before it runs."""
    script = (
        "import atexit, sys\n"
        "atexit.register(lambda: print('atexit ran'))\n"
        f"sys.argv = ['hamrkq', *{argv!r}]\n"
        "from hamrkq.cli import entry_point\n"
        "entry_point()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(hamrkq.__file__).parents[1])}
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, env=env
    )


def test_the_program_flushes_runs_atexit_and_keeps_the_exit_status():
    done = _program(["list"])
    assert done.returncode == 0, done.stderr
    assert all(name in done.stdout for name in hamrkq.list_problems())
    assert done.stdout.endswith("atexit ran\n")
    done = _program(["show", "no_such_problem"])
    assert done.returncode == 2
    assert done.stderr.startswith("hamrkq: error: ") and "no problem named" in done.stderr
    assert done.stdout == "atexit ran\n"


def test_the_version_has_one_home_that_the_installed_metadata_agrees_with(capsys):
    from importlib.metadata import version

    assert version("hamrkq") == hamrkq.__version__
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"hamrkq {hamrkq.__version__}"
