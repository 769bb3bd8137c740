"""Tests of the RKQ family's embedded pairs and quenchers: the digits prove their orders.

For every new tableau (RK3(4) as one tableau, Dormand-Prince 5(4), Verner
6(5), 7(6), 8(7) robust and efficient, 9(8), Feagin 10(8) and 12(10)):

1. structure: explicit, row sums equal the nodes, FSAL where claimed, float
   arrays C-contiguous, read-only and the correctly rounded exact values;
2. every rooted-tree order condition through the claimed order, for the main
   and the embedded weights: exactly (``Fraction``) for rational tableaus, in
   50-digit mpmath for the published 40-60 digit decimals; and some condition
   of the next order fails, so the order is not higher than claimed;
3. the order measured by fixed-step integration of problems with known
   solutions, in 50-digit arithmetic so that rounding never hides it (and in
   float64 for the low orders, through the float arrays the kernel uses).
"""

from __future__ import annotations

import dataclasses
from decimal import Decimal
from fractions import Fraction

import mpmath
import numpy as np
import pytest
import sympy as sp

from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.methods import registry
from hamrkq.methods.dormand_prince import DORMAND_PRINCE_54
from hamrkq.methods.feagin import FEAGIN_10, FEAGIN_12
from hamrkq.methods.registry import (
    ALL_TABLEAUS,
    PAIRS,
    QUENCHERS,
    FamilyMember,
    family_members,
    get_member,
    get_pair,
    get_quencher,
    kernel_arrays,
)
from hamrkq.methods.tableaus import (
    COOPER_VERNER_RK8,
    DOP853_BHH3,
    DOP853_PAIR,
    DOP853_RK8,
    RK3_KUTTA,
    RK4_CLASSIC,
    RK34_PAIR,
    ButcherTableau,
    get_tableau,
)
from hamrkq.methods.verner import (
    VERNER_65,
    VERNER_76,
    VERNER_87,
    VERNER_87_EFFICIENT,
    VERNER_98,
)

try:  # tests/ on sys.path (pytest's default rootdir-less import mode)
    import order_conditions as oc
except ImportError:  # tests/ imported as a package
    from tests import order_conditions as oc

NEW = [
    RK34_PAIR,
    DORMAND_PRINCE_54,
    VERNER_65,
    VERNER_76,
    VERNER_87,
    VERNER_87_EFFICIENT,
    VERNER_98,
    FEAGIN_10,
    FEAGIN_12,
]
IDS = [t.name for t in NEW]

DIGITS = 50
# Verner's tables have 40 significant digits, Feagin's 60.  Taken at those
# digits, the worst residual over all conditions is 3.1e-35 (Verner 6(5),
# whose coefficients reach 208) and 1.4e-50 for Feagin 12 (limited by the 50
# working digits); 1e-30 leaves room and is 14 orders below float64.
DECIMAL_TOL = 1e-30
# A condition of the next order "fails" when it misses by more than this: the
# smallest such miss measured is 4e-7 (Verner's efficient 8(7)), 23 orders of
# magnitude above the residuals of the conditions that hold.
FAIL_MARGIN = 1e-10


def _arithmetic(tableau: ButcherTableau) -> oc.ExactArithmetic:
    return oc.exact_field([]) if tableau.exact else oc.mpmath_arithmetic(DIGITS)


def _weights_of(tableau: ButcherTableau, which: str):
    if which == "main":
        return tableau.b_exact, tableau.order
    return tableau.b_embedded_exact, tableau.embedded_order


def _small(ar: oc.ExactArithmetic, value, exact: bool) -> bool:
    return value == ar.zero if exact else abs(ar.to_float(value)) < DECIMAL_TOL


WEIGHTS = [(t, w) for t in NEW for w in ("main", "embedded")]
WEIGHT_IDS = [f"{t.name}-{w}" for t, w in WEIGHTS]


# ------------------------------------------------------------------ structure


@pytest.mark.parametrize("tableau", NEW, ids=IDS)
def test_shapes_dtypes_and_explicitness(tableau):
    s = tableau.stages
    assert tableau.A.shape == (s, s)
    for array in (tableau.b, tableau.c, tableau.b_embedded, tableau.b_error):
        assert array.shape == (s,)
    for array in (tableau.A, tableau.b, tableau.c, tableau.b_embedded, tableau.b_error):
        assert array.dtype == np.float64
        assert array.flags.c_contiguous
        assert not array.flags.writeable
    assert all(tableau.A_exact[i][j] == 0 for i in range(s) for j in range(i, s))
    assert tableau.c_exact[0] == 0
    assert tableau.is_pair and tableau.embedded_order < tableau.order


