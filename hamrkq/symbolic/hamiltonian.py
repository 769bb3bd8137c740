"""Symbolic Hamiltonians: validation and lazily derived quantities.

A :class:`Hamiltonian` holds ``H(q, p; parameters, t)`` and the symbols that
play each role.  Everything derived from it (Hamilton's equations, the
Jacobian, Poisson brackets, the numerical functions) is computed on first use
and cached; the object itself is immutable.  What it is declared from is
checked by :mod:`~hamrkq.symbolic.declaration`, and the numbers given for its
symbols (parameter and initial values) by :mod:`~hamrkq.symbolic.values`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import (
    CodegenError,
    HamiltonianError,
    UndeclaredSymbolError,
    warn,
)
from hamrkq.symbolic.declaration import (
    TIME,
    ParameterSpec,
    check_scalar,
    complex_kinks,
    declared_parameters,
    degrees_of_freedom,
    numbers_beyond_double,
    shadowed_constants,
    shared_names,
    symbol_tuple,
    time_symbol,
    undeclared_hints,
)
from hamrkq.symbolic.supported import check_supported, what_is_supported
from hamrkq.symbolic.values import bind_parameters, bind_state

__all__ = ["TIME", "Hamiltonian", "is_zero"]


def is_zero(expr: sp.Expr) -> bool:
    """Decide symbolically that ``expr`` is identically zero.

    Tries cheap canonical forms first (expansion, rational cancellation) and
    falls back to :func:`sympy.simplify`.  Returns False when SymPy cannot prove
    it: this is a proof, never a numerical sampling.
    """
    if not isinstance(expr, sp.Basic):
        return expr == 0
    if expr == 0:
        return True
    for transform in (sp.expand, _cancel, _trig_expand, sp.simplify):
        try:
            expr = transform(expr)
        except (TypeError, ValueError, NotImplementedError, RecursionError):
            continue
        if expr == 0:
            return True
    return False


def _cancel(expr: sp.Expr) -> sp.Expr:
    return sp.cancel(sp.together(expr))


def _trig_expand(expr: sp.Expr) -> sp.Expr:
    return sp.expand(sp.expand_trig(expr))


class Hamiltonian:
    """A Hamiltonian ``H(q, p)``, validated, with derived quantities on demand.

    Parameters
    ----------
    H : sympy.Expr
        The Hamiltonian, a scalar expression.
    q, p : sequence of sympy.Symbol
        Coordinates and conjugate momenta, of equal length n.
    parameters : mapping or sequence of sympy.Symbol, optional
        Parameters of H.  A mapping gives default values (``{a: 6.0}``; the key
        may also be the parameter's name); a value of ``None`` means "no
        default, must be given when solving".  A sequence declares parameters
        without defaults.
    t : sympy.Symbol, optional
        The time symbol.  By default the free symbol of H named ``t`` if there
        is one, else :data:`TIME`.
    name : str, optional
        A label used in reports.

    Raises
    ------
    HamiltonianError
        Listing every problem found at once: q and p of different lengths,
        duplicated symbols, different symbols with one name (values are
        bound by name), a non-scalar H, undeclared free symbols
        (:class:`~hamrkq.errors.UndeclaredSymbolError`), bad parameter values,
        and anything the numerical backends cannot evaluate: H may use
        real numbers within the range of a double (not ``Integer(10)**400``
        or ``Float("1e400")``), ``pi``, ``E``, ``+ * **`` and the elementary
        functions (trigonometric, hyperbolic and their inverses, ``exp``,
        ``log``, ``Abs``, ``sign``; ``Abs`` and ``sign`` of symbols declared
        real, ``sp.symbols("q p", real=True)``, whose derivatives SymPy then
        knows), not undefined functions, integrals, ``I`` or infinities.

    Examples
    --------
    >>> import sympy as sp
    >>> q, p = sp.symbols("q p")
    >>> ham = Hamiltonian(p**2/2 - (1 - p/6)*sp.cos(q), q=[q], p=[p])
    >>> ham.rhs.T
    Matrix([[p + cos(q)/6, -(1 - p/6)*sin(q)]])
    """

    def __init__(
        self,
        H: sp.Expr,
        q: Sequence[sp.Symbol] | sp.Symbol,
        p: Sequence[sp.Symbol] | sp.Symbol,
        parameters: ParameterSpec = None,
        *,
        t: sp.Symbol | None = None,
        name: str | None = None,
    ):
        problems: list[str] = []
        H = check_scalar(H, problems)
        before = len(problems)
        q = symbol_tuple(q, "q", problems)
        p = symbol_tuple(p, "p", problems)
        if len(problems) == before:  # else their counts would mislead ("q and p are empty")
            problems += degrees_of_freedom(q, p)
        free = H.free_symbols if H is not None else set()
        t = time_symbol(t, free, q, p, problems)
        params, defaults = declared_parameters(parameters, free, problems)
        if H is not None:
            problems += shadowed_constants(H, params)
        declared = [*q, *p, *params, t]
        seen: set[sp.Symbol] = set()
        duplicated = sorted({str(s) for s in declared if s in seen or seen.add(s)})
        if duplicated:
            problems.append(f"duplicated symbols: {', '.join(duplicated)}")
        problems += shared_names(q, p, params, t)
        undeclared = {s for s in free if s not in set(declared)}
        if undeclared:
            raise UndeclaredSymbolError(
                {str(s) for s in undeclared}, problems + undeclared_hints(undeclared, declared)
            )
        if H is not None:
            problems += complex_kinks(H)
            problems += numbers_beyond_double([H], "H")
            # Only what every numerical backend can evaluate: elementary
            # functions, finite real numbers, the declared symbols.
            try:
                check_supported([H], set(declared))
            except CodegenError as exc:
                unsupported = str(exc).replace("cannot generate scalar code for: ", "")
                problems.append(
                    f"H uses what hamrkq cannot turn into numerical code: {unsupported} "
                    f"(it takes {what_is_supported()})"
                )
        if problems:
            raise HamiltonianError(problems)
        if H.has(sp.Abs, sp.sign):
            warn(  # pointing at the first caller outside hamrkq (load_problem's too)
                f"H = {H} is not differentiable everywhere (Abs or sign): Hamilton's "
                "equations and the Jacobian hold away from the kinks (the Jacobian's "
                "DiracDelta terms are dropped), and the error estimates of a step that "
                "crosses a kink are not reliable"
            )
        object.__setattr__(self, "_H", H)
        object.__setattr__(self, "_q", q)
        object.__setattr__(self, "_p", p)
        object.__setattr__(self, "_params", params)
        object.__setattr__(self, "_defaults", defaults)
        object.__setattr__(self, "_t", t)
        object.__setattr__(self, "name", name)

    # immutability: cached_property writes to __dict__ directly, which is allowed.
    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError(f"Hamiltonian is immutable (cannot set {key!r})")

    def __delattr__(self, key: str) -> None:
        raise AttributeError(f"Hamiltonian is immutable (cannot delete {key!r})")

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # Pickle the declaration only (ensembles ship H to other processes):
        # the cached derived quantities are rebuilt on demand there, and the
        # lambdified functions of ``numeric`` cannot be pickled at all.
        spec = {s: self._defaults.get(s) for s in self._params}
        return (_unpickle, (self._H, self._q, self._p, spec, self._t, self.name))

    # -- the declaration ----------------------------------------------------
    @property
    def H(self) -> sp.Expr:
        """The Hamiltonian expression."""
        return self._H

    @property
    def q(self) -> tuple[sp.Symbol, ...]:
        """Coordinates."""
        return self._q

    @property
    def p(self) -> tuple[sp.Symbol, ...]:
        """Momenta."""
        return self._p

    @property
    def state(self) -> tuple[sp.Symbol, ...]:
        """The state symbols, all q then all p."""
        return self._q + self._p

    @property
    def parameters(self) -> tuple[sp.Symbol, ...]:
        """Parameter symbols, sorted by name (deterministic)."""
        return self._params

    @property
    def defaults(self) -> Mapping[sp.Symbol, float]:
        """Default parameter values (only those that have one)."""
        return dict(self._defaults)

    @property
    def t(self) -> sp.Symbol:
        """The time symbol."""
        return self._t

    @property
    def n(self) -> int:
        """Degrees of freedom."""
        return len(self._q)

    @property
    def dim(self) -> int:
        """Dimension of phase space, 2n."""
        return 2 * len(self._q)

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the state components."""
        # s.name, not str(s): printing a symbol through SymPy costs ~50 us a call,
        # and solve asks for the names every time.
        return tuple(s.name if type(s) is sp.Symbol else str(s) for s in self.state)

    @property
    def time_dependent(self) -> bool:
        """True when H depends explicitly on t."""
        return self._t in self._H.free_symbols

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Hamiltonian({label}H={self._H}, q={list(self._q)}, p={list(self._p)})"

    def __eq__(self, other: object) -> bool:
        if other is self:  # the common case of the memos keyed by a system
            return True
        if not isinstance(other, Hamiltonian):
            return NotImplemented
        return (self._H, self._q, self._p, self._params, self._t) == (
            other._H,
            other._q,
            other._p,
            other._params,
            other._t,
        ) and self._defaults == other._defaults

    def __hash__(self) -> int:
        return self._hash

    @cached_property
    def _hash(self) -> int:
        # Hashed once: the memos keyed by a system (its cache key, its numeric
        # functions) ask on every solve, and hashing the expression tree
        # costs microseconds.
        return hash((self._H, self._q, self._p, self._params, self._t))

    # -- derived, symbolic ----------------------------------------------------
    @cached_property
    def rhs(self) -> sp.Matrix:
        """Hamilton's equations' right-hand side, (dH/dp, -dH/dq), 2n x 1."""
        dq = [sp.diff(self._H, pi) for pi in self._p]
        dp = [-sp.diff(self._H, qi) for qi in self._q]
        return _drop_delta(sp.Matrix(dq + dp))

    @cached_property
    def equations_time_dependent(self) -> bool:
        """True when Hamilton's equations depend explicitly on t (H may
        depend on it through a term that moves no state, ``cos(t)`` added
        alone, and the equations not)."""
        return self.time_dependent and self._t in self.rhs.free_symbols

    @cached_property
    def equations(self) -> list[sp.Eq]:
        """Hamilton's equations as ``Eq(Derivative(y_k, t), rhs_k)``."""
        return [
            sp.Eq(sp.Derivative(y, self._t), f, evaluate=False)
            for y, f in zip(self.state, self.rhs, strict=True)
        ]

    @cached_property
    def jacobian(self) -> sp.Matrix:
        """Jacobian of the right-hand side with respect to (q, p), 2n x 2n.

        Built from the Hessian of H, ``J = [[H_pq, H_pp], [-H_qq, -H_qp]]``,
        differentiating each pair of state variables once (the Hessian is
        symmetric): on outer_solar_system (36 states) 0.2 s of SymPy instead
        of 1.4 s for ``rhs.jacobian(state)``.
        """
        state, n = self.state, self.n
        gradient = self.gradient
        hessian: list[list[sp.Expr]] = [[sp.S.Zero] * (2 * n) for _ in range(2 * n)]
        for i in range(2 * n):
            for j in range(i, 2 * n):
                hessian[i][j] = hessian[j][i] = sp.diff(gradient[i], state[j])
        rows = [hessian[n + i] for i in range(n)] + [[-h for h in hessian[i]] for i in range(n)]
        # d sign(q)/dq = 2 DiracDelta(q): zero wherever the equations hold
        # (away from the kinks of Abs/sign), and no backend can evaluate it.
        return _drop_delta(sp.Matrix(rows))

    @cached_property
    def gradient(self) -> sp.Matrix:
        """Gradient of H with respect to (q, p), 2n x 1."""
        return sp.Matrix([sp.diff(self._H, y) for y in self.state])

    def poisson_bracket(self, F: sp.Expr, G: sp.Expr | None = None) -> sp.Expr:
        """The Poisson bracket ``{F, G}`` (``G`` defaults to H).

        ``{F, G} = sum_i dF/dq_i dG/dp_i - dF/dp_i dG/dq_i``, so that
        ``dF/dt = {F, H} + dF/dt|explicit`` along the flow.
        """
        G = self._H if G is None else G
        return sp.Add(
            *(
                sp.diff(F, qi) * sp.diff(G, pi) - sp.diff(F, pi) * sp.diff(G, qi)
                for qi, pi in zip(self._q, self._p, strict=True)
            )
        )

    def time_derivative(self, F: sp.Expr) -> sp.Expr:
        """The derivative of ``F`` along the flow: ``{F, H} + dF/dt``."""
        return self.poisson_bracket(F) + sp.diff(F, self._t)

    def is_first_integral(self, F: sp.Expr) -> bool:
        """True if ``F`` is conserved by the flow, proved symbolically.

        Checks ``{F, H} + dF/dt == 0`` with :func:`is_zero`; False means SymPy
        could not prove it (or it is false).
        """
        return is_zero(self.time_derivative(F))

    @cached_property
    def is_separable(self) -> bool:
        """True if ``H = T(p) + V(q)``: every mixed derivative d2H/dq_i dp_j is 0."""
        return all(is_zero(sp.diff(self._H, qi, pj)) for qi in self._q for pj in self._p)

    # -- numbers --------------------------------------------------------------
    def parameter_values(self, values: Mapping[Any, Any] | None = None) -> np.ndarray:
        """Parameter values as a float array ordered like :attr:`parameters`.

        Parameters
        ----------
        values : mapping, optional
            Overrides of the defaults, keyed by symbol or by name.

        Raises
        ------
        InputError
            An unknown parameter, a value that is not a finite real number, or a
            parameter with neither a default nor a given value.
        """
        return bind_parameters(self._params, self._defaults, values)

    def state_values(self, q0: Any, p0: Any) -> np.ndarray:
        """Initial values as one float array ``(q0..., p0...)``, validated.

        Parameters
        ----------
        q0, p0 : sequence or mapping
            A sequence of n values in the order of :attr:`q` (:attr:`p`), or a
            mapping that binds every coordinate (momentum) by its name or symbol,
            ``{"x": 1.0}``.  Values are numbers, SymPy numbers or expressions
            without free symbols.

        Raises
        ------
        InputError
            A wrong count; in a mapping, a missing, unknown or twice-bound name.
        """
        return bind_state(self._q, self._p, q0, p0)


def _unpickle(H, q, p, parameters, t, name) -> Hamiltonian:
    return Hamiltonian(H, q, p, parameters, t=t, name=name)


def _drop_delta(matrix: sp.Matrix) -> sp.Matrix:
    """``matrix`` with every DiracDelta (and its derivatives) set to zero."""
    if not matrix.has(sp.DiracDelta):
        return matrix
    return matrix.replace(sp.DiracDelta, lambda *args: sp.S.Zero)
