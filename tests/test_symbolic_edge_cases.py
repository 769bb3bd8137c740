"""Edge cases of the symbolic layer and of the code generated from it: symbols
of other classes (``sympy.Dummy``) and with any name, constants outside double
range, symbols that share a name, warnings' locations and the double-double
right-hand side's constants."""

from __future__ import annotations

import sys
import types
import warnings

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends import codegen
from hamrkq.backends.numeric import numeric_of

# -- 1. every declared symbol is printed as its slot ---------------------------

MARKER = "USER TEXT EXECUTED"
PAYLOAD = f"print({MARKER!r}) or 1.0 if 1 else "


def _dummy_cases(cls):
    """The three systems of QA's dummy_symbols.py, their symbols of class ``cls``
    (a Dummy coordinate, a Dummy parameter, a Dummy time)."""
    q, p = sp.symbols("q p", real=True)
    qd, a, tau = cls("q", real=True), cls("a", positive=True), cls("tau", real=True)
    return [
        hamrkq.Hamiltonian(p**2 / 2 + qd**2 / 2, [qd], [p]),
        hamrkq.Hamiltonian(p**2 / 2 + a * q**2 / 2, [q], [p], parameters={a: 2.0}),
        hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + q * sp.cos(tau), [q], [p], t=tau),
    ]


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_dummy_coordinate_parameter_and_time_integrate_like_symbols(backend):
    # Before: NameError: name 'q_8977807' is not defined (the Dummy's own
    # name printed into the source), after a warning blaming numba.
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback warning either
        for plain, dummy in zip(_dummy_cases(sp.Symbol), _dummy_cases(sp.Dummy), strict=True):
            runs = [
                hamrkq.solve(h, q0=[1.0], p0=[0.0], t_span=(0, 1), atol=1e-8, backend=backend)
                for h in (plain, dummy)
            ]
            assert runs[1].status.name == "SUCCESS"
            np.testing.assert_array_equal(runs[1].t, runs[0].t)
            np.testing.assert_array_equal(runs[1].y, runs[0].y)


def _two_dof(cls):
    q1, q2, p1, p2 = (cls(n, real=True) for n in ("q1", "q2", "p1", "p2"))
    a, b, t = cls("a", positive=True), cls("b", real=True), cls("t", real=True)
    H = (
        (p1**2 + p2**2) / 2 + a * (q1**2 + q2**2) / 2 + b * q1**2 * q2 - q2**3 / 3
        + q1 * sp.cos(t) / 10 + (q1 + a - 1) ** 2 / 7 + sp.sqrt(1 + q1**2)
    )  # fmt: skip
    return hamrkq.Hamiltonian(H, [q1, q2], [p1, p2], parameters={a: 1.0, b: 1.0}, t=t)


def test_a_system_of_dummies_computes_what_the_same_symbols_compute(tmp_path):
    # Every function of both parts, rhs_dd too.  SymPy orders the terms of a
    # sum of Dummies otherwise than those of Symbols (by class name), so the
    # operations may come in another order: equal to rounding, not bit for bit.
    plain, dummy = (_two_dof(cls) for cls in (sp.Symbol, sp.Dummy))
    assert codegen.double_double_unsupported(dummy) == ""
    mods = [_module(h, tmp_path) for h in (plain, dummy)]
    for out_plain, out_dummy in zip(*(_evaluate(m, 4) for m in mods), strict=True):
        np.testing.assert_allclose(out_dummy, out_plain, rtol=1e-14, atol=1e-15)
    runs = [
        hamrkq.solve(h, q0=[0.1, 0.2], p0=[0.3, 0.1], t_span=(0, 5), atol=1e-10, backend="python")
        for h in (plain, dummy)
    ]
    assert runs[1].status.name == "SUCCESS"
    np.testing.assert_allclose(runs[1].y[-1], runs[0].y[-1], rtol=0, atol=1e-12)


def _module(ham, directory):
    system = codegen.load_module(ham, directory)
    tangent = codegen.load_module(ham, directory, part="tangent")
    return types.SimpleNamespace(**{**vars(system), **vars(tangent)})


