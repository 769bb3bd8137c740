"""Verner's embedded Runge-Kutta pairs 6(5), 7(6), 8(7) and 9(8).

Source: J. H. Verner, "Numerically optimal Runge-Kutta pairs with interpolants",
Numer. Algorithms 53 (2010) 383-396, and the coefficient files of "Jim Verner's
Refuge for Runge-Kutta Pairs" (https://www.sfu.ca/~jverner/), which give each
pair as 40-digit decimals.  The digits here were read from ``rkv65e``,
``rkv76e``, ``rkv87r``, ``rkv87e`` and ``rkv98e`` in
``src/rklib_variable_steps.f90`` of J. Williams' rklib, which copies those
files (named in each tableau's ``reference``), and are kept as
:class:`decimal.Decimal` exactly as published; nodes that Verner gives as
rationals are :class:`fractions.Fraction`.  The tests evaluate every order
condition on these digits in 50-digit arithmetic.

The efficient pairs 6(5), 7(6) and 9(8) are the ones SciML's OrdinaryDiffEq
calls ``Vern6``, ``Vern7``, ``Vern9`` (same nodes).  For 8(7) Verner gives an
"efficient" and a "robust" pair: the efficient one (OrdinaryDiffEq's ``Vern8``,
nodes ``0.05, 0.1065625, ...``) has coupling coefficients up to 118 in
magnitude, so rounding in its stage values is amplified about a hundredfold; the
robust one keeps every ``|a_ij|`` below 6.  :data:`VERNER_87` is the robust one;
the efficient one is kept as :data:`VERNER_87_EFFICIENT` for comparison.

In each pair ``b`` is the higher-order (propagated) formula and ``b_embedded``
the lower-order one, as Verner's "c" and "d" weights.

Each pair's table is a module of its own (:mod:`~hamrkq.methods.verner65`,
:mod:`~hamrkq.methods.verner76`, :mod:`~hamrkq.methods.verner87` with both 8(7)
pairs, :mod:`~hamrkq.methods.verner98`); this module gathers them.
"""

from hamrkq.methods.verner65 import VERNER_65
from hamrkq.methods.verner76 import VERNER_76
from hamrkq.methods.verner87 import VERNER_87, VERNER_87_EFFICIENT
from hamrkq.methods.verner98 import VERNER_98

__all__ = [
    "VERNER_65",
    "VERNER_76",
    "VERNER_87",
    "VERNER_87_EFFICIENT",
    "VERNER_98",
]
