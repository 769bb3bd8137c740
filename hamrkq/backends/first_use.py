"""The compiled backend's first use: which backend a run gets, the kernel's
functions for a system, and the warm-up that compiles (or loads) them once
per system and process, announced when it takes long.

:mod:`hamrkq.backends.compiled` compiles a system's generated functions;
this module puts them together with the kernel
(:mod:`hamrkq.backends.kernel`) for a run:

- :func:`resolve_backend`: ``backend="auto"`` is numba when it can be used
  (numba present, ``HAMRKQ_DISABLE_NUMBA`` unset, the system and the kernel
  compile), else the interpreted loop with one
  :class:`~hamrkq.errors.HamrkqWarning` saying what failed
  (:func:`warn_interpreted`).
- :func:`kernel_functions`: the :class:`~hamrkq.rkq.driver.KernelFunctions`
  of a system for a run's estimate of Gamma.
- :func:`warm_up`: one step of the system through the compiled kernel, once
  per system and process, so that every signature a run uses is compiled
  (or loaded from the cache) before it starts.  When that takes longer than
  :data:`ANNOUNCE_AFTER` seconds, a line on stderr (when it is a terminal,
  as the progress bar) and on the ``hamrkq`` logger says that code is being
  compiled once and cached, and another how long it took
  (:class:`hamrkq._progress.WaitNotice`).  For a large system with no
  kernel in the cache, a helper process compiles the kernel meanwhile
  (:func:`hamrkq.backends.kernel_helper.start_helper`).

:mod:`hamrkq.backends.background` runs the same warm-up in helper
processes, while a run starts on the interpreted kernel.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, TextIO

import numpy as np

from hamrkq._progress import WaitNotice
from hamrkq.backends import codegen, compiled, kernel_helper
from hamrkq.backends import kernel as kernel_module
from hamrkq.backends.compiled import BackendUnavailable, CompiledSystem
from hamrkq.backends.numba_compile import available
from hamrkq.errors import OptionError, warn

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "ANNOUNCE_AFTER",
    "double_double_functions",
    "first_use_text",
    "kernel_functions",
    "resolve_backend",
    "system_functions",
    "warm_up",
    "warn_interpreted",
]

#: Cache keys of the systems whose kernel run :func:`warm_up` has made.
_WARM: set[str] = set()


# -- which backend -----------------------------------------------------------------


def resolve_backend(backend: str, ham: Hamiltonian | None = None, gamma: str = "tangent") -> str:
    """The backend to run: ``"python"`` or ``"numba"``.

    Parameters
    ----------
    backend : {"auto", "numba", "python"}
        ``"auto"`` means numba when it can be used, else Python with one
        :class:`~hamrkq.errors.HamrkqWarning`.
    ham : Hamiltonian, optional
        With ``"auto"``, the system is generated and compiled here, so that a
        system numba cannot compile also falls back with the warning.
    gamma : str
        The run's estimate of Gamma: what of the system it compiles
        (:func:`kernel_functions`).

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
            warm_up(ham, gamma=gamma)
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


# -- the kernel's functions and the first use ------------------------------------


def kernel_functions(ham: Hamiltonian, gamma: str = "tangent"):
    """The :class:`~hamrkq.rkq.driver.KernelFunctions` of ``ham`` on this
    backend, for a run whose estimate of Gamma is ``gamma`` (its
    ``global_error_estimate``): ``rhs_jvp`` for ``"tangent"``, ``jac`` for
    ``"paper"``, stand-ins otherwise
    (:meth:`~hamrkq.backends.compiled.CompiledSystem.kernel_arguments`).

    Raises
    ------
    BackendUnavailable
        See :func:`~hamrkq.backends.compiled.compile_system`.
    """
    return system_functions(compiled.compile_system(ham), gamma)


def system_functions(system: CompiledSystem, gamma: str = "tangent"):
    """The :class:`~hamrkq.rkq.driver.KernelFunctions` of a compiled system
    with the compiled kernel (``gamma``: see :func:`kernel_functions`)."""
    kernel = kernel_module.kernel()
    known = _FUNCTIONS.get((id(system), gamma))
    if known is not None and known[0] is system and known[1].advance is kernel:
        return known[1]
    # (imported here, past the functions known: an import statement costs a
    # microsecond of every solve)
    from hamrkq.rkq.driver import KernelFunctions

    functions = KernelFunctions(*system.kernel_arguments(gamma), kernel)
    _FUNCTIONS[(id(system), gamma)] = (system, functions)
    return functions


