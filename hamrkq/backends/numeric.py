"""NumPy functions generated once from a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`.

Every function takes ``(t, y, params)``: the time, the state (all q then all
p) and the parameter values as an array ordered like
``Hamiltonian.parameters``.  Parameters are *arguments*, so changing a value
never re-derives or re-generates anything.  The functions are built with
:func:`sympy.lambdify` with common subexpressions eliminated, and with the
symbols replaced by dummies so that no user-chosen name appears in the
generated source.  Each is built on first use (``lambdify`` of an 18-body
Jacobian takes seconds; the compiled backend never needs it).

``rhs`` and ``jac`` evaluate the scalar code of
:mod:`hamrkq.backends.codegen` (the same code the compiled backend compiles).
Where Python's ``math`` raises (``sqrt(-1)``, ``exp(1000)``, ``1/0.0``) they
return what the compiled code returns, NaN or an infinity, so the step loop
reports ``Status.NON_FINITE`` on both backends instead of the interpreter
raising.
"""

from __future__ import annotations

import math
import threading
import types
import weakref
from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from hamrkq.symbolic.kinks import kinks

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["NumericHamiltonian", "numeric_of", "vectorized"]

#: What Python's floating-point code raises where IEEE arithmetic (and numba's
#: compiled code, ``error_model="numpy"``) gives NaN or an infinity.
_FLOAT_ERRORS = (ValueError, OverflowError, ZeroDivisionError)


def _ieee_math() -> types.SimpleNamespace:
    """A stand-in for :mod:`math` whose functions return NaN or an infinity
    instead of raising (NumPy's ufuncs on float64 scalars, warnings off)."""
    names = {
        "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos,
        "atan": np.arctan, "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh,
        "tanh": np.tanh, "asinh": np.arcsinh, "acosh": np.arccosh, "atanh": np.arctanh,
        "exp": np.exp, "log": np.log, "sqrt": np.sqrt, "copysign": np.copysign,
        "fabs": np.fabs,
    }  # fmt: skip
    namespace = {name: getattr(math, name) for name in dir(math) if not name.startswith("_")}
    for name, ufunc in names.items():
        namespace[name] = lambda *args, _f=ufunc: np.float64(_f(*args))
    return types.SimpleNamespace(**namespace)


def _ieee_function(module: types.ModuleType, name: str) -> Callable:
    """The generated function ``name`` (``rhs``, ``jac`` or ``energy``) re-bound to
    :func:`_ieee_math`.

    The same code object (so the same expressions, in the same order); only
    ``math`` is replaced, and every number is a NumPy float64, whose
    arithmetic divides by zero and overflows to infinities instead of raising.
    """
    namespace = {"math": _ieee_math(), "__name__": module.__name__}
    return types.FunctionType(getattr(module, name).__code__, namespace, name)


def _as_float64(array: np.ndarray) -> np.ndarray:
    return np.asarray(array, dtype=np.float64)


def _lambdify(ham: Hamiltonian, exprs) -> Callable:
    return sp.lambdify(
        (ham.t, list(ham.state), list(ham.parameters)),
        exprs,
        modules="numpy",
        cse=True,
        dummify=True,
    )


def vectorized(ham: Hamiltonian, exprs: Sequence[sp.Expr]) -> Callable:
    """A function ``f(t, Y, params) -> ndarray (N, len(exprs))`` over rows of Y.

    ``t`` may be a scalar or an array of N times.  Used for the energy, the
    gradient of H and the invariants of a problem.
    """
    raw = _lambdify(ham, list(exprs))
    count = len(exprs)

    def evaluate(t, Y, params) -> np.ndarray:
        Y = np.asarray(Y, dtype=float)
        single = Y.ndim == 1
        Y2 = np.atleast_2d(Y)
        N = Y2.shape[0]
        values = raw(np.asarray(t, dtype=float), list(Y2.T), np.asarray(params, dtype=float))
        out = np.empty((N, count))
        for k, column in enumerate(values):
            out[:, k] = np.broadcast_to(column, (N,))
        return out[0] if single else out

    return evaluate


