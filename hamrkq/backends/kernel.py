"""The compiled step kernel: compiled once per version, cached, called cheaply.

:func:`hamrkq.rkq.loop.advance` and everything it calls are ordinary Python
functions marked with numba's public ``register_jitable``
(:mod:`hamrkq.rkq.jit`): the interpreted backend calls them as they are, and
here ``numba.njit`` compiles ``advance`` with an explicit signature in which
``rhs``, ``rhs_jvp`` and ``jac`` are first-class function types, so one
compiled kernel serves every Hamiltonian.  Its machine code is cached once
per kernel version, in ``<cache dir>/kernel-<hash of the kernel's sources and
versions>`` (:func:`kernel_cache_dir`; :mod:`hamrkq.backends.extras` compiles
the kernel's other entry points there too, :func:`compile_in_cache`).

:class:`CompiledKernel` calls the compiled entry point of the signature its
arguments' key names, and numba's lookup of the first-class functions'
addresses is remembered (:func:`remember_function_addresses`): the per-call
overhead of a tiny problem went from 0.367 ms to 0.291 ms, then (with the
identity-keyed memo and the entry point) from 0.299 ms to 0.240 ms, each
measured side by side (``docs/performance.md``).

Runs whose estimate of Gamma calls neither ``rhs_jvp`` nor ``jac`` get
stand-ins of their signatures (:func:`unused_function`), compiled here once
and cached beside the kernel, so that a system's own are compiled only when
a run calls them (:class:`hamrkq.backends.compiled.CompiledSystem`).

:func:`build_kernel` compiles the kernel into the cache without compiling any
system: ``hamrkq compile`` calls it, and so does the helper process that
compiles the kernel on another core during a first use
(:mod:`hamrkq.backends.kernel_helper`).
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq.backends import codegen
from hamrkq.backends.numba_compile import LOCK, BackendUnavailable, jit, numba_module, signatures

__all__ = [
    "KERNEL_MODULES",
    "CompiledKernel",
    "build_kernel",
    "compile_in_cache",
    "describe",
    "kernel",
    "kernel_cache_dir",
    "kernel_cached",
    "probe",
    "probe_rhs",
    "remember_function_addresses",
    "unused_function",
]

#: The modules whose functions make up the compiled kernel (their text keys its cache).
KERNEL_MODULES = (
    "jit", "layout", "arith", "ddarith", "steps", "clock", "certify", "loop", "start", "batch",
)  # fmt: skip

_KERNEL: dict[str, Any] = {}


# -- where it is cached ---------------------------------------------------------


def _kernel_key() -> str:
    """Hash of the kernel's sources and the versions."""
    from hamrkq import rkq

    digest = hashlib.sha256()
    for name in KERNEL_MODULES:
        path = Path(rkq.__file__).parent / f"{name}.py"
        digest.update(path.read_bytes())
        digest.update(b"\0")
    digest.update(codegen._versions().encode())
    return digest.hexdigest()[:16]


def kernel_cache_dir() -> Path:
    """Where numba keeps the kernel's machine code."""
    return codegen.cache_dir() / f"kernel-{_kernel_key()}"


def compile_in_cache(function: Callable, arg_types: tuple):
    """``function -> int64`` compiled for ``arg_types`` (or loaded) with its
    machine code in :func:`kernel_cache_dir`: a folder named by the kernel's
    hash, so that a changed callee (numba only checks the time stamp of the
    compiled function's own file) never loads stale code."""
    numba = numba_module()
    signature = numba.types.int64(*arg_types)
    return jit(function, signature, cache_dir=_cache_folder(), callees_once=True)


def _cache_folder() -> str:
    """:func:`kernel_cache_dir`, created if missing."""
    folder = kernel_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    return str(folder)


# Never called: stand-ins for the kernel's ``jac`` and ``tangent`` in runs
# whose estimate of Gamma does not use them.  NaN, so that a call by
# mistake could not pass unnoticed.
def _unused_jac(t, y, params, out):
    out[:, :] = math.nan


def _unused_rhs_jvp(t, y, params, v, out, dout, JM):
    out[:] = math.nan
    dout[:] = math.nan


