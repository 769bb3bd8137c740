"""Compiled forms of the kernel's helpers outside the step loop.

The dense output (:func:`hamrkq.rkq.dense.evaluate`) and the tangent sweep of
the chaos indicators (:func:`hamrkq.rkq.variational.sweep`) are ``@jitable``
like the step loop; here they are compiled by numba the way
:mod:`hamrkq.backends.kernel` compiles the kernel: an explicit signature in
which the right-hand side (and the tangent) are first-class function types,
so one compiled helper serves every Hamiltonian, cached on disk in the
kernel's cache folder (named by the hash of the kernel's sources).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from hamrkq.backends.kernel import compile_in_cache, describe
from hamrkq.backends.numba_compile import signatures

__all__ = ["compiled_helper"]

_LOCK = threading.RLock()
_HELPERS: dict[tuple, Any] = {}


def compiled_helper(function: Callable, kinds: tuple[str, ...], *args: Any) -> Any:
    """``function`` compiled for the arguments ``args``; ``kinds`` names the
    leading function arguments' types (``"rhs"``, ``"rhs_jvp"``, ``"jac"``),
    the rest are typed from ``args``.  Returns the dispatcher (compiled on
    first use, then loaded from the disk cache)."""
    import numba

    sig = signatures()
    rest = args[len(kinds) :]
    key = (
        function.__module__,
        function.__qualname__,
        kinds,
        tuple(describe(a) for a in rest),
    )
    with _LOCK:
        dispatcher = _HELPERS.get(key)
        if dispatcher is None:
            signature = (
                *(sig[kind + "_type"] for kind in kinds),
                *(numba.typeof(a) for a in rest),
            )
            dispatcher = compile_in_cache(function, signature)
            _HELPERS[key] = dispatcher
    return dispatcher
