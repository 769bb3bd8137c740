"""How the kernel's functions are marked for numba, without requiring it.

:func:`jitable` is :func:`numba.extending.register_jitable` when numba can be
imported: the function stays an ordinary Python function (the interpreted
backend calls it as it is) and numba compiles it wherever a compiled function
calls it.  Without numba it returns the function unchanged, so the
interpreted backend works on a machine where numba is missing or broken.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable)

try:  # numba is a core dependency, but a broken install must not break the fallback
    from numba.extending import register_jitable as _register
except Exception:  # ImportError, or llvmlite failing to load
    _register = None


def jitable(function: F) -> F:
    """Mark ``function`` as callable from compiled kernel code."""
    if _register is None:
        return function
    return _register(function)
