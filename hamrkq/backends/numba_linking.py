"""Compile a numba function whose callees are optimised once, in their caller.

Why: the step kernel (:mod:`hamrkq.backends.kernel`) is one entry point over
about sixty ``register_jitable`` functions (:mod:`hamrkq.rkq.jit`).  numba
compiles each such callee as a dispatcher of its own and *finalises* it as if
it were to be called from Python: it links the callee's own callees into it,
runs LLVM's full module optimisation over the result and generates machine
code for it.  None of that machine code is ever run (a callee has no Python
wrapper; its caller links its LLVM IR and calls it there), and along the chain
``advance -> attempt -> quench_phase -> quencher_step -> ...`` nearly the whole
kernel is optimised and code-generated once per level.  Compiled as below,
LLVM optimises the kernel once and generates its machine code once;
``benchmarks/kernel_compile.py`` measures both ways side by side on an empty
cache (``benchmarks/kernel_compile.md``: the compile about halved, the same
run time, the same bits).

What :func:`callees_optimised_once` changes, while it is active and only for
functions compiled inside it: a callee compiled without a Python wrapper (the
only kind numba never calls through its machine address: its address is 0 in
numba's own path too) is not finalised when it is compiled; when a caller
links it, its callees are linked into it without optimising or generating
code; the one function finalised in full, the entry point, then optimises
the whole kernel once (LLVM's ``O3`` module passes, inlining included) and
generates its code once.  The machine code does the same arithmetic: every
test of the suite runs on a kernel compiled this way, and the benchmark
checks results bit for bit against one compiled the plain way.

numba's internals are not an API: the change is made only for numba
versions it was checked on (:data:`CHECKED_NUMBA`) and when every method it
wraps is where it was; otherwise numba compiles as it always does.  It holds
numba's global compiler lock throughout, so no other thread compiles while
numba's methods are wrapped.  Set :data:`DISABLE_ENV` to compile the plain way.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

__all__ = ["CHECKED_NUMBA", "DISABLE_ENV", "applicable", "callees_optimised_once"]

#: numba releases (major, minor) on which the change was checked against the
#: plain compile, bit for bit (``benchmarks/kernel_compile.py``; 0.66 and
#: 0.67: ``benchmarks/kernel_compile_numba066.md`` and ``..._numba067.md``,
#: with its tests).
CHECKED_NUMBA = ((0, 66), (0, 67), (0, 68))

#: Environment variable: set to 1 (or true/yes/on) to compile the plain way.
DISABLE_ENV = "HAMRKQ_PLAIN_NUMBA_LINKING"

# Attributes set on a numba code library by the wrapped methods.
_DEFERRED = "_hamrkq_deferred"
_ENVIRONMENTS = "_hamrkq_environments"


def _numba_version() -> tuple[int, int]:
    import numba

    major, minor = numba.__version__.split(".")[:2]
    return int(major), int("".join(ch for ch in minor if ch.isdigit()) or 0)


def applicable() -> bool:
    """Whether :func:`callees_optimised_once` changes anything here: a numba
    release in :data:`CHECKED_NUMBA`, every wrapped method present, and
    :data:`DISABLE_ENV` not set."""
    if os.environ.get(DISABLE_ENV, "").strip().lower() in {"1", "true", "yes", "on"}:
        return False
    try:
        if _numba_version() not in CHECKED_NUMBA:
            return False
        from numba.core import codegen, cpu

        library = codegen.CPUCodeLibrary
        wrapped = ("_get_module_for_linking", "add_linking_library", "finalize")
        return all(hasattr(library, name) for name in wrapped) and hasattr(
            cpu.CPUContext, "get_executable"
        )
    except Exception:  # a numba that cannot be imported or is laid out otherwise
        return False


@contextlib.contextmanager
def callees_optimised_once() -> Iterator[None]:
    """While active, numba functions compiled in this thread have their
    wrapper-less callees optimised and code-generated once, inside the
    function that is finalised in full (see the module's docstring); a no-op
    where :func:`applicable` is false."""
    if not applicable():
        yield
        return
    from numba.core import codegen, cpu
    from numba.core.compiler_lock import global_compiler_lock

    library_type = codegen.CPUCodeLibrary
    context_type = cpu.CPUContext
    saved = {
        (library_type, "_get_module_for_linking"): library_type._get_module_for_linking,
        (library_type, "add_linking_library"): library_type.add_linking_library,
        (library_type, "finalize"): library_type.finalize,
        (context_type, "get_executable"): context_type.get_executable,
    }
    plain_module_for_linking = saved[(library_type, "_get_module_for_linking")]
    plain_add_linking_library = saved[(library_type, "add_linking_library")]
    plain_finalize = saved[(library_type, "finalize")]
    plain_get_executable = saved[(context_type, "get_executable")]

    def get_executable(self, library, fndesc, env):
        if library._finalized or _defines(library, fndesc.llvm_cpython_wrapper_name):
            return plain_get_executable(self, library, fndesc, env)
        # A callee without a Python wrapper: numba's own path would finalise
        # it only to find no wrapper and use the address 0.
        from numba import _dynfunc

        setattr(library, _DEFERRED, True)
        setattr(library, _ENVIRONMENTS, [(self.get_env_name(fndesc), env)])
        name = fndesc.qualname.split(".")[-1]
        doc = f"compiled wrapper for {fndesc.qualname!r}"
        return _dynfunc.make_function(fndesc.lookup_module(), name, doc, 0, env, (library,))

    def module_for_linking(self):
        if not self._finalized and getattr(self, _DEFERRED, False):
            _link_only(self, plain_module_for_linking)
        return plain_module_for_linking(self)

    def add_linking_library(self, library):
        if not library._finalized and getattr(library, _DEFERRED, False):
            _link_only(library, plain_module_for_linking)
        return plain_add_linking_library(self, library)

    def finalize(self):
        plain_finalize(self)
        # The deferred callees' environments live in this library's code now.
        engine = self.codegen._engine
        for linked in self._linking_libraries:
            for env_name, env in getattr(linked, _ENVIRONMENTS, ()):
                if engine.get_global_value_address(env_name):
                    self.codegen.set_env(env_name, env)

    with global_compiler_lock:
        library_type._get_module_for_linking = module_for_linking
        library_type.add_linking_library = add_linking_library
        library_type.finalize = finalize
        context_type.get_executable = get_executable
        try:
            yield
        finally:
            for (owner, name), method in saved.items():
                setattr(owner, name, method)


def _defines(library, name: str) -> bool:
    """Whether ``library``'s (unfinalised) module defines the function ``name``."""
    try:
        library._final_module.get_function(name)
    except NameError:
        return False
    return True


def _link_only(library, module_for_linking) -> None:
    """Finalise a deferred callee for linking only: its callees linked in, no
    optimisation, no machine code (its caller optimises it)."""
    environments = list(getattr(library, _ENVIRONMENTS, ()))
    seen = set()
    for callee in library._linking_libraries:
        if callee in seen:
            continue
        seen.add(callee)
        library._reload_init.update(callee._reload_init)
        if not callee._finalized and getattr(callee, _DEFERRED, False):
            _link_only(callee, module_for_linking)
        library._final_module.link_in(module_for_linking(callee), preserve=True)
        environments.extend(getattr(callee, _ENVIRONMENTS, ()))
    library._final_module.verify()
    library._finalized = True
    setattr(library, _ENVIRONMENTS, environments)
