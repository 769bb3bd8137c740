"""The compiled backend: the RKQ kernel and the generated functions under numba.

Nothing here re-implements the algorithm, and no source text is copied:

1. **The system.**  :mod:`hamrkq.backends.codegen` writes ``rhs``, ``jac``,
   ``rhs_jvp``, ``energy`` and ``energy_rows`` of a Hamiltonian as scalar code
   into the cache directory; they are compiled here with explicit signatures
   and ``cache=True``, so numba keeps their machine code beside the generated
   file.
2. **The kernel.**  :func:`hamrkq.rkq.loop.advance` and everything it calls
   are ordinary Python functions marked with numba's public
   ``register_jitable`` (:mod:`hamrkq.rkq.jit`): the interpreted backend calls
   them as they are, and here ``numba.njit`` compiles ``advance`` with an
   explicit signature in which ``rhs``, ``rhs_jvp`` and ``jac`` are
   first-class function types, so one compiled kernel serves every
   Hamiltonian and its machine code is cached once per kernel version, in
   ``<cache dir>/kernel-<hash of the kernel's sources and versions>``.
3. **The driver.**  :class:`hamrkq.rkq.driver.Integration` (chunks, growing
   output, progress, Ctrl-C) runs in Python with the compiled ``advance``.

Parameters are run-time arguments: a parameter sweep never recompiles.

``HAMRKQ_DISABLE_NUMBA=1`` (or numba missing, or a system that cannot be
compiled, or a failure compiling the kernel) makes :func:`resolve_backend`
choose the interpreted backend for ``backend="auto"``, with one
:class:`~hamrkq.errors.HamrkqWarning` saying what failed.

A first use that compiles says so: when preparing a system (and the kernel)
takes longer than :data:`ANNOUNCE_AFTER` seconds, a line on stderr (when it
is a terminal, as the progress bar) and on the ``hamrkq`` logger says that
code is being compiled once and cached, and another how long it took
(:class:`hamrkq._progress.WaitNotice`).

On a first use of a large system (:data:`HELPER_MIN_DIM` state variables or
more) with no kernel in the cache, a helper process compiles the kernel into
the cache (:func:`build_kernel`) while this one derives, generates and
compiles the system, on a second core; the kernel is then loaded from the
cache.  Should the helper fail, the kernel is compiled here as before.

Compilation is counted: :data:`COMPILE_COUNT` grows by one for every function
signature numba had to compile in this process (rather than load from its
cache), so a test can tell that a fresh process with a warm cache compiled
nothing.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import subprocess
import sys
import threading
import time
import types
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from hamrkq._progress import WaitNotice
from hamrkq.backends import codegen
from hamrkq.errors import HamrkqError, OptionError, warn

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "COMPILE_COUNT",
    "DISABLE_ENV",
    "BackendUnavailable",
    "CompiledKernel",
    "CompiledSystem",
    "available",
    "compile_system",
    "energy",
    "kernel",
    "kernel_functions",
    "resolve_backend",
    "stats",
    "warm_up",
]

#: Environment variable: set to 1 (or true/yes/on) to turn the compiled backend off.
DISABLE_ENV = "HAMRKQ_DISABLE_NUMBA"
#: Signatures compiled (not loaded from numba's disk cache) in this process.
COMPILE_COUNT = 0
_STATS = {"compiled": 0, "loaded": 0, "compile_seconds": 0.0, "load_seconds": 0.0}
_LOCK = threading.RLock()
_SYSTEMS: dict[str, CompiledSystem] = {}
_KERNEL: dict[str, Any] = {}
#: Cache keys of the systems whose kernel run :func:`warm_up` has made.
_WARM: set[str] = set()


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
            warm_up(ham)
        except BackendUnavailable as exc:
            ok, reason = False, str(exc)
    if ok:
        return "numba"
    if backend == "numba":
        raise OptionError(f"backend='numba' cannot be used: {reason}")
    warn(
        f"hamrkq: the compiled (numba) backend is not used because {reason}; "
        "running the pure-Python loop, which is about 100 times slower. "
        "Pass backend='python' to choose it explicitly and silence this warning."
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
        "energy_type": nt.FunctionType(nt.float64(nt.float64, vec, vec)),
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


# -- the kernel --------------------------------------------------------------------

#: The modules whose functions make up the compiled kernel (their text keys its cache).
KERNEL_MODULES = ("jit", "layout", "arith", "steps", "loop", "start", "batch")


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


def _signature(args: tuple) -> tuple:
    """The kernel's signature for arguments ``(rhs, tangent, jac, *rest)``:
    the functions as first-class function types, the rest as typed."""
    import numba

    sig = _types()
    rest = tuple(numba.typeof(a) for a in args[3:])
    return (sig["rhs_type"], sig["rhs_jvp_type"], sig["jac_type"], *rest)


def _compile_kernel(signature: tuple):
    """``loop.advance`` compiled for one signature (or loaded from the cache)."""
    numba = _numba()
    from hamrkq.rkq import loop

    folder = kernel_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    previous = numba.config.CACHE_DIR
    # numba reads its cache directory when a dispatcher is created: point it
    # at a folder named by the kernel's hash, so that a changed callee (numba
    # only checks the time stamp of advance's own file) never loads stale code.
    numba.config.CACHE_DIR = str(folder)
    try:
        flags = {"cache": True, "nogil": True, "error_model": "numpy"}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", numba.NumbaWarning)
            started = time.perf_counter()
            dispatcher = numba.njit(numba.types.int64(*signature), **flags)(loop.advance)
            _account(dispatcher, started)
    finally:
        numba.config.CACHE_DIR = previous
    return dispatcher


class CompiledKernel:
    """``advance(rhs, tangent, jac, *args)`` with the compiled kernel: the
    signature of the arguments is compiled (or loaded from the disk cache)
    on first use."""

    def __init__(self):
        self._by_types: dict[tuple, Any] = {}
        #: The numba dispatcher of each signature compiled so far.
        self.dispatchers: dict[tuple, Any] = {}

    def __reduce__(self):
        # Compiled entry points cannot be pickled; another process uses its own
        # kernel (loaded from the disk cache, or compiled).
        return (kernel, ())

    def __call__(self, rhs, tangent, jac, *args):
        key = tuple(_describe(a) for a in args)
        entry = self._by_types.get(key)
        if entry is None:
            with _LOCK:
                entry = self._by_types.get(key)
                if entry is None:
                    dispatcher = _compile_kernel(_signature((rhs, tangent, jac, *args)))
                    # The compiled code's own entry point: the dispatcher would
                    # type every argument again to choose among its one
                    # signature (18 us of a 0.29 ms call of a tiny problem).
                    # ``key`` already says the arguments have those types.
                    (entry,) = (cres.entry_point for cres in dispatcher.overloads.values())
                    self.dispatchers[key] = dispatcher
                    self._by_types[key] = entry
        return entry(rhs, tangent, jac, *args)


def _describe(value: Any) -> Any:
    """A cheap description of an argument's numba type (numba.typeof on every
    call would cost more than a short chunk of steps)."""
    if isinstance(value, np.ndarray):
        # dtype objects compare (and hash) by their fields; flags.num holds
        # C-contiguity and writeability as bits, read once.
        return (value.dtype, value.ndim, value.flags.num & _LAYOUT_FLAGS)
    if isinstance(value, tuple):
        return (type(value), *map(_describe, value))
    return type(value)


#: NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_F_CONTIGUOUS | NPY_ARRAY_ALIGNED |
#: NPY_ARRAY_WRITEABLE: the flags that change the numba type of an array
#: (its layout "C", "F" or "A", alignment and readonly).  The kernel is called
#: through the entry point of the signature its key names, which trusts the
#: types: the key must tell apart every argument numba would type apart.
_LAYOUT_FLAGS = 0x0001 | 0x0002 | 0x0100 | 0x0400


def kernel() -> CompiledKernel:
    """The compiled kernel (one per process)."""
    with _LOCK:
        if "kernel" not in _KERNEL:
            _numba()
            _remember_function_addresses()
            _KERNEL["kernel"] = CompiledKernel()
        return _KERNEL["kernel"]


def _remember_function_addresses() -> None:
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
    # Keyed by identity: numba passes the same signature object on every call
    # (its unpickling is memoised), and hashing a numba type costs microseconds.
    # An entry holds both objects, so neither id is reused while it is kept.
    known: dict[tuple[int, int], tuple] = {}

    def remembered(func, sig):
        entry = known.get((id(func), id(sig)))
        if entry is not None and entry[0] is func and entry[1] is sig:
            return entry[2]
        address = lookup(func, sig)
        if isinstance(func, dispatcher_type) and func.signatures:
            known[(id(func), id(sig))] = (func, sig, address)
        return address

    remembered._hamrkq_remembers = True  # type: ignore[attr-defined]
    return remembered


def kernel_functions(ham: Hamiltonian):
    """The :class:`~hamrkq.rkq.driver.KernelFunctions` of ``ham`` on this backend.

    Raises
    ------
    BackendUnavailable
        See :func:`compile_system`.
    """
    from hamrkq.rkq.driver import KernelFunctions

    system = compile_system(ham)
    return KernelFunctions(system.rhs, system.rhs_jvp, system.jac, kernel())


#: Seconds of preparing a system before the first use is announced: loading
#: from the cache takes well under this, compiling several seconds.
ANNOUNCE_AFTER = 1.0


def _short(text: str, width: int = 60) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def warm_up(ham: Hamiltonian, stream: TextIO | None = None, announce: bool | None = None) -> None:
    """Compile (or load) the system and the kernel for the signatures a run
    uses, by integrating one step of ``ham``, once per system and process;
    raises BackendUnavailable with what failed.  A first use that takes
    long is announced on ``stream`` (stderr; when it is a terminal, or
    ``announce``)."""
    key = codegen.cache_key(ham)
    if key in _WARM:
        return

    def begin() -> str:
        return (
            f"compiling the code for {_short(f'H = {ham.H}')} (first use of this system or "
            f"of this hamrkq version; cached in {codegen.cache_dir()} for later runs) ..."
        )

    with WaitNotice(begin, "compiled", ANNOUNCE_AFTER, stream=stream, enabled=announce):
        _warm_up(ham)
    _WARM.add(key)


def _probe(functions, dim: int, n_params: int):
    """A one-step integration whose kernel call has the signature of every run."""
    from hamrkq.rkq.driver import Integration, Settings
    from hamrkq.rkq.family import get_member
    from hamrkq.rkq.layout import GAMMA_TANGENT, QUENCH_NODE, RULE_COMPONENTWISE

    return Integration(
        functions,
        get_member("rk34q8"),
        np.zeros(n_params),
        0.0,
        np.full(dim, 0.5),
        1e-3,
        np.full(dim, 1e-6),
        np.zeros(dim),
        Settings(QUENCH_NODE, RULE_COMPONENTWISE, GAMMA_TANGENT, max_steps=1),
    )


def _warm_up(ham: Hamiltonian) -> None:
    helper = _kernel_in_background(ham.dim)
    try:
        functions = kernel_functions(ham)  # the system, meanwhile
    finally:
        _join(helper)
    run = _probe(functions, ham.dim, len(ham.parameters))
    try:
        with np.errstate(all="ignore"):
            run.run()
    except Exception as exc:  # numba's TypingError/LoweringError and relatives
        raise BackendUnavailable(
            f"numba failed to compile the RKQ kernel ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''})"
        ) from exc


_HELPER_CODE = "from hamrkq.backends import compiled; compiled.build_kernel()"

#: The longest wait for the helper process that compiles the kernel; after
#: it the helper is stopped and this process compiles the kernel itself.
HELPER_TIMEOUT = 600.0


def _kernel_cached() -> bool:
    """Whether the kernel is loaded in this process or compiled in the cache."""
    kernel_ = _KERNEL.get("kernel")
    if kernel_ is not None and kernel_.dispatchers:
        return True
    return any(kernel_cache_dir().rglob("*.nbi"))


#: Systems of at least this many state variables have the kernel compiled by
#: a helper process while they are prepared, on a first use (measured, empty
#: cache: outer_solar_system, 36, 19.9-20.9 s -> 14.7 s; prentice2011, 2,
#: 11.7-13.3 s -> 15.6 s, since the helper's own start-up, about 1.5 s, is
#: more than a small system's preparation).
HELPER_MIN_DIM = 12


def _kernel_in_background(dim: int) -> subprocess.Popen | None:
    """Start compiling the kernel into the cache in a helper process, when it
    is not there, the system is large (:data:`HELPER_MIN_DIM`) and a second
    core can do it while this process derives, generates and compiles the
    system (outer_solar_system's takes about 6 s beside the kernel's 12 s);
    None otherwise, or if the helper cannot be started."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    if dim < HELPER_MIN_DIM or (cores or 1) < 2 or _kernel_cached():
        return None
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])  # the folder holding hamrkq/
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    try:
        return subprocess.Popen(
            [
                sys.executable,
                "-c",
                "from hamrkq.backends import compiled; compiled.build_kernel()",
            ],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except OSError:
        return None


def _join(helper: subprocess.Popen | None) -> None:
    """Wait for the helper; whatever it did, the kernel's own call then loads
    the kernel from the cache or, if the helper failed, compiles it here."""
    if helper is None:
        return
    try:
        helper.wait(timeout=HELPER_TIMEOUT)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()


class _KernelCompiled(Exception):
    """Raised by :func:`build_kernel`'s stand-in kernel once it has compiled."""


def build_kernel() -> None:
    """Compile the kernel into the cache without compiling any system (the
    helper process of a first use; see :func:`_kernel_in_background`).

    The kernel's arguments are typed from a one-step integration of a
    stand-in system; the functions' types are the fixed signatures of every
    compiled system.
    """
    from hamrkq.rkq.driver import KernelFunctions

    _numba()

    def zero_rhs(t, y, params, out):
        out[:] = 0.0

    def compile_and_stop(rhs, tangent, jac, *args):
        _compile_kernel(_signature((rhs, tangent, jac, *args)))
        raise _KernelCompiled

    run = _probe(KernelFunctions(zero_rhs, None, None, compile_and_stop), 2, 0)
    try:
        run.run()
    except _KernelCompiled:
        pass


def energy(ham: Hamiltonian, t: np.ndarray, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """H at the rows of ``Y`` (times ``t``), with the compiled scalar energy."""
    system = compile_system(ham)
    # The compiled signature takes writable C-contiguous float64 arrays.
    Y = np.require(Y, np.float64, ("C", "W"))
    t = np.array(np.broadcast_to(np.asarray(t, dtype=np.float64), Y.shape[:1]))
    out = np.empty(Y.shape[0])
    system.energy_rows(t, Y, np.require(params, np.float64, ("C", "W")), out)
    return out
