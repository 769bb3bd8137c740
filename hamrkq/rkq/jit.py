"""How the kernel's functions are marked for numba, without requiring it.

:func:`jitable` is :func:`numba.extending.register_jitable` when numba can be
imported: the function stays an ordinary Python function (the interpreted
backend calls it as it is) and numba compiles it wherever a compiled function
calls it.  Without numba it returns the function unchanged, so the
interpreted backend works on a machine where numba is missing or broken.

:func:`borrow` is how the kernel's entry points take their arrays: the
identity in Python; compiled, the same arrays without numba's reference
counting (see its docstring).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable)
T = TypeVar("T")

try:  # numba is a core dependency, but a broken install must not break the fallback
    from numba.extending import register_jitable as _register
except Exception:  # ImportError, or llvmlite failing to load
    _register = None


def jitable(function: F) -> F:
    """Mark ``function`` as callable from compiled kernel code.

    Without a C-callable wrapper (``no_cfunc_wrapper``): numba makes one for
    every function it compiles, so that it can be passed as a first-class
    function, which no kernel helper ever is (only the generated ``rhs``,
    ``jac`` and ``rhs_jvp`` are, :mod:`hamrkq.backends.codegen`); the kernel's
    91 wrappers took 1.7 s of a profiled 24 s compile on an empty cache
    (docs/performance.md, ``benchmarks/kernel_compile_wrappers.md``)."""
    if _register is None:
        return function
    return _register(no_cfunc_wrapper=True)(function)


def jitable_inline(function: F) -> F:
    """:func:`jitable`, inlined into its callers by numba (its IR, not a
    call): for small functions called in the innermost loops, where a call
    costs more than the work (the Taylor interpreter's per-operation cases,
    :mod:`hamrkq.rkq.taylor`)."""
    if _register is None:
        return function
    return _register(inline="always", no_cfunc_wrapper=True)(function)


def borrow(value: T) -> T:
    """``value`` (an array, or a tuple of arrays and numbers) as a borrowed
    reference, for the duration of one call of a kernel entry point.

    In Python this is the identity.  Compiled, it returns the same arrays
    with numba's reference-counting handle (the "meminfo") left empty, so
    passing them on costs nothing.  Without it every call of a helper that
    takes the :class:`~hamrkq.rkq.layout.Work` tuple adds and drops a
    reference on each of its arrays with atomic instructions, which was half
    of the compiled kernel's run time (``docs/performance.md``).

    Safe because the kernel only reads and writes the caller's arrays: it
    allocates nothing, keeps no array beyond the call and returns only
    numbers, while the Python caller holds the real references throughout.
    """
    return value


def _register_borrow() -> None:
    """The compiled form of :func:`borrow` (numba's public extension API)."""
    from numba import types
    from numba.core import cgutils
    from numba.extending import intrinsic, overload

    def borrowed(context, builder, ty, value):
        if isinstance(ty, types.Array):
            array = context.make_array(ty)(context, builder, value)
            array.meminfo = cgutils.get_null_value(array.meminfo.type)
            return array._getvalue()
        if isinstance(ty, types.BaseTuple):
            result = value
            for index, member in enumerate(ty):
                item = builder.extract_value(value, index)
                result = builder.insert_value(
                    result, borrowed(context, builder, member, item), index
                )
            return result
        return value  # numbers and records carry no reference count

    @intrinsic
    def borrow_intrinsic(typingctx, value):
        def codegen(context, builder, signature, args):
            return borrowed(context, builder, signature.args[0], args[0])

        return value(value), codegen

    @overload(borrow)
    def borrow_overload(value):
        def implementation(value):
            return borrow_intrinsic(value)

        return implementation


if _register is not None:
    try:
        _register_borrow()
    except Exception:  # a numba without these APIs: the kernel runs with counting
        _register(borrow)