def unused_function(name: str):
    """A compiled function of the signature of ``name`` (``"jac"`` or
    ``"rhs_jvp"``) that fills its outputs with NaN, for the kernel's argument
    in runs that never call it (compiled once per kernel version, in the
    kernel's cache folder)."""
    with LOCK:
        if name not in _UNUSED:
            plain = {"jac": _unused_jac, "rhs_jvp": _unused_rhs_jvp}[name]
            _UNUSED[name] = jit(plain, signatures()[name], cache_dir=_cache_folder())
        return _UNUSED[name]


_UNUSED: dict[str, Any] = {}


def _zero_rhs(t, y, params, out):
    out[:] = 0.0


def probe_rhs():
    """A compiled ``rhs`` of the systems' signature that is zero everywhere:
    the probe's right-hand side where the system's own is not finite at the
    probe's state (:func:`probe`: every parameter 0 and every component 0.5
    is singular for the double pendulum, the N-body problems and ``(1 -
    p/a) cos q``), so that the probe's step still calls, and compiles, the
    kernel (compiled once per kernel version, in the kernel's cache folder)."""
    with LOCK:
        if "rhs" not in _PROBE:
            _PROBE["rhs"] = jit(_zero_rhs, signatures()["rhs"], cache_dir=_cache_folder())
        return _PROBE["rhs"]


#: The probe's stand-in f (its own home: the NaN-filling stand-ins above
#: are the ones no run may call).
_PROBE: dict[str, Any] = {}


# -- calling it -------------------------------------------------------------------


def _signature(args: tuple) -> tuple:
    """The kernel's argument types for ``(rhs, tangent, jac, *rest)``: the
    functions as first-class function types, the rest as typed."""
    import numba

    sig = signatures()
    rest = tuple(numba.typeof(a) for a in args[3:])
    return (sig["rhs_type"], sig["rhs_jvp_type"], sig["jac_type"], *rest)


def _compile_kernel(arg_types: tuple):
    """``loop.advance`` compiled for one signature (or loaded from the cache)."""
    from hamrkq.rkq import loop

    return compile_in_cache(loop.advance, arg_types)


class CompiledKernel:
    """``advance(rhs, tangent, jac, *args)`` with the compiled kernel: the
    signature of the arguments is compiled (or loaded from the disk cache)
    on first use."""

    def __init__(self):
        self._by_types: dict[tuple, Any] = {}
        #: The numba dispatcher of each signature compiled so far.
        self.dispatchers: dict[tuple, Any] = {}
        #: The description of each member's tableaus met so far, by id (with
        #: the tableaus, so that an id is not reused while it is kept): a
        #: member's tableaus are immutable and passed to every run of it, and
        #: their nine arrays were a third of the key's cost.
        self._tableaus: dict[int, tuple[Any, tuple]] = {}
        #: Seconds spent compiling or loading signatures in calls, so far: a
        #: run's driver counts them as compiling, not as integration.
        self.build_seconds = 0.0

    def __reduce__(self):
        # Compiled entry points cannot be pickled; another process uses its own
        # kernel (loaded from the disk cache, or compiled).
        return (kernel, ())

    def __call__(self, rhs, tangent, jac, *args):
        # args: (problem, tableaus, cfg, state, work, out, budget), loop.advance's
        key = (describe(args[0]), self._describe_tableaus(args[1]), *map(describe, args[2:]))
        entry = self._by_types.get(key)
        if entry is None:
            with LOCK:
                entry = self._by_types.get(key)
                if entry is None:
                    started = time.perf_counter()
                    dispatcher = _compile_kernel(_signature((rhs, tangent, jac, *args)))
                    # The compiled code's own entry point: the dispatcher would
                    # type every argument again to choose among its one
                    # signature (18 us of a 0.29 ms call of a tiny problem).
                    # ``key`` already says the arguments have those types.
                    (entry,) = (cres.entry_point for cres in dispatcher.overloads.values())
                    self.dispatchers[key] = dispatcher
                    self._by_types[key] = entry
                    self.build_seconds += time.perf_counter() - started
        return entry(rhs, tangent, jac, *args)

    def _describe_tableaus(self, tableaus: tuple) -> tuple:
        """:func:`describe` of a member's tableaus, remembered."""
        known = self._tableaus.get(id(tableaus))
        if known is not None and known[0] is tableaus:
            return known[1]
        described = describe(tableaus)
        if len(self._tableaus) >= 256:  # members made on the fly: bounded
            self._tableaus.clear()
        self._tableaus[id(tableaus)] = (tableaus, described)
        return described


