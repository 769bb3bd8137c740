"""Butcher tableaus of the explicit Runge-Kutta methods RKQ uses, as cited data.

Each tableau keeps its coefficients twice: exactly as published
(``A_exact``, ``b_exact``, ``c_exact``) and as read-only float64 arrays
(``A``, ``b``, ``c``) for the integrator.  The order-condition tests in
``tests/test_tableaus.py`` check the exact form against every rooted-tree
condition, and the float form by measured convergence order.

Exact forms, by tableau:

- :data:`RK3_KUTTA`, :data:`RK4_CLASSIC`: :class:`fractions.Fraction`.
- :data:`COOPER_VERNER_RK8`: ``Fraction`` where rational, SymPy expressions in
  ``sqrt(21)`` otherwise (the nodes are the Lobatto points ``(7 +- sqrt 21)/14``).
- :data:`DOP853_RK8`: Hairer's published coefficients are 30-digit decimals.
  Those that are evidently rational (a terminating decimal, or a repeating one
  matching a small fraction to all 30 digits: 1/3, 4/13, 127/195, 6/7, 1/27)
  are stored as ``Fraction``; the rest as the published :class:`decimal.Decimal`
  values, which are *not* exact: the method's true coefficients lie in
  ``Q(sqrt 6)`` (for instance ``c2 = (12 - 2 sqrt 6)/135``, ``c4 = (6 - sqrt
  6)/30``) and the decimals satisfy the order conditions to about 1e-29.

RK3 and RK4 share their first two stages: both have ``c1 = 0`` and ``c2 = 1/2``
with ``a21 = 1/2``, so ``k1`` and ``k2`` can be computed once.  Kutta's third
stage (``c = 1``, ``a31 = -1``, ``a32 = 2``) differs from RK4's stages 3 and 4,
so one step of both methods together costs 5 evaluations of ``f``, not 7.
:data:`RK34_PAIR` is that observation as one 5-stage tableau with an embedded
solution, the form every embedded pair of the RKQ family takes (see
:mod:`hamrkq.methods.registry`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal, localcontext
from fractions import Fraction
from types import MappingProxyType

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError, OptionError

__all__ = [
    "COOPER_VERNER_RK8",
    "DOP853_BHH3",
    "DOP853_PAIR",
    "DOP853_RK8",
    "RK3_KUTTA",
    "RK4_CLASSIC",
    "RK34_PAIR",
    "TABLEAUS",
    "ButcherTableau",
    "Coefficient",
    "get_tableau",
    "matrix_from_entries",
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


def _read_only(values: Sequence) -> np.ndarray:
    array = np.ascontiguousarray([_to_float(v) for v in values], dtype=np.float64)
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
        ``b_exact`` rounded to float64.
    c : ndarray, shape (s,), float64, C-contiguous, read-only
        ``c_exact`` rounded to float64.
    b_embedded : ndarray, shape (s,), float64, read-only, or None
        ``b_embedded_exact`` rounded to float64 (``None`` without one).
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
        object.__setattr__(self, "b", _read_only(self.b_exact))
        object.__setattr__(self, "c", _read_only(self.c_exact))
        embedded = self.b_embedded_exact
        object.__setattr__(self, "b_embedded", None if embedded is None else _read_only(embedded))
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


def _F(text: str) -> Fraction:
    return Fraction(text)


def _square(s: int, entries: Mapping[tuple[int, int], Coefficient]) -> tuple:
    """:func:`matrix_from_entries` with 1-based indices, as printed in the papers."""
    return matrix_from_entries(s, entries)


RK3_KUTTA = ButcherTableau(
    name="rk3",
    order=3,
    stages=3,
    reference=(
        "W. Kutta, Beitrag zur naeherungsweisen Integration totaler "
        "Differentialgleichungen, Z. Math. Phys. 46 (1901) 435-453; "
        "Hairer, Norsett & Wanner, Solving ODEs I, 2nd ed., Table II.1.1"
    ),
    A_exact=_square(3, {(2, 1): _F("1/2"), (3, 1): _F("-1"), (3, 2): _F("2")}),
    b_exact=(_F("1/6"), _F("2/3"), _F("1/6")),
    c_exact=(_F("0"), _F("1/2"), _F("1")),
)
"""Kutta's third-order method (3 stages); its ``k1``, ``k2`` are RK4's."""

RK4_CLASSIC = ButcherTableau(
    name="rk4",
    order=4,
    stages=4,
    reference=(
        "W. Kutta, Z. Math. Phys. 46 (1901) 435-453; "
        "Hairer, Norsett & Wanner, Solving ODEs I, 2nd ed., Table II.1.2 (left)"
    ),
    A_exact=_square(4, {(2, 1): _F("1/2"), (3, 2): _F("1/2"), (4, 3): _F("1")}),
    b_exact=(_F("1/6"), _F("1/3"), _F("1/3"), _F("1/6")),
    c_exact=(_F("0"), _F("1/2"), _F("1/2"), _F("1")),
)
"""The classical fourth-order Runge-Kutta method (4 stages)."""

_s21 = sp.sqrt(21)

COOPER_VERNER_RK8 = ButcherTableau(
    name="cooper_verner",
    order=8,
    stages=11,
    reference=(
        "G. J. Cooper and J. H. Verner, Some explicit Runge-Kutta methods of "
        "high order, SIAM J. Numer. Anal. 9 (1972) 389-405; "
        "J. C. Butcher, Numerical Methods for ODEs, 3rd ed. (2016), Sec. 33"
    ),
    A_exact=_square(
        11,
        {
            (2, 1): _F("1/2"),
            (3, 1): _F("1/4"),
            (3, 2): _F("1/4"),
            (4, 1): _F("1/7"),
            (4, 2): -(7 + 3 * _s21) / 98,
            (4, 3): (21 + 5 * _s21) / 49,
            (5, 1): (11 + _s21) / 84,
            (5, 3): (18 + 4 * _s21) / 63,
            (5, 4): (21 - _s21) / 252,
            (6, 1): (5 + _s21) / 48,
            (6, 3): (9 + _s21) / 36,
            (6, 4): (-231 + 14 * _s21) / 360,
            (6, 5): (63 - 7 * _s21) / 80,
            (7, 1): (10 - _s21) / 42,
            (7, 3): (-432 + 92 * _s21) / 315,
            (7, 4): (633 - 145 * _s21) / 90,
            (7, 5): (-504 + 115 * _s21) / 70,
            (7, 6): (63 - 13 * _s21) / 35,
            (8, 1): _F("1/14"),
            (8, 5): (14 - 3 * _s21) / 126,
            (8, 6): (13 - 3 * _s21) / 63,
            (8, 7): _F("1/9"),
            (9, 1): _F("1/32"),
            (9, 5): (91 - 21 * _s21) / 576,
            (9, 6): _F("11/72"),
            (9, 7): -(385 + 75 * _s21) / 1152,
            (9, 8): (63 + 13 * _s21) / 128,
            (10, 1): _F("1/14"),
            (10, 5): _F("1/9"),
            (10, 6): -(733 + 147 * _s21) / 2205,
            (10, 7): (515 + 111 * _s21) / 504,
            (10, 8): -(51 + 11 * _s21) / 56,
            (10, 9): (132 + 28 * _s21) / 245,
            (11, 5): (-42 + 7 * _s21) / 18,
            (11, 6): (-18 + 28 * _s21) / 45,
            (11, 7): -(273 + 53 * _s21) / 72,
            (11, 8): (301 + 53 * _s21) / 72,
            (11, 9): (28 - 28 * _s21) / 45,
            (11, 10): (49 - 7 * _s21) / 18,
        },
    ),
    b_exact=(
        _F("1/20"),
        *(Fraction(0),) * 6,
        _F("49/180"),
        _F("16/45"),
        _F("49/180"),
        _F("1/20"),
    ),
    c_exact=(
        _F("0"),
        _F("1/2"),
        _F("1/2"),
        (7 + _s21) / 14,
        (7 + _s21) / 14,
        _F("1/2"),
        (7 - _s21) / 14,
        (7 - _s21) / 14,
        _F("1/2"),
        (7 + _s21) / 14,
        _F("1"),
    ),
)
"""Cooper & Verner's 11-stage eighth-order method (weights: Lobatto quadrature
on 5 points)."""


def _D(text: str) -> Decimal:
    return Decimal(text)


DOP853_RK8 = ButcherTableau(
    name="dop853",
    order=8,
    stages=12,
    reference=(
        "E. Hairer, S. P. Norsett and G. Wanner, Solving Ordinary Differential "
        "Equations I, 2nd ed., Springer (1993), Sec. II.10 and the code DOP853 "
        "(Dormand & Prince's 8(5,3) pair); coefficients as in dop853.f"
    ),
    A_exact=_square(
        12,
        {
            (2, 1): _D("5.26001519587677318785587544488e-2"),
            (3, 1): _D("1.97250569845378994544595329183e-2"),
            (3, 2): _D("5.91751709536136983633785987549e-2"),
            (4, 1): _D("2.95875854768068491816892993775e-2"),
            (4, 3): _D("8.87627564304205475450678981324e-2"),
            (5, 1): _D("2.41365134159266685502369798665e-1"),
            (5, 3): _D("-8.84549479328286085344864962717e-1"),
            (5, 4): _D("9.24834003261792003115737966543e-1"),
            (6, 1): _F("1/27"),  # published 3.7037037037037037037037037037e-2
            (6, 4): _D("1.70828608729473871279604482173e-1"),
            (6, 5): _D("1.25467687566822425016691814123e-1"),
            (7, 1): _F("19/512"),  # published 3.7109375e-2
            (7, 4): _D("1.70252211019544039314978060272e-1"),
            (7, 5): _D("6.02165389804559606850219397283e-2"),
            (7, 6): _F("-9/512"),  # published -1.7578125e-2
            (8, 1): _D("3.70920001185047927108779319836e-2"),
            (8, 4): _D("1.70383925712239993810214054705e-1"),
            (8, 5): _D("1.07262030446373284651809199168e-1"),
            (8, 6): _D("-1.53194377486244017527936158236e-2"),
            (8, 7): _D("8.27378916381402288758473766002e-3"),
            (9, 1): _D("6.24110958716075717114429577812e-1"),
            (9, 4): _D("-3.36089262944694129406857109825"),
            (9, 5): _D("-8.68219346841726006818189891453e-1"),
            (9, 6): _D("2.75920996994467083049415600797e1"),
            (9, 7): _D("2.01540675504778934086186788979e1"),
            (9, 8): _D("-4.34898841810699588477366255144e1"),
            (10, 1): _D("4.77662536438264365890433908527e-1"),
            (10, 4): _D("-2.48811461997166764192642586468"),
            (10, 5): _D("-5.90290826836842996371446475743e-1"),
            (10, 6): _D("2.12300514481811942347288949897e1"),
            (10, 7): _D("1.52792336328824235832596922938e1"),
            (10, 8): _D("-3.32882109689848629194453265587e1"),
            (10, 9): _D("-2.03312017085086261358222928593e-2"),
            (11, 1): _D("-9.3714243008598732571704021658e-1"),
            (11, 4): _D("5.18637242884406370830023853209"),
            (11, 5): _D("1.09143734899672957818500254654"),
            (11, 6): _D("-8.14978701074692612513997267357"),
            (11, 7): _D("-1.85200656599969598641566180701e1"),
            (11, 8): _D("2.27394870993505042818970056734e1"),
            (11, 9): _D("2.49360555267965238987089396762"),
            (11, 10): _D("-3.0467644718982195003823669022"),
            (12, 1): _D("2.27331014751653820792359768449"),
            (12, 4): _D("-1.05344954667372501984066689879e1"),
            (12, 5): _D("-2.00087205822486249909675718444"),
            (12, 6): _D("-1.79589318631187989172765950534e1"),
            (12, 7): _D("2.79488845294199600508499808837e1"),
            (12, 8): _D("-2.85899827713502369474065508674"),
            (12, 9): _D("-8.87285693353062954433549289258"),
            (12, 10): _D("1.23605671757943030647266201528e1"),
            (12, 11): _D("6.43392746015763530355970484046e-1"),
        },
    ),
    b_exact=(
        _D("5.42937341165687622380535766363e-2"),
        *(Fraction(0),) * 4,
        _D("4.45031289275240888144113950566"),
        _D("1.89151789931450038304281599044"),
        _D("-5.8012039600105847814672114227"),
        _D("3.1116436695781989440891606237e-1"),
        _D("-1.52160949662516078556178806805e-1"),
        _D("2.01365400804030348374776537501e-1"),
        _D("4.47106157277725905176885569043e-2"),
    ),
    c_exact=(
        _F("0"),
        _D("0.526001519587677318785587544488e-1"),  # (12 - 2 sqrt 6)/135
        _D("0.789002279381515978178381316732e-1"),  # (6 - sqrt 6)/45
        _D("0.118350341907227396726757197510"),  # (6 - sqrt 6)/30
        _D("0.281649658092772603273242802490"),  # (6 + sqrt 6)/30
        _F("1/3"),
        _F("1/4"),
        _F("4/13"),
        _F("127/195"),
        _F("3/5"),
        _F("6/7"),
        _F("1"),
    ),
)
"""The 12-stage eighth-order formula of DOP853 (its 13th stage and embedded
5th/3rd-order error estimators are not part of this tableau; they are in
:data:`DOP853_PAIR` and :data:`DOP853_BHH3`)."""

RK34_PAIR = ButcherTableau(
    name="rk34",
    order=4,
    stages=5,
    reference=(
        "Prentice's RK3(4) of the RKQ algorithm (J. S. C. Prentice, arXiv:1111.6996, "
        "2011): Kutta's RK3 and the classical RK4 (W. Kutta, Z. Math. Phys. 46 (1901) "
        "435-453) as one tableau; stages 1-4 are RK4's, stage 5 is Kutta's third stage"
    ),
    A_exact=_square(
        5,
        {
            (2, 1): _F("1/2"),
            (3, 2): _F("1/2"),
            (4, 3): _F("1"),
            (5, 1): _F("-1"),
            (5, 2): _F("2"),
        },
    ),
    b_exact=(_F("1/6"), _F("1/3"), _F("1/3"), _F("1/6"), _F("0")),
    c_exact=(_F("0"), _F("1/2"), _F("1/2"), _F("1"), _F("1")),
    b_embedded_exact=(_F("1/6"), _F("2/3"), _F("0"), _F("0"), _F("1/6")),
    embedded_order=3,
)
"""The paper's RK3(4) pair as one 5-stage tableau: ``b`` are RK4's weights
(the propagated, locally extrapolated solution), ``b_embedded`` Kutta's RK3
(whose third stage, ``c = 1``, ``a = (-1, 2)``, is stage 5 here).  One step of
both costs 5 evaluations of ``f``, as :data:`RK3_KUTTA` and :data:`RK4_CLASSIC`
evaluated separately with ``k1``, ``k2`` shared."""

# DOP853's error estimators, from dop853.f (Hairer & Wanner; the same
# 28-30 digit decimals as the tableau): the 5th-order estimate is
# h sum_i er_i k_i = y_8 - y_5 over the 12 stages, and the 3rd-order one is
# h (sum_i b_i k_i - bhh_1 k_1 - bhh_2 k_9 - bhh_3 k_12) = y_8 - y_3.
_DOP853_ER = {
    1: "0.1312004499419488073250102996E-01",
    6: "-0.1225156446376204440720569753E+01",
    7: "-0.4957589496572501915214079952E+00",
    8: "0.1664377182454986536961530415E+01",
    9: "-0.3503288487499736816886487290E+00",
    10: "0.3341791187130174790297318841E+00",
    11: "0.8192320648511571246570742613E-01",
    12: "-0.2235530786388629525884427845E-01",
}


def _minus_er(i: int, b: Coefficient) -> Coefficient:
    """``b_i - er_i`` exactly (the published decimals have at most 30 digits)."""
    if i not in _DOP853_ER:
        return b
    with localcontext() as ctx:
        ctx.prec = 80  # enough for every digit of both: the difference is exact
        return b - Decimal(_DOP853_ER[i])  # every such b_i is a published Decimal


DOP853_PAIR = ButcherTableau(
    name="dop853_85",
    order=8,
    stages=12,
    reference=(
        "E. Hairer, S. P. Norsett and G. Wanner, Solving Ordinary Differential "
        "Equations I, 2nd ed., Springer (1993), Sec. II.10; the code DOP853 "
        "(dop853.f): its 12-stage formula with the 5th-order estimator er_i"
    ),
    A_exact=DOP853_RK8.A_exact,
    b_exact=DOP853_RK8.b_exact,
    c_exact=DOP853_RK8.c_exact,
    b_embedded_exact=tuple(_minus_er(i + 1, b) for i, b in enumerate(DOP853_RK8.b_exact)),
    embedded_order=5,
)
"""DOP853's 8th-order formula with its 5th-order embedded solution
``b - er`` (so ``b_error`` is Hairer's ``er``).  Not in the RKQ registry's
pairs: DOP853 serves as a quencher, which needs no estimator."""

#: The weights of DOP853's 3rd-order embedded solution (``bhh`` in dop853.f),
#: on stages 1, 9 and 12 of :data:`DOP853_RK8`.
DOP853_BHH3: tuple[Coefficient, ...] = tuple(
    Decimal(
        {
            1: "0.244094488188976377952755905512E+00",
            9: "0.733846688281611857341361741547E+00",
            12: "0.220588235294117647058823529412E-01",
        }.get(i, "0")
    )
    for i in range(1, 13)
)

#: Every tableau by name (read-only).
TABLEAUS: Mapping[str, ButcherTableau] = MappingProxyType(
    {t.name: t for t in (RK3_KUTTA, RK4_CLASSIC, DOP853_RK8, COOPER_VERNER_RK8)}
)


def get_tableau(name: str) -> ButcherTableau:
    """Look up a tableau by name.

    Parameters
    ----------
    name : str
        One of ``"rk3"``, ``"rk4"``, ``"dop853"``, ``"cooper_verner"``.

    Returns
    -------
    ButcherTableau

    Raises
    ------
    OptionError
        If ``name`` is not a known tableau; the message lists the valid names.
    InputTypeError
        If ``name`` is not a string.
    """
    if not isinstance(name, str):
        raise InputTypeError(f"tableau name must be a str, got {type(name).__name__}: {name!r}")
    try:
        return TABLEAUS[name]
    except KeyError:
        valid = ", ".join(repr(k) for k in TABLEAUS)
        raise OptionError(f"unknown tableau {name!r}; valid names: {valid}") from None
