"""Butcher tableaus of the explicit Runge-Kutta methods RKQ uses, as cited data.

Each tableau (a :class:`~hamrkq.methods.butcher.ButcherTableau`) keeps its
coefficients twice: exactly as published (``A_exact``, ``b_exact``,
``c_exact``) and as read-only float64 arrays (``A``, ``b``, ``c``) for the
integrator.  The order-condition tests in
``tests/test_tableaus.py`` check the exact form against every rooted-tree
condition, and the float form by measured convergence order.

Exact forms, by tableau:

- :data:`RK3_KUTTA`, :data:`RK4_CLASSIC`: :class:`fractions.Fraction`.
- :data:`COOPER_VERNER_RK8`: ``Fraction`` where rational, SymPy expressions in
  ``sqrt(21)`` otherwise (the nodes are the Lobatto points ``(7 +- sqrt 21)/14``).
- :data:`DOP853_RK8`, :data:`DOP853_PAIR`, :data:`DOP853_BHH3`: Hairer's
  published 30-digit decimals, defined in :mod:`hamrkq.methods.dop853` (which
  says which are stored as ``Fraction``) and importable from here.

RK3 and RK4 share their first two stages: both have ``c1 = 0`` and ``c2 = 1/2``
with ``a21 = 1/2``, so ``k1`` and ``k2`` can be computed once.  Kutta's third
stage (``c = 1``, ``a31 = -1``, ``a32 = 2``) differs from RK4's stages 3 and 4,
so one step of both methods together costs 5 evaluations of ``f``, not 7.
:data:`RK34_PAIR` is that observation as one 5-stage tableau with an embedded
solution, the form every embedded pair of the RKQ family takes (see
:mod:`hamrkq.methods.registry`).
"""

from __future__ import annotations

from collections.abc import Mapping
from fractions import Fraction
from types import MappingProxyType

import sympy as sp

from hamrkq.errors import InputTypeError, OptionError
from hamrkq.methods.butcher import ButcherTableau, Coefficient, matrix_from_entries
from hamrkq.methods.dop853 import DOP853_BHH3, DOP853_PAIR, DOP853_RK8

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
