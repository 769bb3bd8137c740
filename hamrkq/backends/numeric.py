"""NumPy functions generated once from a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`.

Every function takes ``(t, y, params)``: the time, the state (all q then all
p) and the parameter values as an array ordered like
``Hamiltonian.parameters``.  Parameters are *arguments*, so changing a value
never re-derives or re-generates anything.  The functions are built with
:func:`sympy.lambdify` with common subexpressions eliminated, and with the
symbols replaced by dummies so that no user-chosen name appears in the
generated source.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["NumericHamiltonian", "vectorized"]


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
        self._rhs = _lambdify(ham, list(ham.rhs))
        self._jac = _lambdify(ham, ham.jacobian.tolist())
        self._energy = vectorized(ham, [ham.H])
        self._gradient = vectorized(ham, list(ham.gradient))
        self._rhs_many = vectorized(ham, list(ham.rhs))

    @cached_property
    def _scalar(self):
        """The scalar functions of :mod:`hamrkq.backends.codegen`, which the compiled
        backend compiles: evaluating f and J with them here too gives every
        integrator (and both backends) the same bits.  None when they cannot
        be generated or cached; then the lambdified functions serve."""
        from hamrkq.backends.codegen import CodegenError, load_module

        try:
            return load_module(self._ham)
        except (CodegenError, OSError):
            return None

    def rhs(self, t: float, y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dy/dt at one state, shape (2n,)."""
        scalar = self._scalar
        if scalar is None:
            return np.array(self._rhs(t, y, params), dtype=float)
        out = np.empty(self.dim)
        scalar.rhs(t, y, params, out)
        return out

    def rhs_many(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dy/dt at the rows of ``Y``, shape (N, 2n)."""
        return self._rhs_many(t, Y, params)

    def jac(self, t: float, y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Jacobian of the right-hand side at one state, shape (2n, 2n)."""
        scalar = self._scalar
        if scalar is None:
            return np.array(self._jac(t, y, params), dtype=float).reshape(self.dim, self.dim)
        out = np.empty((self.dim, self.dim))
        scalar.jac(t, y, params, out)
        return out

    def energy(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """H at the rows of ``Y`` (shape (N,)), or at one state (a float array of shape ())."""
        values = self._energy(t, Y, params)
        return values[..., 0]

    def gradient(self, t, Y: np.ndarray, params: np.ndarray) -> np.ndarray:
        """dH/dy at the rows of ``Y``, shape (N, 2n)."""
        return self._gradient(t, Y, params)