def describe(value: Any) -> Any:
    """A cheap description of an argument's numba type (numba.typeof on every
    call would cost more than a short chunk of steps): equal descriptions
    mean equal numba types."""
    if isinstance(value, np.ndarray):
        # dtype objects compare (and hash) by their fields; flags.num holds
        # the layout, alignment and writeability as bits, read once.
        return (value.dtype, value.ndim, value.flags.num & _LAYOUT_FLAGS)
    if isinstance(value, tuple):
        # a tuple's arrays described here, not by a call each (a run passes
        # three named tuples of 16 arrays on every call)
        return (type(value), *[
            (item.dtype, item.ndim, item.flags.num & _LAYOUT_FLAGS)
            if type(item) is np.ndarray else describe(item)
            for item in value
        ])  # fmt: skip
    return type(value)


#: NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_F_CONTIGUOUS | NPY_ARRAY_ALIGNED |
#: NPY_ARRAY_WRITEABLE: the flags that change the numba type of an array
#: (its layout "C", "F" or "A", alignment and readonly).  The kernel is called
#: through the entry point of the signature its key names, which trusts the
#: types: the key must tell apart every argument numba would type apart.
_LAYOUT_FLAGS = 0x0001 | 0x0002 | 0x0100 | 0x0400


def kernel() -> CompiledKernel:
    """The compiled kernel (one per process)."""
    with LOCK:
        if "kernel" not in _KERNEL:
            numba_module()
            remember_function_addresses()
            _KERNEL["kernel"] = CompiledKernel()
        return _KERNEL["kernel"]


def remember_function_addresses() -> None:
    """Make numba look up the machine address of a first-class function once.

    The kernel takes ``rhs``, ``rhs_jvp`` and ``jac`` as first-class
    functions; on every call numba asks, for each, the compiled result of the
    dispatcher and its address from LLVM (about 9 us each, two per function:
    55 us of a 0.38 ms call of a tiny problem).  For a dispatcher compiled
    with an explicit signature the answer never changes, so it is kept,
    with the dispatcher itself (an address is never reused for another
    object).  numba calls these two functions by name from its compiled
    code; if a later numba renames them, nothing is changed.
    """
    try:
        from numba.core.dispatcher import Dispatcher
        from numba.experimental import function_type
    except ImportError:  # pragma: no cover - another numba layout
        return
    for name in ("_get_wrapper_address", "_get_jit_address"):
        lookup = getattr(function_type, name, None)
        if lookup is None or getattr(lookup, "_hamrkq_remembers", False):
            continue
        function_type.__dict__[name] = _remembering(lookup, Dispatcher)


def _remembering(lookup: Callable, dispatcher_type: type) -> Callable:
    """``lookup(func, sig)`` (numba's address lookup of a first-class
    function) with its answers remembered, for
    :func:`remember_function_addresses`.

    Parameters
    ----------
    lookup : callable
        numba's ``_get_wrapper_address`` or ``_get_jit_address``.
    dispatcher_type : type
        numba's ``Dispatcher``: only a dispatcher's answers are kept.

    Returns
    -------
    callable
        ``remembered(func, sig)``, which numba's compiled code calls by name.
    """
    import ctypes

    # Keyed by identity: numba passes the same signature object on every call
    # (its unpickling is memoised), and hashing a numba type costs microseconds.
    # An entry holds both objects, so neither id is reused while it is kept.
    known: dict[tuple[int, int], tuple] = {}
    # numba's compiled code unpickles ``sig`` and then calls this with
    # PyObject_CallFunctionObjArgs(lookup, func, sig, NULL).  When the
    # unpickling raises (Ctrl-C, or SIGTERM's handler, landing in that Python
    # code), ``sig`` is NULL, which ends the argument list early: this is
    # called with ``func`` alone while the interrupt is still set.  Any
    # exception raised here would replace it (the command line printed
    # "TypeError: remembered() missing 1 required positional argument:
    # 'sig'" with a traceback, and the run's results were lost).  A call
    # through a PYFUNCTYPE function (ctypes.pythonapi's kind) raises the
    # exception set when it returns, so the interrupt goes on as itself.  A
    # private prototype: ctypes.pythonapi's own attribute is shared.
    raise_pending = ctypes.PYFUNCTYPE(ctypes.c_void_p)(("PyErr_Occurred", ctypes.pythonapi))
    missing = object()

    def remembered(func, sig=missing):
        if sig is missing:
            raise_pending()
            raise TypeError(f"{lookup.__name__}() needs a signature")  # called without one
        entry = known.get((id(func), id(sig)))
        if entry is not None and entry[0] is func and entry[1] is sig:
            return entry[2]
        address = lookup(func, sig)
        if isinstance(func, dispatcher_type) and func.signatures:
            known[(id(func), id(sig))] = (func, sig, address)
        return address

    remembered._hamrkq_remembers = True  # type: ignore[attr-defined]
    return remembered


