"""Code generation: the generated scalar functions against the symbolic layer,
hostile names, unsupported expressions, the cache directory and the cache key."""

from __future__ import annotations

import ast
import hashlib
import math
import re
import sys
import types
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends import codegen, source_cache
from hamrkq.backends.codegen import CodegenError
from hamrkq.backends.dd_printer import DD_FUNCTIONS
from hamrkq.backends.numeric import numeric_of

CATALOGUE = hamrkq.list_problems()


def _states(problem, count=4, seed=0):
    """The initial state and a few random states near it."""
    rng = np.random.default_rng(seed)
    y0 = problem.y0
    scale = 0.1 * (1.0 + np.abs(y0))
    return [y0] + [y0 + scale * rng.standard_normal(y0.size) for _ in range(count)]


def _both_parts(ham, directory):
    """The system and tangent parts of ``ham``'s generated code, as one namespace."""
    system = codegen.load_module(ham, directory)
    tangent = codegen.load_module(ham, directory, part="tangent")
    return types.SimpleNamespace(**{**vars(system), **vars(tangent)})


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """Every catalogue problem's generated code, both parts, in a private cache."""
    directory = tmp_path_factory.mktemp("codegen")
    return {
        name: (problem, _both_parts(problem.hamiltonian, directory))
        for name in CATALOGUE
        for problem in [hamrkq.load_problem(name)]
    }


@pytest.mark.parametrize("name", CATALOGUE)
def test_generated_functions_match_the_symbolic_layer(generated, name):
    problem, module = generated[name]
    ham = problem.hamiltonian
    numeric = numeric_of(ham)
    params = ham.parameter_values()
    dim = ham.dim
    assert (module.DIM, module.NPARAMS) == (dim, len(ham.parameters))
    rng = np.random.default_rng(1)
    for t, y in zip((0.0, 0.7, 3.1, -2.0, 11.0), _states(problem), strict=True):
        f = np.full(dim, np.nan)
        module.rhs(t, y, params, f)
        J = np.full((dim, dim), np.nan)
        module.jac(t, y, params, J)
        v = rng.standard_normal(dim)
        Jv = np.full(dim, np.nan)
        module.jvp(t, y, params, v, Jv)
        f_ref = numeric.rhs(t, y, params)
        J_ref = numeric.jac(t, y, params)
        scale_f = np.max(np.abs(f_ref)) + 1e-300
        scale_J = np.max(np.abs(J_ref)) + 1e-300
        assert np.max(np.abs(f - f_ref)) <= 1e-13 * scale_f
        assert np.max(np.abs(J - J_ref)) <= 1e-13 * scale_J
        assert np.max(np.abs(Jv - J_ref @ v)) <= 1e-12 * scale_J * np.max(np.abs(v))
        H = module.energy(t, y, params)
        assert math.isclose(H, float(numeric.energy(t, y, params)), rel_tol=1e-13, abs_tol=1e-15)


@pytest.mark.parametrize("name", CATALOGUE)
def test_fused_rhs_jvp_is_rhs_then_jac_then_matvec_bit_for_bit(generated, name):
    """The compiled loop's tangent propagation calls rhs_jvp where the
    interpreted one calls rhs, jac and arith.matvec: the same bits, or the
    backends would part (zero entries of J and signs of zero included)."""
    import numba

    from hamrkq.rkq import arith

    compiled_matvec = numba.njit(arith.matvec)

    problem, module = generated[name]
    ham = problem.hamiltonian
    params = ham.parameter_values()
    dim = ham.dim
    rng = np.random.default_rng(2)
    for t, y in zip((0.0, 0.7, 3.1, -2.0, 11.0), _states(problem), strict=True):
        for v in (rng.standard_normal(dim), np.zeros(dim), -np.zeros(dim)):
            f, J = np.empty(dim), np.empty((dim, dim))
            module.rhs(t, y, params, f)
            module.jac(t, y, params, J)
            by_numpy, by_loops = np.empty(dim), np.empty(dim)
            arith.matvec(J, v, by_numpy)
            compiled_matvec(J, v, by_loops)
            fused_f, fused_jv = np.full(dim, np.nan), np.full(dim, np.nan)
            module.rhs_jvp(t, y, params, v, fused_f, fused_jv, np.full((dim, dim), np.nan))
            assert f.tobytes() == fused_f.tobytes()
            assert by_loops.tobytes() == fused_jv.tobytes()
            np.testing.assert_array_equal(by_numpy, fused_jv)
            # and it is J v: against the independent symbolic product
            Jv = np.empty(dim)
            module.jvp(t, y, params, v, Jv)
            scale = np.max(np.abs(J)) * np.max(np.abs(v)) + 1e-300
            assert np.max(np.abs(fused_jv - Jv)) <= 1e-12 * scale