class NumericHamiltonian:
    """Right-hand side, Jacobian, energy and gradient of H as NumPy functions.

    Parameters
    ----------
    ham : Hamiltonian
        The symbolic system.  Its derived quantities are computed once here.

    Notes
    -----
    ``rhs`` and ``jac`` work on one state (shape ``(2n,)``) and return fresh
    arrays; ``energy`` and ``gradient`` work on many states at once (rows of
    an ``(N, 2n)`` array).
    """

    def __init__(self, ham: Hamiltonian):
        self.dim = ham.dim
        self._ham = ham
        # The generated functions' NaN/infinity-returning twins, made on
        # the first float error (_call_scalar).
        self._ieee: dict[str, Callable] = {}

    # Built on first use: most runs need one or two of these, and lambdify of
    # a large system's Jacobian costs seconds.
    @cached_property
    def _rhs(self) -> Callable:
        return _lambdify(self._ham, list(self._ham.rhs))

    @cached_property
    def _jac(self) -> Callable:
        return _lambdify(self._ham, self._ham.jacobian.tolist())

    @cached_property
    def _energy(self) -> Callable:
        return vectorized(self._ham, [self._ham.H])

    @cached_property
    def _gradient(self) -> Callable:
        return vectorized(self._ham, list(self._ham.gradient))

    @cached_property
    def _rhs_many(self) -> Callable:
        return vectorized(self._ham, list(self._ham.rhs))

    @cached_property
    def _switching(self) -> Callable:
        found = kinks(self._ham.H)
        guards = [sp.Integer(-1) if k.guard is None else k.guard for k in found]
        return vectorized(self._ham, [k.argument for k in found] + guards)

    def switching(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """At the rows of ``Y``: each kink's argument, then its guard (-1
        where it has none), shape (N, 2K) for the K kinks of
        :func:`hamrkq.symbolic.kinks.kinks`."""
        return self._switching(t, Y, params)

    def _call_scalar(self, name: str, t, y, params, out: np.ndarray) -> None:
        """The generated function ``name``; where the interpreter raises on a
        float error, its NaN/infinity-returning twin (the compiled code's
        values), so the caller sees non-finite numbers, never an exception."""
        module = self._scalar if name == "rhs" else self._tangent_scalar
        try:
            getattr(module, name)(t, y, params, out)
        except _FLOAT_ERRORS:
            twin = self._ieee.get(name)
            if twin is None:
                twin = self._ieee[name] = _ieee_function(module, name)
            with np.errstate(all="ignore"):
                twin(np.float64(t), _as_float64(y), _as_float64(params), out)

    @cached_property
    def _scalar(self):
        """The system part of the scalar code of :mod:`hamrkq.backends.codegen`
        (``rhs``), which the compiled backend compiles: evaluating f with it
        here too gives every integrator (and both backends) the same bits.
        None when it cannot be generated or cached; then the lambdified
        functions serve."""
        return self._generated("system")

    @cached_property
    def _tangent_scalar(self):
        """The tangent part of the scalar code (``jac``), generated on the
        first call of :meth:`jac`; None as for :attr:`_scalar`."""
        return self._generated("tangent")

    def _generated(self, part: str):
        from hamrkq.backends.codegen import CodegenError, load_module

        try:
            return load_module(self._ham, part=part)
        except (CodegenError, OSError):
            return None

    def rhs(self, t: float, y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dy/dt at one state, shape (2n,)."""
        scalar = self._scalar
        if scalar is None:
            return np.array(self._rhs(t, y, params), dtype=float)
        out = np.empty(self.dim)
        self._call_scalar("rhs", t, y, params, out)
        return out

    def rhs_many(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dy/dt at the rows of ``Y``, shape (N, 2n)."""
        return self._rhs_many(t, Y, params)

    def jac(self, t: float, y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Jacobian of the right-hand side at one state, shape (2n, 2n)."""
        scalar = self._tangent_scalar
        if scalar is None:
            return np.array(self._jac(t, y, params), dtype=float).reshape(self.dim, self.dim)
        out = np.empty((self.dim, self.dim))
        self._call_scalar("jac", t, y, params, out)
        return out

    def energy(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """H at the rows of ``Y`` (shape (N,)), or at one state (a float array of shape ())."""
        values = self._energy(t, Y, params)
        return values[..., 0]

    def energy_as_compiled(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """H at the rows of ``Y`` (shape (N, 2n)) by the generated scalar
        code, interpreted: the compiled backend's ``energy_rows`` bit for
        bit, for the energy of a run on the interpreted backend (the
        lambdified :meth:`energy` rounds otherwise, up to 120 ulp on
        arenstorf, so a run's energy showed which backend ran it, found by
        QA).  A Python loop over the rows; :meth:`energy` where the code
        cannot be generated."""
        scalar = self._scalar
        Y = np.asarray(Y, dtype=np.float64)
        if scalar is None or Y.ndim != 2:
            return self.energy(t, Y, params)
        times = np.broadcast_to(np.asarray(t, dtype=np.float64), Y.shape[:1])
        params = _as_float64(params)
        out = np.empty(Y.shape[0])
        for i in range(Y.shape[0]):
            try:
                out[i] = scalar.energy(times[i], Y[i], params)
            except _FLOAT_ERRORS:  # the compiled code's inf or nan instead
                twin = self._ieee.get("energy")
                if twin is None:
                    twin = self._ieee["energy"] = _ieee_function(scalar, "energy")
                with np.errstate(all="ignore"):
                    out[i] = twin(np.float64(times[i]), Y[i], params)
        return out

    def gradient(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dH/dy at the rows of ``Y``, shape (N, 2n)."""
        return self._gradient(t, Y, params)


_NUMERIC: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_NUMERIC_LOCK = threading.Lock()


def numeric_of(ham: Hamiltonian) -> NumericHamiltonian:
    """The numerical functions of ``ham`` (:class:`NumericHamiltonian`), built
    once per Hamiltonian and kept while it lives.  (The symbolic layer does not
    know about numerics: this is where a Hamiltonian meets them.)"""
    with _NUMERIC_LOCK:
        numeric = _NUMERIC.get(ham)
        if numeric is None:
            numeric = NumericHamiltonian(ham)
            _NUMERIC[ham] = numeric
        return numeric
