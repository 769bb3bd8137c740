"""The compiled backend: the RKQ loop and the generated functions under numba.

Nothing here re-implements the algorithm.  The step loop is
:func:`hamrkq.rkq.kernel.advance` and its callees, written in the subset of Python
that :func:`numba.njit` accepts; this module compiles them:

1. **The system.**  :mod:`hamrkq.backends.codegen` writes ``rhs``, ``jac``, ``energy``
   and ``energy_rows`` of a Hamiltonian as scalar code into the cache
   directory; they are compiled here with explicit signatures and
   ``cache=True``, so numba keeps their machine code beside the generated file.
2. **The loop.**  The text of ``hamrkq/rkq.py`` is copied into the cache
   directory (followed by the twins below) under a name that hashes it and
   the versions, imported, and :func:`~hamrkq.rkq.kernel.advance` and the functions
   it calls are compiled there with ``cache=True``.  ``rhs`` and ``jac`` reach
   the loop as *first-class function* arguments (function pointers with a
   fixed signature), so one compiled loop serves every Hamiltonian and its
   machine code is cached once per hamrkq version.  (Passed as ordinary
   numba dispatchers they would specialise the loop to one system and make
   it uncacheable.)  The small vector primitives of :mod:`hamrkq.rkq.kernel` (sums
   over stages, a matrix-vector product, compensated summation, the tolerance
   and the weighted norm) are swapped for element loops (:data:`PRIMITIVES`):
   NumPy calls on arrays of a few elements are the right choice in the
   interpreter and the slowest one under numba (a BLAS call per stage costs
   more than the stage).  The twins do the same arithmetic in the same order
   as rkq's versions, so both backends compute the same bits; the tests check
   that element by element.
3. **The driver.**  :func:`hamrkq.rkq.kernel.run` itself (chunks, growing output,
   progress, Ctrl-C) runs unchanged in Python, with the compiled ``advance``.

Parameters are run-time arguments: a parameter sweep never recompiles.

``HAMRKQ_DISABLE_NUMBA=1`` (or numba missing, or a system that cannot be
compiled) makes :func:`resolve_backend` choose the Python backend for
``backend="auto"``, with one :class:`~hamrkq.errors.HamrkqWarning` saying why.

Compilation is counted: :data:`COMPILE_COUNT` grows by one for every function
signature numba had to compile in this process (rather than load from its
cache), so a test can tell that a fresh process with a warm cache compiled
nothing.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import math
import os
import threading
import time
import types
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.backends import codegen
from hamrkq.errors import HamrkqError, HamrkqWarning, OptionError
from hamrkq.rkq import kernel as rkq

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "COMPILE_COUNT",
    "DISABLE_ENV",
    "PRIMITIVES",
    "BackendUnavailable",
    "CompiledSystem",
    "available",
    "compile_system",
    "energy",
    "resolve_backend",
    "run",
    "stats",
]

#: Environment variable: set to 1 (or true/yes/on) to turn the compiled backend off.
DISABLE_ENV = "HAMRKQ_DISABLE_NUMBA"
#: Signatures compiled (not loaded from numba's disk cache) in this process.
COMPILE_COUNT = 0
_STATS = {"compiled": 0, "loaded": 0, "compile_seconds": 0.0, "load_seconds": 0.0}
_LOCK = threading.RLock()
_SYSTEMS: dict[str, CompiledSystem] = {}
_KERNEL: dict[str, Any] = {}
_TANGENTS: dict[Any, Any] = {}  # compiled jac -> compiled rhs_jvp of the same system
_POINTERS: dict[tuple, tuple] = {}  # (rhs, jac) -> the loop's three function pointers


class BackendUnavailable(HamrkqError, RuntimeError):
    """The compiled backend cannot be used (disabled, numba missing, or the
    system cannot be compiled); the message says which."""


# -- availability ------------------------------------------------------------


def _disabled_by_env() -> bool:
    return os.environ.get(DISABLE_ENV, "").strip().lower() in {"1", "true", "yes", "on"}


def available() -> tuple[bool, str]:
    """Whether the compiled backend can be used here, and if not, why.

    Returns
    -------
    (ok, reason) : (bool, str)
        ``reason`` is empty when ``ok``.
    """
    if _disabled_by_env():
        return False, f"the environment variable {DISABLE_ENV} is set"
    try:
        import numba  # noqa: F401
    except Exception as exc:  # ImportError, or a broken install (llvmlite)
        return False, f"numba cannot be imported ({type(exc).__name__}: {exc})"
    return True, ""


def resolve_backend(backend: str, ham: Hamiltonian | None = None) -> str:
    """The backend to run: ``"python"`` or ``"numba"``.

    Parameters
    ----------
    backend : {"auto", "numba", "python"}
        ``"auto"`` means numba when it can be used, else Python with one
        :class:`~hamrkq.errors.HamrkqWarning`.
    ham : Hamiltonian, optional
        With ``"auto"``, the system is generated and compiled here, so that a
        system numba cannot compile also falls back with the warning.

    Raises
    ------
    OptionError
        An unknown backend name, or ``"numba"`` when it cannot be used.
    """
    if backend == "python":
        return "python"
    if backend not in ("auto", "numba"):
        raise OptionError(f"backend={backend!r} is not valid; valid: 'auto', 'numba', 'python'")
    ok, reason = available()
    if ok and ham is not None:
        try:
            compile_system(ham)
        except BackendUnavailable as exc:
            ok, reason = False, str(exc)
    if ok:
        return "numba"
    if backend == "numba":
        raise OptionError(f"backend='numba' cannot be used: {reason}")
    warnings.warn(
        f"hamrkq: the compiled (numba) backend is not used because {reason}; "
        "running the pure-Python loop, which is about 100 times slower. "
        "Pass backend='python' to choose it explicitly and silence this warning.",
        HamrkqWarning,
        stacklevel=3,
    )
    return "python"


def stats() -> dict[str, float]:
    """Counters of this process: signatures ``compiled`` and ``loaded`` from
    the disk cache, and the seconds spent on each."""
    return {**_STATS, "compile_count": COMPILE_COUNT}


# -- compiling with accounting ---------------------------------------------------


def _numba():
    ok, reason = available()
    if not ok:
        raise BackendUnavailable(reason)
    import numba

    return numba


@functools.cache
def _types():
    from numba import types as nt

    vec, mat = nt.float64[::1], nt.float64[:, ::1]
    rhs = nt.void(nt.float64, vec, vec, vec)
    jac = nt.void(nt.float64, vec, vec, mat)
    rhs_jvp = nt.void(nt.float64, vec, vec, vec, vec, vec, mat)
    return {
        "rhs": rhs,
        "jac": jac,
        "rhs_jvp": rhs_jvp,
        "energy": nt.float64(nt.float64, vec, vec),
        "energy_rows": nt.void(vec, mat, vec, vec),
        "rhs_type": nt.FunctionType(rhs),
        "jac_type": nt.FunctionType(jac),
        "rhs_jvp_type": nt.FunctionType(rhs_jvp),
    }


def _account(dispatcher, started: float) -> None:
    """Add a dispatcher's cache misses and hits to the counters."""
    global COMPILE_COUNT
    elapsed = time.perf_counter() - started
    misses = sum(dispatcher.stats.cache_misses.values())
    hits = sum(dispatcher.stats.cache_hits.values())
    COMPILE_COUNT += misses
    _STATS["compiled"] += misses
    _STATS["loaded"] += hits
    _STATS["compile_seconds" if misses else "load_seconds"] += elapsed


