"""The compiled backend: bit-for-bit parity with the interpreted kernel on the
whole catalogue, one source for both (the compiled kernel is
``hamrkq.rkq.loop.advance`` itself), the on-disk cache across processes,
parameter sweeps without recompilation, and the fallback."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from helpers import counters

import hamrkq
from hamrkq.backends import codegen, compiled, first_use, kernel, kernel_helper, numba_compile
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import HamrkqWarning, OptionError
from hamrkq.rkq import layout, loop
from hamrkq.rkq.config import Settings
from hamrkq.rkq.driver import Integration, python_functions
from hamrkq.rkq.family import get_member

pytestmark = pytest.mark.skipif(
    not compiled.available()[0], reason=f"compiled backend unavailable: {compiled.available()[1]}"
)

ROOT = Path(__file__).resolve().parents[1]
#: Bit-for-bit agreement rests on one source for both backends: the kernel's
#: element loops sum over stages in a fixed order, compiled or not.
CATALOGUE = hamrkq.list_problems()
#: Systems whose generated functions take numba several seconds to compile.
BIG = {"outer_solar_system", "pleiades"}
CASES = [pytest.param(n, marks=pytest.mark.slow) if n in BIG else n for n in CATALOGUE]
METHODS = ("rk34q8", "rk34")


def _settings(problem, fraction=0.02, max_steps=300):
    """The problem's tolerances over a short span (a fraction of its own)."""
    ham = problem.hamiltonian
    dim = ham.dim
    integration = problem.integration
    atol = np.broadcast_to(np.asarray(integration.get("atol", 1e-6), float), (dim,)).copy()
    rtol = np.broadcast_to(np.asarray(integration.get("rtol", 0.0), float), (dim,)).copy()
    t0, t1 = problem.t_span
    return t0, t0 + fraction * (t1 - t0), {"atol": atol, "rtol": rtol, "max_steps": max_steps}


_CODES = {
    "quench": layout.QUENCH_NODE,
    "rule": layout.RULE_COMPONENTWISE,
    "gamma": layout.GAMMA_TANGENT,
}


def _run(functions, problem, t0, t_end, method, atol, rtol, **options):
    ham = problem.hamiltonian
    settings = Settings(**{**_CODES, **options})
    integration = Integration(
        functions,
        get_member(method),
        ham.parameter_values(),
        t0,
        problem.y0,
        t_end,
        atol,
        rtol,
        settings,
    )
    with np.errstate(all="ignore"):
        return integration.run()


def _interpreted(problem, t0, t_end, method, **options):
    """The interpreted kernel on the same generated functions (plain Python)."""
    ham = problem.hamiltonian
    rhs, jac = codegen.load_module(ham).rhs, codegen.load_module(ham, part="tangent").jac
    return _run(python_functions(rhs, jac), problem, t0, t_end, method, **options)


#: The estimate of Gamma by its kernel code (what of the system the kernel calls).
_GAMMA_NAMES = {
    layout.GAMMA_TANGENT: "tangent",
    layout.GAMMA_PAPER: "paper",
    layout.GAMMA_SHADOW: "shadow",
    layout.GAMMA_OFF: "off",
}


def _compiled(problem, t0, t_end, method, **options):
    gamma = _GAMMA_NAMES[options.get("gamma", _CODES["gamma"])]
    functions = first_use.kernel_functions(problem.hamiltonian, gamma)
    return _run(functions, problem, t0, t_end, method, **options)


