"""Scalar double-double arithmetic (hamrkq.rkq.ddarith) against mpmath at 50
digits: the error-free transformations exact (checked with Fractions), the
arithmetic and the elementary functions within their error bounds, special
values without exceptions, and the numba-compiled functions bit for bit equal
to the interpreted ones."""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest

from hamrkq.rkq import ddarith as dd
from hamrkq.rkq.jit import jitable

#: A private mpmath context, so that its precision leaks into no other test.
MP = mpmath.MPContext()
MP.dps = 50

#: Bounds asserted on the relative error (absolute near zeros of sin and cos).
ARITH_BOUND = 1e-30
FUNCTION_BOUND = 1e-29
TRIG_ABS_BOUND = 1e-31

N = 200


def _rng(seed):
    return np.random.default_rng(seed)


def _with_lo(hi, rng):
    """Genuine double-doubles: each hi given a low word of about ulp(hi)/4."""
    out = []
    for h in np.asarray(hi, float):
        h = float(h)
        low = float(rng.uniform(-0.25, 0.25)) * math.ulp(h) if h else 0.0
        out.append(dd.two_sum(h, low))
    return out


def _random_dd(rng, n, low_exp, high_exp, signed=True):
    """n double-doubles with magnitudes log-uniform in [10**low_exp, 10**high_exp]."""
    hi = 10.0 ** rng.uniform(low_exp, high_exp, n)
    if signed:
        hi = hi * rng.choice([-1.0, 1.0], n)
    return _with_lo(hi, rng)


def _uniform_dd(rng, n, low, high):
    return _with_lo(rng.uniform(low, high, n), rng)


def _mp(pair):
    return MP.mpf(pair[0]) + MP.mpf(pair[1])


def _rel(got, ref):
    """Relative error of the double-double ``got`` against the mpf ``ref``."""
    value = _mp(got)
    if ref == 0:
        return float(abs(value))
    return float(abs((value - ref) / ref))


def _is_dd(pair):
    """|lo| <= ulp(hi)/2: the result is a normalised double-double."""
    hi, lo = pair
    return abs(lo) <= math.ulp(hi) / 2


def _check(results, bound, name):
    worst = max(results)
    assert worst <= bound, f"{name}: max relative error {worst:.3g} > {bound:g}"
    return worst


# ---------------------------------------------------------------------------
# Constants


def test_constants_are_correctly_rounded():
    ln2 = MP.log(2)
    pio2 = MP.pi / 2
    assert abs(MP.mpf(dd._LN2_1) + dd._LN2_2 + dd._LN2_3 - ln2) < MP.mpf(10) ** -48
    assert abs(MP.mpf(dd._PIO2_1) + dd._PIO2_2 + dd._PIO2_3 - pio2) < MP.mpf(10) ** -48
    assert dd._LN2_1 == float(ln2) and dd._PIO2_1 == float(pio2)
    assert dd._INV_LN2 == float(1 / ln2) and dd._TWO_OVER_PI == float(2 / MP.pi)
    for k, (hi, lo) in enumerate(zip(dd._SIN_HI, dd._SIN_LO, strict=True)):
        exact = Fraction((-1) ** (k + 1), math.factorial(2 * k + 3))
        assert abs(Fraction(hi) + Fraction(lo) - exact) <= abs(exact) * Fraction(1, 2**106)
    for k, (hi, lo) in enumerate(zip(dd._COS_HI, dd._COS_LO, strict=True)):
        exact = Fraction((-1) ** (k + 1), math.factorial(2 * k + 2))
        assert abs(Fraction(hi) + Fraction(lo) - exact) <= abs(exact) * Fraction(1, 2**106)


# ---------------------------------------------------------------------------
# Error-free transformations


def _huge_and_tiny(rng, n):
    """Doubles over the whole exponent range, both signs."""
    return 10.0 ** rng.uniform(-300, 300, n) * rng.choice([-1.0, 1.0], n)


