"""`hamrkq compile`: the kernel and systems in the cache before their first use."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

import hamrkq
from hamrkq.backends import compiled
from hamrkq.backends import kernel as kernel_module
from hamrkq.cli import main

ROOT = Path(__file__).resolve().parents[1]


def run(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(list(argv))
    return status, out.getvalue(), err.getvalue()


def test_compile_puts_the_systems_and_the_kernel_in_the_cache():
    status, out, err = run("compile", "harmonic", str(ROOT / "problems" / "pendulum.toml"))
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("cache: ")
    # the kernel's line comes first if it is cached, last if a helper compiled it
    labels = sorted(line.split(":")[0] for line in lines[1:])
    assert labels == ["harmonic", "pendulum", "the step kernel"], out
    assert all(("compiled" in line or "already in the cache" in line) for line in lines[1:])
    for name in ("harmonic", "pendulum"):
        for gamma in ("shadow", "tangent", "paper"):  # both parts of the code
            assert compiled.is_compiled(hamrkq.load_problem(name).hamiltonian, gamma)
    assert kernel_module.kernel_cached()
    # a second time, nothing is compiled
    status, out, _ = run("compile", "harmonic")
    assert status == 0 and "harmonic: already in the cache" in out


def test_compile_names_what_is_wrong(monkeypatch):
    status, out, err = run("compile", "harmonic", "no_such_problem")
    assert status == 2 and "no_such_problem" in err and out == ""  # nothing done
    monkeypatch.setenv("HAMRKQ_DISABLE_NUMBA", "1")
    status, _, err = run("compile")
    assert status == 2 and "nothing can be compiled" in err and "HAMRKQ_DISABLE_NUMBA" in err


@pytest.mark.slow
def test_after_compile_a_first_run_in_a_fresh_process_compiles_nothing(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), HAMRKQ_COMPILE="background")
    env["HAMRKQ_CACHE_DIR"] = str(tmp_path / "hamrkq")
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    env.pop("HAMRKQ_DISABLE_NUMBA", None)
    done = subprocess.run([sys.executable, "-m", "hamrkq", "compile", "kepler"], env=env,
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "kepler: compiled" in done.stdout
    code = (
        "import hamrkq\n"
        "from hamrkq.backends import background, compiled\n"
        "sol = hamrkq.solve(hamrkq.load_problem('kepler'), t_span=(0, 1))\n"
        "print(sol.options['backend'], compiled.COMPILE_COUNT, len(background._HELPERS),"
        " sol.stats.get('interpreted_steps', 0))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr
    # compiled from the first step: no helper, nothing compiled, nothing interpreted
    assert done.stdout.split() == ["numba", "0", "0", "0"]
