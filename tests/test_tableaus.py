"""Tests of hamrkq.methods.tableaus: the coefficients prove their order.

Three independent lines of evidence per tableau:

1. every Butcher rooted-tree condition up to the claimed order, in exact
   arithmetic (``Fraction``; ``QQ<sqrt(21)>`` for Cooper-Verner; the exact
   values of the published decimals for DOP853) and in float64;
2. some condition of the next order fails, so the checks have teeth;
3. the order measured on problems with known solutions, by fitting the slope
   of log(error) against log(h) with fixed steps.
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction
from math import factorial

import numpy as np
import pytest
import sympy as sp
from scipy.integrate._ivp import dop853_coefficients as scipy_dop853

from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.methods.tableaus import (
    COOPER_VERNER_RK8,
    DOP853_RK8,
    RK3_KUTTA,
    RK4_CLASSIC,
    TABLEAUS,
    ButcherTableau,
    get_tableau,
)

try:  # tests/ on sys.path (pytest's default rootdir-less import mode)
    import order_conditions as oc
except ImportError:  # tests/ imported as a package
    from tests import order_conditions as oc

ALL = [RK3_KUTTA, RK4_CLASSIC, DOP853_RK8, COOPER_VERNER_RK8]
RK8S = [DOP853_RK8, COOPER_VERNER_RK8]
IDS = [t.name for t in ALL]

# DOP853's published decimals have 30 significant digits; evaluated exactly,
# they satisfy the conditions to ~3e-29 (measured).  1e-27 leaves room and is
# still eleven orders of magnitude below float64 resolution.
DECIMAL_TOL = 1e-27
# float64 coefficients: each is rounded once (relative 1.1e-16); sums of up
# to 12 products of entries of size <= 44 give residuals up to ~2e-15.
FLOAT_TOL = 1e-13


def _exact(tableau: ButcherTableau):
    """The tableau's ``(A, b)`` in exact arithmetic, and that arithmetic."""
    entries = [*tableau.b_exact, *tableau.c_exact, *(a for row in tableau.A_exact for a in row)]
    arithmetic = oc.exact_field(entries)
    A, b = oc.tableau_in(tableau, arithmetic.convert)
    return A, b, arithmetic


def _assert_conditions_hold(tableau: ButcherTableau, max_order: int) -> int:
    """Check every condition through ``max_order``; return how many there were."""
    A, b, ar = _exact(tableau)
    res = oc.residuals(A, b, max_order, ar.one)
    if tableau.exact:
        failed = [t for t, r in res if r != ar.zero]
        assert failed == [], f"{tableau.name}: conditions fail for trees {failed[:5]}"
    else:
        worst = max(abs(ar.to_float(r)) for _, r in res)
        assert worst < DECIMAL_TOL, f"{tableau.name}: worst residual {worst:.3e}"
    return len(res)


# ---------------------------------------------------------------- rooted trees


def test_rooted_tree_counts_match_oeis_a000081():
    counts = [len(oc.rooted_trees(n)) for n in range(1, 9)]
    assert counts == [1, 1, 2, 4, 9, 20, 48, 115]
    assert sum(counts) == 200
    for n in range(1, 9):  # canonical form: no tree listed twice
        assert len(set(oc.rooted_trees(n))) == len(oc.rooted_trees(n))
        assert all(oc.tree_order(t) == n for t in oc.rooted_trees(n))


def test_density_and_symmetry_by_labelling_count():
    # sum over trees of order n of n!/(sigma gamma) counts the monotonically
    # labelled trees on n vertices, which is (n-1)!: an independent check of
    # both gamma and the enumeration.
    for n in range(1, 9):
        total = sum(
            Fraction(factorial(n), oc.symmetry(t) * oc.density(t)) for t in oc.rooted_trees(n)
        )
        assert total == factorial(n - 1)
    # Known values: the tall tree of order 4 has gamma 24, the bushy one 4.
    assert oc.density(((((),),),)) == 24
    assert oc.density(((), (), ())) == 4
    assert oc.symmetry(((), (), ())) == 6