@pytest.mark.parametrize("tableau", NEW, ids=IDS)
def test_row_sums_equal_nodes(tableau):
    ar = _arithmetic(tableau)
    for row, ci in zip(tableau.A_exact, tableau.c_exact, strict=True):
        diff = sum((ar.convert(a) for a in row), ar.zero) - ar.convert(ci)
        assert _small(ar, diff, tableau.exact), (tableau.name, ci)


@pytest.mark.parametrize("tableau", NEW, ids=IDS)
def test_fsal_structure_where_claimed(tableau):
    s = tableau.stages
    last_row_is_b = all(tableau.A_exact[s - 1][j] == tableau.b_exact[j] for j in range(s - 1))
    looks_fsal = tableau.c_exact[-1] == 1 and tableau.b_exact[-1] == 0 and last_row_is_b
    assert tableau.fsal == looks_fsal
    expected = {"rk34": False, "dp54": True, "vern65": True}.get(tableau.name, False)
    assert tableau.fsal is expected
    assert tableau.evaluations_per_step == s - tableau.fsal


def test_fsal_claim_is_validated():
    half, zero, one = Fraction(1, 2), Fraction(0), Fraction(1)
    A = ((zero, zero), (one, zero))
    # Last row equals b = (1, 0), c_2 = 1: FSAL (forward Euler with its next stage).
    euler = ButcherTableau("euler", 1, 2, "Euler", A, (one, zero), (zero, one), fsal=True)
    assert euler.evaluations_per_step == 1
    with pytest.raises(InputError, match="not FSAL"):
        ButcherTableau("bad", 1, 2, "none", A, (half, half), (zero, one), fsal=True)


def test_embedded_weights_and_order_go_together():
    zero, one = Fraction(0), Fraction(1)
    A = ((zero,),)
    with pytest.raises(InputError, match="go together"):
        ButcherTableau("bad", 1, 1, "none", A, (one,), (zero,), b_embedded_exact=(one,))
    with pytest.raises(InputError, match="go together"):
        ButcherTableau("bad", 1, 1, "none", A, (one,), (zero,), embedded_order=1)
    with pytest.raises(InputError, match="1 entries"):
        ButcherTableau(
            "bad", 1, 1, "none", A, (one,), (zero,), b_embedded_exact=(one, one), embedded_order=1
        )
    plain = ButcherTableau("euler", 1, 1, "Euler", A, (one,), (zero,))
    assert plain.b_embedded is None and plain.b_error is None and not plain.is_pair


def _mp(value, ctx) -> mpmath.mpf:
    if isinstance(value, Fraction):
        return ctx.mpf(value.numerator) / value.denominator
    return ctx.mpf(str(value))


@pytest.mark.parametrize("tableau", NEW, ids=IDS)
def test_floats_are_the_correctly_rounded_coefficients(tableau):
    # Reference: the published value in 80-digit binary, rounded once more to
    # float64 (a double rounding could differ only on a tie pattern of ~200
    # bits).  The error weights are rounded from the exact difference.
    ctx = mpmath.MPContext()
    ctx.dps = 80
    pairs = [
        ([a for row in tableau.A_exact for a in row], tableau.A.ravel()),
        (tableau.c_exact, tableau.c),
    ]
    for exact, array in pairs:
        np.testing.assert_array_equal(array, [float(_mp(v, ctx)) for v in exact])
    # The weights are moved off nearest to sum to exactly 1 as doubles
    # (butcher._summing_to_one): within a few ulps, and only where nearest
    # does not sum to 1 already.
    weights = ((tableau.b_exact, tableau.b), (tableau.b_embedded_exact, tableau.b_embedded))
    for exact, array in weights:
        nearest = np.array([float(_mp(v, ctx)) for v in exact])
        assert sum(Fraction(float(x)) for x in array) == 1
        if sum(Fraction(float(x)) for x in nearest) == 1:
            np.testing.assert_array_equal(array, nearest)
        else:
            # one weight moved by the excess (Verner 6(5)'s nearest doubles
            # sum to 1 - 1.4e-14, its weights reaching 176)
            assert np.count_nonzero(array != nearest) == 1
            assert float(abs(sum(Fraction(float(x)) for x in nearest) - 1)) < 2e-14
    error = [
        float(_mp(x, ctx) - _mp(y, ctx))
        for x, y in zip(tableau.b_exact, tableau.b_embedded_exact, strict=True)
    ]
    np.testing.assert_array_equal(tableau.b_error, error)