def probe(functions, dim: int, n_params: int):
    """A one-step integration whose kernel call has the signature of every run
    (:class:`~hamrkq.rkq.driver.Integration` of ``functions``, a stand-in
    state of ``dim`` components and ``n_params`` parameters)."""
    from hamrkq.rkq.config import Settings
    from hamrkq.rkq.driver import Integration
    from hamrkq.rkq.family import PAPER_METHOD, get_member
    from hamrkq.rkq.layout import GAMMA_OFF, QUENCH_NODE, RULE_COMPONENTWISE

    return Integration(
        functions,
        get_member(PAPER_METHOD),
        np.zeros(n_params),
        0.0,
        np.full(dim, 0.5),
        1e-3,
        np.full(dim, 1e-6),
        np.zeros(dim),
        Settings(QUENCH_NODE, RULE_COMPONENTWISE, GAMMA_OFF, max_steps=1),
    )


# -- compiling it ahead of a run ----------------------------------------------------


def kernel_cached() -> bool:
    """Whether the kernel is loaded in this process or compiled in the cache."""
    current = _KERNEL.get("kernel")
    if current is not None and current.dispatchers:
        return True
    # The step kernel's own index (numba names it after the function): the
    # folder also holds the extras and the stand-ins (unused_function).
    return any(kernel_cache_dir().rglob("loop.advance-*.nbi"))


class _KernelCompiled(Exception):
    """Raised by :func:`build_kernel`'s stand-in kernel once it has compiled."""


def build_kernel() -> None:
    """Compile the kernel into the cache without compiling any system (the
    helper process of a first use, :mod:`hamrkq.backends.kernel_helper`,
    and ``hamrkq compile``).

    The kernel's arguments are typed from a one-step integration of a
    stand-in system; the functions' types are the fixed signatures of every
    compiled system.

    Raises
    ------
    BackendUnavailable
        numba cannot be used or fails to compile the kernel (``hamrkq
        compile`` then exits with status 2 and this message, not a
        traceback); a damaged cache file that could not be compiled again is
        named.
    """
    numba_module()
    try:
        _build_kernel()
    except BackendUnavailable:
        raise
    except Exception as exc:  # numba's errors, or an unwritable cache (OSError)
        from hamrkq.backends.compiled import numba_failure  # compiled imports this module

        raise numba_failure("the RKQ kernel", exc) from exc


def _build_kernel() -> None:
    """:func:`build_kernel`'s work, its errors as they are."""
    from hamrkq.rkq.driver import KernelFunctions

    def zero_rhs(t, y, params, out):
        out[:] = 0.0

    def compile_and_stop(rhs, tangent, jac, *args):
        _compile_kernel(_signature((rhs, tangent, jac, *args)))
        raise _KernelCompiled

    run = probe(KernelFunctions(zero_rhs, None, None, compile_and_stop), 2, 0)
    try:
        run.run()
    except _KernelCompiled:
        pass
    for name in ("jac", "rhs_jvp"):  # the stand-ins a run passes in their place
        unused_function(name)