def _jit(function: Callable, signature=None, **options):
    numba = _numba()
    flags = {"cache": True, "nogil": True, "error_model": "numpy", **options}
    with warnings.catch_warnings():
        # numba explains an uncacheable function with a warning; our counter
        # and BackendUnavailable carry that information instead.
        warnings.simplefilter("ignore", numba.NumbaWarning)
        started = time.perf_counter()
        if signature is None:
            return numba.njit(**flags)(function)
        dispatcher = numba.njit(signature, **flags)(function)
        _account(dispatcher, started)
        return dispatcher


# -- the system ------------------------------------------------------------------


class CompiledSystem:
    """The compiled ``rhs``, ``jac``, ``rhs_jvp``, ``energy`` and ``energy_rows``
    of one Hamiltonian (numba dispatchers with fixed signatures).

    ``rhs(t, y, params, out)``, ``jac(t, y, params, out)``,
    ``rhs_jvp(t, y, params, v, out, dout, JM)`` (f and J v at one point, the
    loop's tangent propagation),
    ``energy(t, y, params) -> float`` and ``energy_rows(t, Y, params, out)``
    (``out[i] = H(t[i], Y[i])``).  ``path`` is the generated source file.
    """

    def __init__(self, module: types.ModuleType):
        self.path = Path(module.__file__)
        self.dim = module.DIM
        # A fresh namespace, so the module keeps its plain-Python functions;
        # the code objects (and so numba's cache files) stay the module's.
        namespace: dict[str, Any] = {"math": math, "__name__": module.__name__}
        sig = _types()
        # energy first: energy_rows calls it through the namespace.
        for name in ("rhs", "jac", "rhs_jvp", "energy", "energy_rows"):
            plain = types.FunctionType(getattr(module, name).__code__, namespace, name)
            namespace[name] = _jit(plain, sig[name])
        self.rhs = namespace["rhs"]
        self.jac = namespace["jac"]
        self.rhs_jvp = namespace["rhs_jvp"]
        # The loop is handed (rhs, jac) by rkq.run; it finds the fused
        # function of the same system through its jac.
        _TANGENTS[self.jac] = self.rhs_jvp
        self.energy = namespace["energy"]
        self.energy_rows = namespace["energy_rows"]