# ------------------------------------------------------------------ structure


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_explicit_and_shapes(tableau):
    s = tableau.stages
    assert tableau.A.shape == (s, s) and tableau.b.shape == (s,) and tableau.c.shape == (s,)
    for array in (tableau.A, tableau.b, tableau.c):
        assert array.dtype == np.float64
    assert np.all(np.triu(tableau.A) == 0.0)
    assert all(tableau.A_exact[i][j] == 0 for i in range(s) for j in range(i, s))
    assert tableau.c_exact[0] == 0


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_row_sums_equal_nodes(tableau):
    A, _, ar = _exact(tableau)
    diffs = [
        sum(row, ar.zero) - ar.convert(ci) for row, ci in zip(A, tableau.c_exact, strict=True)
    ]
    if tableau.exact:
        assert all(d == ar.zero for d in diffs)
    else:
        assert max(abs(ar.to_float(d)) for d in diffs) < DECIMAL_TOL
    np.testing.assert_allclose(tableau.A.sum(axis=1), tableau.c, rtol=0, atol=1e-14)


def _sym(value) -> sp.Expr:
    """A coefficient as a SymPy number (a Decimal at its published digits)."""
    if isinstance(value, Fraction):
        return sp.Rational(value.numerator, value.denominator)
    if isinstance(value, sp.Expr):
        return value
    return sp.Float(str(value), 40)


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_floats_are_the_rounded_coefficients(tableau):
    for exact, array in [
        (tableau.c_exact, tableau.c),
        ([a for row in tableau.A_exact for a in row], tableau.A.ravel()),
    ]:
        reference = np.array([float(sp.N(_sym(v), 40)) for v in exact])
        np.testing.assert_array_equal(array, reference)
    # The weights: within a few ulps of nearest, summing to exactly 1 as
    # doubles (rounded to nearest, DOP853's summed to 1 + 6.9e-17, a
    # consistency error of the method run that neither Gamma nor the
    # witness sees: benchmarks/coefficient_rounding.py).
    nearest = np.array([float(sp.N(_sym(v), 40)) for v in tableau.b_exact])
    excess = sum(Fraction(float(x)) for x in nearest) - 1
    assert sum(Fraction(float(x)) for x in tableau.b) == 1
    assert np.count_nonzero(tableau.b != nearest) == (excess != 0)  # one moved, by the excess
    assert np.abs(tableau.b - nearest).max() <= 2 * abs(float(excess))


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_read_only_and_frozen(tableau):
    for array in (tableau.A, tableau.b, tableau.c):
        assert not array.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        tableau.order = 99
    with pytest.raises(dataclasses.FrozenInstanceError):
        tableau.A = np.zeros((2, 2))
    hash(tableau)  # frozen and compared by exact data: usable as a key


def test_exact_flag():
    assert RK3_KUTTA.exact and RK4_CLASSIC.exact and COOPER_VERNER_RK8.exact
    assert not DOP853_RK8.exact  # published decimals


def test_metadata():
    assert [(t.order, t.stages) for t in ALL] == [(3, 3), (4, 4), (8, 12), (8, 11)]
    for t in ALL:
        assert t.reference and len(t.reference) > 30
        assert t.name in repr(t)


def test_cooper_verner_nodes_are_lobatto_points():
    root = sp.sqrt(21)
    assert sp.simplify(COOPER_VERNER_RK8.c_exact[3] - (7 + root) / 14) == 0
    assert sp.simplify(COOPER_VERNER_RK8.c_exact[6] - (7 - root) / 14) == 0
    # The interior 5-point Lobatto nodes on [0, 1] are the roots of P_4'(2x - 1).
    x = sp.symbols("x")
    lobatto = sp.diff(sp.legendre(4, x), x).subs(x, 2 * x - 1)
    for node in {COOPER_VERNER_RK8.c_exact[i] for i in (3, 5, 6)}:
        assert sp.simplify(lobatto.subs(x, node)) == 0


def test_dop853_matches_scipy():
    # Independent transcription of the same publication (dop853.f).
    s = DOP853_RK8.stages
    np.testing.assert_array_equal(DOP853_RK8.A, scipy_dop853.A[:s, :s])
    # The weights: SciPy's are rounded to nearest and sum to 1 + 6.9e-17;
    # ours move one of them by that excess to sum to exactly 1.
    excess = sum(Fraction(float(x)) for x in scipy_dop853.B) - 1
    assert excess == Fraction(2**-54 + 2**-56)
    moved = np.flatnonzero(DOP853_RK8.b != scipy_dop853.B)
    assert moved.size == 1
    theirs, ours = scipy_dop853.B[moved[0]], DOP853_RK8.b[moved[0]]
    assert Fraction(float(theirs)) - Fraction(float(ours)) == excess
    np.testing.assert_array_equal(DOP853_RK8.c, scipy_dop853.C[:s])