@pytest.mark.parametrize("tableau", NEW, ids=IDS)
def test_frozen(tableau):
    with pytest.raises(dataclasses.FrozenInstanceError):
        tableau.fsal = True
    with pytest.raises(dataclasses.FrozenInstanceError):
        tableau.b_embedded = np.zeros(tableau.stages)
    with pytest.raises(ValueError, match="read-only"):
        tableau.b_embedded[0] = 1.0
    hash(tableau)


def test_exact_flag_and_decimal_storage():
    assert RK34_PAIR.exact and DORMAND_PRINCE_54.exact
    for t in (VERNER_65, VERNER_76, VERNER_87, VERNER_87_EFFICIENT, VERNER_98, FEAGIN_10):
        assert not t.exact
        # Published digits are stored as Decimal, never as Python floats.
        values = [*t.b_exact, *t.c_exact, *(a for row in t.A_exact for a in row)]
        assert not any(isinstance(v, float) for v in values)
        assert any(isinstance(v, Decimal) and len(v.as_tuple().digits) >= 38 for v in values)


def test_metadata():
    table = {t.name: (t.order, t.embedded_order, t.stages) for t in NEW}
    assert table == {
        "rk34": (4, 3, 5),
        "dp54": (5, 4, 7),
        "vern65": (6, 5, 9),
        "vern76": (7, 6, 10),
        "vern87": (8, 7, 13),
        "vern87e": (8, 7, 13),
        "vern98": (9, 8, 16),
        "feagin10": (10, 8, 17),
        "feagin12": (12, 10, 25),
    }
    for t in NEW:
        assert t.reference and len(t.reference) > 60


def test_largest_coupling_coefficients():
    # Recorded for docs/algorithm.md; the robust 8(7) is chosen over the
    # efficient one for exactly this number.
    measured = {t.name: round(t.max_abs_a, 2) for t in NEW}
    assert measured == {
        "rk34": 2.0,
        "dp54": 11.6,
        "vern65": 207.95,
        "vern76": 187.33,
        "vern87": 5.92,
        "vern87e": 123.38,
        "vern98": 35.89,
        "feagin10": 5.78,
        "feagin12": 12.37,
    }
    for t in NEW:
        exact_max = max(abs(Fraction(a)) for row in t.A_exact for a in row)
        assert t.max_abs_a == float(exact_max)


# ---------------------------------------------------------- order conditions


@pytest.mark.parametrize(("tableau", "which"), WEIGHTS, ids=WEIGHT_IDS)
def test_every_order_condition_holds(tableau, which):
    weights, order = _weights_of(tableau, which)
    ar = _arithmetic(tableau)
    A, _ = oc.tableau_in(tableau, ar.convert)
    b = [ar.convert(x) for x in weights]
    trees = [t for k in range(1, order + 1) for t in oc.rooted_trees(k)]
    vectors = oc.StageVectors(A, ar.one)
    failed = []
    for tree in trees:
        residual = vectors.weight(b, tree) - ar.one / oc.density(tree)
        if not _small(ar, residual, tableau.exact):
            failed.append((tree, ar.to_float(residual)))
    assert failed == [], f"{tableau.name} {which}: {len(failed)} of {len(trees)} fail"
    # Conditions through order p (cumulative OEIS A000081).
    through = {3: 4, 4: 8, 5: 17, 6: 37, 7: 85, 8: 200, 9: 486, 10: 1205, 12: 7813}
    assert len(trees) == through[order]


def test_a_wrong_25th_digit_is_caught():
    # The 50-digit check has teeth at the level of the published digits: one
    # coupling of Verner's robust 8(7) moved by 1e-25 breaks conditions by
    # ~8e-27, far above DECIMAL_TOL (the true table's worst is 1.9e-40).
    ar = oc.mpmath_arithmetic(DIGITS)
    A, b = oc.tableau_in(VERNER_87, ar.convert)
    assert max(abs(ar.to_float(r)) for _, r in oc.residuals(A, b, 8, ar.one)) < 1e-38
    A[9][4] += ar.convert(Decimal("1e-25"))
    worst = max(abs(ar.to_float(r)) for _, r in oc.residuals(A, b, 8, ar.one))
    assert 1e-28 < worst < 1e-25