def test_jac_overwrites_every_entry(generated):
    """Callers reuse the Jacobian array, so the zeros must be written too."""
    problem, module = generated["outer_solar_system"]
    ham = problem.hamiltonian
    J = np.full((ham.dim, ham.dim), 7.0)
    module.jac(0.0, problem.y0, ham.parameter_values(), J)
    reference = numeric_of(ham).jac(0.0, problem.y0, ham.parameter_values())
    assert np.count_nonzero(reference == 0) > ham.dim**2 // 2  # mostly zeros
    assert np.all(J[reference == 0] == 0)
    np.testing.assert_allclose(J, reference, rtol=1e-13, atol=1e-13 * np.abs(reference).max())


def test_energy_rows(generated):
    problem, module = generated["kepler"]
    ham = problem.hamiltonian
    Y = np.array(_states(problem))
    t = np.linspace(0.0, 1.0, len(Y))
    out = np.empty(len(Y))
    module.energy_rows(t, Y, ham.parameter_values(), out)
    np.testing.assert_allclose(
        out, numeric_of(ham).energy(t, Y, ham.parameter_values()), rtol=1e-14
    )


def test_time_dependent_hamiltonian_uses_t(tmp_path):
    q, p, t, w = sp.symbols("q p t w", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 - q * sp.cos(w * t), q=[q], p=[p],
                             parameters={w: 1.3})  # fmt: skip
    module = codegen.load_module(ham, tmp_path)
    out = np.empty(2)
    module.rhs(2.0, np.array([0.5, -0.25]), np.array([1.3]), out)
    np.testing.assert_allclose(out, [-0.25, -0.5 + math.cos(2.6)], rtol=1e-15)


def test_floats_are_printed_exactly(tmp_path):
    """SymPy prints 15 digits by default; the generated code must keep all 17."""
    c = 0.1 + 0.2  # 0.30000000000000004, which '0.3' would change
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(sp.Float(c) * p**2 / 2 + q**2 / 2, q=[q], p=[p])
    module = codegen.load_module(ham, tmp_path)
    out = np.empty(2)
    module.rhs(0.0, np.array([0.0, 1.0]), np.empty(0), out)
    assert out[0] == c


def test_a_sum_of_constants_is_added_as_a_double_double(tmp_path):
    """Near the zero of q - (1 - mu) (SymPy writes q + mu - 1) the force is
    the correctly rounded exact value: the constant 1 - mu keeps the bits of
    mu that one double loses, and the sum with q cancels exactly.  Added in
    doubles, the centre moves by up to half an ulp of 1, the same way for
    every q of a binade (a systematic force error, docs/algorithm.md)."""
    q, p, mu = sp.symbols("q p mu", real=True)
    m = 0.012277471
    ham = hamrkq.Hamiltonian(p**2 / 2 + (q - (1 - mu)) ** 2 / 2, q=[q], p=[p],
                             parameters={mu: m})  # fmt: skip
    module = codegen.load_module(ham, tmp_path)
    out = np.empty(2)
    naive_wrong = 0
    for k in range(-40, 41, 3):
        position = (1 - m) + k * 2.0**-53  # a few ulps around the centre
        module.rhs(0.0, np.array([position, 0.0]), np.array([m]), out)
        exact = float(-(Fraction(position) - 1 + Fraction(m)))
        assert out[1] == exact
        naive_wrong += -((position + m) - 1) != exact
    assert naive_wrong > 10  # the test can tell the two apart


