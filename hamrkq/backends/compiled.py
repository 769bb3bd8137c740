"""The compiled backend: the generated functions and the RKQ kernel under numba.

Nothing here re-implements the algorithm, and no source text is copied:

1. **The system.**  :mod:`hamrkq.backends.codegen` writes ``rhs``, ``jac``,
   ``rhs_jvp``, ``energy`` and ``energy_rows`` of a Hamiltonian as scalar code
   into the cache directory; they are compiled here with explicit signatures
   and ``cache=True``, so numba keeps their machine code beside the generated
   file.
2. **The kernel.**  :mod:`hamrkq.backends.kernel` compiles
   :func:`hamrkq.rkq.loop.advance` once for every Hamiltonian (the system's
   functions are its first-class function arguments) and caches it per
   kernel version.
3. **The driver.**  :class:`hamrkq.rkq.driver.Integration` (chunks, growing
   output, progress, Ctrl-C) runs in Python with the compiled ``advance``.

Parameters are run-time arguments: a parameter sweep never recompiles.

Which backend a run gets, the kernel's functions for a system and the
warm-up of a first use are :mod:`hamrkq.backends.first_use`'s.

Compilation is counted: :data:`COMPILE_COUNT` (and :func:`stats`) grows by
one for every function signature numba had to compile in this process
(rather than load from its cache), so a test can tell that a fresh process
with a warm cache compiled nothing
(:mod:`hamrkq.backends.numba_compile`).
"""

from __future__ import annotations

import contextlib
import math
import os
import types
import weakref
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq._floats import writable_float64
from hamrkq.backends import codegen
from hamrkq.backends import kernel as kernel_module
from hamrkq.backends.codegen import PART_FUNCTIONS
from hamrkq.backends.kernel import CompiledKernel, kernel, kernel_cache_dir
from hamrkq.backends.numba_compile import (
    DISABLE_ENV,
    LOCK,
    BackendUnavailable,
    available,
    jit,
    numba_module,
    signatures,
    stats,
)

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "COMPILED_SUFFIX",
    "COMPILE_COUNT",  # noqa: F822 - module __getattr__, a live count
    "DISABLE_ENV",
    "BackendUnavailable",
    "CompiledKernel",
    "CompiledSystem",
    "available",
    "compile_system",
    "energy",
    "is_compiled",
    "kernel",
    "kernel_cache_dir",
    "loaded_system",
    "mark_compiled",
    "numba_failure",
    "remembered_system",
    "stats",
]

_SYSTEMS: dict[str, CompiledSystem] = {}