@pytest.mark.parametrize(("tableau", "which"), WEIGHTS, ids=WEIGHT_IDS)
def test_next_order_is_not_reached(tableau, which):
    weights, order = _weights_of(tableau, which)
    ar = _arithmetic(tableau)
    A, _ = oc.tableau_in(tableau, ar.convert)
    b = [ar.convert(x) for x in weights]
    vectors = oc.StageVectors(A, ar.one)
    # Stop at the first tree that fails clearly: order 13 has 12486 trees,
    # and Feagin 12's symmetric weights satisfy many of them.
    for tree in oc.rooted_trees(order + 1):
        residual = vectors.weight(b, tree) - ar.one / oc.density(tree)
        if abs(ar.to_float(residual)) > FAIL_MARGIN:
            return
    pytest.fail(f"{tableau.name} {which} satisfies every order-{order + 1} condition")


def test_rooted_tree_counts_through_order_13():
    # OEIS A000081; 7813 conditions through order 12.
    counts = [len(oc.rooted_trees(n)) for n in range(1, 14)]
    assert counts == [1, 1, 2, 4, 9, 20, 48, 115, 286, 719, 1842, 4766, 12486]
    assert sum(counts[:12]) == 7813


def test_feagin_embedded_weights_are_his_two_stage_estimates():
    # y_10 - y_8 = h (k_1 - k_15) / 360 and y_12 - y_10 = 49 h (k_1 - k_23) / 640.
    for tableau, stage, factor in (
        (FEAGIN_10, 15, Fraction(1, 360)),
        (FEAGIN_12, 23, Fraction(49, 640)),
    ):
        diff = [
            Fraction(x) - Fraction(y)
            for x, y in zip(tableau.b_exact, tableau.b_embedded_exact, strict=True)
        ]
        expected = [Fraction(0)] * tableau.stages
        expected[1], expected[stage] = factor, -factor
        assert diff == expected


def _max_residual(ar, A, weights, order: int) -> float:
    b = [ar.convert(x) for x in weights]
    return max(abs(ar.to_float(r)) for _, r in oc.residuals(A, b, order, ar.one, min_order=order))


def test_dop853_estimators_have_orders_5_and_3():
    # Hairer's er_i have 28 digits: the 5th-order weights b - er satisfy their
    # conditions to 4.7e-28 (measured), the 3rd-order bhh to 2.5e-29.
    ar = oc.mpmath_arithmetic(DIGITS)
    A, _ = oc.tableau_in(DOP853_PAIR, ar.convert)
    for order in range(1, 6):
        assert _max_residual(ar, A, DOP853_PAIR.b_embedded_exact, order) < 1e-26
    assert _max_residual(ar, A, DOP853_PAIR.b_embedded_exact, 6) > FAIL_MARGIN
    for order in range(1, 4):
        assert _max_residual(ar, A, DOP853_BHH3, order) < 1e-27
    assert _max_residual(ar, A, DOP853_BHH3, 4) > FAIL_MARGIN
    assert (DOP853_PAIR.order, DOP853_PAIR.embedded_order) == (8, 5)


def test_dop853_estimators_match_scipy():
    # An independent transcription of dop853.f: SciPy's E5 is er, its E3 is
    # b - bhh (SciPy subtracts in float64, hence the ulp tolerance).
    from scipy.integrate._ivp import dop853_coefficients as scipy_dop853

    for name in ("A", "b", "c"):
        assert getattr(DOP853_PAIR, name) is not getattr(DOP853_RK8, name)
        np.testing.assert_array_equal(getattr(DOP853_PAIR, name), getattr(DOP853_RK8, name))
    np.testing.assert_array_equal(DOP853_PAIR.b_error, scipy_dop853.E5[:12])
    assert scipy_dop853.E5[12] == scipy_dop853.E3[12] == 0
    bhh = np.array([float(x) for x in DOP853_BHH3])
    np.testing.assert_allclose(DOP853_RK8.b - bhh, scipy_dop853.E3[:12], rtol=0, atol=1e-15)