def test_rk3_and_rk4_share_two_stages_so_together_cost_five():
    assert RK3_KUTTA.c[:2].tolist() == RK4_CLASSIC.c[:2].tolist() == [0.0, 0.5]
    np.testing.assert_array_equal(RK3_KUTTA.A[:2, :2], RK4_CLASSIC.A[:2, :2])

    def stage(t, i):
        return (t.c_exact[i], t.A_exact[i][:i])

    distinct = {stage(RK3_KUTTA, i) for i in range(3)} | {stage(RK4_CLASSIC, i) for i in range(4)}
    assert len(distinct) == 5


# ---------------------------------------------------------- order conditions


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_order_conditions_through_order_4(tableau):
    # RK3 is checked through its own order; its order-4 failures are below.
    order = min(4, tableau.order)
    trees_through = {3: 1 + 1 + 2, 4: 1 + 1 + 2 + 4}
    assert _assert_conditions_hold(tableau, order) == trees_through[order]


@pytest.mark.parametrize("tableau", RK8S, ids=[t.name for t in RK8S])
def test_all_200_conditions_through_order_8(tableau):
    assert _assert_conditions_hold(tableau, 8) == 200


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_order_conditions_in_float64(tableau):
    res = oc.residuals(tableau.A.tolist(), tableau.b.tolist(), tableau.order, 1.0)
    assert max(abs(r) for _, r in res) < FLOAT_TOL


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_quadrature_conditions(tableau):
    # sum_i b_i c_i^(k-1) = 1/k for k = 1..order, written out on their own.
    _, _, ar = _exact(tableau)
    b = [ar.convert(v) for v in tableau.b_exact]
    c = [ar.convert(v) for v in tableau.c_exact]
    for k in range(1, tableau.order + 1):
        total = sum((bi * ci ** (k - 1) for bi, ci in zip(b, c, strict=True)), ar.zero)
        residual = total - ar.one / k
        if tableau.exact:
            assert residual == ar.zero, (tableau.name, k)
        else:
            assert abs(ar.to_float(residual)) < DECIMAL_TOL, (tableau.name, k)
        float_sum = float(np.sum(tableau.b * tableau.c ** (k - 1)))
        assert abs(float_sum - 1 / k) < FLOAT_TOL


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_next_order_fails(tableau):
    # Order exactly p: at least one condition of order p+1 is violated, by far
    # more than rounding.  (RK3: 2 of the 4 order-4 trees fail; RK4: all 9
    # order-5 trees; the RK8s: order-9 trees.)
    A, b, ar = _exact(tableau)
    res = oc.residuals(A, b, tableau.order + 1, ar.one, min_order=tableau.order + 1)
    sizes = [abs(ar.to_float(r)) for _, r in res if r != ar.zero]
    assert sizes, f"{tableau.name} satisfies every order-{tableau.order + 1} condition"
    assert max(sizes) > 1e-7


# ------------------------------------------------------- measured convergence


def fixed_step(tableau: ButcherTableau, f, y0, t0: float, t1: float, n: int) -> np.ndarray:
    """Integrate ``y' = f(t, y)`` from ``t0`` to ``t1`` with ``n`` equal steps,
    using only the tableau's float arrays; return ``y(t1)``."""
    A, b, c = tableau.A, tableau.b, tableau.c
    h = (t1 - t0) / n
    y = np.array(y0, dtype=float)
    k = np.empty((tableau.stages, y.size))
    for m in range(n):
        t = t0 + m * h
        for i in range(tableau.stages):
            k[i] = f(t + c[i] * h, y + h * (A[i, :i] @ k[:i]))
        y = y + h * (b @ k)
    return y


def _kepler(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])


def _kepler_one_period(e: float):
    # Perihelion start with unit semi-major axis: period 2 pi, so the exact
    # solution after one period is the initial value.
    y0 = np.array([1 - e, 0.0, 0.0, np.sqrt((1 + e) / (1 - e))])
    return _kepler, y0, 0.0, 2 * np.pi, y0


def _tan_riccati():
    # y' = 1 + y^2, y(0) = 0: y = tan t, nonlinear, with growing derivatives.
    return (lambda t, y: 1.0 + y**2), np.array([0.0]), 0.0, 1.3, np.array([np.tan(1.3)])