def test_the_printer_parses_no_text(monkeypatch):
    """Generation works on SymPy objects only: no sympify, and a string
    handed to the printer is refused, not parsed."""
    from hamrkq.backends import scalar_printer

    def forbidden(*args, **kwargs):
        raise AssertionError("sympify called")

    monkeypatch.setattr(sp, "sympify", forbidden)
    for part in codegen.PARTS:
        codegen.generate_source(hamrkq.load_problem("arenstorf").hamiltonian, part)
    with pytest.raises(TypeError, match="str"):
        scalar_printer._constant_offsets(["q + 1"], frozenset(), sp.numbered_symbols("_k"))


def test_a_single_constant_term_is_added_plainly(tmp_path):
    """q + mu has nothing to lose (mu is one double): no offset is generated."""
    q, p, mu = sp.symbols("q p mu", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + (q + mu) ** 4, q=[q], p=[p], parameters={mu: 0.1})
    source = codegen.generate_source(ham)
    assert "k0_lo" not in source
    two = hamrkq.Hamiltonian(p**2 / 2 + (q + mu + 1) ** 4, q=[q], p=[p], parameters={mu: 0.1})
    assert "k0_lo" in codegen.generate_source(two)


HOSTILE = [
    "__import__('os').system('echo pwned')",
    "y[0]); import os; (",
    "out",
    "math",
    "def",
    "lambda",
]


def test_user_names_never_reach_the_source(tmp_path):
    qs = [sp.Symbol(name, real=True) for name in HOSTILE[:3]]
    ps = [sp.Symbol(name, real=True) for name in HOSTILE[3:]]
    a = sp.Symbol("params[0] + exec('1')", real=True)
    H = sum(pi**2 for pi in ps) / 2 + a * sum(qi**2 for qi in qs) + qs[0] * ps[1]
    ham = hamrkq.Hamiltonian(H, q=qs, p=ps, parameters={a: 2.0})
    expected_imports = {"system": ["math", *DD_FUNCTIONS], "tangent": ["math"]}
    for part in codegen.PARTS:
        source = codegen.generate_source(ham, part)
        for name in [*HOSTILE, "exec", "__import__", "pwned", "import os"]:
            if name in ("out", "math", "def"):
                continue  # these words legitimately occur in every generated file
            assert name not in source
        # Only the names the generator itself uses appear as identifiers.
        tree = ast.parse(source)
        identifiers = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
        allowed = {"math", "t", "y", "params", "out", "dout", "JM", "v", "Y", "i", "k", "acc",
                   "range", "energy", "ylo", "outlo", *DD_FUNCTIONS}  # fmt: skip
        # Numbered temporaries: c0 (CSE), f0/g0 (rhs_jvp's two CSEs), r0/d0 (its
        # outputs), j0_1 (its Jacobian entries), h0/l0 (rhs_dd's high and low words,
        # sh0/sl0/ch0/cl0 a sine and cosine of one argument).
        pattern = r"[cfgrdhl][0-9]+|(sh|sl|ch|cl)[0-9]+|j[0-9]+_[0-9]+"
        temporaries = {n for n in identifiers if re.fullmatch(pattern, n)}
        constants = {"DIM", "NPARAMS", "CODEGEN_VERSION", "DD_UNSUPPORTED"}
        assert identifiers - temporaries <= allowed | constants
        imports = [n for n in ast.walk(tree) if isinstance(n, ast.Import | ast.ImportFrom)]
        assert [alias.name for node in imports for alias in node.names] == expected_imports[part]
    # And it computes the right thing.
    module = codegen.load_module(ham, tmp_path)
    y = np.arange(1.0, 7.0)
    out = np.empty(6)
    module.rhs(0.0, y, np.array([2.0]), out)
    np.testing.assert_allclose(out, numeric_of(ham).rhs(0.0, y, np.array([2.0])), rtol=1e-15)


