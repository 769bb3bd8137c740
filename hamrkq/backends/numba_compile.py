"""numba, when it can be used, and every compile counted.

:func:`available` says whether the compiled backend can run here (numba
importable, :data:`DISABLE_ENV` not set); :func:`numba_module` returns numba
or raises :class:`BackendUnavailable`.  :func:`jit` compiles a function with
an explicit signature and ``cache=True`` and adds the dispatcher's cache
misses and hits to this process's counters
(:func:`stats`), so that a test can tell that a fresh process with a warm
cache compiled nothing.  :func:`signatures` holds the fixed numba signatures
of a compiled system's functions, which the kernel takes as first-class
function types.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
import time
import warnings
from collections.abc import Callable
from typing import Any

from hamrkq.backends.numba_cache import DamagedEntry, compile_checked, error_text
from hamrkq.backends.numba_linking import callees_optimised_once
from hamrkq.errors import HamrkqError, warn

__all__ = [
    "DISABLE_ENV",
    "LOCK",
    "BackendUnavailable",
    "available",
    "jit",
    "numba_module",
    "signatures",
    "stats",
]

#: Environment variable: set to 1 (or true/yes/on) to turn the compiled backend off.
DISABLE_ENV = "HAMRKQ_DISABLE_NUMBA"
#: Held while compiling or registering compiled code (numba's own lock is not
#: re-entrant across our checks of what is already compiled).
LOCK = threading.RLock()
_STATS: dict[str, Any] = {
    "compiled": 0,
    "loaded": 0,
    "compile_seconds": 0.0,
    "load_seconds": 0.0,
}


class BackendUnavailable(HamrkqError, RuntimeError):
    """The compiled backend cannot be used (disabled, numba missing, or the
    system cannot be compiled); the message says which."""


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
    if _IMPORTED:  # imported once: asked again by every solve
        return True, ""
    try:
        import numba  # noqa: F401
    except Exception as exc:  # ImportError, or a broken install (llvmlite)
        return False, f"numba cannot be imported ({type(exc).__name__}: {exc})"
    _IMPORTED.append(True)
    return True, ""


#: Not empty once numba has been imported here (:func:`available`).
_IMPORTED: list[bool] = []


def numba_module():
    """numba itself; raises :class:`BackendUnavailable` when it cannot be used."""
    ok, reason = available()
    if not ok:
        raise BackendUnavailable(reason)
    import numba

    return numba


@functools.cache
def signatures() -> dict[str, Any]:
    """numba signatures of a compiled system's ``rhs``, ``jac``, ``rhs_jvp``,
    ``energy`` and ``energy_rows``, and (``*_type``) the first-class function
    types the kernel takes them as."""
    from numba import types as nt

    vec, mat = nt.float64[::1], nt.float64[:, ::1]
    functions = {
        "rhs": nt.void(nt.float64, vec, vec, vec),
        "jac": nt.void(nt.float64, vec, vec, mat),
        "rhs_jvp": nt.void(nt.float64, vec, vec, vec, vec, vec, mat),
        "energy": nt.float64(nt.float64, vec, vec),
        "energy_rows": nt.void(vec, mat, vec, vec),
    }
    # The kernel (rhs, rhs_jvp, jac) and its extras (energy,
    # hamrkq.backends.extras) take these as first-class functions.
    passed = ("rhs", "jac", "rhs_jvp", "energy")
    return {**functions, **{f"{name}_type": nt.FunctionType(functions[name]) for name in passed}}


def _account(dispatcher, started: float) -> None:
    """Add a dispatcher's cache misses and hits, and the seconds since
    ``started``, to the counters."""
    elapsed = time.perf_counter() - started
    misses = sum(dispatcher.stats.cache_misses.values())
    hits = sum(dispatcher.stats.cache_hits.values())
    _STATS["compiled"] += misses
    _STATS["loaded"] += hits
    _STATS["compile_seconds" if misses else "load_seconds"] += elapsed


def jit(
    function: Callable,
    signature,
    cache_dir: str | None = None,
    callees_once: bool = False,
):
    """``function`` compiled by numba for ``signature`` (or loaded from its
    disk cache: in ``cache_dir`` when given, else beside the function's
    source file), counted; with ``callees_once``, its ``register_jitable``
    callees are optimised once, inside it
    (:func:`~hamrkq.backends.numba_linking.callees_optimised_once`).

    The cache's files carry checksums
    (:func:`~hamrkq.backends.numba_cache.compile_checked`): a damaged one is
    removed and the function compiled again, with one
    :class:`~hamrkq.errors.HamrkqWarning` naming the file.

    Raises
    ------
    BackendUnavailable
        A damaged cache file was found and compiling the function again
        failed; the message names the file and the real reason.  Other
        failures of numba (its TypingError and relatives) propagate as they
        are.
    """
    numba = numba_module()
    flags = {"nogil": True, "error_model": "numpy"}
    previous = numba.config.CACHE_DIR
    if cache_dir is not None:
        # numba reads its cache directory when a dispatcher is created.
        numba.config.CACHE_DIR = cache_dir
    damaged: list[DamagedEntry] = []
    started = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # numba explains an uncacheable function with a warning; the
            # counters and BackendUnavailable carry that information instead.
            warnings.simplefilter("ignore", numba.NumbaWarning)
            linking = callees_optimised_once() if callees_once else contextlib.nullcontext()
            with linking:
                dispatcher = compile_checked(
                    numba, function, signature, flags, damaged, in_folder=cache_dir is not None
                )
            _account(dispatcher, started)
    except Exception as exc:
        if not damaged:
            raise
        # The damaged file is named with the real reason, as the reason of
        # the interpreted fallback or of `hamrkq compile`'s exit status 2.
        raise BackendUnavailable(
            f"{_damage_text(function, damaged[0])}, but compiling it again failed "
            f"({error_text(exc)})"
        ) from exc
    finally:
        numba.config.CACHE_DIR = previous
    not_saved = getattr(getattr(dispatcher, "_cache", None), "not_saved", None) or ()
    for damage in damaged:
        # In a read-only folder the new code is not kept: said here, once
        # (it said "cached the new code", then that the folder is read-only;
        # found by QA).
        kept = (
            "; its folder is read-only, so the new code is not kept and every process will "
            "compile it again"
            if not_saved
            else " and cached the new code"
        )
        warn(
            f"hamrkq: {_damage_text(function, damage)}; compiled it again "
            f"({time.perf_counter() - started:.1f} s){kept}"
        )
    if damaged:  # the read-only folder is said above: not again below
        _READ_ONLY_WARNED.update(not_saved)
    _warn_not_saved(function, dispatcher, time.perf_counter() - started)
    _warn_uncached(function, dispatcher, cache_dir, time.perf_counter() - started)
    return dispatcher


#: Cache folders that could not be used at all, already warned about.
_UNUSABLE_WARNED: set[str] = set()


def _warn_uncached(
    function: Callable, dispatcher: Any, folder: str | None, seconds: float
) -> None:
    """One warning per cache folder that could not be used at all (neither
    written nor read: a file where numba's subfolder belongs, say): the
    function was compiled without a cache, as every process will."""
    reason = getattr(dispatcher, "uncached_reason", None)
    if reason is None or str(folder) in _UNUSABLE_WARNED:
        return
    _UNUSABLE_WARNED.add(str(folder))
    warn(
        f"hamrkq: the cache folder {folder} cannot hold "
        f"{function.__module__}.{function.__qualname__} ({reason}): compiled it without a "
        f"cache ({seconds:.1f} s), and every process will compile it again; removing the "
        "folder lets hamrkq build it anew"
    )


#: Read-only cache folders already warned about in this process.
_READ_ONLY_WARNED: set[str] = set()


def _warn_not_saved(function: Callable, dispatcher: Any, seconds: float) -> None:
    """One warning per read-only cache folder where a function had to be
    compiled (it was not there) and could not be kept: every process
    compiles it again (:class:`~hamrkq.backends.numba_cache` reads such a
    folder and never writes it)."""
    folders = getattr(getattr(dispatcher, "_cache", None), "not_saved", None) or ()
    for folder in folders:
        if folder in _READ_ONLY_WARNED:
            continue
        _READ_ONLY_WARNED.add(folder)
        warn(
            f"hamrkq: the cache folder {folder} is read-only and does not hold "
            f"{function.__module__}.{function.__qualname__}: compiled it here ({seconds:.1f} s), "
            "and every process will compile it again; run `hamrkq compile` with a writable "
            "cache to add it"
        )


def _damage_text(function: Callable, damage: DamagedEntry) -> str:
    """What was damaged, in the words of a warning or an error."""
    name = f"{function.__module__}.{function.__qualname__}"
    kind = "index" if damage.path.endswith(".nbi") else "machine code"
    text = f"numba's cached {kind} of {name}, {damage.path}, is damaged ({damage.reason})"
    if damage.not_removed is not None:
        return f"{text} and cannot be removed ({damage.not_removed})"
    return text + "; removed it"


def stats() -> dict[str, float]:
    """Counters of this process: signatures ``compiled`` (also as
    ``compile_count``) and ``loaded`` from the disk cache, and the seconds
    spent on each."""
    return {**_STATS, "compile_count": _STATS["compiled"]}