# Step counts where the error is well above roundoff (about 1e-14 here) and
# the asymptotic regime has been reached; measured error range and fitted slope
# in the comments.  DOP853 approaches order 8 from below: its 10th-order error
# coefficients are about twice its 9th-order ones (2-norms over the trees,
# weighted by 1/sigma: 1.4e-5 vs 6.3e-6), so the h^9 term lingers longer.
CONVERGENCE_CASES = [
    ("kepler", RK3_KUTTA, [64, 128, 256, 512, 1024]),  # 7.6e-3 .. 1.8e-6, 3.01
    ("kepler", RK4_CLASSIC, [64, 128, 256, 512, 1024]),  # 3.2e-5 .. 3.2e-10, 4.16
    ("kepler", DOP853_RK8, [17, 21, 25, 30, 37, 45, 54]),  # 3.5e-8 .. 4.0e-12, 7.88
    ("kepler", COOPER_VERNER_RK8, [37, 45, 54, 65, 79, 96, 116]),  # 3.2e-8 .. 2.9e-12, 8.15
    ("tan", RK3_KUTTA, [32, 64, 128, 256, 512]),  # 4.6e-4 .. 1.4e-7, 2.91
    ("tan", RK4_CLASSIC, [32, 64, 128, 256, 512]),  # 1.5e-5 .. 2.2e-10, 4.03
    ("tan", DOP853_RK8, [16, 20, 24, 32, 40, 48]),  # 5.4e-9 .. 9.4e-13, 7.89
    ("tan", COOPER_VERNER_RK8, [24, 32, 40, 48, 64]),  # 2.3e-9 .. 1.1e-12, 7.82
]
PROBLEMS = {"kepler": lambda: _kepler_one_period(0.05), "tan": _tan_riccati}


@pytest.mark.parametrize(
    ("problem", "tableau", "steps"),
    CONVERGENCE_CASES,
    ids=[f"{p}-{t.name}" for p, t, _ in CONVERGENCE_CASES],
)
def test_measured_convergence_order(problem, tableau, steps):
    f, y0, t0, t1, exact = PROBLEMS[problem]()
    errors = np.array(
        [np.linalg.norm(fixed_step(tableau, f, y0, t0, t1, n) - exact) for n in steps]
    )
    h = (t1 - t0) / np.array(steps, dtype=float)
    assert np.all(errors > 5e-13), "window reaches roundoff: the slope would mean nothing"
    slope = np.polyfit(np.log(h), np.log(errors), 1)[0]
    assert abs(slope - tableau.order) < 0.3, f"{tableau.name} on {problem}: slope {slope:.3f}"


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_polynomials_integrated_exactly_up_to_the_order(tableau):
    # y' = k t^(k-1) on [0.5, 2]: a method of order p is exact for k <= p.
    # Non-autonomous, so this also checks the float nodes c.
    def relative_error(k: int) -> float:
        y1 = fixed_step(tableau, lambda t, y: k * t ** (k - 1) + 0 * y, [0.5**k], 0.5, 2.0, 3)
        return abs(y1[0] - 2.0**k) / 2.0**k

    for k in range(1, tableau.order + 1):
        assert relative_error(k) < 1e-13, (tableau.name, k)
    # One degree more is not exact (measured 1.2e-4 for RK4, 2.8e-9 and 2.9e-9
    # for the RK8s), except for RK3, whose weights are Simpson's rule: exact
    # for cubics although the method has order 3 only.
    if tableau is RK3_KUTTA:
        assert relative_error(4) < 1e-13
    else:
        assert relative_error(tableau.order + 1) > 1e-9


# ------------------------------------------------------------------- lookup


@pytest.mark.parametrize("tableau", ALL, ids=IDS)
def test_get_tableau(tableau):
    assert get_tableau(tableau.name) is tableau
    assert TABLEAUS[tableau.name] is tableau


def test_get_tableau_unknown_name_lists_valid_ones():
    with pytest.raises(OptionError) as info:
        get_tableau("rk45")
    message = str(info.value)
    assert "'rk45'" in message
    for name in ("rk3", "rk4", "dop853", "cooper_verner"):
        assert repr(name) in message
    assert isinstance(info.value, ValueError)


def test_get_tableau_rejects_non_strings():
    with pytest.raises(InputTypeError, match="int"):
        get_tableau(4)


def test_tableaus_mapping_is_read_only():
    with pytest.raises(TypeError):
        TABLEAUS["mine"] = RK4_CLASSIC


def test_validation_of_new_tableaus():
    half = Fraction(1, 2)
    zero = Fraction(0)
    with pytest.raises(InputError, match="not explicit"):
        ButcherTableau("bad", 1, 2, "none", ((zero, half), (half, zero)), (half, half), (0, 1))
    with pytest.raises(InputError, match="2 entries"):
        ButcherTableau("bad", 1, 2, "none", ((zero, zero), (half, zero)), (half,), (0, half))
    euler = ButcherTableau("euler", 1, 1, "Euler 1768", ((zero,),), (Fraction(1),), (zero,))
    assert euler.A.shape == (1, 1) and euler.b.tolist() == [1.0]
