"""Compiled forms of the kernel's helpers outside the step loop.

The dense output (:func:`hamrkq.rkq.dense.evaluate`) and the tangent sweep of
the chaos indicators (:func:`hamrkq.rkq.variational.sweep`) are ``@jitable``
like the step loop; here they are compiled by numba the way
:mod:`hamrkq.backends.compiled` compiles the kernel: an explicit signature in
which the right-hand side (and the tangent) are first-class function types,
so one compiled helper serves every Hamiltonian, cached on disk in the
kernel's cache folder (named by the hash of the kernel's sources).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from typing import Any

from hamrkq.backends import compiled

__all__ = ["compiled_helper"]

_LOCK = threading.RLock()
_HELPERS: dict[tuple, Any] = {}


def _compile(function: Callable, signature: tuple):
    numba = compiled._numba()
    import time

    folder = compiled.kernel_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(folder)  # see compiled._compile_kernel: a stale callee
    try:
        flags = {"cache": True, "nogil": True, "error_model": "numpy"}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", numba.NumbaWarning)
            started = time.perf_counter()
            dispatcher = numba.njit(numba.types.int64(*signature), **flags)(function)
            compiled._account(dispatcher, started)
    finally:
        numba.config.CACHE_DIR = previous
    return dispatcher


def compiled_helper(function: Callable, kinds: tuple[str, ...], *args: Any) -> Any:
    """``function`` compiled for the arguments ``args``; ``kinds`` names the
    leading function arguments' types (``"rhs"``, ``"rhs_jvp"``, ``"jac"``),
    the rest are typed from ``args``.  Returns the dispatcher (compiled on
    first use, then loaded from the disk cache)."""
    import numba

    sig = compiled._types()
    rest = args[len(kinds) :]
    key = (
        function.__module__,
        function.__qualname__,
        kinds,
        tuple(compiled._describe(a) for a in rest),
    )
    with _LOCK:
        dispatcher = _HELPERS.get(key)
        if dispatcher is None:
            signature = (
                *(sig[kind + "_type"] for kind in kinds),
                *(numba.typeof(a) for a in rest),
            )
            dispatcher = _compile(function, signature)
            _HELPERS[key] = dispatcher
    return dispatcher
