"""DOP853's eighth-order formula and its error estimators, as published decimals.

Source: E. Hairer, S. P. Norsett and G. Wanner, *Solving Ordinary
Differential Equations I*, 2nd ed., Springer (1993), Sec. II.10, and the code
DOP853 (``dop853.f``, Dormand & Prince's 8(5,3) pair).  Hairer's published
coefficients are 30-digit decimals.  Those that are evidently rational (a
terminating decimal, or a repeating one matching a small fraction to all 30
digits: 1/3, 4/13, 127/195, 6/7, 1/27) are stored as ``Fraction``; the rest
as the published :class:`decimal.Decimal` values, which are *not* exact: the
method's true coefficients lie in ``Q(sqrt 6)`` (for instance ``c2 = (12 - 2
sqrt 6)/135``, ``c4 = (6 - sqrt 6)/30``) and the decimals satisfy the order
conditions to about 1e-29.
"""

from __future__ import annotations

from decimal import Decimal, localcontext
from fractions import Fraction

from hamrkq.methods.butcher import ButcherTableau, Coefficient, matrix_from_entries

__all__ = ["DOP853_BHH3", "DOP853_PAIR", "DOP853_RK8"]


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
    A_exact=matrix_from_entries(
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
            (6, 1): Fraction("1/27"),  # published 3.7037037037037037037037037037e-2
            (6, 4): _D("1.70828608729473871279604482173e-1"),
            (6, 5): _D("1.25467687566822425016691814123e-1"),
            (7, 1): Fraction("19/512"),  # published 3.7109375e-2
            (7, 4): _D("1.70252211019544039314978060272e-1"),
            (7, 5): _D("6.02165389804559606850219397283e-2"),
            (7, 6): Fraction("-9/512"),  # published -1.7578125e-2
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
        Fraction("0"),
        _D("0.526001519587677318785587544488e-1"),  # (12 - 2 sqrt 6)/135
        _D("0.789002279381515978178381316732e-1"),  # (6 - sqrt 6)/45
        _D("0.118350341907227396726757197510"),  # (6 - sqrt 6)/30
        _D("0.281649658092772603273242802490"),  # (6 + sqrt 6)/30
        Fraction("1/3"),
        Fraction("1/4"),
        Fraction("4/13"),
        Fraction("127/195"),
        Fraction("3/5"),
        Fraction("6/7"),
        Fraction("1"),
    ),
)
"""The 12-stage eighth-order formula of DOP853 (its 13th stage and embedded
5th/3rd-order error estimators are not part of this tableau; they are in
:data:`DOP853_PAIR` and :data:`DOP853_BHH3`)."""


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