@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda q, p: p**2 / 2 + sp.Function("f")(q), "f"),
        (lambda q, p: p**2 / 2 + sp.gamma(q), "gamma"),
        (lambda q, p: p**2 / 2 + sp.Piecewise((q, q > 0), (0, True)), "Piecewise"),
        (lambda q, p: p**2 / 2 + sp.zoo * q, "zoo"),
        (lambda q, p: p**2 / 2 + sp.erf(q), "erf"),
        (lambda q, p: p**2 / 2 + sp.Symbol("stranger") * q, "symbol stranger"),
    ],
)
def test_unsupported_expressions_are_named(make, fragment):
    # The Hamiltonian refuses these already; the generator checks on its own
    # (it is the last line of defence before text is compiled).
    q, p = sp.symbols("q p", real=True)
    with pytest.raises(CodegenError, match=fragment):
        codegen.check_supported([make(q, p)], {q, p})


def test_the_hamiltonians_refusal_says_what_is_supported():
    q, p = sp.symbols("q p", real=True)
    with pytest.raises(hamrkq.errors.HamiltonianError) as caught:
        hamrkq.Hamiltonian(p**2 / 2 + sp.besselj(0, q), q=[q], p=[p])
    message = str(caught.value)
    assert "cannot turn into numerical code: besselj (besselj(0, q))" in message
    assert "(it takes numbers, pi, E, the declared symbols, + * ** and sin, cos," in message


def test_abs_of_a_non_real_symbol_is_refused():
    # For complex symbols d|q|/dq involves re, im and Derivative: not scalar code.
    # The Hamiltonian refuses it first, saying how to fix it (issue 16).
    q, p = sp.symbols("q p")
    with pytest.raises(hamrkq.errors.HamiltonianError, match="not declared real"):
        hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), q=[q], p=[p])
    q_real = sp.Symbol("q", real=True)
    with pytest.raises(CodegenError, match="cannot generate scalar code"):
        codegen.check_supported([sp.diff(sp.Abs(q), q)], {q, q_real})


def test_abs_of_a_real_symbol_generates_code_without_diracdelta():
    # rhs has sign(q); the Jacobian's DiracDelta(q) (zero away from the kink,
    # and printable by no backend) is dropped by the Hamiltonian (issue 16).
    q, p = sp.symbols("q p", real=True)
    with pytest.warns(hamrkq.errors.HamrkqWarning, match="not differentiable"):
        ham = hamrkq.Hamiltonian(p**2 / 2 + sp.Abs(q), q=[q], p=[p])
    for part in codegen.PARTS:
        assert "DiracDelta" not in codegen.generate_source(ham, part)
    assert ham.jacobian == sp.Matrix([[0, 1], [0, 0]])
    assert ham.rhs == sp.Matrix([p, -sp.sign(q)])


# -- cache key and directory -------------------------------------------------------


def _kepler(e=0.6):
    return hamrkq.load_problem("kepler", e=e).hamiltonian


def test_cache_key_is_stable_and_ignores_parameter_values():
    assert codegen.cache_key(_kepler()) == codegen.cache_key(_kepler())
    # Parameters are arguments of the generated code: their values are not in the key.
    assert codegen.cache_key(_kepler(0.6)) == codegen.cache_key(_kepler(0.9))
    assert len(codegen.cache_key(_kepler())) == 64


def test_cache_key_changes_with_the_expressions_and_the_symbol_order():
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2", real=True)
    H = (p1**2 + p2**2) / 2 + q1**4 + q2**2
    base = hamrkq.Hamiltonian(H, q=[q1, q2], p=[p1, p2])
    swapped = hamrkq.Hamiltonian(H, q=[q2, q1], p=[p2, p1])
    other = hamrkq.Hamiltonian(H + q1 * q2, q=[q1, q2], p=[p1, p2])
    keys = {codegen.cache_key(h) for h in (base, swapped, other)}
    assert len(keys) == 3
    assert codegen.cache_key(base, "rk34q8") != codegen.cache_key(base, "rk34")


