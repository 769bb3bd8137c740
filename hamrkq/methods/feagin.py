"""Feagin's tenth- and twelfth-order Runge-Kutta methods, with their estimators.

Sources: T. Feagin, "A tenth-order Runge-Kutta method with error estimate",
Proc. IAENG Conf. on Scientific Computing (2007), and T. Feagin, "High-order
explicit Runge-Kutta methods using m-symmetry", Neural, Parallel and Scientific
Computations 20 (2012) 437-458; coefficients as 60-digit decimals in Feagin's
files ``rk108.txt`` and ``rk1210.txt`` (sce.uhcl.edu/rungekutta/), read here
from ``rkf108`` and ``rkf1210`` in ``src/rklib_variable_steps.f90`` of
J. Williams' rklib, which copies them.  Kept as :class:`decimal.Decimal`
exactly as published; stage indices below are 0-based, as in Feagin's files.

Feagin's error estimates are not full weight vectors but one difference of two
stages: ``y_10 - y_8 = h (k_1 - k_15) / 360`` and ``y_12 - y_10 = 49 h (k_1 -
k_23) / 640``.  The embedded weights are therefore the main ones with two
entries changed, ``b_1 - 1/360`` and ``b_15 + 1/360`` (both ``+-1/45``, exact)
for 10(8), and ``b_1 - 49/640`` and ``b_23 + 49/640`` (``-+17/320``) for
12(10); the tests prove they have orders 8 and 10.

The tables are in :mod:`~hamrkq.methods.feagin10` and
:mod:`~hamrkq.methods.feagin12`; this module gathers them.
"""

from hamrkq.methods.feagin10 import FEAGIN_10
from hamrkq.methods.feagin12 import FEAGIN_12

__all__ = ["FEAGIN_10", "FEAGIN_12"]