def _assert_parity(a, b):
    """The same nodes, values, estimates and counters, bit for bit."""
    assert a.status == b.status
    assert a.stats == b.stats
    for name in ("t", "y", "z", "gamma", "quenched"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None
            continue
        np.testing.assert_array_equal(y, x, err_msg=name)


@pytest.fixture(scope="module", autouse=True)
def compiled_loop():
    """Compile (or load) the loop once, up front (about 8 s when the cache is
    cold), rather than inside whichever test happens to run first."""
    problem = hamrkq.load_problem("harmonic")
    _compiled(problem, 0.0, 0.1, "rk34q8", atol=np.full(2, 1e-6), rtol=np.zeros(2))


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("method", METHODS)
def test_parity_with_the_interpreted_loop(name, method):
    problem = hamrkq.load_problem(name)
    t0, t_end, options = _settings(problem)
    a = _interpreted(problem, t0, t_end, method, **options)
    b = _compiled(problem, t0, t_end, method, **options)
    assert a.t.size >= 9
    _assert_parity(a, b)


@pytest.mark.parametrize(
    "options",
    [
        {"gamma": layout.GAMMA_PAPER},
        {"gamma": layout.GAMMA_OFF},
        {"quench": layout.QUENCH_REDO, "theta": 0.5},
        {"rule": layout.RULE_PRENTICE},
        {"keep_every": 7},
        {"t_eval": np.linspace(0.0, 30.0, 41)},
    ],
)
def test_parity_for_the_options(options):
    problem = hamrkq.load_problem("prentice2011")
    base = {"atol": np.full(2, 1e-7), "rtol": np.full(2, 1e-9)}
    a = _interpreted(problem, 0.0, 30.0, "rk34q8", **base, **options)
    b = _compiled(problem, 0.0, 30.0, "rk34q8", **base, **options)
    _assert_parity(a, b)


def test_parity_backward_and_from_nonzero_t0():
    problem = hamrkq.load_problem("kepler", e=0.9)
    options = {"atol": np.full(4, 1e-9), "rtol": np.zeros(4)}
    a = _interpreted(problem, 3.0, -4.0, "rk34q8", **options)
    b = _compiled(problem, 3.0, -4.0, "rk34q8", **options)
    assert a.t[-1] == -4.0 and a.status == 0
    _assert_parity(a, b)


# -- one source -------------------------------------------------------------------


def test_the_compiled_kernel_is_the_interpreted_function_itself():
    problem = hamrkq.load_problem("harmonic")
    functions = first_use.kernel_functions(problem.hamiltonian)
    dispatchers = list(functions.advance.dispatchers.values())
    assert dispatchers and all(d.py_func is loop.advance for d in dispatchers)
    # Its machine code is cached under a folder named by the kernel's hash.
    assert compiled.kernel_cache_dir().name.startswith("kernel-")


# -- what is compiled for whom -----------------------------------------------------


def test_jac_and_rhs_jvp_are_compiled_only_for_the_runs_that_call_them():
    # 14 state variables: above the fused dimension, rhs_jvp calls jac.  Before,
    # both were compiled for every system (about half of the outer solar
    # system's compile), though only rk34q8's tangent estimate calls rhs_jvp
    # and only the paper's estimate calls jac.
    q, p = sp.symbols("x0:7", real=True), sp.symbols("u0:7", real=True)
    H = sum(u**2 / 2 for u in p) + sum(x**4 / 4 for x in q)
    H += sum((q[i] - q[i + 1]) ** 2 / 2 for i in range(6))
    ham = hamrkq.Hamiltonian(H, q=list(q), p=list(p))
    q0, p0 = [0.1 * (k + 1) for k in range(7)], [0.0] * 7

    def both_backends(**options):
        runs = [hamrkq.solve(ham, q0, p0, (0.0, 1.0), backend=b, **options)
                for b in ("numba", "python")]  # fmt: skip
        for name in ("t", "y", "z", "gamma"):
            np.testing.assert_array_equal(getattr(runs[0], name), getattr(runs[1], name))
        return runs[0]

    auto = both_backends(method="auto", atol=1e-9)
    system = compiled.compile_system(ham)
    assert auto.success and not system.compiled_for("tangent")
    assert not system.compiled_for("paper")
    tangent = both_backends(method="rk34q8", atol=1e-8)
    assert tangent.success and np.all(np.isfinite(tangent.gamma))
    assert system.compiled_for("tangent") and system.compiled_for("paper")  # rhs_jvp calls jac
    paper = both_backends(method="rk34q8", atol=1e-8, global_error_estimate="paper")
    assert paper.success and np.all(np.isfinite(paper.gamma))


def test_the_kernel_counts_as_cached_by_its_own_index_only(tmp_path, monkeypatch):
    # The kernel's folder also holds the stand-ins and the extras: their
    # indexes alone must not spare a first use the kernel's helper.
    monkeypatch.setattr(kernel, "_KERNEL", {})
    monkeypatch.setattr(kernel, "kernel_cache_dir", lambda: tmp_path)
    (tmp_path / "backends_0").mkdir()
    (tmp_path / "backends_0" / "kernel._unused_jac-1.py311.nbi").write_bytes(b"")
    assert not kernel.kernel_cached()
    (tmp_path / "rkq_0").mkdir()
    (tmp_path / "rkq_0" / "loop.advance-2.py311.nbi").write_bytes(b"")
    assert kernel.kernel_cached()


def test_the_stand_ins_fill_their_outputs_with_nan():
    dim = 3
    out, dout, JM = np.zeros(dim), np.zeros(dim), np.zeros((dim, dim))
    y, params = np.ones(dim), np.empty(0)
    kernel.unused_function("jac")(0.0, y, params, JM)
    kernel.unused_function("rhs_jvp")(0.0, y, params, y, out, dout, JM)
    assert np.isnan(JM).all() and np.isnan(out).all() and np.isnan(dout).all()


# -- parameters, cache, counters ---------------------------------------------------


def test_a_parameter_sweep_does_not_recompile():
    problem = hamrkq.load_problem("kepler")
    options = {"atol": np.full(4, 1e-8), "rtol": np.zeros(4)}
    _compiled(problem, 0.0, 1.0, "rk34q8", **options)
    before = compiled.COMPILE_COUNT
    for e in (0.1, 0.5, 0.9):
        swept = hamrkq.load_problem("kepler", e=e)
        params = swept.hamiltonian.parameter_values()
        out = _compiled(swept, 0.0, 2 * np.pi, "rk34q8", **options)
        # One period later the orbit is back at pericentre (1 - e, 0).
        assert abs(out.y[-1, 0] - (1 - e)) < 1e-6
        np.testing.assert_allclose(
            compiled.energy(swept.hamiltonian, out.t, out.y, params), -0.5, atol=1e-7
        )
    assert compiled.COMPILE_COUNT == before


def test_energy_matches_the_numeric_layer():
    problem = hamrkq.load_problem("double_pendulum")
    ham = problem.hamiltonian
    rng = np.random.default_rng(2)
    Y = problem.y0 + 0.1 * rng.standard_normal((50, ham.dim))
    t = np.linspace(0.0, 5.0, 50)
    params = ham.parameter_values()
    np.testing.assert_allclose(
        compiled.energy(ham, t, Y, params), numeric_of(ham).energy(t, Y, params), rtol=1e-13
    )


SCRIPT = textwrap.dedent(
    """
    import json
    import numpy as np
    import sympy as sp
    import hamrkq
    from hamrkq.backends import compiled

    q, p, w = sp.symbols("q p w", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + w * (1 - sp.cos(q)) + q**4 / 24, q=[q], p=[p],
                             parameters={w: 1.0})
    out = hamrkq.solve(ham, [0.5], [0.25], (0.0, 20.0), parameters={"w": 1.25},
                       atol=1e-8, backend="numba")
    print(json.dumps({"compiled": compiled.COMPILE_COUNT, "stats": compiled.stats(),
                      "nodes": int(out.t.size), "last": out.y[-1].tolist()}))
    """
)


def _fresh_process(cache: Path, script: str = SCRIPT) -> dict:
    env = {**os.environ, codegen.CACHE_ENV: str(cache), "PYTHONPATH": str(ROOT)}
    env.pop(compiled.DISABLE_ENV, None)
    # numba's own cache directory would take the machine code elsewhere; this
    # test is about hamrkq's cache directory holding it.
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run(
        [sys.executable, "-c", script],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


WARM_UP_SINGULAR = textwrap.dedent(
    """
    import json
    import sympy as sp
    import hamrkq
    from hamrkq.backends import first_use, kernel

    q, p, a = sp.symbols("q p a", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 - (1 - p / a) * sp.cos(q), q=[q], p=[p],
                             parameters={a: 6.0})
    first_use.warm_up(ham, announce=False)
    print(json.dumps({"kernels": len(kernel.kernel().dispatchers)}))
    """
)


def test_the_warm_up_makes_the_kernel_where_f_is_singular_at_the_probe():
    # QA: the probe runs one step with every parameter 0; (1 - p/a) cos q is
    # not finite there, the probe ended before its step, the kernel was not
    # made by the warm-up, and the first run compiled it inside its
    # integration (12.7 s of integrate_s, compile_s 1.2 s); hamrkq compile
    # left no kernel.  A fresh process, with this session's caches.
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop(compiled.DISABLE_ENV, None)
    done = subprocess.run([sys.executable, "-c", WARM_UP_SINGULAR], env=env,
                          capture_output=True, text=True, timeout=600, check=True)  # fmt: skip
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {"kernels": 1}


@pytest.mark.slow
def test_a_second_process_loads_everything_from_the_cache(tmp_path):
    first = _fresh_process(tmp_path)
    # rhs, jac, energy, energy_rows and the loop: compiled once ...
    assert first["compiled"] >= 5
    second = _fresh_process(tmp_path)
    # ... and a new process compiles nothing: it loads the machine code.
    assert second["compiled"] == 0
    assert second["stats"]["loaded"] >= 5
    assert second["nodes"] == first["nodes"]
    assert second["last"] == first["last"]
    names = {f.name for f in tmp_path.iterdir()}
    assert any(n.startswith("kernel-") for n in names)
    assert (tmp_path / "__pycache__").is_dir()


CHAIN_SCRIPT = textwrap.dedent(
    """
    import json
    import sympy as sp
    import hamrkq
    from hamrkq.backends import compiled

    q, p = sp.symbols("q0:6", real=True), sp.symbols("p0:6", real=True)
    H = sum(x**2 / 2 for x in p) + sum(x**4 / 4 for x in q)
    H += sum((q[i] - q[i + 1]) ** 2 / 2 for i in range(5))
    ham = hamrkq.Hamiltonian(H, q=list(q), p=list(p))
    out = hamrkq.solve(ham, [0.1] * 6, [0.0] * 6, (0.0, 2.0), atol=1e-8, backend="numba",
                       method="rk34q8")
    print(json.dumps({"compiled": compiled.COMPILE_COUNT, "stats": compiled.stats(),
                      "status": out.status.name}))
    """
)


@pytest.mark.slow
def test_a_large_system_has_the_kernel_compiled_by_a_helper_process(tmp_path):
    # 12 state variables (HELPER_MIN_DIM): on an empty cache a helper process
    # compiles the kernel while this one prepares the system, which then
    # loads the kernel from the cache instead of compiling it.
    assert kernel_helper.HELPER_MIN_DIM <= 12
    result = _fresh_process(tmp_path, CHAIN_SCRIPT)
    assert result["status"] == "SUCCESS"
    # rhs, rhs_jvp, energy and energy_rows compiled here (not jac: rk34q8's
    # tangent estimate does not call it); the kernel and the stand-ins of
    # rhs_jvp and jac, which the helper compiled beside it, loaded
    assert result["compiled"] == 4
    assert result["stats"]["loaded"] == 3
    assert any(tmp_path.glob("kernel-*/**/*.nbi"))


def test_the_helper_is_not_started_for_a_small_system_or_a_cached_kernel():
    assert kernel_helper.start_helper(kernel_helper.HELPER_MIN_DIM - 1) is None
    options = {"atol": np.full(2, 1e-8), "rtol": np.zeros(2)}
    _compiled(hamrkq.load_problem("harmonic"), 0.0, 0.1, "rk34q8", **options)
    assert kernel.kernel_cached()
    assert kernel_helper.start_helper(kernel_helper.HELPER_MIN_DIM) is None


# -- availability and fallback -----------------------------------------------------


def test_the_environment_variable_disables_the_backend(monkeypatch):
    monkeypatch.setenv(compiled.DISABLE_ENV, "1")
    ok, reason = compiled.available()
    assert not ok and compiled.DISABLE_ENV in reason
    with pytest.warns(HamrkqWarning, match=compiled.DISABLE_ENV) as caught:
        assert first_use.resolve_backend("auto") == "python"
    assert len([w for w in caught if issubclass(w.category, HamrkqWarning)]) == 1
    with pytest.raises(OptionError, match="backend='numba' cannot be used"):
        first_use.resolve_backend("numba")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert first_use.resolve_backend("python") == "python"  # no warning when chosen


@pytest.mark.parametrize("value", ["0", "", "no"])
def test_other_values_leave_the_backend_on(monkeypatch, value):
    monkeypatch.setenv(compiled.DISABLE_ENV, value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert first_use.resolve_backend("auto") == "numba"


def test_a_system_that_cannot_be_compiled_falls_back_with_one_warning(monkeypatch):
    # Hamiltonian validation now refuses what the code generator cannot print
    # (|q| of a real q compiles since issue 16), so a failing compilation is
    # simulated at the point where resolve_backend meets it.
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**4, q=[q], p=[p])

    def fail(system):
        raise compiled.BackendUnavailable("the system cannot be compiled: NoSuchFunction(q)")

    monkeypatch.setattr(compiled, "compile_system", fail)
    with pytest.warns(HamrkqWarning, match="cannot be compiled.*NoSuchFunction") as caught:
        assert first_use.resolve_backend("auto", ham) == "python"
    assert len(caught) == 1
    with pytest.raises(OptionError, match="NoSuchFunction"):
        first_use.resolve_backend("numba", ham)


def test_unknown_backend_is_an_option_error():
    with pytest.raises(OptionError, match="'auto', 'numba', 'python'"):
        first_use.resolve_backend("cuda")


SOLVE_MODULE = importlib.import_module("hamrkq.solve")


@pytest.mark.skipif(
    "numba" not in getattr(SOLVE_MODULE, "BACKENDS", ()),
    reason="hamrkq.solve has no backend='numba' yet (the hook in docs/performance.md)",
)
@pytest.mark.parametrize("name", CASES)
def test_solve_gives_the_same_solution_on_both_backends(name):
    problem = hamrkq.load_problem(name)
    t0, t1 = problem.t_span
    span = (t0, t0 + 0.02 * (t1 - t0))
    a = hamrkq.solve(problem, t_span=span, max_steps=300, backend="python")
    b = hamrkq.solve(problem, t_span=span, max_steps=300, backend="numba")
    assert (a.options["backend"], b.options["backend"]) == ("python", "numba")
    assert a.status == b.status
    assert counters(a.stats) == counters(b.stats)
    np.testing.assert_array_equal(b.t, a.t)
    # the energy too (QA: the interpreted run's came from lambdify, up to
    # 120 ulp off the compiled one's on arenstorf)
    for name in ("y", "z", "gamma", "global_error", "energy"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)


def test_a_slow_first_use_says_that_it_compiles(monkeypatch):
    import io

    monkeypatch.setattr(first_use, "ANNOUNCE_AFTER", 0.0)
    prepare = first_use._warm_up

    def slow_prepare(ham):  # longer than ANNOUNCE_AFTER even with a warm disk cache
        time.sleep(0.05)
        prepare(ham)

    monkeypatch.setattr(first_use, "_warm_up", slow_prepare)
    q, p, w = sp.symbols("q p omega_notice")
    ham = hamrkq.Hamiltonian(p**2 / 2 + w**2 * q**2 / 2, [q], [p], parameters=[w])
    stream = io.StringIO()
    first_use.warm_up(ham, stream=stream, announce=True)
    text = stream.getvalue()
    assert "hamrkq: compiling the code for H = " in text
    assert str(codegen.cache_dir()) in text
    assert "hamrkq: compiled in" in text
    # once per system and process: no second notice
    again = io.StringIO()
    first_use.warm_up(ham, stream=again, announce=True)
    assert again.getvalue() == ""


def test_the_compile_notice_is_quiet_off_a_terminal_and_when_fast(monkeypatch):
    import io

    from hamrkq._progress import WaitNotice

    notice = WaitNotice(lambda: "x", "done", 1.0, stream=io.StringIO())
    assert not notice.enabled  # a StringIO is not a terminal
    stream = io.StringIO()
    with WaitNotice(lambda: "x", "done", 1.0, stream=stream, enabled=True):
        pass  # done long before a second has passed
    assert stream.getvalue() == ""


def test_the_kernel_functions_pickle_to_the_receiving_process_kernel():
    import pickle

    problem = hamrkq.load_problem("harmonic")
    functions = first_use.kernel_functions(problem.hamiltonian)
    copy = pickle.loads(pickle.dumps(functions))
    assert copy.advance is compiled.kernel()
    options = {"atol": np.full(2, 1e-8), "rtol": np.zeros(2)}
    _assert_parity(
        _run(copy, problem, 0.0, 1.0, "rk34q8", **options),
        _run(functions, problem, 0.0, 1.0, "rk34q8", **options),
    )


def test_the_kernel_key_tells_apart_every_argument_numba_types_apart():
    # The kernel is called through the entry point of the signature its key
    # names, which does not check types: equal keys must mean equal types.
    import numba

    Inputs = layout.Inputs
    base = np.zeros((4, 3))
    readonly = np.zeros(3)
    readonly.setflags(write=False)
    unaligned = np.frombuffer(bytearray(8 * 4 + 1), dtype=np.float64, offset=1, count=4)
    record = np.zeros(1, dtype=[("t", "f8"), ("n", "i8")])
    samples = [
        np.zeros(3), np.zeros(3, dtype=np.int64), np.zeros(3, dtype=np.float32), readonly,
        unaligned, np.zeros(6)[::2], base, np.asfortranarray(base), base[:, ::2], base.T,
        np.zeros((2, 2, 2)), record, np.zeros(1, dtype=[("t", "f8"), ("m", "i8")]),
        1, 1.0, True,
        Inputs(*(np.zeros(2) for _ in Inputs._fields)),
        Inputs(*(np.zeros(2) for _ in Inputs._fields[:-1]), np.zeros(2, dtype=np.int64)),
        (np.zeros(2), np.zeros(2)),
    ]  # fmt: skip
    keys = [kernel.describe(value) for value in samples]
    types = [numba.typeof(value) for value in samples]
    for i in range(len(samples)):
        for j in range(len(samples)):
            if keys[i] == keys[j]:
                assert types[i] == types[j], (samples[i], samples[j])
    # Neither is C-contiguous, yet numba types them apart ("F" and "A"): a key
    # of C-contiguity alone would call the F-layout code with a strided array.
    assert types[7].layout == "F" and types[8].layout == "A"
    assert keys[7] != keys[8]


def test_the_kernel_remembers_first_class_function_addresses_numba_would_give():
    from numba.experimental import function_type

    compiled.kernel()
    system = compiled.compile_system(hamrkq.load_problem("harmonic").hamiltonian)
    sig = numba_compile.signatures()["rhs"]
    result = system.rhs.get_compile_result(sig)
    library = result.library
    wrapper = library.get_pointer_to_function(result.fndesc.llvm_cfunc_wrapper_name)
    jit = library.get_pointer_to_function(result.fndesc.llvm_func_name)
    for _ in range(2):  # computed, then remembered
        assert function_type._get_wrapper_address(system.rhs, sig) == wrapper
        assert function_type._get_jit_address(system.rhs, sig) == jit
    assert function_type._get_wrapper_address._hamrkq_remembers
    # anything that is not a compiled dispatcher goes to numba unchanged
    with pytest.raises(NotImplementedError):
        function_type._get_wrapper_address(object(), sig)


def test_the_pair_alone_runs_the_kernel_compiled_for_the_members_with_a_quencher():
    """rk34's placeholder quencher arrays were writeable where every
    tableau's are read-only: another numba type, so a second kernel was
    compiled for the pair alone (7.6 s on an empty cache; QA)."""
    import numba

    pendulum = hamrkq.load_problem("pendulum")
    for method in ("rk34q8", "rk34"):
        hamrkq.solve(pendulum, method=method, t_span=(0.0, 1.0), backend="numba")
    signatures = {
        tuple(d.signatures[0]) for d in kernel.kernel().dispatchers.values() if d.signatures
    }
    assert len(signatures) == 1, [numba.typeof(s) for s in signatures]


def test_the_kernel_loaded_or_compiled_in_a_run_counts_as_compiling(monkeypatch):
    """It was counted as the run's integrate_s (rk34: 7.6 s of 7.6; QA)."""
    compiled_kernel = kernel.kernel()
    monkeypatch.setattr(compiled_kernel, "_by_types", {})  # the next call builds again
    build = kernel._compile_kernel

    def slow_build(arg_types):
        time.sleep(0.3)
        return build(arg_types)

    monkeypatch.setattr(kernel, "_compile_kernel", slow_build)
    sol = hamrkq.solve(hamrkq.load_problem("pendulum"), method="rk34", t_span=(0.0, 1.0),
                       backend="numba")  # fmt: skip
    assert sol.stats["compile_s"] >= 0.3 and sol.stats["integrate_s"] < 0.3, sol.stats
