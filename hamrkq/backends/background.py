"""Compile in the background: the first run of a system starts at once.

Compiling a system's functions and the RKQ kernel takes 10-15 s on a first
use (``docs/performance.md``).  Instead of waiting, :func:`hamrkq.solve`
(with ``backend="auto"``) starts a helper process that compiles them into
the cache (:func:`build`), and its run begins at once with the interpreted
kernel: the same kernel source (:mod:`hamrkq.rkq`), run by Python on the
same generated scalar functions, which give the same bits as the compiled
code (``tests/test_compiled.py`` checks every catalogue problem and method
for it).  Between chunks of steps the run asks :meth:`BackgroundCompile.functions`
whether the helper has finished; once it has, the compiled code is loaded
from the cache (about 0.3 s) and the run goes on compiled, on the same
arrays.  A run shorter than the compile ends interpreted, and the helper
carries on, so that the next run (in this process or another) finds the
compiled code in the cache.

It is used when all of these hold:

- :data:`COMPILE_ENV` is unset or ``background`` (``wait`` compiles first,
  in the calling process, as before);
- numba can be used, and the process may run on two cores or more (the
  helper takes one);
- the kernel is not in the cache, or the system's functions that the run
  calls are not (:func:`hamrkq.backends.compiled.is_compiled`: a run with
  the tangent estimate of Gamma calls the tangent part too);
- the system's scalar code can be generated.

For a large system (:data:`hamrkq.backends.kernel_helper.HELPER_MIN_DIM` state
variables or more) missing both, two helpers compile the system and the
kernel side by side: its interpreted steps are slow (about 9 ms each for the
outer solar system), so the compiled code matters more than the run's own
core.

If the helper fails, the run compiles in its own process at the next check
(whose error, if any, gives the usual warning and the interpreted backend
for the rest of the run).
"""

from __future__ import annotations

import logging
import os
import subprocess
import time
from typing import TYPE_CHECKING

from hamrkq._progress import say
from hamrkq.backends import codegen, compiled, first_use, kernel_helper
from hamrkq.backends import kernel as kernel_module
from hamrkq.backends.numba_compile import BackendUnavailable, available
from hamrkq.errors import CodegenError, OptionError

if TYPE_CHECKING:
    from hamrkq.rkq.driver import KernelFunctions
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["COMPILE_ENV", "COMPILE_MODES", "BackgroundCompile", "build", "compile_mode", "start"]

#: Environment variable choosing how a first use compiles: ``background``
#: (the default) or ``wait``.
COMPILE_ENV = "HAMRKQ_COMPILE"
COMPILE_MODES = ("background", "wait")

#: The helper of each system (by code-generation key) started by this process.
_HELPERS: dict[str, BackgroundCompile] = {}


def compile_mode() -> str:
    """The value of :data:`COMPILE_ENV` (``"background"`` when unset).

    Raises
    ------
    OptionError
        Any other value, with the valid ones.
    """
    value = os.environ.get(COMPILE_ENV, "").strip().lower() or "background"
    if value not in COMPILE_MODES:
        raise OptionError(
            f"the environment variable {COMPILE_ENV}={os.environ[COMPILE_ENV]!r} is not valid; "
            f"valid: {', '.join(map(repr, COMPILE_MODES))}"
        )
    return value