def test_cache_key_changes_with_the_versions(monkeypatch):
    ham = _kepler()
    before = codegen.cache_key(ham)
    monkeypatch.setattr(codegen, "CODEGEN_VERSION", codegen.CODEGEN_VERSION + 1)
    assert codegen.cache_key(ham) != before
    monkeypatch.setattr(hamrkq._version, "__version__", "999.0")
    monkeypatch.setattr(codegen, "CODEGEN_VERSION", codegen.CODEGEN_VERSION - 1)
    assert codegen.cache_key(ham) != before


def test_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv(codegen.CACHE_ENV, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    assert codegen.cache_dir() == tmp_path / "home" / ".cache" / "hamrkq"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert codegen.cache_dir() == tmp_path / "xdg" / "hamrkq"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")  # invalid by the XDG spec
    assert codegen.cache_dir() == tmp_path / "home" / ".cache" / "hamrkq"
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "mine"))
    assert codegen.cache_dir() == tmp_path / "mine"
    monkeypatch.delenv(codegen.CACHE_ENV)
    monkeypatch.setattr(sys, "platform", "darwin")
    assert codegen.cache_dir() == tmp_path / "home" / "Library" / "Caches" / "hamrkq"


def test_load_module_writes_once_and_names_the_file_by_the_key(tmp_path):
    ham = hamrkq.load_problem("henon_heiles").hamiltonian
    module = codegen.load_module(ham, tmp_path)
    files = list(tmp_path.glob("*.py"))
    assert [f.name for f in files] == [f"{codegen.MODULE_PREFIX}{codegen.cache_key(ham)[:32]}.py"]
    stamp = files[0].stat().st_mtime_ns
    assert codegen.load_module(ham, tmp_path) is module  # memoised in the process
    assert files[0].stat().st_mtime_ns == stamp  # and never rewritten
    body, checksum = files[0].read_text().rstrip("\n").rsplit("\n", 1)
    assert body + "\n" == codegen.generate_source(ham)
    named = f"{files[0].stem}\n{body}\n"  # the name hashed with the text
    assert checksum == codegen.CHECKSUM_PREFIX + hashlib.sha256(named.encode()).hexdigest()


def test_the_tangent_part_is_generated_on_its_first_use(tmp_path):
    """A run with the shadow estimate (auto's) never calls the Jacobian: the
    system part is generated without deriving it, the tangent part (its
    own file, keyed by the system's key) when it is asked for."""
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 - sp.cos(q) + q**4 / 24, q=[q], p=[p])
    system = codegen.load_module(ham, tmp_path)
    assert not hasattr(system, "jac") and "jacobian" not in vars(ham)
    assert [f.name for f in tmp_path.glob("*.py")] == [Path(system.__file__).name]
    assert not codegen.is_cached(ham, tmp_path, part="tangent")
    tangent = codegen.load_module(ham, tmp_path, part="tangent")
    assert "jacobian" in vars(ham) and codegen.is_cached(ham, tmp_path, part="tangent")
    key = codegen.cache_key(ham)
    assert tangent.__file__ == str(codegen.module_path(codegen.part_key(key, "tangent"), tmp_path))
    assert codegen.load_part(key, "tangent", directory=tmp_path) is tangent
    y, J = np.array([0.3, -0.2]), np.empty((2, 2))
    tangent.jac(0.0, y, np.empty(0), J)
    np.testing.assert_allclose(J, [[0.0, 1.0], [-math.cos(0.3) - 0.3**2 / 2, 0.0]], rtol=1e-15)
    with pytest.raises(ValueError, match="unknown part 'hessian'"):
        codegen.part_key(key, "hessian")


def test_a_helper_finds_only_the_cached_parts(tmp_path):
    """A helper process knows the key only: it loads what is cached and
    cannot generate the rest."""
    ham = hamrkq.load_problem("toda").hamiltonian
    key = codegen.cache_key(ham)
    with pytest.raises(FileNotFoundError):
        codegen.load_part(key, "system", directory=tmp_path)
    system = codegen.load_module(ham, tmp_path)
    assert codegen.load_part(key, "system", directory=tmp_path) is system
    assert not codegen.part_cached(key, "tangent", tmp_path)
    with pytest.raises(FileNotFoundError):
        codegen.load_part(key, "tangent", directory=tmp_path)