def _evaluate(module, dim, t=0.3):
    """Every generated function of ``module`` at one state (parameters 1.0, 1.0)."""
    rng = np.random.default_rng(1)
    y, v, params = rng.uniform(0.1, 0.9, dim), rng.uniform(-1, 1, dim), np.ones(module.NPARAMS)
    rhs, jac, jvp = np.empty(dim), np.empty((dim, dim)), np.empty(dim)
    fused, dfused = np.empty(dim), np.empty(dim)
    hi, lo = np.empty(dim), np.empty(dim)
    module.rhs(t, y, params, rhs)
    module.jac(t, y, params, jac)
    module.jvp(t, y, params, v, jvp)
    module.rhs_jvp(t, y, params, v, fused, dfused, np.empty((dim, dim)))
    module.rhs_dd(t, y, params, np.zeros(dim), hi, lo, np.empty((dim, dim)))
    energy = module.energy(t, y, params)
    return [rhs, jac, jvp, fused, dfused, hi + lo, np.array([energy])]


def test_a_dummys_name_text_never_reaches_the_source(tmp_path, capsys):
    # Before: QA's dummy_inject.py printed USER TEXT EXECUTED: the name was
    # copied into the generated module and executed.
    q, a, tau = (sp.Dummy(PAYLOAD + n, real=True) for n in ("q", "a", "tau"))
    p = sp.Symbol("p", real=True)
    plain_q, plain_a, plain_tau = sp.symbols("q a tau", real=True)

    def build(q, a, tau, extra=0):
        H = p**2 / 2 + a * q**2 / 2 + q * sp.cos(tau) / 10 + extra
        return hamrkq.Hamiltonian(H, [q], [p], parameters={a: 2.0}, t=tau)

    ham = build(q, a, tau)
    # tanh has no double-double form: the reason written into the module
    # (DD_UNSUPPORTED) names the function, not the expression.
    no_dd = build(q, a, tau, sp.tanh(q) / 100)
    for system in (ham, no_dd):
        for part in codegen.PARTS:
            source = codegen.generate_source(system, part)
            assert MARKER not in source and "print" not in source
    assert codegen.double_double_unsupported(no_dd).startswith(
        "cannot generate double-double code for tanh:"
    )
    reference = hamrkq.solve(
        build(plain_q, plain_a, plain_tau), q0=[1.0], p0=[0.0], t_span=(0, 1), atol=1e-8
    )
    for backend in ("python", "numba"):
        sol = hamrkq.solve(ham, q0=[1.0], p0=[0.0], t_span=(0, 1), atol=1e-8, backend=backend)
        np.testing.assert_array_equal(sol.y, reference.y)
    sol = hamrkq.solve(ham, q0=[1.0], p0=[0.0], t_span=(0, 1), atol=1e-8, method="scipy:Radau")
    assert sol.success
    # The energy and gradient through lambdify, whose symbols are dummies of its own.
    numeric, Y = numeric_of(ham), np.array([[1.0, 0.5]])
    assert numeric.energy(0.0, Y, np.array([2.0]))[0] == 0.125 + 1.0 + np.cos(0.0) / 10
    np.testing.assert_allclose(numeric.gradient(0.0, Y, np.array([2.0])), [[2.1, 0.5]])
    assert MARKER not in capsys.readouterr().out


@pytest.mark.parametrize(
    "names",
    [
        ("_c0", "_c1", "mu", "t"),  # CSE temporaries (UnboundLocalError: c0)
        ("_k0", "p", "_k1", "t"),  # a constant offset's (silently wrong by 0.44)
        ("q", "p", "mu", "_k0"),
        ("_v0", "p", "mu", "t"),  # the tangent's vector, real=True (NameError: v)
        ("_d0", "_d1", "_d2", "_d3"),  # rhs_dd's temporaries
    ],
)
@pytest.mark.parametrize("real", [True, False])
def test_a_symbol_named_like_a_temporary_is_still_its_slot(tmp_path, names, real):
    def build(qn, pn, mun, tn):
        q, p, mu, t = (
            sp.Symbol(n, real=True) if real else sp.Symbol(n) for n in (qn, pn, mun, tn)
        )
        H = p**2 / 2 + (q + mu - 1) ** 2 / 2 + sp.cos(q) ** 3 + q * p * sp.cos(t) / 10
        return hamrkq.Hamiltonian(H, [q], [p], parameters={mu: 0.3}, t=t)

    odd, plain = build(*names), build("q", "p", "mu", "t")
    expected = _evaluate(_module(plain, tmp_path), 2)
    for got, want in zip(_evaluate(_module(odd, tmp_path), 2), expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-15)