#: :func:`system_functions` by system (its id, kept with it) and estimate of
#: Gamma: the same functions for every run of a system (a compiled system's
#: functions never change once compiled).
_FUNCTIONS: dict[tuple[int, str], tuple] = {}


#: Seconds of preparing a system before the first use is announced: loading
#: from the cache takes well under this, compiling several seconds.
ANNOUNCE_AFTER = 1.0


def _short(text: str, width: int = 60) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def first_use_text(ham: Hamiltonian, what: str = "the code") -> str:
    """What a first use of ``ham`` says: its code (``what``) is compiled once
    and cached."""
    return (
        f"compiling {what} for {_short(f'H = {ham.H}')} (first use of this system or "
        f"of this hamrkq version; cached in {codegen.cache_dir()} for later runs)"
    )


def double_double_functions(
    ham: Hamiltonian, stream: TextIO | None = None, announce: bool | None = None
):
    """The compiled kernel's functions for a run with the quencher in
    double-double: the shadow estimate's, with ``rhs_dd`` (f in
    double-double) in the tangent's place.  ``rhs_dd`` is compiled on its
    first use (seconds for a system of a few dozen state variables); a wait
    longer than :data:`ANNOUNCE_AFTER` is announced as :func:`warm_up`'s."""
    system = compiled.compile_system(ham)

    def begin() -> str:
        what = "f in double-double (the quencher's extended precision)"
        return first_use_text(ham, what) + " ..."

    with WaitNotice(begin, "compiled", ANNOUNCE_AFTER, stream=stream, enabled=announce):
        rhs_dd = system.rhs_dd()
    return system_functions(system, "shadow")._replace(tangent=rhs_dd)


def warm_up(
    ham: Hamiltonian,
    stream: TextIO | None = None,
    announce: bool | None = None,
    gamma: str = "tangent",
) -> None:
    """Compile (or load) the system and the kernel for the signatures a run
    uses, by integrating one step of ``ham``, once per system and process,
    and what a run with the estimate of Gamma ``gamma`` calls
    (:func:`kernel_functions`); raises BackendUnavailable with what failed.
    A first use that takes long is announced on ``stream`` (stderr; when it
    is a terminal, or ``announce``)."""
    # (the object's key and system as compile_system remembers them: every
    # solve asks this)
    known = compiled.remembered_system(ham)
    if known is None:
        key = codegen.cache_key(ham)
        known = key, compiled.loaded_system(key)
    key, system = known
    if key in _WARM and system is not None and system.compiled_for(gamma):
        return

    def begin() -> str:
        return first_use_text(ham) + " ..."

    with WaitNotice(begin, "compiled", ANNOUNCE_AFTER, stream=stream, enabled=announce):
        if key not in _WARM:
            _warm_up(ham)
            _WARM.add(key)
        compiled.compile_system(ham).prepare(gamma)


def _warm_up(ham: Hamiltonian) -> None:
    helper = kernel_helper.start_helper(ham.dim)
    try:
        compiled.compile_system(ham)  # meanwhile
    finally:
        kernel_helper.join_helper(helper)
    try:
        # With the stand-ins of rhs_jvp and jac (the helper compiled them
        # beside the kernel): the probe's kernel signature is every run's.
        functions = kernel_functions(ham, "off")
        run = kernel_module.probe(functions, ham.dim, len(ham.parameters))
        with np.errstate(all="ignore"):
            run.run()
        if not kernel_module.kernel().dispatchers:
            # The system's f is not finite at the probe's state (it ended
            # before its step): the step with a stand-in f compiles the
            # kernel here, counted as compiling, not in the first run's
            # integration (found by QA: 12.7 s of a run's integrate_s, and
            # `hamrkq compile` left no kernel in the cache).
            stand_in = functions._replace(rhs=kernel_module.probe_rhs())
            kernel_module.probe(stand_in, ham.dim, len(ham.parameters)).run()
    except BackendUnavailable:
        raise  # already says what failed (a damaged cache file, by name)
    except Exception as exc:  # numba's TypingError/LoweringError and relatives
        raise compiled.numba_failure("the RKQ kernel", exc) from exc
