"""The data type of every method: :class:`ButcherTableau`, and how its tables are built.

A tableau keeps its coefficients twice: exactly as published (``A_exact``,
``b_exact``, ``c_exact``, as :class:`fractions.Fraction`, SymPy expressions or
the published :class:`decimal.Decimal` digits) and as read-only float64
arrays (``A``, ``b``, ``c``) for the integrator.  :func:`matrix_from_entries`
and :func:`weights` build the tuples from the nonzero entries as printed in a
paper; :func:`decimal_matrix`, :func:`decimal_weights` and
:func:`decimal_nodes` do the same from published digits given as strings
(Verner's and Feagin's files).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from fractions import Fraction

import numpy as np
import sympy as sp

from hamrkq.errors import InputError

__all__ = [
    "ButcherTableau",
    "Coefficient",
    "decimal_matrix",
    "decimal_nodes",
    "decimal_weights",
    "matrix_from_entries",
    "weights",
]


#: One published coefficient: an exact rational, an exact SymPy expression
#: (irrational algebraic numbers), or a published decimal that is not exact.
Coefficient = Fraction | sp.Expr | Decimal

# How the fields map onto the usual drawing of an s-stage explicit tableau
# (indices 1-based in the drawing, 0-based in the arrays):
#
#   c_1 |                                 c[0]   |
#   c_2 | a_21                            c[1]   | A[1,0]
#   c_3 | a_31  a_32                      c[2]   | A[2,0]   A[2,1]
#    :  |  :           .                   :     |   :               .
#   c_s | a_s1  a_s2  ...  a_s,s-1        c[s-1] | A[s-1,0] ...  A[s-1,s-2]
#   ----+---------------------------      -------+---------------------------
#       | b_1   b_2   ...  b_s-1  b_s            | b[0]     ...  b[s-1]
#
# Stage i evaluates k_i = f(t + c_i h, y + h sum_{j<i} a_ij k_j) and the step
# is y + h sum_i b_i k_i.  Entries on and above the diagonal are zero (explicit).


def _to_float(value: Coefficient) -> float:
    """Nearest float64 to an exact or decimal coefficient."""
    if isinstance(value, (Fraction, Decimal, int)):
        return float(value)  # correctly rounded for Fraction and Decimal
    # 40 significant digits, then one rounding to float64.
    return float(sp.N(value, 40))


def _low_word(value: Coefficient) -> float:
    """``value - float(value)`` rounded to float64: what the nearest double
    leaves out.  With it a coefficient is a double-double, good to about 32
    digits (as far as the published digits go)."""
    high = _to_float(value)
    if isinstance(value, (Fraction, Decimal, int)):
        return float(Fraction(value) - Fraction(high))
    exact_high = Fraction(high)
    return float(sp.N(_sym(value) - sp.Rational(exact_high.numerator, exact_high.denominator), 40))


def _read_only(values: Sequence, convert=_to_float) -> np.ndarray:
    array = np.ascontiguousarray([convert(v) for v in values], dtype=np.float64)
    array.setflags(write=False)
    return array


def _summing_to_one(values: Sequence[Coefficient]) -> np.ndarray:
    """Weights that sum to 1 (``b``, ``b_embedded``) rounded to float64 so
    that the doubles sum to 1 exactly, as closely as doubles allow: each
    rounded to nearest, then, smallest first, moved by the exact excess of
    their sum over 1 (rounded again): a change of about that excess, 1e-17,
    to one or two of them.

    Rounded to nearest alone, the weights of a method do not sum to 1
    (DOP853's by 6.9e-17): a consistency error of the method actually run,
    which drifts an oscillator's phase by that much per unit of time, the
    same on every track, so that neither Gamma nor the rounding witness sees
    it (``rk34q8`` on the harmonic oscillator at atol 1e-13 over 50 periods:
    the quencher 0.06 of the tolerance off where its Gamma and witness read
    under 0.05, nodes of 1.058 delta; ``benchmarks/coefficient_rounding.py``:
    2.0e-13 over 3000 time units, 3.1e-15 with the sum exactly 1)."""
    high = [_to_float(v) for v in values]
    # Smallest first: a weight's ulp bounds what rounding leaves of the
    # excess, so a small weight takes it almost exactly and the others keep
    # their nearest doubles (moving Verner 6(5)'s weight of 176 first, whose
    # ulp is 2.8e-14, moved the weights by up to 1.3e-14 to make up for it).
    for i in sorted(range(len(high)), key=lambda k: abs(high[k])):
        excess = sum(Fraction(h) for h in high) - 1
        if excess == 0:
            break
        # a zero weight (a stage not in the sum) stays out; none changes sign
        if abs(high[i]) > 4 * abs(excess):
            high[i] = float(Fraction(high[i]) - excess)
    array = np.ascontiguousarray(high, dtype=np.float64)
    array.setflags(write=False)
    return array


def _low_words(values: Sequence[Coefficient], high: np.ndarray) -> np.ndarray:
    """``values - high`` rounded to float64, each exactly computed: what the
    doubles ``high`` leave out of the coefficients (double-double's low
    words, for weights moved off nearest by :func:`_summing_to_one`)."""
    low = []
    for value, h in zip(values, high, strict=True):
        exact_high = Fraction(float(h))
        if isinstance(value, (Fraction, Decimal, int)):
            low.append(float(Fraction(value) - exact_high))
        else:
            rational = sp.Rational(exact_high.numerator, exact_high.denominator)
            low.append(float(sp.N(_sym(value) - rational, 40)))
    array = np.ascontiguousarray(low, dtype=np.float64)
    array.setflags(write=False)
    return array


def _difference(x: Coefficient, y: Coefficient) -> Coefficient:
    """``x - y`` without rounding: ``Fraction`` for rationals and decimals
    (a decimal is a rational), SymPy for anything irrational."""
    if isinstance(x, (Fraction, Decimal, int)) and isinstance(y, (Fraction, Decimal, int)):
        return Fraction(x) - Fraction(y)
    return _sym(x) - _sym(y)


def _sym(value: Coefficient) -> sp.Expr:
    if isinstance(value, (Fraction, Decimal, int)):
        f = Fraction(value)
        return sp.Rational(f.numerator, f.denominator)
    return value


@dataclass(frozen=True)
class ButcherTableau:
    """An explicit Runge-Kutta method (optionally an embedded pair) as immutable, cited data.

    Parameters
    ----------
    name : str
        Short name, the key in :mod:`hamrkq.methods.registry` (and in
        :func:`get_tableau` for RK3, RK4, DOP853 and Cooper-Verner).
    order : int
        Classical order of the method (of the weights ``b``).
    stages : int
        Number of stages ``s``, counting an FSAL stage.
    reference : str
        Citation of the publication the coefficients come from, and where the
        digits were taken from.
    A_exact : tuple of tuple of Coefficient
        The ``s x s`` coupling matrix, zero on and above the diagonal.
    b_exact : tuple of Coefficient
        The ``s`` weights of the propagated solution.
    c_exact : tuple of Coefficient
        The ``s`` nodes.
    b_embedded_exact : tuple of Coefficient, optional
        The ``s`` weights of the embedded solution of an embedded pair; the
        local error estimate is ``h * sum_i (b_i - b_embedded_i) k_i``.
    embedded_order : int, optional
        Classical order of the embedded weights; required with
        ``b_embedded_exact`` and only with it.
    fsal : bool, default False
        First same as last: the last stage is evaluated at ``t + h`` on the
        propagated solution (``c_s = 1``, last row of ``A`` equal to ``b``,
        ``b_s = 0``), so it is the first stage of the next step and a step
        costs ``s - 1`` new evaluations of ``f``.

    Attributes
    ----------
    A : ndarray, shape (s, s), float64, C-contiguous, read-only
        ``A_exact`` rounded to float64, strictly lower triangular.
    b : ndarray, shape (s,), float64, C-contiguous, read-only
        ``b_exact`` rounded to float64 so that the doubles sum to exactly 1
        (each within about an ulp of nearest; :func:`_summing_to_one`).
    c : ndarray, shape (s,), float64, C-contiguous, read-only
        ``c_exact`` rounded to float64.
    b_embedded : ndarray, shape (s,), float64, read-only, or None
        ``b_embedded_exact`` rounded to float64 like ``b`` (``None``
        without one).
    A_low, b_low : ndarray, float64, C-contiguous, read-only
        What rounding to float64 left out of ``A`` and ``b``
        (``A_exact - A``, rounded): ``A + A_low`` is the coefficient as a
        double-double.  The quencher's stage sums and weights use both words,
        because the rounded coefficients satisfy the order conditions only
        to about 1e-17, and that defect is systematic: on a periodic orbit
        it makes the energy drift and the phase error grow like t^2
        (Feagin 12 on prentice2011 over [0, 2000]: 1.1e-11 with float64
        coefficients, 7e-13 with both words, ``docs/algorithm.md``).
    b_error : ndarray, shape (s,), float64, read-only, or None
        ``b - b_embedded`` computed exactly, then rounded once: the weights of
        the local error estimate (more accurate than subtracting the floats).
    exact : bool
        Whether every coefficient is exact (``False`` when some are published
        decimals, as for DOP853, Verner's and Feagin's methods).
    max_abs_a : float
        The largest ``|a_ij|``.  Large coefficients can amplify rounding
        through cancellation in the stage sums: Verner's "efficient" 8(7)
        reaches 123, and its float64 error floor is ten times the robust
        pair's (``docs/algorithm.md``).

    Raises
    ------
    InputError
        If the shapes disagree with ``stages``, ``A_exact`` has a nonzero
        entry on or above the diagonal, the embedded weights and order are not
        given together, or ``fsal`` is claimed for a tableau without that
        structure.
    """

    name: str
    order: int
    stages: int
    reference: str
    A_exact: tuple[tuple[Coefficient, ...], ...] = field(repr=False)
    b_exact: tuple[Coefficient, ...] = field(repr=False)
    c_exact: tuple[Coefficient, ...] = field(repr=False)
    b_embedded_exact: tuple[Coefficient, ...] | None = field(default=None, repr=False)
    embedded_order: int | None = None
    fsal: bool = False
    A: np.ndarray = field(init=False, repr=False, compare=False)
    b: np.ndarray = field(init=False, repr=False, compare=False)
    A_low: np.ndarray = field(init=False, repr=False, compare=False)
    b_low: np.ndarray = field(init=False, repr=False, compare=False)
    c: np.ndarray = field(init=False, repr=False, compare=False)
    b_embedded: np.ndarray | None = field(init=False, repr=False, compare=False)
    b_error: np.ndarray | None = field(init=False, repr=False, compare=False)
    exact: bool = field(init=False, repr=False, compare=False)
    max_abs_a: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        s = self.stages
        if len(self.b_exact) != s or len(self.c_exact) != s:
            raise InputError(
                f"tableau {self.name!r}: b_exact and c_exact must have {s} entries "
                f"(stages), got {len(self.b_exact)} and {len(self.c_exact)}"
            )
        if len(self.A_exact) != s or any(len(row) != s for row in self.A_exact):
            raise InputError(f"tableau {self.name!r}: A_exact must be {s} x {s}")
        for i, row in enumerate(self.A_exact):
            for j in range(i, s):
                if row[j] != 0:
                    raise InputError(
                        f"tableau {self.name!r} is not explicit: "
                        f"A_exact[{i}][{j}] = {row[j]} is on or above the diagonal"
                    )
        self._check_embedded()
        if self.fsal:
            self._check_fsal()
        A = np.ascontiguousarray(
            [[_to_float(a) for a in row] for row in self.A_exact], dtype=np.float64
        )
        A.setflags(write=False)
        # Frozen dataclass: derived fields are set once, here, and never again.
        object.__setattr__(self, "A", A)
        b = _summing_to_one(self.b_exact)
        object.__setattr__(self, "b", b)
        A_low = np.ascontiguousarray(
            [[_low_word(a) for a in row] for row in self.A_exact], dtype=np.float64
        )
        A_low.setflags(write=False)
        object.__setattr__(self, "A_low", A_low)
        object.__setattr__(self, "b_low", _low_words(self.b_exact, b))
        object.__setattr__(self, "c", _read_only(self.c_exact))
        embedded = self.b_embedded_exact
        object.__setattr__(
            self, "b_embedded", None if embedded is None else _summing_to_one(embedded)
        )
        if embedded is None:
            b_error = None
        else:
            b_error = _read_only(
                [_difference(x, y) for x, y in zip(self.b_exact, embedded, strict=True)]
            )
        object.__setattr__(self, "b_error", b_error)
        everything = (
            *self.b_exact,
            *self.c_exact,
            *(embedded or ()),
            *(a for row in self.A_exact for a in row),
        )
        object.__setattr__(self, "exact", not any(isinstance(v, Decimal) for v in everything))
        object.__setattr__(self, "max_abs_a", float(np.max(np.abs(A))))

    def _check_embedded(self) -> None:
        embedded, order = self.b_embedded_exact, self.embedded_order
        if (embedded is None) != (order is None):
            raise InputError(
                f"tableau {self.name!r}: b_embedded_exact and embedded_order go together, "
                f"got b_embedded_exact={'given' if embedded is not None else None} and "
                f"embedded_order={order!r}"
            )
        if embedded is not None and len(embedded) != self.stages:
            raise InputError(
                f"tableau {self.name!r}: b_embedded_exact must have {self.stages} entries "
                f"(stages), got {len(embedded)}"
            )

    def _check_fsal(self) -> None:
        last = self.A_exact[-1]
        if (
            self.c_exact[-1] != 1
            or self.b_exact[-1] != 0
            or any(last[j] != self.b_exact[j] for j in range(self.stages - 1))
        ):
            raise InputError(
                f"tableau {self.name!r} is not FSAL: that needs c_s = 1, b_s = 0 and the "
                "last row of A_exact equal to b_exact"
            )

    @property
    def is_pair(self) -> bool:
        """Whether the tableau carries an embedded solution."""
        return self.b_embedded_exact is not None

    @property
    def evaluations_per_step(self) -> int:
        """New evaluations of ``f`` per accepted step (``s - 1`` when FSAL)."""
        return self.stages - 1 if self.fsal else self.stages


def matrix_from_entries(
    s: int, entries: Mapping[tuple[int, int], Coefficient], *, base: int = 1
) -> tuple[tuple[Coefficient, ...], ...]:
    """An ``s x s`` tuple matrix from ``{(i, j): a_ij}``; missing entries are
    exact zeros.

    ``base`` is the index of the first stage as printed in the source: 1 for
    most papers (``a_21`` is the first coupling), 0 for Feagin's tables
    (``a_10``).
    """
    rows = [[Fraction(0)] * s for _ in range(s)]
    for (i, j), value in entries.items():
        rows[i - base][j - base] = value
    return tuple(tuple(row) for row in rows)


def weights(s: int, entries: Mapping[int, Coefficient], *, base: int = 1) -> tuple:
    """A length-``s`` tuple from ``{i: value}``; missing entries are exact zeros."""
    values = [Fraction(0)] * s
    for i, value in entries.items():
        values[i - base] = value
    return tuple(values)


def decimal_matrix(
    s: int, rows: Mapping[int, Mapping[int, str]], *, base: int = 1
) -> tuple[tuple[Coefficient, ...], ...]:
    """The coupling matrix from ``{i: {j: "a_ij"}}``, published digits kept as
    :class:`~decimal.Decimal` (``base`` as in :func:`matrix_from_entries`)."""
    return matrix_from_entries(
        s, {(i, j): Decimal(v) for i, row in rows.items() for j, v in row.items()}, base=base
    )


def decimal_weights(s: int, entries: Mapping[int, str | Coefficient], *, base: int = 1) -> tuple:
    """:func:`weights` with the entries given as strings read as :class:`~decimal.Decimal`."""
    return weights(
        s, {i: Decimal(v) if isinstance(v, str) else v for i, v in entries.items()}, base=base
    )


def decimal_nodes(values: list[str | Coefficient]) -> tuple:
    """The nodes ``c``, the entries given as strings read as :class:`~decimal.Decimal`."""
    return tuple(Decimal(v) if isinstance(v, str) else v for v in values)
