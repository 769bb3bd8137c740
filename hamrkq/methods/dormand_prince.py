"""Dormand & Prince's RK5(4)7M pair (DOPRI5), exact rationals.

Source: J. R. Dormand and P. J. Prince, "A family of embedded Runge-Kutta
formulae", J. Comput. Appl. Math. 6 (1980) 19-26, Table 2 (RK5(4)7M); the same
rationals are in Hairer, Norsett & Wanner, *Solving ODEs I*, 2nd ed., Table
II.5.2, and in ``rkdp54`` of ``src/rklib_variable_steps.f90`` (J. Williams,
rklib), from which they were read and checked.

The pair is FSAL: its seventh stage is ``f(t + h, y_new)``, the first stage of
the next step, so an accepted step costs six evaluations of ``f``.
"""

from __future__ import annotations

from fractions import Fraction as F

from hamrkq.methods.butcher import ButcherTableau, matrix_from_entries

__all__ = ["DORMAND_PRINCE_54"]

# Stage 7's row is the 5th-order weights: the FSAL stage.
_B5 = (F(35, 384), F(0), F(500, 1113), F(125, 192), F(-2187, 6784), F(11, 84), F(0))

DORMAND_PRINCE_54 = ButcherTableau(
    name="dp54",
    order=5,
    stages=7,
    reference=(
        "J. R. Dormand and P. J. Prince, A family of embedded Runge-Kutta formulae, "
        "J. Comput. Appl. Math. 6 (1980) 19-26, RK5(4)7M; Hairer, Norsett & Wanner, "
        "Solving ODEs I, 2nd ed., Table II.5.2; digits as in rklib's rkdp54"
    ),
    A_exact=matrix_from_entries(
        7,
        {
            (2, 1): F(1, 5),
            (3, 1): F(3, 40),
            (3, 2): F(9, 40),
            (4, 1): F(44, 45),
            (4, 2): F(-56, 15),
            (4, 3): F(32, 9),
            (5, 1): F(19372, 6561),
            (5, 2): F(-25360, 2187),
            (5, 3): F(64448, 6561),
            (5, 4): F(-212, 729),
            (6, 1): F(9017, 3168),
            (6, 2): F(-355, 33),
            (6, 3): F(46732, 5247),
            (6, 4): F(49, 176),
            (6, 5): F(-5103, 18656),
            **{(7, j + 1): _B5[j] for j in range(6) if _B5[j] != 0},
        },
    ),
    b_exact=_B5,
    c_exact=(F(0), F(1, 5), F(3, 10), F(4, 5), F(8, 9), F(1), F(1)),
    b_embedded_exact=(
        F(5179, 57600),
        F(0),
        F(7571, 16695),
        F(393, 640),
        F(-92097, 339200),
        F(187, 2100),
        F(1, 40),
    ),
    embedded_order=4,
    fsal=True,
)
"""Dormand-Prince 5(4): 7 stages (6 evaluations per step, FSAL), propagates
the 5th-order solution."""