def __getattr__(name: str) -> Any:
    # COMPILE_COUNT: signatures compiled (not loaded from numba's disk cache)
    # in this process; read from the counters, where every compile is added.
    if name == "COMPILE_COUNT":
        return stats()["compiled"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# -- the system ------------------------------------------------------------------


class CompiledSystem:
    """The compiled ``rhs``, ``jac``, ``rhs_jvp``, ``energy`` and ``energy_rows``
    of one Hamiltonian (numba dispatchers with fixed signatures).

    ``rhs(t, y, params, out)``, ``jac(t, y, params, out)``,
    ``rhs_jvp(t, y, params, v, out, dout, JM)`` (f and J v at one point, the
    loop's tangent propagation),
    ``energy(t, y, params) -> float`` and ``energy_rows(t, Y, params, out)``
    (``out[i] = H(t[i], Y[i])``).  ``path`` is the generated source file.

    ``jac`` and ``rhs_jvp`` are generated (the tangent part,
    :data:`~hamrkq.backends.codegen.PARTS`) and compiled on their first use:
    a run calls ``rhs_jvp`` only with the tangent estimate of Gamma
    (``rk34q8``'s) and ``jac`` only with the paper's (and inside ``rhs_jvp``
    above :data:`~hamrkq.backends.scalar_printer.MAX_FUSED_DIM` state
    variables), while for a large system they are most of the generation and
    the compile (``benchmarks/lazy_functions.md``).  The kernel gets
    stand-ins for the ones a run does not call (:meth:`kernel_arguments`).

    Parameters
    ----------
    module : module
        The system part of the generated code.
    tangent : callable, optional
        Returns the tangent part (generating it if needed); without it, only
        what the system part defines can be compiled.
    """

    def __init__(
        self, module: types.ModuleType, tangent: Callable[[], types.ModuleType] | None = None
    ):
        self.path = Path(module.__file__)
        self.dim = module.DIM
        # A fresh namespace, so the module keeps its plain-Python functions;
        # the code objects (and so numba's cache files) stay the module's.
        self._namespace: dict[str, Any] = {"math": math, "__name__": module.__name__}
        self._module = module
        self._tangent = tangent
        self._rhs_dd = None
        # energy before energy_rows, which calls it through the namespace.
        self.rhs = self._compile("rhs")
        self.energy = self._compile("energy")
        self.energy_rows = self._compile("energy_rows")

    def _source(self, name: str) -> types.ModuleType:
        """The generated module that defines ``name``."""
        if name in PART_FUNCTIONS["system"]:
            return self._module
        if self._tangent is None:
            raise BackendUnavailable(f"the tangent part ({name}) of {self.path.name} is unknown")
        return self._tangent()

    def _compile(self, name: str):
        """The generated ``name`` compiled (or loaded) into the namespace, once;
        what it calls by name first (``rhs_jvp`` calls ``rhs`` and ``jac``
        above the fused dimension)."""
        with LOCK:
            compiled = self._namespace.get(name)
            if compiled is None:
                code = getattr(self._source(name), name).__code__
                for callee in ("rhs", "jac", "energy"):
                    if callee != name and callee in code.co_names:
                        self._compile(callee)
                plain = types.FunctionType(code, self._namespace, name)
                compiled = self._namespace[name] = jit(plain, signatures()[name])
            return compiled

    @property
    def jac(self):
        """The compiled Jacobian, compiled (or loaded) on first use."""
        return self._compile("jac")

    @property
    def rhs_jvp(self):
        """The compiled f and Jacobian-vector product, compiled (or loaded) on first use."""
        return self._compile("rhs_jvp")

    def compile_all(self) -> None:
        """Generate and compile (or load) every function now (``hamrkq
        compile``); raises BackendUnavailable if that cannot be done."""
        self._compile_each(("jac", "rhs_jvp"))

    def compiled_for(self, gamma: str) -> bool:
        """Whether what a run with this estimate of Gamma calls is compiled."""
        return all(name in self._namespace for name in _CALLED.get(gamma, ()))

    def prepare(self, gamma: str) -> None:
        """Generate and compile (or load) what a run with this estimate of
        Gamma calls; raises BackendUnavailable if that cannot be done."""
        self._compile_each(_CALLED.get(gamma, ()))

    def _compile_each(self, names) -> None:
        with _failures_as_unavailable("the system's Jacobian"):
            for name in names:
                self._compile(name)
            if any(name in PART_FUNCTIONS["tangent"] for name in names):
                mark_compiled(Path(self._tangent().__file__))

    def kernel_arguments(self, gamma: str) -> tuple:
        """``(rhs, tangent, jac)`` for the kernel in a run with this estimate
        of Gamma: ``rhs_jvp`` and ``jac`` where it calls them, else stand-ins
        of their signatures (:func:`~hamrkq.backends.kernel.unused_function`), so that nothing is
        compiled for them."""
        called = _CALLED.get(gamma, ())
        return (
            self.rhs,
            self.rhs_jvp if "rhs_jvp" in called else kernel_module.unused_function("rhs_jvp"),
            self.jac if "jac" in called else kernel_module.unused_function("jac"),
        )

    def rhs_dd(self):
        """``rhs_dd(t, y, params, ylo, out, outlo, JM)``, f in double-double
        (:mod:`hamrkq.backends.dd_printer`), compiled on its first use with
        ``rhs_jvp``'s signature (the kernel takes it in the tangent's place)."""
        if self._rhs_dd is None:
            from hamrkq.backends.dd_printer import DD_FUNCTIONS
            from hamrkq.rkq import ddarith

            namespace: dict[str, Any] = {"math": math, "__name__": self._module.__name__}
            namespace.update({name: getattr(ddarith, name) for name in DD_FUNCTIONS})
            plain = types.FunctionType(self._module.rhs_dd.__code__, namespace, "rhs_dd")
            # its ddarith callees optimised once, inside it (numba_linking)
            self._rhs_dd = jit(plain, signatures()["rhs_jvp"], callees_once=True)
        return self._rhs_dd


@contextlib.contextmanager
def _failures_as_unavailable(what: str) -> Iterator[None]:
    """Generating, caching or compiling ``what`` failing as BackendUnavailable,
    with what failed: the expressions (CodegenError), the cache directory
    (OSError) or numba (its TypingError, LoweringError and relatives)."""
    try:
        yield
    except BackendUnavailable:
        raise
    except codegen.CodegenError as exc:
        raise BackendUnavailable(f"{what} cannot be compiled: {exc}") from exc
    except OSError as exc:
        raise BackendUnavailable(
            f"the cache directory {codegen.cache_dir()} cannot be used ({exc}); "
            f"set {codegen.CACHE_ENV} to a writable directory"
        ) from exc
    except Exception as exc:  # numba's TypingError/LoweringError and relatives
        raise numba_failure("the system", exc) from exc


def numba_failure(what: str, exc: Exception) -> BackendUnavailable:
    """The error for numba failing to compile ``what`` (its TypingError,
    LoweringError and relatives), with the first line of numba's message."""
    first = str(exc).splitlines()[0] if str(exc) else ""
    return BackendUnavailable(f"numba failed to compile {what} ({type(exc).__name__}: {first})")


#: What the kernel calls besides ``rhs``, by estimate of Gamma
#: (``global_error_estimate``): the tangent propagation takes f and J v in
#: one call, the paper's (I + h J) propagation the Jacobian.
_CALLED = {"tangent": ("rhs_jvp",), "paper": ("jac",)}


def calls_tangent_part(gamma: str) -> bool:
    """Whether a run with this estimate of Gamma calls the tangent part of a
    system's code (:data:`~hamrkq.backends.codegen.PARTS`)."""
    return any(name in PART_FUNCTIONS["tangent"] for name in _CALLED.get(gamma, ()))


def loaded_system(key: str) -> CompiledSystem | None:
    """The system of the code-generation key ``key`` if :func:`compile_system`
    has made it in this process, else None."""
    return _SYSTEMS.get(key)


#: :func:`compile_system`'s answers by Hamiltonian object, dropped with it
#: (as :mod:`hamrkq.backends.codegen`'s keys and
#: :func:`hamrkq.backends.numeric.numeric_of`'s functions): its key and its
#: system.  A solve asks for the system of the same object two or three
#: times (the kernel's functions, H at the nodes, the warm-up's check), and
#: the key's lookup and the lock cost a microsecond and a half each time
#: (a lookup here: 0.15 us, the object's hash computed once).
_BY_OBJECT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def remembered_system(ham: Hamiltonian) -> tuple[str, CompiledSystem] | None:
    """The code-generation key and the system of ``ham`` where
    :func:`compile_system` made or found it for this object and the system
    is still the one its key names (:func:`loaded_system`), else None."""
    known = _BY_OBJECT.get(ham)
    if known is None or _SYSTEMS.get(known[0]) is not known[1]:
        return None
    return known


def compile_system(ham: Hamiltonian) -> CompiledSystem:
    """Generate (or find in the cache) and compile the functions of ``ham``.

    Memoised per process by the code-generation key (and by the object:
    :func:`remembered_system`).

    Raises
    ------
    BackendUnavailable
        The backend is disabled or missing, the expressions cannot be turned
        into scalar code, numba cannot compile them, or the cache directory
        cannot be written; the message says which.
    """
    numba_module()  # (asked every time: HAMRKQ_DISABLE_NUMBA may be set since)
    known = remembered_system(ham)
    if known is not None:
        return known[1]
    key = codegen.cache_key(ham)
    with LOCK:
        system = _SYSTEMS.get(key)
        if system is None:
            with _failures_as_unavailable("the system"):
                module = codegen.load_module(ham)
                system = CompiledSystem(module, lambda: codegen.load_module(ham, part="tangent"))
            _SYSTEMS[key] = system
            mark_compiled(system.path)
        _BY_OBJECT[ham] = (key, system)
        return system


#: Written beside a generated module once its functions are compiled (or
#: loaded): numba keeps their machine code in its own cache, which cannot be
#: asked cheaply whether it holds them.  Holds numba's cache setting, so a
#: changed ``NUMBA_CACHE_DIR`` does not count as compiled.
COMPILED_SUFFIX = ".compiled"


def _numba_cache_setting() -> str:
    return "NUMBA_CACHE_DIR=" + os.environ.get("NUMBA_CACHE_DIR", "")


def _marker_text(marker: Path) -> str | None:
    """A compiled-marker's text, or None where it cannot be read as text (a
    damaged one: bytes 0xff 0xfe made every run end in UnicodeDecodeError's
    traceback, found by QA; it only saves a later helper, and is rewritten)."""
    try:
        return marker.read_text()
    except (OSError, ValueError):
        return None


def mark_compiled(path: Path) -> None:
    marker = path.with_suffix(COMPILED_SUFFIX)
    try:
        if _marker_text(marker) != _numba_cache_setting():
            marker.write_text(_numba_cache_setting())
    except OSError:  # a read-only cache: the marker only saves a later helper
        pass


def is_compiled(ham: Hamiltonian, gamma: str = "off") -> bool:
    """Whether the functions of ``ham`` that a run with the estimate of
    Gamma ``gamma`` calls (the system part; and the tangent part, where
    :func:`calls_tangent_part`) were compiled in this process or (as far as
    hamrkq can tell without loading them) are in numba's disk cache."""
    key = codegen.cache_key(ham)
    parts = ("system", "tangent") if calls_tangent_part(gamma) else ("system",)
    system = _SYSTEMS.get(key)
    if system is not None and system.compiled_for(gamma):
        return True
    for part in parts:
        marker = codegen.module_path(codegen.part_key(key, part)).with_suffix(COMPILED_SUFFIX)
        if _marker_text(marker) != _numba_cache_setting():
            return False
    return True


def energy(ham: Hamiltonian, t: np.ndarray, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """H at the rows of ``Y`` (times ``t``), with the compiled scalar energy."""
    system = compile_system(ham)
    Y = writable_float64(Y)
    t = np.asarray(t, dtype=np.float64)
    if t.shape != Y.shape[:1]:
        t = np.array(np.broadcast_to(t, Y.shape[:1]))
    out = np.empty(Y.shape[0])
    system.energy_rows(writable_float64(t), Y, writable_float64(params), out)
    return out