def test_rk34_pair_is_kutta_rk3_and_classical_rk4():
    # Stages 1-4 and the weights are RK4's; stages 1, 2, 5 and the embedded
    # weights are Kutta's RK3.  So one step of the pair costs 5 evaluations.
    assert RK34_PAIR.A_exact[:4] == tuple((*row, Fraction(0)) for row in RK4_CLASSIC.A_exact)
    assert RK34_PAIR.c_exact[:4] == RK4_CLASSIC.c_exact
    assert RK34_PAIR.b_exact[:4] == RK4_CLASSIC.b_exact and RK34_PAIR.b_exact[4] == 0
    rk3_stages = (0, 1, 4)
    for i, si in enumerate(rk3_stages):
        assert RK34_PAIR.c_exact[si] == RK3_KUTTA.c_exact[i]
        assert [RK34_PAIR.A_exact[si][sj] for sj in rk3_stages] == list(RK3_KUTTA.A_exact[i])
        assert RK34_PAIR.b_embedded_exact[si] == RK3_KUTTA.b_exact[i]
    assert sum(RK34_PAIR.b_embedded_exact[j] for j in (2, 3)) == 0
    assert RK34_PAIR.evaluations_per_step == 5


# ------------------------------------------------------- measured convergence


def mp_fixed_step(tableau, weights, f, y0, t1, n: int, ctx) -> mpmath.mpf:
    """``n`` equal steps of ``y' = f(t, y)`` from ``t = 0`` in ``ctx``'s precision,
    with the tableau's published coefficients and the given weights."""
    s = tableau.stages
    A = [[(j, _mp(a, ctx)) for j, a in enumerate(row) if a != 0] for row in tableau.A_exact]
    c = [_mp(x, ctx) for x in tableau.c_exact]
    b = [(i, _mp(x, ctx)) for i, x in enumerate(weights) if x != 0]
    h = ctx.mpf(t1) / n
    y = ctx.mpf(y0)
    for m in range(n):
        t = m * h
        k = []
        for i in range(s):
            k.append(f(t + c[i] * h, y + h * ctx.fsum(a * k[j] for j, a in A[i])))
        y = y + h * ctx.fsum(w * k[i] for i, w in b)
    return y


def _mp_problems(ctx):
    return {
        # y' = 1 + y^2, y(0) = 0: y = tan t (nonlinear, autonomous).
        "tan": (lambda t, y: 1 + y * y, 0, 1, ctx.tan(1)),
        # y' = y cos t, y(0) = 1: y = exp(sin t) (non-autonomous: checks c).
        "expsin": (lambda t, y: y * ctx.cos(t), 1, 2, ctx.exp(ctx.sin(2))),
    }


# Step counts in the asymptotic regime, chosen from a scan of n = 4..724; the
# measured error range and fitted slope are in the comments.  Problems are
# chosen per case where the leading error coefficient is not nearly zero.  On
# the scalar Riccati equation some methods' leading term nearly cancels (the
# scalar autonomous case merges elementary differentials): Verner 7(6) then
# measures 7.92 and Feagin 12 climbs past 13; on expsin, Verner 6(5)'s h^6
# term is small and its slope sits near 6.7 down to n = 256.
MP_CASES = [
    ("tan", VERNER_65, "main", [128, 181, 256, 362, 512, 724]),  # 2.2e-17..7.3e-22, 5.96
    ("tan", VERNER_65, "embedded", [32, 45, 64, 90, 128, 181]),  # 2.8e-9..5.4e-13, 4.94
    ("expsin", VERNER_76, "main", [32, 45, 64, 90, 128, 181, 256]),  # 6.1e-14..2.9e-20, 7.00
    ("expsin", VERNER_76, "embedded", [32, 45, 64, 90, 128]),  # 2.5e-11..5.9e-15, 6.03
    ("tan", VERNER_87, "main", [64, 90, 128, 181, 256, 362]),  # 7.4e-18..7.2e-24, 7.99
    ("tan", VERNER_87, "embedded", [64, 90, 128, 181, 256, 362]),  # 3.7e-16..2.0e-21, 6.99
    ("expsin", VERNER_87_EFFICIENT, "main", [64, 90, 128, 181, 256]),  # 3.2e-19..5.2e-24, 7.95
    ("expsin", VERNER_87_EFFICIENT, "embedded", [32, 45, 64, 90, 128, 181]),  # 4.1e-14.., 6.98
    ("tan", VERNER_98, "main", [64, 90, 128, 181, 256, 362]),  # 6.8e-21..1.3e-27, 8.93
    ("tan", VERNER_98, "embedded", [64, 90, 128, 181, 256, 362]),  # 4.6e-18..4.9e-24, 7.93
    ("tan", FEAGIN_10, "main", [32, 45, 64, 90, 128]),  # 4.4e-17..4.1e-23, 10.03
    ("expsin", FEAGIN_10, "embedded", [64, 90, 128, 181, 256, 362]),  # 9.0e-19..1.0e-24, 7.91
    ("expsin", FEAGIN_12, "main", [64, 90, 128, 181, 256, 362]),  # 2.4e-26..2.4e-35, 11.96
    ("tan", FEAGIN_12, "embedded", [64, 90, 128, 181, 256, 362]),  # 6.9e-21..1.5e-28, 10.18
]