# -- 2. a number of H beyond the range of a double ------------------------------


@pytest.mark.parametrize(
    ("number", "named"),
    [
        (sp.Integer(10) ** 400, "1.0e+400 (Integer)"),
        (sp.Float("1e400"), "1.0e+400 (Float)"),
        (sp.Integer(2) ** 1024, "1.7976931348623159e+308 (Integer)"),
        (-sp.Rational(10**500, 3), "-3.3333333333333333e+499 (Rational)"),
    ],
)
def test_a_number_beyond_double_range_is_refused_by_the_hamiltonian(number, named):
    # Before: accepted; solve raised OverflowError ("integer division result
    # too large for a float") or NameError ("name 'inf' is not defined"),
    # after a warning blaming numba.
    q, p = sp.symbols("q p", real=True)
    with pytest.raises(hamrkq.errors.HamiltonianError, match="beyond the range of a double") as e:
        hamrkq.Hamiltonian(p**2 / 2 + number * q**2, [q], [p])
    assert named in str(e.value)
    assert isinstance(e.value, hamrkq.errors.HamrkqError)


def test_every_number_beyond_double_range_is_named_once():
    q, p = sp.symbols("q p", real=True)
    big = sp.Integer(10) ** 400
    with pytest.raises(hamrkq.errors.HamiltonianError) as e:
        hamrkq.Hamiltonian(p**2 / 2 + big * q**2 + q**big + sp.Float("-2e400") * q, [q], [p])
    assert str(e.value).count("1.0e+400 (Integer)") == 1
    assert "-2.0e+400 (Float)" in str(e.value)


@pytest.mark.parametrize(
    "number",
    [
        sp.Float("1.7976931348623157e308"),  # the largest double
        sp.Integer(2) ** 1023,
        sp.Rational(10**400 + 1, 10**400),  # huge terms, a value near 1
        sp.Rational(1, 10**400),  # underflows to 0, as in a problem file
    ],
)
def test_a_number_a_double_holds_is_accepted(number):
    q, p = sp.symbols("q p", real=True)
    hamrkq.Hamiltonian(p**2 / 2 + number * q**2, [q], [p])


# -- 3. different symbols with one name -----------------------------------------


def _same_name_cases():
    x, x_real, x_dummy = sp.Symbol("x"), sp.Symbol("x", real=True), sp.Dummy("x")
    p1, p2 = sp.symbols("p1 p2")
    kinetic = (p1**2 + p2**2) / 2
    return {
        # QA's same_name.py: accepted, names ('x', 'x', 'p1', 'p2'), then
        # q0={"x": 1.0} raised "q0: no value for x".
        "two coordinates": (
            dict(H=kinetic + x**2 / 2 + 2 * x_real**2, q=[x, x_real], p=[p1, p2]),
            "the coordinate x (no assumptions), the coordinate x (real=True)",
        ),
        "a coordinate and a momentum": (
            dict(H=x**2 / 2 + x_real**2 / 2 + p1**2, q=[x, p2], p=[x_real, p1]),
            "the coordinate x (no assumptions), the momentum x (real=True)",
        ),
        "a coordinate and a parameter": (
            dict(H=p1**2 / 2 + x_real * x**2, q=[x], p=[p1], parameters={x_real: 1.0}),
            "the coordinate x (no assumptions), the parameter x (real=True)",
        ),
        "a coordinate and the time": (
            dict(H=p1**2 / 2 + x**2 + sp.cos(x_real), q=[x], p=[p1], t=x_real),
            "the coordinate x (no assumptions), the time x (real=True)",
        ),
        "a Symbol and a Dummy": (
            dict(H=kinetic + x**2 + x_dummy**2, q=[x, x_dummy], p=[p1, p2]),
            "the coordinate x (no assumptions), the coordinate x (no assumptions, a Dummy)",
        ),
    }


