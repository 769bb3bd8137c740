"""The background compile of a first use (hamrkq.backends.background).

A first run starts on the interpreted loop while helpers compile, and goes
on compiled once the code is ready.  That is only sound if the two backends
compute the same bits for every method a user gets by default, so that the
switch cannot show in the result: checked here for the family's members
(test_compiled.py checks rk34q8 and rk34 on every catalogue problem), then
the switch itself with a stand-in helper whose readiness the test controls,
then the real helpers in a fresh process with empty caches.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import sympy
from helpers import counters

import hamrkq
from hamrkq.backends import background, codegen, compiled, first_use, kernel_helper, numba_compile
from hamrkq.errors import HamrkqWarning, OptionError

ROOT = Path(__file__).resolve().parents[1]

# (problem, method, atol): the default member of each tolerance band, the
# highest orders, the rounding witness (tight tolerance), Richardson's Gamma.
FAMILY_CASES = [
    ("prentice2011", "auto", 1e-6),
    ("kepler", "rk45q12", 1e-8),
    ("henon_heiles", "rk67q12", 1e-9),
    ("kepler", "rk89q12", 1e-12),
    ("prentice2011", "rk78q12", 1e-12),
    ("double_pendulum", "rk56q10", 1e-7),
]


def _same_run(a, b):
    assert a.status == b.status
    same = [counters(s.stats) for s in (a, b)]
    for stats in same:
        stats.pop("interpreted_steps", None)
    assert same[0] == same[1]
    np.testing.assert_array_equal(b.t, a.t)
    for name in ("y", "z", "gamma", "global_error"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)


@pytest.mark.parametrize(("name", "method", "atol"), FAMILY_CASES)
def test_the_family_gives_the_same_bits_on_both_backends(name, method, atol):
    problem = hamrkq.load_problem(name)
    t0, t1 = problem.t_span
    span = (t0, t0 + 0.05 * (t1 - t0))
    options = {"t_span": span, "method": method, "atol": atol, "rtol": 0.0, "max_steps": 400}
    a = hamrkq.solve(problem, backend="python", **options)
    b = hamrkq.solve(problem, backend="numba", **options)
    assert a.t.size >= 5
    _same_run(a, b)


# -- the switch, with a stand-in helper ------------------------------------------


class StandIn:
    """A helper that is ready after ``checks`` questions (never, if None)."""

    def __init__(self, ham, checks):
        self.ham, self.checks, self.asked = ham, checks, 0
        self.loaded = False

    def functions(self, gamma="tangent"):
        self.asked += 1
        if self.checks is None or self.asked <= self.checks:
            return None
        self.loaded = True
        return first_use.kernel_functions(self.ham, gamma)


@pytest.mark.parametrize("checks", [0, 3, 8, None])
def test_a_run_that_switches_to_compiled_code_midway_gives_the_same_bits(monkeypatch, checks):
    problem = hamrkq.load_problem("prentice2011")
    options = {"t_span": (0.0, 60.0), "method": "rk34q8"}
    reference = hamrkq.solve(problem, backend="numba", **options)
    stand_in = StandIn(problem.hamiltonian, checks)
    monkeypatch.setattr(background, "start", lambda ham, gamma: stand_in)
    sol = hamrkq.solve(problem, **options)
    _same_run(reference, sol)
    np.testing.assert_allclose(sol.energy, reference.energy, rtol=1e-14)
    steps, interpreted = sol.stats["steps"], sol.stats["interpreted_steps"]
    if checks == 0:  # ready before the first step
        assert (interpreted, sol.options["backend"]) == (0, "numba")
    elif checks is None:  # never ready: the whole run interpreted, and said so
        assert (interpreted, sol.options["backend"]) == (steps, "python")
    else:
        assert 0 < interpreted < steps and sol.options["backend"] == "numba"
        assert stand_in.asked == checks + 1


def test_chunks_are_short_until_the_switch(monkeypatch):
    # 1 step, then sized to UPGRADE_CHECK_SECONDS: many checks in a short run.
    problem = hamrkq.load_problem("prentice2011")
    stand_in = StandIn(problem.hamiltonian, None)
    monkeypatch.setattr(background, "start", lambda ham, gamma: stand_in)
    sol = hamrkq.solve(problem, t_span=(0.0, 30.0), method="rk34q8")
    assert sol.stats["steps"] > 400
    assert stand_in.asked > 4


def test_the_mode_is_read_from_the_environment(monkeypatch):
    monkeypatch.delenv(background.COMPILE_ENV, raising=False)
    assert background.compile_mode() == "background"
    monkeypatch.setenv(background.COMPILE_ENV, " Wait ")
    assert background.compile_mode() == "wait"
    monkeypatch.setenv(background.COMPILE_ENV, "later")
    with pytest.raises(OptionError, match=r"HAMRKQ_COMPILE='later'.*'background', 'wait'"):
        background.compile_mode()


def test_explicit_numba_and_wait_mode_compile_first(monkeypatch):
    calls = []
    monkeypatch.setattr(background, "start", lambda ham, gamma: calls.append(ham))
    problem = hamrkq.load_problem("harmonic")
    hamrkq.solve(problem, backend="numba", t_span=(0.0, 1.0))
    hamrkq.solve(problem, backend="python", t_span=(0.0, 1.0))
    hamrkq.solve(problem, method="verlet", step=0.1, t_span=(0.0, 1.0))
    assert calls == []
    # ensemble members are prepared without it (they compile once, up front)
    from hamrkq.solve import prepare

    assert prepare(problem, t_span=(0.0, 1.0)).task.compiling is None


def test_nothing_starts_when_the_code_is_cached(monkeypatch):
    monkeypatch.setenv(background.COMPILE_ENV, "background")
    ham = hamrkq.load_problem("harmonic").hamiltonian
    first_use.warm_up(ham)
    assert compiled.is_compiled(ham)
    assert background.start(ham) is None


def _unique_system(k):
    """A small system no other test compiles (its own cache key)."""
    q, p = sympy.symbols("q p", real=True)
    return hamrkq.Hamiltonian(p**2 / 2 + sympy.cos(q) * k + q**4 / 11, q=[q], p=[p])


def test_the_tangent_part_is_generated_for_the_helper_only_where_the_run_calls_it(
    monkeypatch, tmp_path
):
    """auto's shadow estimate calls no Jacobian: its first use neither derives
    nor prints one; rk34q8's tangent estimate does, so the helper, which
    cannot generate code, finds it in the cache and compiles it too."""
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path))
    monkeypatch.setenv(background.COMPILE_ENV, "background")
    monkeypatch.setattr(kernel_helper, "cores", lambda: 2)
    spawned = []
    monkeypatch.setattr(
        kernel_helper, "spawn_helper", lambda code: spawned.append(code) or _finished("pass")
    )
    shadow, tangent = _unique_system(3), _unique_system(5)
    assert background.start(shadow, "shadow") is not None
    assert background.start(tangent, "tangent") is not None
    assert len(spawned) == 2
    assert codegen.is_cached(shadow) and not codegen.is_cached(shadow, part="tangent")
    assert "jacobian" not in vars(shadow)
    assert codegen.is_cached(tangent, part="tangent")
    # The helper's work, here: the system part only, then both.
    before = numba_compile.stats()["compiled"]
    background.build(codegen.cache_key(shadow), "system")
    assert numba_compile.stats()["compiled"] - before == 3  # rhs, energy, energy_rows
    assert not codegen.is_cached(shadow, part="tangent")
    assert compiled.is_compiled(shadow, "shadow") and not compiled.is_compiled(shadow, "tangent")
    before = numba_compile.stats()["compiled"]
    background.build(codegen.cache_key(tangent), "system")
    assert numba_compile.stats()["compiled"] - before == 5  # and jac, rhs_jvp
    assert compiled.is_compiled(tangent, "tangent")
    # A later run of the first system with the tangent estimate: its helper
    # compiles the tangent part, which the run generates first.
    spawned.clear()
    assert background.start(shadow, "tangent") is not None and len(spawned) == 1
    assert codegen.is_cached(shadow, part="tangent")
    before = numba_compile.stats()
    background.build(codegen.cache_key(shadow), "system")
    after = numba_compile.stats()
    assert (after["compiled"] - before["compiled"], after["loaded"] - before["loaded"]) == (2, 3)
    assert compiled.is_compiled(shadow, "tangent")


# -- a helper that fails --------------------------------------------------------


def _finished(code):
    process = subprocess.Popen([sys.executable, "-c", code])
    process.wait()
    return process


def test_a_failed_helper_makes_the_run_compile_here():
    ham = hamrkq.load_problem("kepler").hamiltonian
    helper = background.BackgroundCompile(ham, [_finished("raise SystemExit(3)")])
    functions = helper.functions()
    assert functions is not None and helper.loaded
    assert functions.rhs is compiled.compile_system(ham).rhs


def test_a_helper_still_running_is_waited_for_only_by_wait():
    ham = hamrkq.load_problem("kepler").hamiltonian
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        helper = background.BackgroundCompile(ham, [process])
        assert helper.running and helper.functions() is None
        assert helper.wait(timeout=0.2) is False
    finally:
        process.kill()
        process.wait()
    assert helper.wait(timeout=5) is True and not helper.running


def test_when_numba_cannot_be_used_the_run_stays_interpreted_with_the_warning(monkeypatch):
    ham = hamrkq.load_problem("kepler").hamiltonian
    helper = background.BackgroundCompile(ham, [_finished("pass")])
    monkeypatch.setenv(numba_compile.DISABLE_ENV, "1")
    monkeypatch.setattr(first_use, "_WARM", set())
    monkeypatch.setattr(compiled, "_SYSTEMS", {})
    with pytest.warns(HamrkqWarning, match="HAMRKQ_DISABLE_NUMBA is set.*pure-Python"):
        assert helper.functions() is None
    assert helper.failed and not helper.loaded
    assert helper.functions() is None  # asked again: no second warning, no retry


# -- the real helpers, in a fresh process with empty caches -----------------------

FIRST_USE = textwrap.dedent(
    """
    import json, sys
    import hamrkq
    from hamrkq.backends import background, compiled
    problem = hamrkq.load_problem(sys.argv[1], **json.loads(sys.argv[4]))
    t0 = problem.t_span[0]
    options = json.loads(sys.argv[3])
    sol = hamrkq.solve(problem, t_span=(t0, t0 + float(sys.argv[2])), **options)
    helpers = list(background._HELPERS.values())
    finished = all(h.wait(timeout=600) for h in helpers)
    print(json.dumps({
        "backend": sol.options["backend"], "stats": dict(sol.stats), "helpers": len(helpers),
        "processes": [len(h.processes) for h in helpers],
        "returncodes": [p.returncode for h in helpers for p in h.processes],
        "finished": finished, "numba": compiled.stats(),
        "y": sol.y.tolist(), "t": sol.t.tolist(), "options": dict(sol.options),
    }))
    """
)


def _fresh(tmp_path, name, span, mode="background", params=None, **options):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env["HAMRKQ_CACHE_DIR"] = str(tmp_path / "hamrkq")
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    env[background.COMPILE_ENV] = mode
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            FIRST_USE,
            name,
            str(span),
            json.dumps(options),
            json.dumps(params or {}),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
        check=True,
    )
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.slow
def test_autos_rerun_in_double_double_loads_what_the_helpers_compile(tmp_path):
    # Kepler e = 0.6 at 1e-13: auto's first run (interpreted, the helpers
    # compiling) stops at double precision's floor near t = 4.6, and auto
    # runs again with the quencher in double-double.  Before, that rerun
    # compiled the kernel and the system again in this process, beside the
    # helpers, and then reported the compiled rerun as interpreted (backend
    # "python", 0 interpreted steps).
    kepler = dict(params={"e": 0.6}, method="auto", atol=1e-13)
    run = _fresh(tmp_path, "kepler", 10.0, **kepler)
    assert run["options"]["quencher_precision"] == "double-double"
    assert run["stats"]["discarded_evaluations"] > 0
    assert run["backend"] == "numba" and run["stats"]["interpreted_steps"] == 0
    # compiled here: rhs_dd alone (the helpers compiled the rest)
    assert run["numba"]["compiled"] == 1
    wait = _fresh(tmp_path / "wait", "kepler", 10.0, "wait", **kepler)
    assert wait["y"] == run["y"] and wait["t"] == run["t"]


@pytest.mark.slow
def test_a_first_use_runs_at_once_and_leaves_the_compiled_code_in_the_cache(tmp_path):
    first = _fresh(tmp_path, "prentice2011", 10.0)
    # Nothing compiled in the calling process; the whole short run interpreted.
    assert first["numba"]["compiled"] == 0
    assert first["backend"] == "python"
    assert first["stats"]["interpreted_steps"] == first["stats"]["steps"] > 100
    assert first["helpers"] == 1 and first["processes"] == [1]
    assert first["finished"] and first["returncodes"] == [0]
    # The next process loads everything from the cache and compiles nothing.
    second = _fresh(tmp_path, "prentice2011", 10.0)
    assert second["backend"] == "numba" and second["helpers"] == 0
    assert "interpreted_steps" not in second["stats"]
    assert second["numba"]["compiled"] == 0 and second["numba"]["loaded"] >= 5
    assert second["y"] == first["y"] and second["t"] == first["t"]