def test_two_sum_is_exact():
    rng = _rng(1)
    a = _huge_and_tiny(rng, 4 * N)
    b = _huge_and_tiny(rng, 4 * N)
    pairs = list(zip(a.tolist(), b.tolist(), strict=True))
    pairs += [(1e308, -1e-308), (1.0, 1e-300), (1e-300, 1.0), (3.0, -3.0), (0.1, 0.2)]
    pairs += [(x, y) for x in (1.0, -2.5, 1e300, 5e-324) for y in (1e-16, 3e-17, -7e-200)]
    for x, y in pairs:
        s, e = dd.two_sum(x, y)
        assert s == x + y
        assert Fraction(s) + Fraction(e) == Fraction(x) + Fraction(y), (x, y)


def test_fast_two_sum_is_exact():
    rng = _rng(2)
    a = _huge_and_tiny(rng, 4 * N)
    b = _huge_and_tiny(rng, 4 * N)
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        if abs(x) < abs(y):
            x, y = y, x
        s, e = dd.fast_two_sum(x, y)
        assert s == x + y
        assert Fraction(s) + Fraction(e) == Fraction(x) + Fraction(y), (x, y)


def test_two_prod_is_exact():
    rng = _rng(3)
    pairs = []
    while len(pairs) < 4 * N:
        x, y = _huge_and_tiny(rng, 2).tolist()
        if 1e-290 < abs(x * y) < 1e300:  # exact unless the error term is subnormal
            pairs.append((x, y))
    pairs += [
        (1e305, 1e-10),  # above 2**996: split after scaling
        (-1.7e308, 0.9),
        (1.7976931348623157e308, 0.5),
        (1e300, 1e-300),
        (1e-300, 1e300),
        (1e-150, 1e-140),
        (2.0**-1000, 2.0**30 + 1.0),
        (134217729.0, 134217729.0),
        (1.0 + 2.0**-52, 1.0 - 2.0**-53),
        (0.0, 1e300),
    ]
    for x, y in pairs:
        p, e = dd.two_prod(x, y)
        assert p == x * y
        assert Fraction(p) + Fraction(e) == Fraction(x) * Fraction(y), (x, y)


# ---------------------------------------------------------------------------
# Arithmetic


def test_add_sub():
    rng = _rng(4)
    a = _random_dd(rng, N, -20, 20)
    b = _random_dd(rng, N, -20, 20)
    worst = []
    for x, y in zip(a, b, strict=True):
        got = dd.dd_add(*x, *y)
        worst.append(_rel(got, _mp(x) + _mp(y)))
        assert _is_dd(got)
        worst.append(_rel(dd.dd_sub(*x, *y), _mp(x) - _mp(y)))
    _check(worst, ARITH_BOUND, "dd_add/dd_sub")


def test_add_sub_cancellation():
    rng = _rng(5)
    worst = []
    for x in _random_dd(rng, N, -20, 20):
        # exact cancellation
        assert dd.dd_sub(*x, *x) == (0.0, 0.0)
        assert dd.dd_add(*x, *dd.dd_neg(*x)) == (0.0, 0.0)
        # same hi, other lo: the difference of the lo words, exactly
        other = (x[0], float(rng.uniform(-0.4, 0.4)) * math.ulp(x[0]))
        got = dd.dd_sub(*x, *other)
        assert _mp(got) == _mp(x) - _mp(other)
        # nearby numbers: a few ulps of hi apart, relative error kept
        near = dd.two_sum(x[0] + int(rng.integers(-3, 4)) * math.ulp(x[0]), x[1] * 0.7)
        ref = _mp(x) - _mp(near)
        if ref != 0:
            worst.append(_rel(dd.dd_sub(*x, *near), ref))
    _check(worst, ARITH_BOUND, "dd_sub near cancellation")


