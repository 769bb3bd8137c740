"""The quencher in double-double: the generated f against mpmath, the options,
and runs below double precision's rounding floor checked against exact
solutions."""

from __future__ import annotations

import io
import time

import mpmath
import numpy as np
import pytest
import sympy as sp
from helpers import kepler_flow_mpmath

import hamrkq
from hamrkq.backends import codegen
from hamrkq.errors import OptionError

CATALOGUE = hamrkq.list_problems()


def _mp_rhs(problem, y_hi, y_lo):
    """The right-hand side at the double-double state, to 40 digits."""
    ham = problem.hamiltonian
    values = {
        s: sp.Float(float(v), 40)
        for s, v in zip(ham.parameters, problem.parameter_array, strict=True)
    }
    for s, hi, lo in zip(ham.state, y_hi, y_lo, strict=True):
        values[s] = sp.Float(mpmath.mpf(hi) + mpmath.mpf(lo), 40)
    values[ham.t] = sp.Float(0.0, 40)
    return [sp.N(e.xreplace(values), 40) for e in ham.rhs]


@pytest.mark.parametrize("name", CATALOGUE)
def test_rhs_dd_is_f_to_about_30_digits(name, tmp_path):
    problem = hamrkq.load_problem(name)
    module = codegen.load_module(problem.hamiltonian, tmp_path)
    assert module.DD_UNSUPPORTED == ""
    rng = np.random.default_rng(7)
    mpmath.mp.dps = 40
    for _ in range(3):
        y = problem.y0 + 0.05 * (1.0 + np.abs(problem.y0)) * rng.standard_normal(problem.y0.size)
        ylo = y * 2.0**-60 * rng.standard_normal(y.size)  # a genuine low word
        out, outlo = np.empty_like(y), np.empty_like(y)
        module.rhs_dd(0.0, y, problem.parameter_array, ylo, out, outlo, np.empty((y.size,) * 2))
        exact = _mp_rhs(problem, y, ylo)
        scale = max(1.0, max(abs(float(v)) for v in exact))
        for k, value in enumerate(exact):
            got = mpmath.mpf(out[k]) + mpmath.mpf(outlo[k])
            assert abs(got - mpmath.mpf(str(value))) <= 1e-27 * scale, (name, k)


def test_an_unsupported_function_is_named():
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + sp.atan(q) * q, q=[q], p=[p])
    with pytest.raises(OptionError, match="atan"):
        hamrkq.solve(
            ham, [0.5], [0.0], (0, 1), method="rk78q12", quencher_precision="double-double"
        )


def test_double_double_needs_the_shadow_estimate():
    problem = hamrkq.load_problem("harmonic")
    with pytest.raises(OptionError, match="shadow"):
        hamrkq.solve(problem, method="rk34q8", quencher_precision="double-double")
    with pytest.raises(OptionError, match="quencher_precision"):
        hamrkq.solve(problem, method="rk78q12", quencher_precision="quad")


def _kepler_errors(sol, problem, atol):
    exact = kepler_flow_mpmath(problem.y0, sol.t)
    z = sol.y - sol.global_error
    return np.abs(sol.y - exact).max() / atol, np.abs(z - exact).max()


def test_kepler_below_the_double_floor():
    """Kepler e = 0.6 over ten orbits at 1e-12: in double the quencher stops
    at its rounding floor; in double-double it reaches the end with every
    node within the tolerance of the exact solution, and so does auto, which
    switches by itself."""
    problem = hamrkq.load_problem("kepler", e=0.6)
    span = (0.0, 20 * np.pi)
    double = hamrkq.solve(problem, t_span=span, method="rk78q12", atol=1e-12, rtol=0.0)
    assert double.status is hamrkq.Status.TOLERANCE_UNATTAINABLE and "floor" in double.message
    dd = hamrkq.solve(
        problem, t_span=span, method="rk78q12", atol=1e-12, rtol=0.0,
        quencher_precision="double-double", z_substeps=3,
    )  # fmt: skip
    assert dd.success, dd.message
    ratio, z_error = _kepler_errors(dd, problem, 1e-12)
    assert ratio <= 1.05
    assert z_error < 1e-13  # the quencher far below the tolerance
    auto = hamrkq.solve(problem, t_span=span, method="auto", atol=1e-12, rtol=0.0)
    assert auto.success and auto.options["quencher_precision"] == "double-double"
    assert _kepler_errors(auto, problem, 1e-12)[0] <= 1.05