@pytest.mark.parametrize(
    ("problem", "tableau", "which", "steps"),
    MP_CASES,
    ids=[f"{p}-{t.name}-{w}" for p, t, w, _ in MP_CASES],
)
def test_measured_order_in_50_digit_arithmetic(problem, tableau, which, steps):
    ctx = mpmath.MPContext()
    ctx.dps = DIGITS
    f, y0, t1, exact = _mp_problems(ctx)[problem]
    weights, order = _weights_of(tableau, which)
    errors = [abs(mp_fixed_step(tableau, weights, f, y0, t1, n, ctx) - exact) for n in steps]
    # The smallest error must stay far above the 50-digit rounding (and above
    # the 40-digit coefficients' own ~1e-40), or the slope would mean nothing.
    assert min(errors) > ctx.mpf("1e-36")
    log_h = np.log(t1 / np.array(steps, dtype=float))
    slope = np.polyfit(log_h, np.log([float(e) for e in errors]), 1)[0]
    assert abs(slope - order) < 0.3, f"{tableau.name} {which} on {problem}: slope {slope:.3f}"


def fixed_step(tableau, weights, f, y0, t0, t1, n):
    """``n`` equal float64 steps with the tableau's float arrays (as a kernel would)."""
    A, c = tableau.A, tableau.c
    h = (t1 - t0) / n
    y = np.array(y0, dtype=float)
    k = np.empty((tableau.stages, y.size))
    for m in range(n):
        t = t0 + m * h
        for i in range(tableau.stages):
            k[i] = f(t + c[i] * h, y + h * (A[i, :i] @ k[:i]))
        y = y + h * (weights @ k)
    return y