def test_add_d_mul_d():
    rng = _rng(6)
    a = _random_dd(rng, N, -20, 20)
    b = (10.0 ** rng.uniform(-20, 20, N) * rng.choice([-1.0, 1.0], N)).tolist()
    add = [_rel(dd.dd_add_d(*x, y), _mp(x) + y) for x, y in zip(a, b, strict=True)]
    mul = [_rel(dd.dd_mul_d(*x, y), _mp(x) * y) for x, y in zip(a, b, strict=True)]
    _check(add, ARITH_BOUND, "dd_add_d")
    _check(mul, ARITH_BOUND, "dd_mul_d")


def test_mul_div():
    rng = _rng(7)
    a = _random_dd(rng, N, -30, 30)
    b = _random_dd(rng, N, -30, 30)
    mul, div = [], []
    for x, y in zip(a, b, strict=True):
        got = dd.dd_mul(*x, *y)
        assert _is_dd(got)
        mul.append(_rel(got, _mp(x) * _mp(y)))
        got = dd.dd_div(*x, *y)
        assert _is_dd(got)
        div.append(_rel(got, _mp(x) / _mp(y)))
    _check(mul, ARITH_BOUND, "dd_mul")
    _check(div, ARITH_BOUND, "dd_div")
    # huge operands (split after scaling) and exact quotients
    for x, y in [((1e300, 1e283), (3e5, 1e-12)), ((1.5, 0.0), (0.5, 0.0))]:
        assert _rel(dd.dd_mul(*x, *y), _mp(x) * _mp(y)) <= ARITH_BOUND
        assert _rel(dd.dd_div(*x, *y), _mp(x) / _mp(y)) <= ARITH_BOUND
    assert dd.dd_div(3.0, 0.0, 3.0, 0.0) == (1.0, 0.0)


def test_sqrt():
    rng = _rng(8)
    worst = []
    for x in _random_dd(rng, N, -300, 300, signed=False):
        got = dd.dd_sqrt(*x)
        assert _is_dd(got)
        worst.append(_rel(got, MP.sqrt(_mp(x))))
    for x in [(4.0, 0.0), (2.0, 1e-17), (1.7976931348623157e308, 9e291), (1e-305, 0.0)]:
        worst.append(_rel(dd.dd_sqrt(*x), MP.sqrt(_mp(x))))
    _check(worst, ARITH_BOUND, "dd_sqrt")
    assert dd.dd_sqrt(0.0, 0.0) == (0.0, 0.0)
    assert dd.dd_sqrt(9.0, 0.0) == (3.0, 0.0)


# ---------------------------------------------------------------------------
# Elementary functions


