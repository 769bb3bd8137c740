"""The compiled backend: parity with the interpreted loop on the whole
catalogue, the element-loop primitives against rkq's, the on-disk cache across
processes, parameter sweeps without recompilation, and the fallback."""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends import codegen, compiled
from hamrkq.errors import HamrkqWarning, OptionError
from hamrkq.methods.tableaus import DOP853_RK8, RK3_KUTTA, RK4_CLASSIC
from hamrkq.rkq import kernel as rkq

pytestmark = pytest.mark.skipif(
    not compiled.available()[0], reason=f"compiled backend unavailable: {compiled.available()[1]}"
)

ROOT = Path(__file__).resolve().parents[1]
#: Bit-for-bit agreement rests on rkq's sums over stages in a fixed order
#: (rkq._stage_sum, rkq._matvec), which the compiled twins reproduce; with
#: np.dot (BLAS's order) the backends agreed only to rounding, which the step
#: controller amplified to ~1e-11 in the nodes.
CATALOGUE = hamrkq.list_problems()
#: Systems whose generated functions take numba several seconds to compile.
BIG = {"outer_solar_system", "pleiades"}
CASES = [pytest.param(n, marks=pytest.mark.slow) if n in BIG else n for n in CATALOGUE]
METHODS = {"rk34q8": DOP853_RK8, "rk34": None}


def _settings(problem, fraction=0.02, max_steps=300):
    """The problem's tolerances over a short span (a fraction of its own)."""
    ham = problem.hamiltonian
    dim = ham.dim
    integration = problem.integration
    atol = np.broadcast_to(np.asarray(integration.get("atol", 1e-6), float), (dim,)).copy()
    rtol = np.broadcast_to(np.asarray(integration.get("rtol", 0.0), float), (dim,)).copy()
    t0, t1 = problem.t_span
    return t0, t0 + fraction * (t1 - t0), {"atol": atol, "rtol": rtol, "max_steps": max_steps}


def _interpreted(problem, t0, t_end, rk8, **options):
    """The Python backend on the same generated functions (plain Python)."""
    ham = problem.hamiltonian
    module = codegen.load_module(ham)
    return rkq.run(module.rhs, module.jac, ham.parameter_values(), t0, problem.y0, t_end,
                   rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=rk8, inplace=True, **options)  # fmt: skip


def _compiled(problem, t0, t_end, rk8, **options):
    ham = problem.hamiltonian
    return compiled.run(ham, ham.parameter_values(), t0, problem.y0, t_end,
                        rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=rk8, **options)  # fmt: skip