def _kepler(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


_E = 0.05
_KEPLER_Y0 = np.array([1 - _E, 0.0, 0.0, np.sqrt((1 + _E) / (1 - _E))])
FLOAT_PROBLEMS = {
    # One period of a Kepler orbit: the exact solution is the initial value.
    "kepler": (_kepler, _KEPLER_Y0, 0.0, 2 * np.pi, _KEPLER_Y0),
    "expsin": (lambda t, y: y * np.cos(t), [1.0], 0.0, 2.0, [np.exp(np.sin(2.0))]),
}
FLOAT_CASES = [
    ("expsin", RK34_PAIR, "main", [16, 23, 32, 45, 64, 90, 128]),  # 2.6e-6..6.1e-10, 4.01
    ("expsin", RK34_PAIR, "embedded", [16, 23, 32, 45, 64, 90, 128]),  # 1.1e-4..2.3e-7, 2.97
    ("kepler", RK34_PAIR, "embedded", [64, 90, 128, 181, 256]),  # 7.6e-3..1.2e-4, 3.02
    ("expsin", DORMAND_PRINCE_54, "main", [16, 23, 32, 45, 64, 90]),  # 9.3e-9..1.3e-12, 5.12
    ("expsin", DORMAND_PRINCE_54, "embedded", [32, 45, 64, 90, 128, 181]),  # 3.0e-9..3.5e-12
    ("kepler", DORMAND_PRINCE_54, "embedded", [64, 90, 128, 181, 256]),  # 5.2e-7..1.8e-9, 4.10
]


@pytest.mark.parametrize(
    ("problem", "tableau", "which", "steps"),
    FLOAT_CASES,
    ids=[f"{p}-{t.name}-{w}" for p, t, w, _ in FLOAT_CASES],
)
def test_measured_order_in_float64(problem, tableau, which, steps):
    f, y0, t0, t1, exact = FLOAT_PROBLEMS[problem]
    weights = tableau.b if which == "main" else tableau.b_embedded
    order = tableau.order if which == "main" else tableau.embedded_order
    errors = np.array(
        [np.linalg.norm(fixed_step(tableau, weights, f, y0, t0, t1, n) - exact) for n in steps]
    )
    assert np.all(errors > 5e-13), "window reaches roundoff: the slope would mean nothing"
    h = (t1 - t0) / np.array(steps, dtype=float)
    slope = np.polyfit(np.log(h), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.3, f"{tableau.name} {which} on {problem}: slope {slope:.3f}"


# ------------------------------------------------------------------ registry


def test_pairs_and_quenchers():
    assert list(PAIRS) == ["rk34", "dp54", "vern65", "vern76", "vern87", "vern98"]
    assert list(QUENCHERS) == ["dop853", "cooper_verner", "vern98", "feagin10", "feagin12"]
    assert PAIRS["vern87"] is VERNER_87  # the robust 8(7), not the efficient one
    for name, pair in PAIRS.items():
        assert get_pair(name) is pair and pair.is_pair and pair.name == name
    for name, quencher in QUENCHERS.items():
        assert get_quencher(name) is quencher and quencher.name == name
    # The z_method values of the first release name the same objects.
    assert get_quencher("dop853") is get_tableau("dop853") is DOP853_RK8
    assert get_quencher("cooper_verner") is get_tableau("cooper_verner") is COOPER_VERNER_RK8
    assert set(ALL_TABLEAUS) >= {*PAIRS, *QUENCHERS, "rk3", "rk4", "vern87e"}
    for mapping in (PAIRS, QUENCHERS, ALL_TABLEAUS):
        with pytest.raises(TypeError):
            mapping["mine"] = RK4_CLASSIC


@pytest.mark.parametrize(
    ("lookup", "valid"),
    [(get_pair, PAIRS), (get_quencher, QUENCHERS), (get_member, None)],
    ids=["pair", "quencher", "member"],
)
def test_unknown_names_list_every_valid_one(lookup, valid):
    names = valid if valid is not None else [m.name for m in family_members()]
    with pytest.raises(OptionError) as info:
        lookup("rk99")
    message = str(info.value)
    assert "'rk99'" in message
    for name in names:
        assert repr(name) in message
    with pytest.raises(InputTypeError, match="int"):
        lookup(8)


def test_family_members_follow_the_papers_naming():
    members = family_members()
    names = [m.name for m in members]
    assert len(set(names)) == len(names) == 18
    for m in members:
        assert isinstance(m, FamilyMember)
        assert m.name == f"rk{m.r}{m.v}q{m.z}"
        assert m.r < m.v and m.z >= m.v + registry.MIN_ORDER_GAP
        assert (m.pair_tableau.embedded_order, m.pair_tableau.order) == (m.r, m.v)
        assert m.quencher_tableau.order == m.z
        assert get_member(m.name) is m
    # The paper's method, and the two examples of the issue.
    assert get_member("rk34q8") == FamilyMember("rk34q8", "rk34", "dop853", 3, 4, 8)
    assert get_member("rk45q12") == FamilyMember("rk45q12", "dp54", "feagin12", 4, 5, 12)
    assert get_member("rk67q9") == FamilyMember("rk67q9", "vern76", "vern98", 6, 7, 9)
    # RK3(4) + RK8: 5 + 12 evaluations per step, as the paper counts them.
    assert get_member("rk34q8").evaluations_per_step == 17
    with pytest.raises(dataclasses.FrozenInstanceError):
        members[0].z = 10


@pytest.mark.parametrize("tableau", [*PAIRS.values(), *QUENCHERS.values()], ids=lambda t: t.name)
def test_kernel_arrays(tableau):
    arrays = kernel_arrays(tableau)
    assert arrays.A is tableau.A and arrays.b is tableau.b and arrays.c is tableau.c
    assert (arrays.stages, arrays.fsal) == (tableau.stages, tableau.fsal)
    expected = 0 if tableau.b_embedded is None else tableau.stages
    for array in (arrays.b_embedded, arrays.b_error, arrays.A, arrays.b, arrays.c):
        assert array.dtype == np.float64 and array.flags.c_contiguous
        assert not array.flags.writeable
    assert arrays.b_embedded.shape == arrays.b_error.shape == (expected,)


def test_kernel_arrays_rejects_non_tableaus():
    with pytest.raises(InputTypeError, match="ButcherTableau"):
        kernel_arrays("rk34")


def test_kernel_arrays_feed_one_compiled_step_for_every_tableau():
    # The arrays' types (read-only, C-contiguous float64) are the same for
    # every pair and quencher, so a numba kernel compiles once for all of them.
    numba = pytest.importorskip("numba")

    @numba.njit(cache=False)
    def step(A, b, b_error, c, y, h):  # y' = -y, one step
        s = b.size
        k = np.empty((s, y.size))
        for i in range(s):
            stage = y.copy()
            for j in range(i):
                stage += h * A[i, j] * k[j]
            k[i] = -stage
        y_new = y.copy()
        err = np.zeros_like(y)
        for i in range(s):
            y_new += h * b[i] * k[i]
            if b_error.size:
                err += h * b_error[i] * k[i]
        return y_new, err

    # h = 0.5 keeps even Verner 9(8)'s estimate (3e-10) far above rounding.
    h, y0 = 0.5, np.array([1.0])
    for tableau in [*PAIRS.values(), *QUENCHERS.values()]:
        arrays = kernel_arrays(tableau)
        y1, err = step(arrays.A, arrays.b, arrays.b_error, arrays.c, y0, h)
        # Local error of an order-p method on y' = -y: about h^(p+1)/(p+1)!.
        assert abs(y1[0] - np.exp(-h)) < max(h ** (tableau.order + 1), 1e-16)
        if tableau.is_pair:
            low = fixed_step(tableau, tableau.b_embedded, lambda t, y: -y, y0, 0.0, h, 1)
            # y1 - low cancels (both near 1): equal to a few ulps of y, not of
            # err; each sums up to 16 products, rounded as the CPU's kernels
            # round them (within 4 eps on one machine, 6 eps on another).
            # The weights moved to sum to 1 (Verner 6(5)'s by 1.4e-14) and
            # the error weights, exact differences, part by that much more.
            moved = sum(
                float(abs(Fraction(float(w)) - Fraction(v)))
                for weights, exact in (
                    (tableau.b, tableau.b_exact),
                    (tableau.b_embedded, tableau.b_embedded_exact),
                )
                for w, v in zip(weights, exact, strict=True)
                if not isinstance(v, sp.Expr)
            )
            atol = 16 * np.finfo(float).eps + 2 * h * moved
            np.testing.assert_allclose(err, y1 - low, rtol=0, atol=atol)
            assert abs(err[0]) > 1e-12
    assert len(step.signatures) == 1


# ------------------------------------------------------- double-double quenchers

QUENCHERS_DD = [DOP853_RK8, COOPER_VERNER_RK8, VERNER_98, FEAGIN_10, FEAGIN_12]


@pytest.mark.parametrize("tableau", QUENCHERS_DD, ids=[t.name for t in QUENCHERS_DD])
def test_low_words_make_the_coefficients_double_doubles(tableau):
    # A + A_low (and b + b_low), added exactly, is the published coefficient
    # to about 2^-106 of its size, where A alone is off by up to 2^-53.
    ctx = mpmath.MPContext()
    ctx.dps = 80
    pairs = [
        ([a for row in tableau.A_exact for a in row], tableau.A.ravel(), tableau.A_low.ravel()),
        (tableau.b_exact, tableau.b, tableau.b_low),
    ]
    for exact, high, low in pairs:
        for value, hi, lo in zip(exact, high, low, strict=True):
            v = ctx.mpf(str(sp.N(value, 70))) if isinstance(value, sp.Expr) else _mp(value, ctx)
            # (a weight moved off nearest to sum to 1 keeps the excess moved,
            # at most 6.9e-17 for a quencher (DOP853's), in its low word,
            # which rounds it: 2^-101 of the weight)
            assert abs(lo) <= 2.0**-53 * abs(hi) + 2.0**-53
            assert abs(ctx.mpf(hi) + ctx.mpf(lo) - v) <= 2.0**-101 * abs(v)
    assert not tableau.A_low.flags.writeable and not tableau.b_low.flags.writeable


@pytest.mark.parametrize("tableau", QUENCHERS_DD, ids=[t.name for t in QUENCHERS_DD])
def test_double_double_coefficients_satisfy_the_low_order_conditions(tableau):
    # The float64 coefficients, taken exactly, miss the conditions of orders
    # 1 to 4 by up to about 1e-17 (the systematic defect that made the
    # quencher's error grow like t^2); with the low words by less than 1e-28.
    ar = oc.mpmath_arithmetic(60)
    ctx_mpf = ar.one.context.mpf

    def rounded(low: bool):
        s = tableau.stages
        A_low = tableau.A_low if low else np.zeros_like(tableau.A)
        b_low = tableau.b_low if low else np.zeros_like(tableau.b)
        A = [[ctx_mpf(tableau.A[i, j]) + ctx_mpf(A_low[i, j]) for j in range(s)] for i in range(s)]
        b = [ctx_mpf(tableau.b[i]) + ctx_mpf(b_low[i]) for i in range(s)]
        return max(abs(r) for _, r in oc.residuals(A, b, 4, ar.one))

    plain, double_double = rounded(False), rounded(True)
    assert 1e-19 < plain < 1e-15
    assert double_double < 1e-28