def test_exp():
    rng = _rng(9)
    args = _uniform_dd(rng, N, -50.0, 50.0) + _random_dd(rng, N // 4, -20, 0)
    # below exp(-669) = 2**-965 the low word is subnormal and the precision falls
    args += [(700.0, 1e-14), (-660.0, 3e-14), (709.5, 0.0), (-669.0, 0.0), (0.0, 0.0)]
    worst = [_rel(dd.dd_exp(*x), MP.exp(_mp(x))) for x in args]
    _check(worst, FUNCTION_BOUND, "dd_exp")
    assert dd.dd_exp(0.0, 0.0) == (1.0, 0.0)


def test_log():
    rng = _rng(10)
    args = _random_dd(rng, N, -10, 10, signed=False)
    # near 1, where only a relative-accurate residual keeps log's relative error
    args += _with_lo(1.0 + rng.uniform(-1e-3, 1e-3, N // 4), rng)
    args += [(1.0, float(v)) for v in rng.uniform(-1e-17, 1e-17, 10)]
    args += [(1e-300, 0.0), (1e300, 1e283), (2.0, 0.0), (0.5, 1e-20)]
    worst = [_rel(dd.dd_log(*x), MP.log(_mp(x))) for x in args]
    _check(worst, FUNCTION_BOUND, "dd_log")
    assert dd.dd_log(1.0, 0.0) == (0.0, 0.0)


def _near_half_pi_multiples():
    """Double-doubles at and next to k pi/2 (rounded to a double-double), and
    the doubles nearest k pi/2."""
    args = []
    for k in range(-64, 65):
        for offset in (0, 1e-3, -1e-9, 1e-17, -1e-25, 1e-31):
            x = k * MP.pi / 2 + offset
            hi = float(x)
            args.append((hi, float(x - hi)))
            args.append((hi, 0.0))
    for k in (1000, 12345, 63661):  # up to 1e5
        x = k * MP.pi / 2
        hi = float(x)
        args.append((hi, float(x - hi)))
    return args


def test_sin_cos_sincos():
    rng = _rng(11)
    args = _uniform_dd(rng, N, -100.0, 100.0) + _random_dd(rng, N // 4, -30, 1)
    worst = []
    for x in args:
        sin_ref, cos_ref = MP.sin(_mp(x)), MP.cos(_mp(x))
        s, c = dd.dd_sin(*x), dd.dd_cos(*x)
        assert dd.dd_sincos(*x) == s + c
        worst += [_rel(s, sin_ref), _rel(c, cos_ref)]
    _check(worst, FUNCTION_BOUND, "dd_sin/dd_cos")


def test_sin_cos_near_multiples_of_half_pi():
    worst = 0.0
    for x in _near_half_pi_multiples():
        sh, sl, ch, cl = dd.dd_sincos(*x)
        worst = max(
            worst,
            float(abs(_mp((sh, sl)) - MP.sin(_mp(x)))),
            float(abs(_mp((ch, cl)) - MP.cos(_mp(x)))),
        )
    assert worst <= TRIG_ABS_BOUND, worst


def test_sin_cos_large_arguments():
    rng = _rng(12)
    worst = []
    for x in _uniform_dd(rng, N // 2, -1e5, 1e5):
        sh, sl, ch, cl = dd.dd_sincos(*x)
        worst += [_rel((sh, sl), MP.sin(_mp(x))), _rel((ch, cl), MP.cos(_mp(x)))]
    _check(worst, FUNCTION_BOUND, "dd_sincos on [-1e5, 1e5]")


def test_pow_int():
    rng = _rng(13)
    worst = []
    for x in _random_dd(rng, N // 4, -3, 3):
        for n in range(-7, 8):
            worst.append(_rel(dd.dd_pow_int(*x, n), _mp(x) ** n))
    _check(worst, FUNCTION_BOUND, "dd_pow_int")
    assert dd.dd_pow_int(3.0, 0.0, 0) == (1.0, 0.0)
    assert dd.dd_pow_int(3.0, 0.0, 5) == (243.0, 0.0)
    assert dd.dd_pow_int(2.0, 0.0, -3) == (0.125, 0.0)


def test_pow():
    rng = _rng(14)
    bases = _random_dd(rng, N, -2, 2, signed=False)
    exponents = _uniform_dd(rng, N, -8.0, 8.0)
    worst = [
        _rel(dd.dd_pow(*a, *b), _mp(a) ** _mp(b)) for a, b in zip(bases, exponents, strict=True)
    ]
    _check(worst, FUNCTION_BOUND, "dd_pow")
    assert _rel(dd.dd_pow(2.0, 0.0, 0.5, 0.0), MP.sqrt(2)) <= FUNCTION_BOUND
    assert _rel(dd.dd_pow(2.0, 0.0, 10.0, 0.0), MP.mpf(1024)) <= FUNCTION_BOUND


# ---------------------------------------------------------------------------
# Special values


def _same(got, want):
    """Tuples equal, NaN equal to NaN."""
    return len(got) == len(want) and all(
        (g == w) or (g != g and w != w) for g, w in zip(got, want, strict=True)
    )


NAN, INF = math.nan, math.inf


@pytest.mark.parametrize(
    ("function", "args", "want"),
    [
        (dd.dd_add, (INF, 0.0, 1.0, 0.0), (INF, 0.0)),
        (dd.dd_add, (INF, 0.0, -INF, 0.0), (NAN, 0.0)),
        (dd.dd_add, (1e308, 0.0, 1e308, 0.0), (INF, 0.0)),
        (dd.dd_add, (NAN, 0.0, 1.0, 0.0), (NAN, 0.0)),
        (dd.dd_sub, (INF, 0.0, INF, 0.0), (NAN, 0.0)),
        (dd.dd_add_d, (1.0, 0.0, -INF), (-INF, 0.0)),
        (dd.dd_mul, (INF, 0.0, 2.0, 0.0), (INF, 0.0)),
        (dd.dd_mul, (INF, 0.0, 0.0, 0.0), (NAN, 0.0)),
        (dd.dd_mul, (1e200, 0.0, -1e200, 0.0), (-INF, 0.0)),
        (dd.dd_mul_d, (1e200, 0.0, 1e200), (INF, 0.0)),
        (dd.dd_div, (1.0, 0.0, 0.0, 0.0), (INF, 0.0)),
        (dd.dd_div, (-1.0, 0.0, 0.0, 0.0), (-INF, 0.0)),
        (dd.dd_div, (0.0, 0.0, 0.0, 0.0), (NAN, 0.0)),
        (dd.dd_div, (1.0, 0.0, INF, 0.0), (0.0, 0.0)),
        (dd.dd_div, (INF, 0.0, 2.0, 0.0), (INF, 0.0)),
        (dd.dd_div, (1e300, 0.0, 1e-300, 0.0), (INF, 0.0)),
        (dd.dd_sqrt, (-1.0, 0.0), (NAN, NAN)),
        (dd.dd_sqrt, (INF, 0.0), (INF, 0.0)),
        (dd.dd_sqrt, (NAN, 0.0), (NAN, NAN)),
        (dd.dd_exp, (710.0, 0.0), (INF, 0.0)),
        (dd.dd_exp, (709.79, 0.0), (INF, 0.0)),
        (dd.dd_exp, (INF, 0.0), (INF, 0.0)),
        (dd.dd_exp, (-INF, 0.0), (0.0, 0.0)),
        (dd.dd_exp, (-800.0, 0.0), (0.0, 0.0)),
        (dd.dd_exp, (NAN, 0.0), (NAN, NAN)),
        (dd.dd_log, (0.0, 0.0), (-INF, 0.0)),
        (dd.dd_log, (-1.0, 0.0), (NAN, NAN)),
        (dd.dd_log, (INF, 0.0), (INF, 0.0)),
        (dd.dd_log, (NAN, 0.0), (NAN, NAN)),
        (dd.dd_sin, (INF, 0.0), (NAN, NAN)),
        (dd.dd_cos, (NAN, 0.0), (NAN, NAN)),
        (dd.dd_sincos, (-INF, 0.0), (NAN, NAN, NAN, NAN)),
        (dd.dd_sin, (1e300, 0.0), (math.sin(1e300), 0.0)),
        (dd.dd_pow, (-2.0, 0.0, 0.5, 0.0), (NAN, NAN)),
        (dd.dd_pow, (0.0, 0.0, 2.0, 0.0), (0.0, 0.0)),
        (dd.dd_pow, (0.0, 0.0, -2.0, 0.0), (INF, 0.0)),
        (dd.dd_pow, (NAN, 0.0, 0.0, 0.0), (1.0, 0.0)),
        (dd.dd_pow, (1.0, 0.0, INF, 0.0), (1.0, 0.0)),
        (dd.dd_pow, (2.0, 0.0, INF, 0.0), (INF, 0.0)),
        (dd.dd_pow, (0.5, 0.0, INF, 0.0), (0.0, 0.0)),
        (dd.dd_pow, (10.0, 0.0, 400.0, 0.0), (INF, 0.0)),
        (dd.dd_pow_int, (0.0, 0.0, -2), (INF, 0.0)),
        (dd.dd_pow_int, (NAN, 0.0, 0), (1.0, 0.0)),
        (dd.dd_pow_int, (1e200, 0.0, 2), (INF, 0.0)),
    ],
)
def test_special_values(function, args, want):
    assert _same(function(*args), want), function(*args)


def test_exp_near_overflow_and_underflow():
    big = dd.dd_exp(709.78, 0.0)  # below the overflow threshold, 2**1024 scaling
    assert math.isfinite(big[0])
    assert _rel(big, MP.exp(709.78)) <= FUNCTION_BOUND
    tiny = dd.dd_exp(-745.0, 0.0)  # subnormal: the double result
    assert tiny[0] == float(MP.exp(-745)) and tiny[1] == 0.0


# ---------------------------------------------------------------------------
# Compiled == interpreted, bit for bit

#: Results per input row of :func:`_every_function`.
WIDTH = 38


@jitable
def _every_function(ah, al, bh, bl, n, out):
    """Every public function on one input row, its results written to out."""
    out[0], out[1] = dd.two_sum(ah, bh)
    out[2], out[3] = dd.fast_two_sum(ah, bh) if abs(ah) >= abs(bh) else dd.fast_two_sum(bh, ah)
    out[4], out[5] = dd.two_prod(ah, bh)
    out[6], out[7] = dd.dd_add(ah, al, bh, bl)
    out[8], out[9] = dd.dd_sub(ah, al, bh, bl)
    out[10], out[11] = dd.dd_mul(ah, al, bh, bl)
    out[12], out[13] = dd.dd_div(ah, al, bh, bl)
    out[14], out[15] = dd.dd_add_d(ah, al, bh)
    out[16], out[17] = dd.dd_mul_d(ah, al, bh)
    out[18], out[19] = dd.dd_sqrt(ah, al)
    out[20], out[21] = dd.dd_exp(ah, al)
    out[22], out[23] = dd.dd_log(ah, al)
    out[24], out[25], out[26], out[27] = dd.dd_sincos(ah, al)
    out[28], out[29] = dd.dd_sin(ah, al)
    out[30], out[31] = dd.dd_cos(ah, al)
    out[32], out[33] = dd.dd_pow_int(ah, al, n)
    out[34], out[35] = dd.dd_pow(ah, al, bh, bl)
    out[36], out[37] = dd.dd_neg(ah, al)


def _inputs():
    rng = _rng(15)
    count = 300
    a = _uniform_dd(rng, count // 3, -60.0, 60.0) + _random_dd(rng, count // 3, -12, 12)
    a += _random_dd(rng, count - len(a), -300, 300)
    b = _random_dd(rng, count // 2, -3, 3) + _uniform_dd(rng, count - count // 2, -9.0, 9.0)
    special = [(0.0, 0.0), (-0.0, 0.0), (INF, 0.0), (-INF, 0.0), (NAN, 0.0), (1e300, 1e283)]
    for x in special:
        for y in [*special, (2.0, 0.0), (-0.5, 0.0)]:
            a.append(x)
            b.append(y)
    a = np.array(a, dtype=float)
    b = np.array(b, dtype=float)
    n = rng.integers(-7, 8, len(a)).astype(np.int64)
    return a[:, 0].copy(), a[:, 1].copy(), b[:, 0].copy(), b[:, 1].copy(), n


def test_compiled_is_bit_identical_to_python():
    numba = pytest.importorskip("numba")

    @numba.njit
    def run(ah, al, bh, bl, n, out):
        for i in range(ah.shape[0]):
            _every_function(ah[i], al[i], bh[i], bl[i], n[i], out[i])

    ah, al, bh, bl, n = _inputs()
    compiled = np.zeros((len(ah), WIDTH))
    run(ah, al, bh, bl, n, compiled)
    interpreted = np.zeros((len(ah), WIDTH))
    for i in range(len(ah)):
        args = float(ah[i]), float(al[i]), float(bh[i]), float(bl[i]), int(n[i])
        _every_function(*args, interpreted[i])
    assert np.array_equal(compiled, interpreted, equal_nan=True)