def _assert_parity(a, b):
    assert a.status == b.status
    assert a.stats == b.stats
    assert a.t.shape == b.t.shape
    scale_t = max(1.0, float(np.max(np.abs(a.t))))
    np.testing.assert_allclose(b.t, a.t, rtol=1e-12, atol=1e-12 * scale_t)
    for name in ("y", "z", "gamma"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None
            continue
        # Relative to each component's size over the run (components cross zero).
        scale = np.max(np.abs(x), axis=0) + 1e-300
        worst = float(np.max(np.abs(y - x) / scale))
        assert worst <= 1e-12, f"{name}: relative difference {worst:.3g}"
    if a.quenched is not None:
        assert np.array_equal(a.quenched, b.quenched)


@pytest.fixture(scope="module", autouse=True)
def compiled_loop():
    """Compile (or load) the loop once, up front (about 8 s when the cache is
    cold), rather than inside whichever test happens to run first."""
    problem = hamrkq.load_problem("harmonic")
    _compiled(problem, 0.0, 0.1, DOP853_RK8, atol=np.full(2, 1e-6), rtol=np.zeros(2))


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("method", sorted(METHODS))
def test_parity_with_the_interpreted_loop(name, method):
    problem = hamrkq.load_problem(name)
    t0, t_end, options = _settings(problem)
    a = _interpreted(problem, t0, t_end, METHODS[method], **options)
    b = _compiled(problem, t0, t_end, METHODS[method], **options)
    assert a.t.size >= 9
    _assert_parity(a, b)


@pytest.mark.parametrize(
    "options",
    [
        {"gamma": rkq.GAMMA_PAPER},
        {"gamma": rkq.GAMMA_OFF},
        {"quench": rkq.QUENCH_REDO, "theta": 0.5},
        {"rule": rkq.RULE_PRENTICE},
        {"keep_every": 7},
        {"t_eval": np.linspace(0.0, 30.0, 41)},
    ],
)
def test_parity_for_the_options(options):
    problem = hamrkq.load_problem("prentice2011")
    base = {"atol": np.full(2, 1e-7), "rtol": np.full(2, 1e-9)}
    a = _interpreted(problem, 0.0, 30.0, DOP853_RK8, **base, **options)
    b = _compiled(problem, 0.0, 30.0, DOP853_RK8, **base, **options)
    _assert_parity(a, b)


def test_parity_backward_and_from_nonzero_t0():
    problem = hamrkq.load_problem("kepler", e=0.9)
    options = {"atol": np.full(4, 1e-9), "rtol": np.zeros(4)}
    a = _interpreted(problem, 3.0, -4.0, DOP853_RK8, **options)
    b = _compiled(problem, 3.0, -4.0, DOP853_RK8, **options)
    assert a.t[-1] == -4.0 and a.status == 0
    _assert_parity(a, b)


# -- the element-loop primitives ---------------------------------------------------


def test_every_primitive_exists_in_rkq():
    """A primitive renamed in rkq would silently lose its fast twin."""
    missing = [name for name in compiled.PRIMITIVES if not hasattr(rkq, name)]
    assert not missing


@pytest.fixture(scope="module")
def kernel():
    compiled._kernel()
    return compiled._KERNEL["namespace"]


def _random_case(rng, dim, stages):
    A = np.tril(rng.standard_normal((stages, stages)), -1)
    K = rng.standard_normal((stages, dim)) * 10.0 ** rng.integers(-6, 6, (stages, 1))
    return A, K


def test_stage_sums_match_rkq_bit_for_bit(kernel):
    rng = np.random.default_rng(7)
    for _ in range(200):
        dim = int(rng.integers(2, 40))
        A, K = _random_case(rng, dim, 12)
        base, lo = rng.standard_normal(dim), rng.standard_normal(dim) * 1e-17
        h = float(rng.uniform(-1, 1))
        for j in range(12):
            expected, got = np.empty(dim), np.empty(dim)
            rkq._combine(base, lo, h, A, j, K, expected)
            kernel["_combine"](base, lo, h, A, j, K, got)
            np.testing.assert_array_equal(got, expected)
            rkq._plain(base, h, A, j, K, expected)
            kernel["_plain"](base, h, A, j, K, got)
            np.testing.assert_array_equal(got, expected)
        b = A[-1].copy()
        expected, got = np.empty(dim), np.empty(dim)
        rkq._increment(h, b, K, expected)
        kernel["_increment"](h, b, K, got)
        np.testing.assert_array_equal(got, expected)
        M, v = rng.standard_normal((dim, dim)), rng.standard_normal(dim)
        rkq._matvec(M, v, expected)
        kernel["_matvec"](M, v, got)
        np.testing.assert_array_equal(got, expected)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_two_sum_delta_and_norm_match_rkq_bit_for_bit(kernel):
    rng = np.random.default_rng(8)
    for _ in range(200):
        dim = int(rng.integers(2, 40))
        hi, inc = rng.standard_normal(dim) * 1e3, rng.standard_normal(dim) * 1e-3
        lo = rng.standard_normal(dim) * 1e-14
        out = [np.empty(dim) for _ in range(4)]
        tmp = [np.empty(dim) for _ in range(4)]
        rkq._two_sum(hi, lo, inc, out[0], out[1], tmp[0], tmp[1])
        kernel["_two_sum"](hi, lo, inc, out[2], out[3], tmp[2], tmp[3])
        np.testing.assert_array_equal(out[2], out[0])
        np.testing.assert_array_equal(out[3], out[1])
        a, b = rng.standard_normal(dim), rng.standard_normal(dim)
        if rng.random() < 0.3:  # NaN and inf must propagate the same way
            a[rng.integers(dim)] = rng.choice([np.nan, np.inf])
        atol = rng.uniform(1e-9, 1e-6, dim)
        rtol = rng.choice([0.0, 1e-8], dim)
        for rel in (0, 1):
            for rule in (rkq.RULE_COMPONENTWISE, rkq.RULE_PRENTICE):
                rkq._delta(atol, rtol, a, b, rel, rule, out[0], tmp[0])
                kernel["_delta"](atol, rtol, a, b, rel, rule, out[1], tmp[1])
                np.testing.assert_array_equal(out[1], out[0])
                expected = rkq._wnorm(a, out[0], tmp[0])
                got = kernel["_wnorm"](a, out[0], tmp[0])
                assert got == expected or (np.isnan(got) and np.isnan(expected))


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_copy_and_max_match_rkq_bit_for_bit(kernel):
    """The compiled loop runs without numba's runtime, so slice copies and
    ndarray.max (which would need it) are element loops: same values, and
    NaN wins the maximum as in NumPy."""
    rng = np.random.default_rng(9)
    for _ in range(200):
        dim = int(rng.integers(1, 40))
        x = rng.standard_normal(dim) * 10.0 ** rng.integers(-300, 300)
        if rng.random() < 0.4:
            x[rng.integers(dim)] = rng.choice([np.nan, np.inf, -np.inf, -0.0])
        expected, got = np.full(dim, 5.0), np.full(dim, 7.0)
        rkq._copy(x, expected)
        kernel["_copy"](x, got)
        assert got.tobytes() == expected.tobytes() == x.tobytes()
        want, have = rkq._max(x), kernel["_max"](x)
        assert have == want or (np.isnan(have) and np.isnan(want))


# -- parameters, cache, counters ---------------------------------------------------


def test_a_parameter_sweep_does_not_recompile():
    problem = hamrkq.load_problem("kepler")
    ham = problem.hamiltonian
    options = {"atol": np.full(4, 1e-8), "rtol": np.zeros(4)}
    compiled.run(ham, ham.parameter_values(), 0.0, problem.y0, 1.0,
                 rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=DOP853_RK8, **options)  # fmt: skip
    before = compiled.COMPILE_COUNT
    for e in (0.1, 0.5, 0.9):
        swept = hamrkq.load_problem("kepler", e=e)
        params = swept.hamiltonian.parameter_values()
        out = compiled.run(swept.hamiltonian, params, 0.0, swept.y0, 2 * np.pi,
                           rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=DOP853_RK8, **options)  # fmt: skip
        # One period later the orbit is back at pericentre (1 - e, 0).
        assert abs(out.y[-1, 0] - (1 - e)) < 1e-6
        np.testing.assert_allclose(compiled.energy(swept.hamiltonian, out.t, out.y, params),
                                   -0.5, atol=1e-7)  # fmt: skip
    assert compiled.COMPILE_COUNT == before


def test_energy_matches_the_numeric_layer():
    problem = hamrkq.load_problem("double_pendulum")
    ham = problem.hamiltonian
    rng = np.random.default_rng(2)
    Y = problem.y0 + 0.1 * rng.standard_normal((50, ham.dim))
    t = np.linspace(0.0, 5.0, 50)
    params = ham.parameter_values()
    np.testing.assert_allclose(compiled.energy(ham, t, Y, params),
                               ham.numeric.energy(t, Y, params), rtol=1e-13)  # fmt: skip


SCRIPT = textwrap.dedent(
    """
    import json
    import numpy as np
    import sympy as sp
    import hamrkq
    from hamrkq.backends import compiled
    from hamrkq.methods.tableaus import DOP853_RK8, RK3_KUTTA, RK4_CLASSIC

    q, p, w = sp.symbols("q p w", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + w * (1 - sp.cos(q)) + q**4 / 24, q=[q], p=[p],
                             parameters={w: 1.0})
    out = compiled.run(ham, np.array([1.25]), 0.0, np.array([0.5, 0.25]), 20.0,
                       rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=DOP853_RK8,
                       atol=np.full(2, 1e-8), rtol=np.zeros(2))
    print(json.dumps({"compiled": compiled.COMPILE_COUNT, "stats": compiled.stats(),
                      "nodes": int(out.t.size), "last": out.y[-1].tolist()}))
    """
)


def _fresh_process(cache: Path) -> dict:
    env = {**os.environ, codegen.CACHE_ENV: str(cache), "PYTHONPATH": str(ROOT)}
    env.pop(compiled.DISABLE_ENV, None)
    # numba's own cache directory would take the machine code elsewhere; this
    # test is about hamrkq's cache directory holding it.
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                          text=True, timeout=300, check=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


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
    assert any(n.startswith(codegen.MODULE_PREFIX + "kernel_") for n in names)
    assert (tmp_path / "__pycache__").is_dir()


# -- availability and fallback -----------------------------------------------------


def test_the_environment_variable_disables_the_backend(monkeypatch):
    monkeypatch.setenv(compiled.DISABLE_ENV, "1")
    ok, reason = compiled.available()
    assert not ok and compiled.DISABLE_ENV in reason
    with pytest.warns(HamrkqWarning, match=compiled.DISABLE_ENV) as caught:
        assert compiled.resolve_backend("auto") == "python"
    assert len([w for w in caught if issubclass(w.category, HamrkqWarning)]) == 1
    with pytest.raises(OptionError, match="backend='numba' cannot be used"):
        compiled.resolve_backend("numba")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert compiled.resolve_backend("python") == "python"  # no warning when chosen


@pytest.mark.parametrize("value", ["0", "", "no"])
def test_other_values_leave_the_backend_on(monkeypatch, value):
    monkeypatch.setenv(compiled.DISABLE_ENV, value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert compiled.resolve_backend("auto") == "numba"


def test_a_system_that_cannot_be_compiled_falls_back_with_one_warning():
    # |q| is a valid Hamiltonian term, but its Jacobian holds DiracDelta(q).
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), q=[q], p=[p])
    with pytest.warns(HamrkqWarning, match="cannot be compiled.*DiracDelta") as caught:
        assert compiled.resolve_backend("auto", ham) == "python"
    assert len(caught) == 1
    with pytest.raises(OptionError, match="DiracDelta"):
        compiled.resolve_backend("numba", ham)


def test_unknown_backend_is_an_option_error():
    with pytest.raises(OptionError, match="'auto', 'numba', 'python'"):
        compiled.resolve_backend("cuda")


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
    assert a.status == b.status and dict(a.stats) == dict(b.stats)
    np.testing.assert_array_equal(b.t, a.t)
    for name in ("y", "z", "gamma", "global_error"):
        np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
    np.testing.assert_allclose(b.energy, a.energy, rtol=1e-12, atol=1e-14)
