"""A damaged cache entry is detected, rebuilt and reported once (issue 17, item 3),
and the interpreted backend reports float errors as NON_FINITE, like the
compiled one (issue 17, item 5)."""

from __future__ import annotations

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
from hamrkq.backends import codegen, compiled, source_cache
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import HamrkqWarning
from hamrkq.result import Status

ROOT = Path(__file__).resolve().parents[1]


def _system(tag: float) -> hamrkq.Hamiltonian:
    # A coefficient of its own per test, so each test owns its cache file.
    q, p = sp.symbols("q p", real=True)
    return hamrkq.Hamiltonian(p**2 / 2 - sp.cos(q) + sp.Float(tag) * q**4, q=[q], p=[p])


def _forget(path: Path) -> None:
    """What a new process would see: nothing of ``path`` imported yet."""
    module = source_cache._LOADED.pop(str(path), None)
    if module is not None:
        sys.modules.pop(module.__name__, None)


def _rhs(module, y) -> np.ndarray:
    out = np.empty(2)
    module.rhs(0.0, np.asarray(y, dtype=float), np.empty(0), out)
    return out


def _exact_rhs(tag: float, y) -> np.ndarray:
    q, p = y
    return np.array([p, -(np.sin(q) + 4 * tag * q**3)])


DAMAGES = {
    "emptied": lambda text: "",
    "truncated": lambda text: text[: len(text) // 2],
    "cut before the checksum": lambda text: text[: text.rindex(codegen.CHECKSUM_PREFIX)],
    "edited": lambda text: text.replace("y[1]", "y[0]", 1),
    "not UTF-8": lambda text: text[:40] + "\udcff",
}


@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_generated_file_is_rebuilt_with_one_warning(tmp_path, damage):
    tag = 0.001 * (1 + list(DAMAGES).index(damage))
    ham = _system(tag)
    module = codegen.load_module(ham, tmp_path)
    path = Path(module.__file__)
    intact = path.read_text()
    y = [0.7, -0.3]
    np.testing.assert_allclose(_rhs(module, y), _exact_rhs(tag, y), rtol=1e-15)

    _forget(path)
    damaged = DAMAGES[damage](intact)
    path.write_bytes(damaged.encode("utf-8", "surrogateescape"))
    with pytest.warns(HamrkqWarning, match="damaged") as caught:
        module = codegen.load_module(ham, tmp_path)
    assert len([w for w in caught if issubclass(w.category, HamrkqWarning)]) == 1
    assert str(path) in str(caught[0].message)
    assert caught[0].filename == __file__  # the warning points at the caller
    np.testing.assert_allclose(_rhs(module, y), _exact_rhs(tag, y), rtol=1e-15)
    assert path.read_text() == intact  # rebuilt to the same text

    # The next process finds the rebuilt file intact: no warning, no rewrite.
    _forget(path)
    stamp = path.stat().st_mtime_ns
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        codegen.load_module(ham, tmp_path)
    assert path.stat().st_mtime_ns == stamp


def test_a_damaged_file_that_cannot_be_rebuilt_is_an_error_not_a_warning(tmp_path, monkeypatch):
    """In a read-only cache it warned "rebuilding it", twice, and rebuilt
    nothing (QA): now the error says why the file cannot be used, once, as
    the compiled backend's reason to fall back, and nothing is claimed."""
    ham = _system(0.0303)
    path = Path(codegen.load_module(ham, tmp_path).__file__)
    _forget(path)
    path.write_text("emptied\n")

    def read_only(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(source_cache, "_write_atomically", read_only)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(OSError, match=r"is damaged .* and cannot be rebuilt there"):
            codegen.load_module(ham, tmp_path)


def test_another_systems_intact_file_under_this_ones_name_is_rebuilt(tmp_path):
    """The checksum covered the text alone: one system's file copied under
    another's name was imported, and the other system's equations
    integrated, to SUCCESS (QA).  It hashes the file's name too."""
    ham, other = _system(0.0301), _system(0.0302)
    path = Path(codegen.load_module(ham, tmp_path).__file__)
    source = Path(codegen.load_module(other, tmp_path).__file__)
    _forget(path)
    path.write_text(source.read_text())
    with pytest.warns(HamrkqWarning, match="checksum does not match its contents and name"):
        module = codegen.load_module(ham, tmp_path)
    y = [0.7, -0.3]
    np.testing.assert_allclose(_rhs(module, y), _exact_rhs(0.0301, y), rtol=1e-15)


def test_every_cached_file_ends_with_the_checksum_of_its_text(tmp_path):
    module = codegen.load_module(_system(0.01), tmp_path)
    body, last = Path(module.__file__).read_text().rstrip("\n").rsplit("\n", 1)
    assert last == source_cache._checksum_line(Path(module.__file__).stem, body + "\n")
    assert source_cache.damage_of(Path(module.__file__)) is None


SCRIPT = textwrap.dedent(
    """
    import json, warnings
    import sympy as sp
    import hamrkq
    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 - sp.cos(q) + sp.Float({tag!r}) * q**4, q=[q], p=[p])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol = hamrkq.solve(ham, [1.0], [0.0], (0.0, 5.0), atol=1e-8, rtol=0.0)
    print(json.dumps({{"status": str(sol.status), "backend": sol.options["backend"],
                      "last": sol.y[-1].tolist(),
                      "warnings": [str(w.message) for w in caught]}}))
    """
)


def _process(tag: float) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop(compiled.DISABLE_ENV, None)
    done = subprocess.run([sys.executable, "-c", SCRIPT.format(tag=tag)], env=env,
                          capture_output=True, text=True, timeout=600, check=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.skipif(not compiled.available()[0], reason="compiled backend unavailable")
@pytest.mark.parametrize("damage", ["emptied", "truncated"])
def test_the_compiled_backend_recovers_from_a_damaged_cache(damage):
    """Before: an emptied file gave an AttributeError traceback, a truncated one
    a permanent fallback to the interpreter that blamed numba."""
    tag = {"emptied": 0.0123, "truncated": 0.0456}[damage]
    first = _process(tag)
    assert first["backend"] == "numba" and first["status"] == "Status.SUCCESS"
    path = (
        codegen.cache_dir() / f"{codegen.MODULE_PREFIX}{codegen.cache_key(_system(tag))[:32]}.py"
    )
    assert path.exists()
    path.write_text(DAMAGES[damage](path.read_text()))
    second = _process(tag)
    assert second["backend"] == "numba"
    assert second["status"] == "Status.SUCCESS"
    assert second["last"] == first["last"]
    assert len([w for w in second["warnings"] if "damaged" in w]) == 1
    assert not [w for w in second["warnings"] if "not used" in w]  # no fallback
    third = _process(tag)
    assert third["warnings"] == [] and third["last"] == first["last"]


# -- float errors on the interpreted backend ------------------------------------------

q, p = sp.symbols("q p", real=True)
DOMAIN_ERRORS = {
    "sqrt of a negative number": (p**2 / 2 + sp.sqrt(q) ** 3, -1.0),
    "exp overflow": (p**2 / 2 + sp.exp(q), 1000.0),
    "division by zero": (p**2 / 2 + 1 / q, 0.0),
    "log of zero": (p**2 / 2 + q * sp.log(q), 0.0),
    "acos outside [-1, 1]": (p**2 / 2 + sp.acos(q), 2.0),
}


@pytest.mark.parametrize("case", DOMAIN_ERRORS)
def test_a_float_error_at_t0_is_non_finite_on_both_backends(case):
    """Before: the interpreter raised ValueError/OverflowError/ZeroDivisionError."""
    H, q0 = DOMAIN_ERRORS[case]
    ham = hamrkq.Hamiltonian(H, q=[q], p=[p])
    backends = ["python"] + (["numba"] if compiled.available()[0] else [])
    results = {}
    for backend in backends:
        sol = hamrkq.solve(ham, [q0], [0.5], (0.0, 1.0), backend=backend)
        assert sol.status is Status.NON_FINITE, backend
        results[backend] = sol
    if "numba" in results:
        np.testing.assert_array_equal(results["python"].t, results["numba"].t)


def test_the_interpreted_rhs_gives_the_compiled_values_where_math_raises():
    """NaN and infinities component by component, as IEEE arithmetic (numba) gives."""
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2", real=True)
    H = p1**2 / 2 + p2**2 / 2 + sp.sqrt(q1) ** 3 + sp.exp(q2)
    ham = hamrkq.Hamiltonian(H, q=[q1, q2], p=[p1, p2])
    y = np.array([-1.0, 1000.0, 0.25, 0.5])
    f = numeric_of(ham).rhs(0.0, y, np.empty(0))
    assert f[0] == 0.25 and f[1] == 0.5
    assert np.isnan(f[2]) and f[3] == -np.inf
    J = numeric_of(ham).jac(0.0, y, np.empty(0))
    assert np.isnan(J[2, 0]) and J[3, 1] == -np.inf and J[0, 2] == 1.0
    if compiled.available()[0]:
        system = compiled.compile_system(ham)
        out = np.empty(4)
        system.rhs(0.0, y, np.empty(0), out)
        np.testing.assert_array_equal(out, f)
        JM = np.empty((4, 4))
        system.jac(0.0, y, np.empty(0), JM)
        np.testing.assert_array_equal(JM, J)
    # A finite point still takes the fast path and gives ordinary numbers.
    y = np.array([4.0, 0.0, 0.25, 0.5])
    np.testing.assert_allclose(
        numeric_of(ham).rhs(0.0, y, np.empty(0)), [0.25, 0.5, -1.5 * 2.0, -1.0], rtol=1e-15
    )


def test_is_cached_tells_a_missing_or_damaged_module_from_an_intact_one(tmp_path):
    ham = _system(0.077)
    assert not codegen.is_cached(ham, tmp_path)
    module = codegen.load_module(ham, tmp_path)
    path = Path(module.__file__)
    assert path == codegen.module_path(codegen.cache_key(ham), tmp_path)
    assert codegen.is_cached(ham, tmp_path)
    path.write_text(path.read_text()[:-10])
    assert not codegen.is_cached(ham, tmp_path)


@pytest.mark.skipif(not compiled.available()[0], reason="compiled backend unavailable")
def test_the_compiled_path_never_lambdifies(monkeypatch):
    """lambdify is built on first use only: a compiled solve (generation, compilation,
    energy) needs none of it (it cost 2-3 s on outer_solar_system when eager)."""
    from hamrkq.backends import numeric

    monkeypatch.setattr(numeric, "_lambdify", lambda *a, **k: pytest.fail("lambdified"))
    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2", real=True)
    H = (p1**2 + p2**2) / 2 - 1 / sp.sqrt(q1**2 + q2**2) + sp.Float(0.0031) * q1
    ham = hamrkq.Hamiltonian(H, q=[q1, q2], p=[p1, p2])
    sol = hamrkq.solve(ham, [1.0, 0.0], [0.0, 1.0], (0.0, 1.0), backend="numba")
    assert sol.status is Status.SUCCESS
    # Constructing the numerical functions lambdifies nothing either, and the
    # interpreted rhs runs the generated scalar code, not a lambdified one.
    f = numeric_of(ham).rhs(0.0, np.array([1.0, 0.0, 0.0, 1.0]), np.empty(0))
    np.testing.assert_allclose(f, [0.0, 1.0, -1.0031, 0.0], rtol=1e-15)


def test_the_key_changes_with_the_code_the_generated_module_calls(monkeypatch):
    """``rhs_dd`` calls hamrkq.rkq.ddarith, which numba compiles into it, and
    numba's cache checks only the generated file: an edit to ddarith must
    name a new module (and so a new machine-code cache), as a new generator
    version does."""
    from hamrkq.rkq import ddarith

    assert Path(ddarith.__file__).resolve() in codegen.CALLED_SOURCES
    ham = _system(0.071)
    before = codegen.cache_key(ham)
    monkeypatch.setattr(codegen, "_called_sources_digest", lambda: "edited")
    assert codegen.cache_key(ham) != before