def compile_system(ham: Hamiltonian) -> CompiledSystem:
    """Generate (or find in the cache) and compile the functions of ``ham``.

    Memoised per process by the code-generation key.

    Raises
    ------
    BackendUnavailable
        The backend is disabled or missing, the expressions cannot be turned
        into scalar code, numba cannot compile them, or the cache directory
        cannot be written; the message says which.
    """
    _numba()
    key = codegen.cache_key(ham)
    with _LOCK:
        system = _SYSTEMS.get(key)
        if system is not None:
            return system
        try:
            module = codegen.load_module(ham)
            system = CompiledSystem(module)
        except codegen.CodegenError as exc:
            raise BackendUnavailable(f"the system cannot be compiled: {exc}") from exc
        except OSError as exc:
            raise BackendUnavailable(
                f"the cache directory {codegen.cache_dir()} cannot be used ({exc}); "
                f"set {codegen.CACHE_ENV} to a writable directory"
            ) from exc
        except Exception as exc:  # numba's TypingError/LoweringError and relatives
            raise BackendUnavailable(
                f"numba failed to compile the system ({type(exc).__name__}: "
                f"{str(exc).splitlines()[0] if str(exc) else ''})"
            ) from exc
        _SYSTEMS[key] = system
        return system


# -- the loop --------------------------------------------------------------------
# Element-loop versions of rkq's small vector primitives, with the same
# arguments and the same arithmetic per element.  Only the order of the sums
# over stages differs from NumPy's dot (so results agree to rounding, not
# bit for bit).  Under numba a loop over a few elements costs nanoseconds,
# where a BLAS call costs a few hundred.


def _fmax(x, y):
    """np.fmax for two floats: the larger, ignoring a NaN."""
    return x if (x >= y or y != y) else y


def _stage_sum(A, j, K, i):
    acc = 0.0
    for m in range(j):
        acc += A[j, m] * K[m, i]
    return acc


def _combine_loops(base, lo, h, A, j, K, out):
    for i in range(out.shape[0]):
        out[i] = base[i] + (lo[i] + _stage_sum(A, j, K, i) * h) if j else base[i] + lo[i]


def _plain_loops(base, h, A, j, K, out):
    for i in range(out.shape[0]):
        out[i] = _stage_sum(A, j, K, i) * h + base[i] if j else base[i]


def _max_loops(x):
    top = -math.inf
    for i in range(x.shape[0]):
        value = x[i]
        if value != value:  # NaN wins, like ndarray.max
            return value
        if value > top:
            top = value
    return top


def _copy_loops(src, out):
    for i in range(out.shape[0]):
        out[i] = src[i]


def _matvec_loops(M, v, out):
    for i in range(out.shape[0]):
        acc = 0.0
        for k in range(v.shape[0]):
            acc += M[i, k] * v[k]
        out[i] = acc


def _increment_loops(h, b, K, out):
    for i in range(out.shape[0]):
        acc = 0.0
        for m in range(b.shape[0]):
            acc += b[m] * K[m, i]
        out[i] = acc * h


def _two_sum_loops(hi, lo, inc, out_hi, out_lo, tmp, tmp2):
    for i in range(hi.shape[0]):
        b = inc[i] + lo[i]
        s = hi[i] + b
        bb = s - hi[i]
        out_lo[i] = (hi[i] - (s - bb)) + (b - bb)
        out_hi[i] = s