@pytest.mark.parametrize("case", list(_same_name_cases()))
def test_different_symbols_with_one_name_are_refused(case):
    declaration, named = _same_name_cases()[case]
    parameters = declaration.pop("parameters", None)
    with pytest.raises(hamrkq.errors.HamiltonianError) as e:
        hamrkq.Hamiltonian(parameters=parameters, **declaration)
    message = str(e.value)
    assert "2 different symbols are named x: " + named in message
    assert "duplicated" not in message
    assert len(e.value.problems) == 1


def test_the_same_symbol_twice_is_still_reported_as_duplicated():
    q, p = sp.symbols("q p")
    with pytest.raises(hamrkq.errors.HamiltonianError) as e:
        hamrkq.Hamiltonian(p**2 / 2 + q**2, [q, q], [p, p])
    assert "duplicated symbols: p, q" in str(e.value)
    assert "different symbols" not in str(e.value)


# -- 4a. the Abs/sign warning names the caller's line ---------------------------


def test_the_abs_warning_of_a_problem_file_names_the_callers_line(tmp_path):
    # Before: it pointed at hamrkq/catalogue/problem_file.py:232 (a fixed
    # stacklevel=2 is right only for a direct Hamiltonian(...) call).
    path = tmp_path / "vwell2.toml"
    path.write_text(
        'name = "vwell2"\ntitle = "t"\ncoordinates = ["q"]\nmomenta = ["p"]\n'
        'hamiltonian = "p**2/2 + Abs(q)"\n\n[initial]\nq = 1\np = 0\n\n'
        "[integration]\nt_span = [0, 1]\n"
    )
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        line = sys._getframe().f_lineno + 1
        hamrkq.load_problem(path)
    [warning] = [w for w in record if "not differentiable everywhere" in str(w.message)]
    assert (warning.filename, warning.lineno) == (__file__, line)
    assert issubclass(warning.category, hamrkq.errors.HamrkqWarning)


# -- 4b. a Float coefficient in rhs_dd keeps its own precision ------------------


@pytest.mark.parametrize(
    ("coefficient", "bound"),
    [
        # Before: 5.6e-17, the Float rounded to a double; now 5.3e-32, of which
        # 4.9e-32 is the Float's own (103 bits) distance from 0.1.
        (sp.Float("0.1", 30), 6e-32),
        (sp.Float("0.1", 40), 1e-32),  # 136 bits: as exact as the Rational
        (sp.Rational(1, 10), 1e-32),  # 2.2e-33
    ],
)
def test_rhs_dd_keeps_a_floats_precision(tmp_path, coefficient, bound):
    # QA's dd_float_precision.py: -dH/dq at q = 0.7 (the double) against 40 digits.
    mpmath = pytest.importorskip("mpmath")
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + coefficient * q**2, [q], [p])
    module = codegen.load_module(ham, tmp_path)
    out, lo = np.empty(2), np.empty(2)
    module.rhs_dd(0.0, np.array([0.7, 0.0]), np.zeros(0), np.zeros(2), out, lo, np.empty((2, 2)))
    with mpmath.workdps(40):
        truth = -2 * mpmath.mpf("0.1") * mpmath.mpf(0.7)
        error = abs(mpmath.mpf(out[1]) + mpmath.mpf(lo[1]) - truth) / abs(truth)
    assert error < bound


def test_a_double_float_is_still_a_double_in_rhs_dd():
    # A Float of 53 bits (from a Python float) has the low word 0: a double
    # times a double-double, as before.
    q, p = sp.symbols("q p", real=True)
    source = codegen.generate_source(hamrkq.Hamiltonian(p**2 / 2 + 0.1 * q**2, [q], [p]))
    rhs_dd = source[source.index("def rhs_dd") : source.index("DD_UNSUPPORTED")]
    assert "dd_mul_d(y[0], ylo[0], -0.2)" in rhs_dd
