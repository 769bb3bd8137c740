"""Compiling with callees optimised once (hamrkq.backends.numba_linking).

Every other compiled test runs on a kernel compiled this way (the suite's
cache starts empty); these check the mechanism itself on small chains of
``register_jitable`` functions defined afresh in each test, so that numba
compiles them here rather than reusing anything: the values, an exception
raised deep in the chain, how many libraries are finalised in full, and that
numba is left as it was.
"""

from __future__ import annotations

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from numba.core import codegen, cpu  # noqa: E402
from numba.extending import register_jitable  # noqa: E402

from hamrkq.backends import numba_linking  # noqa: E402

pytestmark = pytest.mark.skipif(
    not numba_linking.applicable(), reason="numba release not checked for this change"
)


def _chain():
    """A fresh entry point over four levels of jitable callees, a loop, a
    math function, an array argument and an exception in the deepest one."""

    @register_jitable
    def deepest(x, scale):
        if x < 0.0:
            raise ValueError("negative input")
        return np.sqrt(x) * scale

    @register_jitable
    def third(values, scale):
        total = 0.0
        for v in values:
            total += deepest(v, scale)
        return total

    @register_jitable
    def second(values, scale):
        return third(values, scale) + third(values[::2], 2.0 * scale)

    @register_jitable
    def first(values, scale):
        return second(values, scale) - 1.0

    def entry(values, scale):
        return first(values, scale)

    return entry


def _expected(values, scale):
    return np.sum(np.sqrt(values) * scale) + np.sum(np.sqrt(values[::2]) * 2.0 * scale) - 1.0


def _compile(entry, once: bool, counter: list[int] | None = None):
    from numba.core.compiler_lock import global_compiler_lock

    signature = numba.float64(numba.float64[::1], numba.float64)
    # Under numba's (reentrant) compiler lock: a compile still running in
    # another thread of this process (an earlier test's) would otherwise
    # restore the finalize it saved over the counting one (the suite once
    # counted one finalisation of the plain compile).
    with global_compiler_lock:
        plain_finalize = codegen.CPUCodeLibrary.finalize
        if counter is not None:

            def counting(self):
                counter.append(1)
                return plain_finalize(self)

            codegen.CPUCodeLibrary.finalize = counting
        try:
            if once:
                with numba_linking.callees_optimised_once():
                    return numba.njit(signature)(entry)
            return numba.njit(signature)(entry)
        finally:
            codegen.CPUCodeLibrary.finalize = plain_finalize


def test_the_compiled_chain_computes_what_the_plain_compile_does():
    values = np.linspace(0.1, 3.0, 17)
    once = _compile(_chain(), once=True)
    plain = _compile(_chain(), once=False)
    assert once(values, 1.5) == plain(values, 1.5)
    assert once(values, 1.5) == pytest.approx(_expected(values, 1.5), rel=1e-15)


def test_only_the_entry_point_is_finalised_in_full():
    """Counted in a fresh interpreter: in the full suite the plain compile
    once counted a single finalisation (after some earlier test of the same
    worker, not identified; the file alone, and each file tried beside it,
    counted five or more)."""
    import subprocess
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parent
    code = (
        "from test_numba_linking import _chain, _compile\n"
        # numba finalises its own helpers on a process's first compile
        "_compile(_chain(), once=False)\n"
        "once, plain = [], []\n"
        "_compile(_chain(), once=True, counter=once)\n"
        "_compile(_chain(), once=False, counter=plain)\n"
        "print(len(once), len(plain))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=here, capture_output=True, text=True, check=True
    )
    full_once, full_plain = map(int, result.stdout.split())
    # Plain: the entry point, each of its four callees and numba's own
    # jitted helpers; once: the entry point alone.
    assert full_once == 1
    assert full_plain >= 5


def test_an_exception_raised_in_a_deferred_callee_reaches_the_caller():
    compiled = _compile(_chain(), once=True)
    with pytest.raises(ValueError, match="negative input"):
        compiled(np.array([1.0, -1.0]), 1.0)


def test_numba_is_left_as_it_was_even_when_the_compile_fails():
    before = (
        codegen.CPUCodeLibrary.finalize,
        codegen.CPUCodeLibrary.add_linking_library,
        codegen.CPUCodeLibrary._get_module_for_linking,
        cpu.CPUContext.get_executable,
    )

    def broken(values, scale):
        return undefined_name(values)  # noqa: F821

    with pytest.raises(numba.core.errors.TypingError):
        _compile(broken, once=True)
    after = (
        codegen.CPUCodeLibrary.finalize,
        codegen.CPUCodeLibrary.add_linking_library,
        codegen.CPUCodeLibrary._get_module_for_linking,
        cpu.CPUContext.get_executable,
    )
    assert after == before


def test_the_environment_variable_and_an_unchecked_numba_turn_it_off(monkeypatch):
    monkeypatch.setenv(numba_linking.DISABLE_ENV, "1")
    assert not numba_linking.applicable()
    plain = codegen.CPUCodeLibrary.finalize
    with numba_linking.callees_optimised_once():
        assert codegen.CPUCodeLibrary.finalize is plain
    monkeypatch.delenv(numba_linking.DISABLE_ENV)
    monkeypatch.setattr(numba_linking, "CHECKED_NUMBA", ((0, 1),))
    assert not numba_linking.applicable()


def test_every_kernel_entry_point_is_compiled_with_it(monkeypatch):
    from hamrkq.backends import kernel

    calls = []
    monkeypatch.setattr(kernel, "jit", lambda *args, **kwargs: calls.append(kwargs))
    kernel.compile_in_cache(lambda: 0, ())
    assert calls and calls[0]["callees_once"] is True