def _delta_loops(atol, rtol, a, b, rel, rule, out, tmp):
    low = math.inf
    for i in range(out.shape[0]):
        if rel:
            value = _fmax(_fmax(abs(a[i]), abs(b[i])) * rtol[i], atol[i])
        else:
            value = atol[i]
        out[i] = value
        # The minimum propagates NaN, like ndarray.min.
        if value < low or (value != value and low == low):
            low = value
    if rule == RULE_PRENTICE:  # noqa: F821 - a global of the kernel module
        for i in range(out.shape[0]):
            out[i] = low


def _wnorm_loops(e, delta, tmp):
    top = -math.inf
    for i in range(e.shape[0]):
        value = abs(e[i]) / delta[i]
        if value != value:  # NaN wins, like ndarray.max
            return value
        if value > top:
            top = value
    return top


#: rkq primitive -> its element-loop twin, swapped in when compiling.
PRIMITIVES: dict[str, Callable] = {
    "_copy": _copy_loops,
    "_max": _max_loops,
    "_combine": _combine_loops,
    "_plain": _plain_loops,
    "_increment": _increment_loops,
    "_matvec": _matvec_loops,
    "_two_sum": _two_sum_loops,
    "_delta": _delta_loops,
    "_wnorm": _wnorm_loops,
}
_HELPERS = (_fmax, _stage_sum)


def _kernel_source() -> str:
    """rkq's text followed by the primitives' twins: one file, so that numba
    caches all of the loop's machine code beside it, in the cache directory."""
    parts = [Path(rkq.__file__).read_text(encoding="utf-8"), "", "", _TWINS_BANNER]
    parts += [inspect.getsource(f) + "\n" for f in (*_HELPERS, *PRIMITIVES.values())]
    return "\n".join(parts)


_TWINS_BANNER = (
    "# ---- appended by hamrkq.backends.compiled: element-loop twins of the primitives above ----"
)


def _kernel_key(source: str) -> str:
    """Hash of the kernel text and the versions (the text includes the twins)."""
    digest = hashlib.sha256()
    for part in (source, codegen._versions()):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()


def _callees(function: types.FunctionType, namespace: dict[str, Any]) -> set[str]:
    """Names of the module functions that ``function`` calls, transitively."""
    found: set[str] = set()
    pending = [function]
    while pending:
        code = pending.pop().__code__
        for name in code.co_names:
            value = namespace.get(name)
            if isinstance(value, types.FunctionType) and name not in found:
                found.add(name)
                pending.append(value)
    return found


def _kernel():
    """The compiled ``advance`` (memoised): rkq's source copied into the cache,
    its loop (``_advance``, which takes the fused ``rhs_jvp`` besides ``rhs``
    and ``jac``) and the primitives' twins compiled in that module."""
    with _LOCK:
        if "advance" in _KERNEL:
            return _KERNEL["advance"]
        _numba()
        source = _kernel_source()
        module = codegen.load_source("kernel_" + _kernel_key(source), lambda: source)
        namespace = vars(module)
        # A primitive rkq does not define is simply not swapped (its callers
        # are compiled as written); tests/test_compiled.py checks every one.
        for name, twin in PRIMITIVES.items():
            if name in namespace:
                namespace[name] = namespace[twin.__name__]
        for name in [*sorted(_callees(namespace["_advance"], namespace)), "_advance"]:
            # Without numba's runtime (NRT): the loop allocates nothing, and
            # with the runtime every array view and every array argument
            # costs atomic reference-count updates (measured: about a third
            # of the run time).  A stray allocation fails to compile.
            namespace[name] = _jit(namespace[name], _nrt=False)
        _KERNEL["advance"] = _Advance(namespace["_advance"])
        _KERNEL["namespace"] = namespace
        return _KERNEL["advance"]


def _pointers(rhs, jac) -> tuple:
    """``rhs``, ``jac`` and the system's ``rhs_jvp`` as function pointers
    whose addresses are looked up once (memoised): numba would otherwise
    look up a dispatcher's address on every call of the loop, which costs
    about a tenth of a millisecond each time."""
    from numba.core.types import WrapperAddressProtocol
    from numba.experimental.function_type import _get_wrapper_address

    class Pointer(WrapperAddressProtocol):
        def __init__(self, function, signature):
            self._function = function  # keeps the machine code alive
            self._signature = signature
            self._address = _get_wrapper_address(function, signature)

        def __wrapper_address__(self):
            return self._address

        def signature(self):
            return self._signature

    sig = _types()
    pointers = (
        Pointer(rhs, sig["rhs"]),
        Pointer(jac, sig["jac"]),
        Pointer(_TANGENTS[jac], sig["rhs_jvp"]),
    )
    _POINTERS[(rhs, jac)] = pointers
    return pointers