class BackgroundCompile:
    """A helper process compiling the code of one system into the cache.

    Parameters
    ----------
    ham : Hamiltonian
    processes : list of subprocess.Popen
        The helpers (:func:`build`).
    """

    def __init__(self, ham: Hamiltonian, processes: list[subprocess.Popen]):
        self.ham = ham
        self.processes = processes
        self.started = time.perf_counter()
        #: Whether the compiled code has been loaded into this process.
        self.loaded = False
        #: Whether the compiled backend turned out unusable (then the run
        #: stays interpreted, after the usual warning).
        self.failed = False

    @property
    def running(self) -> bool:
        """Whether a helper is still compiling."""
        return any(process.poll() is None for process in self.processes)

    def functions(self, gamma: str = "tangent") -> KernelFunctions | None:
        """The compiled :class:`~hamrkq.rkq.driver.KernelFunctions` once the
        helper has finished (loaded from the cache, or compiled here if the
        helper failed); None while it compiles, or if the compiled backend
        cannot be used (warned once).  ``gamma``: the run's estimate of Gamma
        (:func:`hamrkq.backends.first_use.kernel_functions`)."""
        if self.failed or self.running:
            return None
        try:
            # Loads what the helper cached; compiles here only if it failed.
            first_use.warm_up(self.ham, announce=False, gamma=gamma)
            functions = first_use.kernel_functions(self.ham, gamma)
        except BackendUnavailable as exc:
            self.failed = True
            first_use.warn_interpreted(str(exc))
            return None
        self.loaded = True
        elapsed = time.perf_counter() - self.started
        logging.getLogger("hamrkq").info(f"compiled in the background in {elapsed:.1f} s")
        return functions

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the helpers (at most ``timeout`` seconds); whether they have finished."""
        deadline = None if timeout is None else time.perf_counter() + timeout
        for process in self.processes:
            left = None if deadline is None else max(0.0, deadline - time.perf_counter())
            try:
                process.wait(timeout=left)
            except subprocess.TimeoutExpired:
                return False
        return True


def start(ham: Hamiltonian, gamma: str = "tangent") -> BackgroundCompile | None:
    """Start compiling ``ham``'s code (and the kernel) in a helper process,
    when the conditions in the module's description hold; None otherwise
    (the caller then compiles, or loads, in its own process).  ``gamma``:
    the run's estimate of Gamma; the tangent part of the code (the
    Jacobian) is generated here first where it calls it, so that the helper
    compiles it too."""
    if compile_mode() != "background" or kernel_helper.cores() < 2:
        return None
    key = codegen.cache_key(ham)
    current = _HELPERS.get(key)
    if current is not None and current.running:
        return current
    if not available()[0]:
        return None
    parts = []
    if not compiled.is_compiled(ham, gamma):
        parts.append("system")
    if not kernel_module.kernel_cached():
        parts.append("kernel")
    if not parts:
        return None
    try:
        codegen.load_module(ham)  # the helper compiles these files
        if compiled.calls_tangent_part(gamma):
            codegen.load_module(ham, part="tangent")
    except (CodegenError, OSError):
        return None  # the caller's own compile reports it
    if ham.dim < kernel_helper.HELPER_MIN_DIM:
        parts = [" ".join(parts)]  # one helper: its start-up costs more than a small system
    processes = []
    for part in parts:
        code = f"from hamrkq.backends import background; background.build({key!r}, {part!r})"
        process = kernel_helper.spawn_helper(code)
        if process is None:
            for started in processes:
                started.kill()
            return None
        processes.append(process)
    helper = _HELPERS[key] = BackgroundCompile(ham, processes)
    say(
        first_use.first_use_text(ham)
        + " in the background; the run starts at once on the interpreted loop and "
        "goes on compiled when the code is ready"
    )
    return helper


def build(key: str, parts: str = "system kernel") -> None:
    """Compile (or load) into the cache the system cached under ``key``
    and/or the kernel (``parts``; the helper process of :func:`start`)."""
    if "system" in parts.split():
        module = codegen.load_part(key, "system")
        system = compiled.CompiledSystem(module, lambda: codegen.load_part(key, "tangent"))
        if codegen.part_cached(key, "tangent"):  # generated where the run calls it
            system.compile_all()
        compiled.mark_compiled(system.path)
    if "kernel" in parts.split():
        # With a stand-in system: a probe of the real one may end before its
        # first step (a state of 0.5s can be singular), and the kernel's
        # signature is the same for every system.
        kernel_module.build_kernel()