def test_both_backends_agree():
    problem = hamrkq.load_problem("kepler", e=0.6)
    options = dict(method="rk78q12", atol=1e-12, rtol=0.0, quencher_precision="double-double")
    runs = [
        hamrkq.solve(problem, t_span=(0.0, 2.0), backend=backend, **options)
        for backend in ("numba", "python")
    ]
    np.testing.assert_array_equal(runs[0].t, runs[1].t)
    np.testing.assert_allclose(runs[0].y, runs[1].y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(runs[0].global_error, runs[1].global_error, rtol=0, atol=1e-15)


def test_auto_carries_prentice2011_at_1e_12():
    """The paper's problem over [0, 4000] at 1e-12: in double the quencher
    stops at its floor near t = 80 (the rounding witness measures it; 129
    while the witness rounded Feagin's stage values to nearest);
    auto runs again in double-double, where two quencher steps a step are
    projected past half the limit at t = 80 and abandoned, and three reach
    the end (every node within the tolerance against the long-double
    reference, benchmarks/double_double.md)."""
    prentice = hamrkq.load_problem("prentice2011")
    sol = hamrkq.solve(prentice, method="auto", atol=1e-12, rtol=0.0)
    assert sol.success and sol.t[-1] == 4000.0
    assert sol.options["quencher_precision"] == "double-double"
    assert sol.options["z_substeps"] == 3
    assert sol.stats["discarded_evaluations"] > 0  # the discarded runs, counted
    # the message says which run was in which precision, and why each stopped
    assert (
        "ran rk78q12 with z_substeps=3, the quencher in double-double: the run with "
        "z_substeps=2 and the rounding witness stopped at t = 80." in sol.message
    )
    assert "(measured by the witness) is 0.04" in sol.message
    assert "double precision's floor" in sol.message
    assert (
        "the run with z_substeps=2, the quencher in double-double was abandoned at t = 79."
        in sol.message
    )
    assert np.abs(sol.gamma).max() <= 0.05e-12


def test_a_rerun_in_double_double_reports_its_compiling(monkeypatch):
    """auto's rerun in double-double compiles f in double-double on its
    first use: that wait is in ``compile_s`` (it was in neither timing, so a
    13-second first call of an 8-body system read as 1.5 s of compiling),
    the discarded run's integration is ``discarded_s``, and the summary
    shows both."""
    from hamrkq.backends import first_use
    from hamrkq.io.report import summary_rows

    compiling = first_use.double_double_functions
    wait = 0.4

    def slow(*args, **kwargs):
        time.sleep(wait)  # stands in for numba compiling rhs_dd
        return compiling(*args, **kwargs)

    monkeypatch.setattr(first_use, "double_double_functions", slow)
    problem = hamrkq.load_problem("kepler", e=0.6)
    sol = hamrkq.solve(problem, t_span=(0.0, 20 * np.pi), method="auto", atol=1e-12, rtol=0.0)
    assert sol.options["quencher_precision"] == "double-double"
    assert sol.stats["compile_s"] >= wait
    assert sol.stats["integrate_s"] < sol.stats["compile_s"]
    assert sol.stats["discarded_s"] > 0.0 and sol.stats["discarded_evaluations"] > 0
    assert "compile_wait_s" not in sol.stats
    wall = dict(summary_rows(sol, None, wall_time=1.0))["wall time (solve)"]
    assert "discarded runs" in wall and "compiling or loading code" in wall


def test_compiling_f_in_double_double_is_announced(monkeypatch):
    """A long first compile of f in double-double says what it compiles,
    like the first use of a system (a silent wait of seconds otherwise)."""
    from hamrkq.backends import compiled, first_use

    monkeypatch.setattr(first_use, "ANNOUNCE_AFTER", 0.0)
    original = compiled.CompiledSystem.rhs_dd

    def slow(self):
        time.sleep(0.3)
        return original(self)

    monkeypatch.setattr(compiled.CompiledSystem, "rhs_dd", slow)
    stream = io.StringIO()
    ham = hamrkq.load_problem("harmonic").hamiltonian
    functions = first_use.double_double_functions(ham, stream=stream, announce=True)
    assert functions.tangent is compiled.compile_system(ham).rhs_dd()
    said = stream.getvalue()
    assert "compiling f in double-double" in said and "compiled in" in said


@pytest.mark.parametrize("substeps", [3, 6, 8])
def test_the_quencher_in_double_double_has_no_floor_from_its_substeps(substeps):
    """m substeps of fl(h/m) fall short of h by a few 1e-17 where m is not a
    power of two; the shortfall is covered at the slope at the step's end.
    Covered at the last substep's mean slope instead, the quencher in
    double-double on prentice2011 to t = 1000 ended 1.5e-14 (m = 3) and
    4.3e-15 (m = 6) off heyoka in 113-bit floats, exact to double with
    m = 8, and Gamma (1e-16 to 1e-20) did not see it."""
    from helpers import multiprecision_states

    problem = hamrkq.load_problem("prentice2011")
    sol = hamrkq.solve(
        problem, method="rk78q12", z_substeps=substeps, quencher_precision="double-double",
        atol=1e-16, rtol=1e-10, t_span=(0.0, 1000.0), gamma_limit=np.inf,
    )  # fmt: skip
    reference = multiprecision_states(
        problem.hamiltonian, problem.parameter_array, problem.y0, np.array([0.0, 1000.0]), bits=113
    )[1]
    assert sol.t[-1] == 1000.0
    # the stored value's own rounding (half an ulp of 2.5 is 2.2e-16); 1.7e-16 with 3
    # quencher steps, 0 with 6 and 8 (benchmarks/algorithm_facts.txt)
    assert np.max(np.abs(sol.z[-1] - reference)) <= 3e-16


def test_quencher_in_double_double_covers_the_substeps_shortfall_exactly():
    """m substeps of fl(h/m) leave h - m fl(h/m) (about 1e-17) of each step.
    Covered at a slope extrapolated from the last substep (off by hs^2), the
    track left its energy surface by 1e-20 a step: invisible in double, but
    near a separatrix, where such an energy error shifts the phase by 1e-10
    a period, a pendulum 1e-5 below it was 1.9e-9 off at t = 31 with 6
    substeps (1e-16 with 8: no shortfall) while Gamma read 1e-13.  At its
    own slope, in double-double, the error is the quencher's truncation."""
    import mpmath as mp

    q, p, w = sp.symbols("q p w")
    omega = 1.3
    ham = hamrkq.Hamiltonian(p**2 / 2 - w**2 * sp.cos(q), q=[q], p=[p], parameters={w: omega})
    q0 = float(mp.pi - mp.mpf("1e-5"))
    mp.mp.dps = 32
    m = mp.sin(mp.mpf(q0) / 2) ** 2
    k, quarter = mp.sqrt(m), mp.ellipk(m)
    times = np.array([25.0, 31.0])
    exact = np.array(
        [
            [
                float(2 * mp.asin(k * mp.ellipfun("sn", quarter + omega * t, m=m))),
                float(2 * k * omega * mp.ellipfun("cn", quarter + omega * t, m=m)),
            ]
            for t in times
        ]
    )
    errors = {}
    for substeps in (6, 8):
        sol = hamrkq.solve(ham, q0=[q0], p0=[0.0], t_span=(0.0, 31.0), atol=1e-10, t_eval=times,
                           method="rk78q12", z_substeps=substeps,
                           quencher_precision="double-double")  # fmt: skip
        errors[substeps] = np.abs(sol.z - exact).max()
    assert errors[8] < 1e-14  # no shortfall: the reference of what is attainable
    assert errors[6] < 5e-13  # measured 4.5e-14 (1.9e-9 before)