class _Advance:
    """Calls the compiled ``_advance`` as ``advance(rhs, jac, *args)``, adding
    the system's fused ``rhs_jvp`` (found through ``jac``) and compiling (or
    loading from the disk cache) the signature of its arguments first, with
    the functions typed as function pointers rather than as the particular
    functions, so that one compiled loop serves every system."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self.seen: set[tuple] = set()

    def __call__(self, rhs, jac, *args):
        # A cheap description of the arguments (numba.typeof on all of them
        # would cost more than the call itself on a short chunk).
        seen = tuple(
            (type(a), a.dtype.char, a.ndim, a.flags.c_contiguous, a.flags.writeable)
            if isinstance(a, np.ndarray)
            else type(a)
            for a in args
        )
        if seen not in self.seen:
            self._prepare(args)
            self.seen.add(seen)
        pointers = _POINTERS.get((rhs, jac))
        if pointers is None:
            pointers = _pointers(rhs, jac)
        return self.dispatcher(*pointers, *args)

    def _prepare(self, args) -> None:
        import numba

        sig = _types()
        key = (sig["rhs_type"], sig["jac_type"], sig["rhs_jvp_type"],
               *(numba.typeof(a) for a in args))  # fmt: skip
        if key not in self.dispatcher.signatures:
            dispatcher = self.dispatcher
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", numba.NumbaWarning)
                started = time.perf_counter()
                before = sum(dispatcher.stats.cache_misses.values())
                dispatcher.disable_compile(False)
                try:
                    dispatcher.compile(key)
                finally:
                    # Calls must use the compiled signatures: left enabled,
                    # numba would compile a copy specialised to this rhs.
                    if dispatcher.signatures:
                        dispatcher.disable_compile()
            global COMPILE_COUNT
            compiled = sum(dispatcher.stats.cache_misses.values()) - before
            COMPILE_COUNT += compiled
            _STATS["compiled" if compiled else "loaded"] += 1
            _STATS["compile_seconds" if compiled else "load_seconds"] += (
                time.perf_counter() - started
            )


def run(ham: Hamiltonian, params: np.ndarray, t0: float, y0: np.ndarray, t_end: float,
        **options: Any) -> rkq.RunOutput:  # fmt: skip
    """:func:`hamrkq.rkq.kernel.run` with the compiled loop and the compiled system.

    Parameters
    ----------
    ham : Hamiltonian
    params, t0, y0, t_end, **options
        As for :func:`hamrkq.rkq.kernel.run` (``rk3``, ``rk4``, ``rk8``, ``atol``,
        ``rtol``, ...), except ``inplace``, which is implied.

    Raises
    ------
    BackendUnavailable
        See :func:`compile_system`.
    """
    system = compile_system(ham)
    try:
        driver = _driver()
    except BackendUnavailable:
        raise
    except Exception as exc:  # numba failing on the loop itself
        raise BackendUnavailable(
            f"numba failed to compile the RKQ loop ({type(exc).__name__})"
        ) from exc
    return driver(system.rhs, system.jac, np.require(params, np.float64, ("C", "W")),
                  float(t0), np.require(y0, np.float64, ("C", "W")), float(t_end),
                  inplace=True, **options)  # fmt: skip


def _driver():
    """``rkq.run`` rebound so that its global ``advance`` is the compiled one."""
    with _LOCK:
        if "run" not in _KERNEL:
            advance = _kernel()
            namespace = dict(vars(rkq))
            namespace["advance"] = advance
            original = rkq.run
            driver = types.FunctionType(
                original.__code__, namespace, original.__name__, original.__defaults__
            )
            driver.__kwdefaults__ = original.__kwdefaults__
            driver.__doc__ = original.__doc__
            _KERNEL["run"] = driver
        return _KERNEL["run"]


def energy(ham: Hamiltonian, t: np.ndarray, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """H at the rows of ``Y`` (times ``t``), with the compiled scalar energy."""
    system = compile_system(ham)
    # The compiled signature takes writable C-contiguous float64 arrays.
    Y = np.require(Y, np.float64, ("C", "W"))
    t = np.array(np.broadcast_to(np.asarray(t, dtype=np.float64), Y.shape[:1]))
    out = np.empty(Y.shape[0])
    system.energy_rows(t, Y, np.require(params, np.float64, ("C", "W")), out)
    return out