def test_load_module_uses_the_environment_directory(monkeypatch, tmp_path):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "via-env"))
    ham = hamrkq.load_problem("harmonic").hamiltonian
    module = codegen.load_module(ham)
    assert module.__file__.startswith(str(tmp_path / "via-env"))


def test_an_existing_file_is_imported_not_regenerated(tmp_path, monkeypatch):
    """A second process finds the file: nothing is derived or printed again."""
    ham = hamrkq.load_problem("toda").hamiltonian
    path = tmp_path / f"{codegen.MODULE_PREFIX}{codegen.cache_key(ham)[:32]}.py"
    path.write_text(source_cache.sealed(codegen.generate_source(ham), path.stem))
    monkeypatch.setattr(codegen, "generate_source", lambda *a: pytest.fail("regenerated"))
    module = codegen.load_module(ham, tmp_path)
    assert module.DIM == 6


def test_integer_powers_are_spelled_out_and_correct(tmp_path):
    """Python's float ** int calls pow() and numba multiplies: the generator
    prints products (|n| <= 4) or float exponents, so both compute the same."""
    q, p = sp.symbols("q p", real=True)
    H = (
        p**2 / 2
        + q**3 / (1 + p**2) ** 2
        + sp.cos(q) ** 4
        + (q + p) ** 7 / 5040
        - 1 / (2 + sp.sin(p)) ** 3
        + q**-2 / 100
        + (1 + q**2) ** sp.Rational(-3, 2)
        + sp.exp(q / 9) ** -9
    )
    ham = hamrkq.Hamiltonian(H, q=[q], p=[p])
    source = "\n".join(codegen.generate_source(ham, part) for part in codegen.PARTS)
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            exponent = node.right
            if isinstance(exponent, ast.UnaryOp):
                exponent = exponent.operand
            # Only float literals or rational expressions like (3/2) remain.
            assert not (isinstance(exponent, ast.Constant) and isinstance(exponent.value, int))
    assert "math.cos(y[0])*math.cos(y[0])" not in source  # compound bases are hoisted
    module = _both_parts(ham, tmp_path)
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = rng.uniform(0.3, 1.5, 2) * rng.choice([-1, 1], 2)
        out = np.empty(2)
        module.rhs(0.0, y, np.empty(0), out)
        np.testing.assert_allclose(out, numeric_of(ham).rhs(0.0, y, np.empty(0)), rtol=1e-13)
        J = np.empty((2, 2))
        module.jac(0.0, y, np.empty(0), J)
        np.testing.assert_allclose(J, numeric_of(ham).jac(0.0, y, np.empty(0)), rtol=1e-12)
        H = float(numeric_of(ham).energy(0.0, y, np.empty(0)))
        assert math.isclose(module.energy(0.0, y, np.empty(0)), H, rel_tol=1e-13)


# 3**50 is not a double: the printed literal is the double Python rounds it to
@pytest.mark.parametrize("constant", [sp.Rational(1, 10**20), sp.Integer(3**50)])
def test_an_integer_beyond_int64_is_compiled_as_the_double_it_becomes(constant):
    # QA: a problem file's 1e20 is the exact integer 10**20; numba refused
    # the literal ("Int value is too large") and the system ran interpreted,
    # about 100 times slower.  Now printed as the double Python converts it
    # to: compiled, and the same bits on both backends.
    import warnings

    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + constant * q**2 / 2, q=[q], p=[p])
    # about two periods (the frequency is sqrt(constant)): a long span of
    # 3**50's spring took six minutes on the interpreted backend
    span = (0.0, 10.0 / math.sqrt(float(constant))) if constant > 1 else (0.0, 10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback warning
        compiled = hamrkq.solve(ham, [1e-10], [1.0], span, atol=1e-12, backend="numba")
    interpreted = hamrkq.solve(ham, [1e-10], [1.0], span, atol=1e-12, backend="python")
    assert compiled.options["backend"] == "numba" and compiled.success
    np.testing.assert_array_equal(compiled.y, interpreted.y)
    np.testing.assert_array_equal(compiled.energy, interpreted.energy)
