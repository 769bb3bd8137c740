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

``HAMRKQ_DISABLE_NUMBA=1`` (or numba missing, or a system that cannot be
compiled, or a failure compiling the kernel) makes :func:`resolve_backend`
choose the interpreted backend for ``backend="auto"``, with one
:class:`~hamrkq.errors.HamrkqWarning` saying what failed.

A first use that compiles says so: when preparing a system (and the kernel)
takes longer than :data:`ANNOUNCE_AFTER` seconds, a line on stderr (when it
is a terminal, as the progress bar) and on the ``hamrkq`` logger says that
code is being compiled once and cached, and another how long it took
(:class:`hamrkq._progress.WaitNotice`).  For a large system with no kernel
in the cache, a helper process compiles the kernel meanwhile
(:func:`hamrkq.backends.kernel.start_helper`).

Compilation is counted: :data:`COMPILE_COUNT` (and :func:`stats`) grows by
one for every function signature numba had to compile in this process
(rather than load from its cache), so a test can tell that a fresh process
with a warm cache compiled nothing
(:mod:`hamrkq.backends.numba_compile`).
"""

from __future__ import annotations

import math
import os
import types
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from hamrkq._progress import WaitNotice
from hamrkq.backends import codegen
from hamrkq.backends import kernel as kernel_module
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
from hamrkq.errors import OptionError, warn

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
    "first_use_text",
    "is_compiled",
    "kernel",
    "kernel_cache_dir",
    "kernel_functions",
    "mark_compiled",
    "resolve_backend",
    "stats",
    "system_functions",
    "warm_up",
    "warn_interpreted",
]

_SYSTEMS: dict[str, CompiledSystem] = {}
#: Cache keys of the systems whose kernel run :func:`warm_up` has made.
_WARM: set[str] = set()


def __getattr__(name: str) -> Any:
    # COMPILE_COUNT: signatures compiled (not loaded from numba's disk cache)
    # in this process; read from the counters, where every compile is added.
    if name == "COMPILE_COUNT":
        return stats()["compiled"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# -- which backend -----------------------------------------------------------------


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
    warn_interpreted(reason)
    return "python"


def warn_interpreted(reason: str) -> None:
    """The warning of ``backend="auto"`` falling back to the interpreted loop."""
    warn(
        f"hamrkq: the compiled (numba) backend is not used because {reason}; "
        "running the pure-Python loop, which is about 100 times slower. "
        "Pass backend='python' to choose it explicitly and silence this warning."
    )


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
        sig = signatures()
        # energy first: energy_rows calls it through the namespace.
        for name in ("rhs", "jac", "rhs_jvp", "energy", "energy_rows"):
            plain = types.FunctionType(getattr(module, name).__code__, namespace, name)
            namespace[name] = jit(plain, sig[name])
        self.rhs = namespace["rhs"]
        self.jac = namespace["jac"]
        self.rhs_jvp = namespace["rhs_jvp"]
        self.energy = namespace["energy"]
        self.energy_rows = namespace["energy_rows"]
        self._module = module
        self._rhs_dd = None

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
            self._rhs_dd = jit(plain, signatures()["rhs_jvp"])
        return self._rhs_dd


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
    numba_module()
    key = codegen.cache_key(ham)
    with LOCK:
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
        mark_compiled(system.path)
        return system


#: Written beside a generated module once its functions are compiled (or
#: loaded): numba keeps their machine code in its own cache, which cannot be
#: asked cheaply whether it holds them.  Holds numba's cache setting, so a
#: changed ``NUMBA_CACHE_DIR`` does not count as compiled.
COMPILED_SUFFIX = ".compiled"


def _numba_cache_setting() -> str:
    return "NUMBA_CACHE_DIR=" + os.environ.get("NUMBA_CACHE_DIR", "")


def mark_compiled(path: Path) -> None:
    marker = path.with_suffix(COMPILED_SUFFIX)
    try:
        if not marker.exists() or marker.read_text() != _numba_cache_setting():
            marker.write_text(_numba_cache_setting())
    except OSError:  # a read-only cache: the marker only saves a later helper
        pass


def is_compiled(ham: Hamiltonian) -> bool:
    """Whether the functions of ``ham`` were compiled in this process or (as
    far as hamrkq can tell without loading them) are in numba's disk cache."""
    key = codegen.cache_key(ham)
    if key in _SYSTEMS:
        return True
    marker = codegen.module_path(key).with_suffix(COMPILED_SUFFIX)
    try:
        return marker.read_text() == _numba_cache_setting()
    except OSError:
        return False


# -- the kernel's functions and the first use ------------------------------------


def kernel_functions(ham: Hamiltonian):
    """The :class:`~hamrkq.rkq.driver.KernelFunctions` of ``ham`` on this backend.

    Raises
    ------
    BackendUnavailable
        See :func:`compile_system`.
    """
    return system_functions(compile_system(ham))


def system_functions(system: CompiledSystem):
    """The :class:`~hamrkq.rkq.driver.KernelFunctions` of a compiled system
    with the compiled kernel."""
    from hamrkq.rkq.driver import KernelFunctions

    return KernelFunctions(system.rhs, system.rhs_jvp, system.jac, kernel_module.kernel())


#: Seconds of preparing a system before the first use is announced: loading
#: from the cache takes well under this, compiling several seconds.
ANNOUNCE_AFTER = 1.0


def _short(text: str, width: int = 60) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def first_use_text(ham: Hamiltonian) -> str:
    """What a first use of ``ham`` says: its code is compiled once and cached."""
    return (
        f"compiling the code for {_short(f'H = {ham.H}')} (first use of this system or "
        f"of this hamrkq version; cached in {codegen.cache_dir()} for later runs)"
    )


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
        return first_use_text(ham) + " ..."

    with WaitNotice(begin, "compiled", ANNOUNCE_AFTER, stream=stream, enabled=announce):
        _warm_up(ham)
    _WARM.add(key)


def _warm_up(ham: Hamiltonian) -> None:
    helper = kernel_module.start_helper(ham.dim)
    try:
        functions = kernel_functions(ham)  # the system, meanwhile
    finally:
        kernel_module.join_helper(helper)
    run = kernel_module.probe(functions, ham.dim, len(ham.parameters))
    try:
        with np.errstate(all="ignore"):
            run.run()
    except Exception as exc:  # numba's TypingError/LoweringError and relatives
        raise BackendUnavailable(
            f"numba failed to compile the RKQ kernel ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''})"
        ) from exc


def energy(ham: Hamiltonian, t: np.ndarray, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
    """H at the rows of ``Y`` (times ``t``), with the compiled scalar energy."""
    system = compile_system(ham)
    # The compiled signature takes writable C-contiguous float64 arrays.
    Y = np.require(Y, np.float64, ("C", "W"))
    t = np.array(np.broadcast_to(np.asarray(t, dtype=np.float64), Y.shape[:1]))
    out = np.empty(Y.shape[0])
    system.energy_rows(t, Y, np.require(params, np.float64, ("C", "W")), out)
    return out
