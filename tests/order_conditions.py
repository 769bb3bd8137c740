"""Butcher order conditions from rooted trees, for the tableau tests.

A Runge-Kutta method ``(A, b)`` has order ``p`` exactly when, for every rooted
tree ``t`` with at most ``p`` vertices, its elementary weight equals the
reciprocal of the tree's density: ``Phi(t) = 1 / gamma(t)`` (Butcher 1963;
Hairer, Norsett & Wanner, *Solving ODEs I*, Thm. II.2.13).

Trees are generated here from scratch rather than tabulated, so the count per
order (1, 1, 2, 4, 9, 20, 48, 115: OEIS A000081) is itself a check.

Representation: a tree is the sorted tuple of its root's subtrees, so the
single vertex is ``()``, the two-vertex tree is ``((),)``, and the "bushy"
tree with three vertices is ``((), ())``.  Sorting the children recursively
makes the representation canonical, so equal trees compare and hash equal.

The arithmetic is generic: the weights are computed with whatever number type
the coefficients are given in (``Fraction`` for exact rationals, elements of
SymPy's algebraic field ``QQ<sqrt(21)>`` for Cooper-Verner, ``float``), so the
same code proves conditions exactly or measures floating-point residuals.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from functools import cache
from math import factorial
from typing import Any

import mpmath
import sympy as sp

Tree = tuple  # tuple of subtrees (recursively), children sorted


def _graft(tree: Tree) -> Iterator[Tree]:
    """Every tree obtained from ``tree`` by adding one leaf to one vertex."""
    yield tuple(sorted((*tree, ())))
    for i, child in enumerate(tree):
        for grown in _graft(child):
            yield tuple(sorted((*tree[:i], grown, *tree[i + 1 :])))


@cache
def rooted_trees(order: int) -> tuple[Tree, ...]:
    """All rooted trees with exactly ``order`` vertices, each once."""
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    if order == 1:
        return ((),)
    grown = {new for tree in rooted_trees(order - 1) for new in _graft(tree)}
    return tuple(sorted(grown, key=repr))


@cache
def tree_order(tree: Tree) -> int:
    """Number of vertices ``|t|``."""
    return 1 + sum(tree_order(child) for child in tree)


@cache
def density(tree: Tree) -> int:
    """The density ``gamma(t) = |t| * prod gamma(children)``."""
    result = tree_order(tree)
    for child in tree:
        result *= density(child)
    return result


@cache
def symmetry(tree: Tree) -> int:
    """The symmetry ``sigma(t)``: prod over distinct children ``u`` of
    ``m_u! * sigma(u)^m_u`` where ``m_u`` is the multiplicity of ``u``."""
    result = 1
    for child in set(tree):
        m = tree.count(child)
        result *= factorial(m) * symmetry(child) ** m
    return result


def elementary_weights(
    A: Sequence[Sequence[Any]], b: Sequence[Any], trees: Sequence[Tree], one: Any
) -> list[Any]:
    """``Phi(t) = sum_i b_i g_i(t)`` with ``g(t)_i = prod_children (A g(child))_i``.

    ``one`` is the multiplicative identity of the number type in use; the
    leaf's ``A g`` is then ``A 1 = c`` (row sums, as the conditions assume).
    """
    g = StageVectors(A, one)
    return [g.weight(b, t) for t in trees]


class StageVectors:
    """The stage vectors ``g(t)`` and ``A g(t)`` of one coupling matrix, memoised.

    Every subtree's ``A g`` is computed once (an ``s x s`` product), and a
    tree's ``g`` is the entrywise product of its children's: the 7813 trees
    through order 12 share about 3000 distinct subtrees, so checking a
    25-stage tableau costs seconds, not minutes.
    """

    def __init__(self, A: Sequence[Sequence[Any]], one: Any) -> None:
        self.A = A
        self.one = one
        self.zero = one - one
        self.s = len(A)
        # Only the nonzero couplings matter; sparse rows make A g cheaper.
        self.rows = [
            [(j, A[i][j]) for j in range(i) if A[i][j] != self.zero] for i in range(self.s)
        ]
        self._g: dict[Tree, list[Any]] = {}
        self._Ag: dict[Tree, list[Any]] = {}

    def g(self, tree: Tree) -> list[Any]:
        if tree not in self._g:
            vec = [self.one] * self.s
            for child in tree:
                agc = self.Ag(child)
                vec = [v * a for v, a in zip(vec, agc, strict=True)]
            self._g[tree] = vec
        return self._g[tree]

    def Ag(self, tree: Tree) -> list[Any]:
        if tree not in self._Ag:
            gc = self.g(tree)
            self._Ag[tree] = [sum((a * gc[j] for j, a in row), self.zero) for row in self.rows]
        return self._Ag[tree]

    def weight(self, b: Sequence[Any], tree: Tree) -> Any:
        """The elementary weight ``Phi(t) = b . g(t)``."""
        return sum((bi * gi for bi, gi in zip(b, self.g(tree), strict=True)), self.zero)


def residuals(
    A: Sequence[Sequence[Any]],
    b: Sequence[Any],
    max_order: int,
    one: Any,
    min_order: int = 1,
) -> list[tuple[Tree, Any]]:
    """``(tree, Phi(t) - 1/gamma(t))`` for every tree of order in
    ``[min_order, max_order]``, in the number type of ``A``, ``b``, ``one``."""
    trees = [t for k in range(min_order, max_order + 1) for t in rooted_trees(k)]
    phis = elementary_weights(A, b, trees, one)
    return [(t, phi - one / density(t)) for t, phi in zip(trees, phis, strict=True)]


@dataclass(frozen=True)
class ExactArithmetic:
    """An exact number type: ``convert`` maps coefficients into it, ``one`` and
    ``zero`` are its identities, ``to_float`` reads an element back."""

    convert: Callable[[Any], Any]
    one: Any
    zero: Any
    to_float: Callable[[Any], float]


def exact_field(values: Sequence[Any]) -> ExactArithmetic:
    """The exact number type in which to compute with all of ``values``.

    ``Fraction`` and ``Decimal`` coefficients (a decimal is taken at its exact
    value) give ``Fraction``; SymPy expressions give the smallest algebraic
    field SymPy finds for them (``QQ<sqrt(21)>`` for Cooper-Verner).
    Elements of both support ``+ - *`` and ``/`` by an int, which is all
    :func:`residuals` needs.
    """
    symbolic = [v for v in values if isinstance(v, sp.Expr)]
    if not symbolic:
        return ExactArithmetic(Fraction, Fraction(1), Fraction(0), float)
    irrationals = sorted(
        {a for v in symbolic for a in v.atoms(sp.Pow) if not a.is_Rational}, key=str
    )
    field = sp.QQ.algebraic_field(*irrationals) if irrationals else sp.QQ

    def convert(v: Any) -> Any:
        if isinstance(v, (Fraction, Decimal, int)):
            f = Fraction(v)
            return field.from_sympy(sp.Rational(f.numerator, f.denominator))
        return field.from_sympy(sp.expand(v))

    def to_float(v: Any) -> float:
        return float(sp.N(field.to_sympy(v), 30))

    return ExactArithmetic(convert, field.one, field.zero, to_float)


def mpmath_arithmetic(digits: int) -> ExactArithmetic:
    """Arbitrary-precision arithmetic for tableaus given as published decimals.

    Coefficients enter at ``digits`` significant digits (a ``Decimal`` through
    its string, a ``Fraction`` as a quotient), so 40-60 digit tables are taken
    at their full published precision and the residuals measure the tables,
    not float64.  The precision is a per-call context, so nothing global is
    changed for other tests.
    """
    ctx = mpmath.MPContext()
    ctx.dps = digits

    def convert(v: Any) -> Any:
        if isinstance(v, Fraction):
            return ctx.mpf(v.numerator) / v.denominator
        if isinstance(v, Decimal):
            return ctx.mpf(str(v))
        if isinstance(v, int):
            return ctx.mpf(v)
        return ctx.mpf(str(sp.N(v, digits + 5)))

    return ExactArithmetic(convert, ctx.mpf(1), ctx.mpf(0), float)


def tableau_in(tableau: Any, convert: Callable[[Any], Any]) -> tuple[list[list[Any]], list[Any]]:
    """``(A, b)`` of a :class:`hamrkq.methods.tableaus.ButcherTableau` converted entrywise."""
    A = [[convert(a) for a in row] for row in tableau.A_exact]
    b = [convert(x) for x in tableau.b_exact]
    return A, b
