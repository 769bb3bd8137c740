"""Scalar double-double arithmetic, for the interpreted and the compiled kernel.

A double-double ("dd") number is an unevaluated sum ``hi + lo`` of two
float64 values with ``|lo| <= ulp(hi) / 2``: about 106 significant bits
(32 decimal digits) with the exponent range of a double.  Every function here
takes and returns such pairs as separate floats -- ``dd_mul(ah, al, bh, bl)``
returns the tuple ``(hi, lo)`` -- so that nothing is allocated.

Sources of the algorithms (the code is written from the published
descriptions):

* error-free transformations: TwoSum (Knuth, *The Art of Computer
  Programming* vol. 2, 4.2.2), Fast2Sum and the product by Veltkamp's splitting
  (Dekker, "A floating-point technique for extending the available
  precision", Numer. Math. 18, 1971); no fused multiply-add is assumed;
* addition, multiplication and the products and sums with a double:
  Joldes, Muller & Popescu, "Tight and rigorous error bounds for basic
  building blocks of double-word arithmetic", ACM TOMS 44(2), 2017
  (AccurateDWPlusDW, DWPlusFP, DWTimesFP1, DWTimesDW1);
* division: the quotient of the leading words corrected twice by exactly
  computed remainders, as in the "accurate" division of the QD library
  (Hida, Li & Bailey, "Algorithms for quad-double precision floating point
  arithmetic", ARITH-15, 2001);
* square root: one Newton (Karp-Markstein) correction of ``math.sqrt``;
* exp, log, sin, cos: Cody-Waite argument reduction with ln 2 and pi/2 held
  as triple-doubles, Taylor series evaluated in double-double (the tail
  terms, below 1e-17 of the result, in double), and for exp the scaling
  ``r / 2**8`` undone by doubling ``expm1`` (``E <- 2E + E**2``, which keeps
  the relative accuracy that squaring ``1 + E`` would lose); log is one
  Newton step on ``exp(y) = a`` from ``math.log`` of the reduced argument.

Accuracy (relative; u = 2**-53, u**2 = 2**-106 = 1.2e-32, about what the
rounding of an exact value to a double-double alone costs): proven bounds
3 u**2 for add and sub (also under cancellation), 2 u**2 for ``dd_add_d``,
1.5 u**2 for ``dd_mul_d`` and 7 u**2 for ``dd_mul`` (Joldes et al.);
measured maxima (20000 random arguments each) below 3e-32 for these, division and
square root, and below 1e-31 for exp (|x| <= 709), log (any a > 0, also
near 1), sin and cos (|x| <= 2**50; near their zeros an absolute error below
1e-32).  ``dd_pow_int`` adds about one product's error per multiplication;
``dd_pow`` has an error of about 4e-32 times ``|b log a|``, from the
double-double ``b log a`` (past 1e-29 for ``|b log a|`` above about 250).
Full precision needs ``|hi| >= 2**-969`` (about 2e-292): below, the low word
is subnormal and the precision falls towards a double's.  The error-free
transformations are exact unless the result overflows or (for ``two_prod``)
the product falls below 2**-969, where its error term would be subnormal.

Special values: a sum, difference, product or quotient (and ``dd_pow_int``)
whose double result is not finite is returned as ``(v, 0.0)`` with ``v`` that
inf or nan.  The functions return ``(inf, 0.0)`` on overflow, ``(0.0, 0.0)``
on underflow and ``(nan, nan)`` for a NaN result (sqrt or log of a negative
number, pow of a negative base, sin or cos of an infinity, a NaN argument;
``dd_pow`` gives 1 for ``b == 0`` or ``a == 1`` as IEEE ``pow`` does).
Nothing raises and nothing loops on any input.

Every function is ``@jitable``: one source that the interpreted backend calls
as plain Python and that numba compiles into the kernel, with the same bits
in both (no fused multiply-add, no reassociation).  They use only float
arithmetic, :mod:`math` and tuples.
"""

from __future__ import annotations

import math
from fractions import Fraction

from hamrkq.rkq.jit import jitable

__all__ = [
    "dd_add",
    "dd_add_d",
    "dd_cos",
    "dd_div",
    "dd_exp",
    "dd_log",
    "dd_mul",
    "dd_mul_d",
    "dd_neg",
    "dd_pow",
    "dd_pow_int",
    "dd_sin",
    "dd_sincos",
    "dd_sqrt",
    "dd_sub",
    "fast_two_sum",
    "two_prod",
    "two_sum",
]

_INF = math.inf
_NAN = math.nan

# Veltkamp's splitter 2**27 + 1; above 2**996 the operand is scaled down by
# 2**28 first, so that splitter * a cannot overflow.
_SPLITTER = 134217729.0
_SPLIT_LIMIT = 2.0**996
_SPLIT_DOWN = 2.0**-28
_SPLIT_UP = 2.0**28

# (t + _ROUND) - _ROUND is t rounded to the nearest integer, for |t| < 2**51.
_ROUND = 6755399441055744.0  # 1.5 * 2**52

# ln 2 and pi / 2 as triple-doubles (checked against mpmath in the tests).
_LN2_1 = 0.6931471805599453
_LN2_2 = 2.3190468138462996e-17
_LN2_3 = 5.707708438416212e-34
_INV_LN2 = 1.4426950408889634
_PIO2_1 = 1.5707963267948966
_PIO2_2 = 6.123233995736766e-17
_PIO2_3 = -1.4973849048591698e-33
_TWO_OVER_PI = 0.6366197723675814
_PIO4 = 0.7853981633974483
_SQRT_HALF = 0.7071067811865476

# exp overflows above, and underflows to zero below, these arguments.
_EXP_MAX = 709.79
_EXP_MIN = -745.2
# expm1(r), |r| <= ln(2) / 2, is summed at r / 2**_EXP_HALVINGS.
_EXP_HALVINGS = 8
_EXP_SCALE = 2.0**-_EXP_HALVINGS
# Beyond 2**50 the triple-double pi / 2 no longer reduces to 1e-32.
_TRIG_MAX = 2.0**50
# sqrt scales arguments outside [2**-600, 2**600] by 2**-+600, the roots by 2**+-300.
_SQRT_BIG = 2.0**600
_SQRT_SMALL = 2.0**-600
_SQRT_ROOT_BIG = 2.0**300
_SQRT_ROOT_SMALL = 2.0**-300


def _dd(value: Fraction) -> tuple[float, float]:
    """The double-double nearest a rational (at import; not jitable)."""
    hi = float(value)
    return hi, float(value - Fraction(hi))


def _series(sign: int, first: int, count: int, step: int) -> list[tuple[float, float]]:
    """``sign**j / (first + step j)!`` for j = 0 .. count - 1, as double-doubles."""
    return [_dd(Fraction(sign**j, math.factorial(first + step * j))) for j in range(count)]


# expm1(t) = t (1 + t (1/2 + t (1/3! + ... + t / 9!))): 1 .. 1/5! in double-double,
# 1/6! .. 1/9! (terms below 1e-17 of the sum at |t| <= 1.4e-3) in double.
_EXP_COEF = _series(1, 1, 9, 1)
_EXP_HI = tuple(c[0] for c in _EXP_COEF[:5])
_EXP_LO = tuple(c[1] for c in _EXP_COEF[:5])
_EXP_TAIL = tuple(c[0] for c in _EXP_COEF[5:])
# sin(r) = r (1 + z (-1/3! + z (1/5! - ...))), z = r**2, to r**27 / 27!;
# cos(r) = 1 + z (-1/2! + z (1/4! - ...)), to r**28 / 28!  (|r| <= pi / 4).
_SIN_COEF = [(-a, -b) for a, b in _series(-1, 3, 13, 2)]  # starts at -1/3!
_SIN_HI = tuple(c[0] for c in _SIN_COEF[:8])
_SIN_LO = tuple(c[1] for c in _SIN_COEF[:8])
_SIN_TAIL = tuple(c[0] for c in _SIN_COEF[8:])
_COS_COEF = [(-a, -b) for a, b in _series(-1, 2, 14, 2)]  # starts at -1/2!
_COS_HI = tuple(c[0] for c in _COS_COEF[:8])
_COS_LO = tuple(c[1] for c in _COS_COEF[:8])
_COS_TAIL = tuple(c[0] for c in _COS_COEF[8:])


# ----------------------------------------------------------------------------
# Error-free transformations


@jitable
def two_sum(a, b):
    """Knuth's TwoSum: ``s + e == a + b`` exactly, ``s = fl(a + b)``.

    Exact for any finite a, b whose sum does not overflow; no ordering needed.
    """
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)
    return s, e


@jitable
def fast_two_sum(a, b):
    """Dekker's Fast2Sum: ``s + e == a + b`` exactly, ``s = fl(a + b)``.

    Requires ``|a| >= |b|`` (or ``a == 0``).
    """
    s = a + b
    e = b - (s - a)
    return s, e


@jitable
def _split(a):
    """Veltkamp's splitting: ``a = hi + lo``, each with at most 26 bits
    (for ``|a| <= 2**996``, where ``splitter * a`` cannot overflow)."""
    t = _SPLITTER * a
    hi = t - (t - a)
    return hi, a - hi


@jitable
def _dekker_prod(a, b):
    """Dekker's product for ``|a|, |b| <= 2**996``."""
    p = a * b
    a1, a2 = _split(a)
    b1, b2 = _split(b)
    e = ((a1 * b1 - p) + a1 * b2 + a2 * b1) + a2 * b2
    return p, e


@jitable
def two_prod(a, b):
    """Dekker's exact product without FMA: ``p + e == a * b``, ``p = fl(a b)``.

    An operand above 2**996 in magnitude is scaled by 2**-28 before the
    splitting and the product scaled back after (exact: powers of two).
    Exact unless ``a b`` overflows or is below 2**-969 in magnitude (where
    ``e`` would be subnormal).
    """
    if a > _SPLIT_LIMIT or a < -_SPLIT_LIMIT:
        p, e = _dekker_prod(a * _SPLIT_DOWN, b)
        return p * _SPLIT_UP, e * _SPLIT_UP
    if b > _SPLIT_LIMIT or b < -_SPLIT_LIMIT:
        p, e = _dekker_prod(a, b * _SPLIT_DOWN)
        return p * _SPLIT_UP, e * _SPLIT_UP
    return _dekker_prod(a, b)


@jitable
def _nonfinite(z, v):
    """A nonfinite result ``z``: ``(v, 0)`` if z is a NaN made from the
    nonfinite double result v, else ``(z, 0)``."""
    if z != z and not math.isfinite(v):
        return v, 0.0
    return z, 0.0


# ----------------------------------------------------------------------------
# Arithmetic


@jitable
def dd_neg(ah, al):
    """``-a``."""
    return -ah, -al


@jitable
def dd_add(ah, al, bh, bl):
    """``a + b`` (AccurateDWPlusDW of Joldes, Muller & Popescu).

    Relative error at most 3 u**2 + 13 u**3 (u = 2**-53), also under
    cancellation.

    Returns
    -------
    (hi, lo) : tuple of float
    """
    sh, sl = two_sum(ah, bh)
    th, tl = two_sum(al, bl)
    c = sl + th
    vh, vl = fast_two_sum(sh, c)
    w = tl + vl
    zh, zl = fast_two_sum(vh, w)
    if math.isfinite(zh):
        return zh, zl
    return _nonfinite(zh, sh)


@jitable
def dd_sub(ah, al, bh, bl):
    """``a - b``, as :func:`dd_add` of ``-b``."""
    return dd_add(ah, al, -bh, -bl)


@jitable
def dd_add_d(ah, al, b):
    """``a + b`` for a double b (DWPlusFP; relative error at most 2 u**2)."""
    sh, sl = two_sum(ah, b)
    v = al + sl
    zh, zl = fast_two_sum(sh, v)
    if math.isfinite(zh):
        return zh, zl
    return _nonfinite(zh, sh)


@jitable
def dd_mul_d(ah, al, b):
    """``a * b`` for a double b (DWTimesFP1; relative error at most 1.5 u**2)."""
    ch, cl1 = two_prod(ah, b)
    cl2 = al * b
    th, tl1 = fast_two_sum(ch, cl2)
    tl2 = tl1 + cl1
    zh, zl = fast_two_sum(th, tl2)
    if math.isfinite(zh):
        return zh, zl
    return _nonfinite(zh, ah * b)


@jitable
def dd_mul(ah, al, bh, bl):
    """``a * b`` (DWTimesDW1, no FMA; relative error at most 7 u**2).

    Returns
    -------
    (hi, lo) : tuple of float
    """
    ch, cl1 = two_prod(ah, bh)
    cl2 = ah * bl + al * bh
    cl3 = cl1 + cl2
    zh, zl = fast_two_sum(ch, cl3)
    if math.isfinite(zh):
        return zh, zl
    return _nonfinite(zh, ah * bh)


@jitable
def dd_div(ah, al, bh, bl):
    """``a / b``: ``ah / bh`` corrected by two exactly computed remainders.

    Relative error about u**2 (the rounding of the result to a double-double).
    ``b == 0`` gives ``(+-inf, 0.0)``, or ``(nan, 0.0)`` for ``0 / 0``.

    Returns
    -------
    (hi, lo) : tuple of float
    """
    if bh == 0.0:
        if ah == 0.0 or ah != ah:
            return _NAN, 0.0
        return math.copysign(_INF, ah) * math.copysign(1.0, bh), 0.0
    q1 = ah / bh
    if q1 == 0.0 or not math.isfinite(q1):
        return q1, 0.0
    # r = a - q1 b to a few u**3 |a|: q1 bh is exact, and ah - p1 (Sterbenz).
    p1, p2 = two_prod(q1, bh)
    t1, t2 = two_prod(q1, bl)
    s, e1 = two_sum(ah - p1, al)
    s, e2 = two_sum(s, -p2)
    s, e3 = two_sum(s, -t1)
    rh, rl = fast_two_sum(s, ((e1 + e2) + e3) - t2)
    q2 = rh / bh
    # r - q2 b, to relative accuracy u: its terms are all near u |r|.
    p3, p4 = two_prod(q2, bh)
    q3 = ((((rh - p3) - p4) + rl) - q2 * bl) / bh
    zh, zl = fast_two_sum(q1, q2)
    return fast_two_sum(zh, zl + q3)


@jitable
def dd_pow_int(ah, al, n):
    """``a ** n`` for an integer n, by binary powering (``a ** 0 == 1``).

    A negative n takes the reciprocal of ``a ** -n``.

    Parameters
    ----------
    ah, al : float
        The base.
    n : int
        The exponent.

    Returns
    -------
    (hi, lo) : tuple of float
    """
    m = -n if n < 0 else n
    rh, rl = 1.0, 0.0
    bh, bl = ah, al
    while m > 0:
        if m & 1:
            rh, rl = dd_mul(rh, rl, bh, bl)
        m >>= 1
        if m > 0:
            bh, bl = dd_mul(bh, bl, bh, bl)
    if n < 0:
        return dd_div(1.0, 0.0, rh, rl)
    return rh, rl


# ----------------------------------------------------------------------------
# Elementary functions


@jitable
def dd_sqrt(ah, al):
    """``sqrt(a)`` for a >= 0: ``s = math.sqrt(ah)`` and one Newton correction
    ``(a - s**2) / 2s``, the residual from the exact ``s**2`` (relative error
    a few u**2).

    ``sqrt(+-0) = (+-0, 0)``; a negative a gives ``(nan, nan)``.
    """
    if not ah > 0.0:
        if ah == 0.0:
            return ah, 0.0
        return _NAN, _NAN
    if ah == _INF:
        return _INF, 0.0
    # keep s * s clear of overflow and of subnormals
    if ah > _SQRT_BIG:
        sh, sl = _sqrt_normal(ah * _SQRT_SMALL, al * _SQRT_SMALL)
        return sh * _SQRT_ROOT_BIG, sl * _SQRT_ROOT_BIG
    if ah < _SQRT_SMALL:
        sh, sl = _sqrt_normal(ah * _SQRT_BIG, al * _SQRT_BIG)
        return sh * _SQRT_ROOT_SMALL, sl * _SQRT_ROOT_SMALL
    return _sqrt_normal(ah, al)


@jitable
def _sqrt_normal(ah, al):
    """:func:`dd_sqrt` for 2**-600 <= a <= 2**600 (with a margin)."""
    s = math.sqrt(ah)
    p, e = two_prod(s, s)
    r = ((ah - p) - e) + al  # a - s**2; ah - p is exact (Sterbenz)
    return fast_two_sum(s, r / (s + s))


@jitable
def _expm1_reduced(rh, rl):
    """``expm1(r)`` for ``|r| <= 0.35``, to relative accuracy a few u**2.

    Taylor series at ``t = r / 2**8`` (truncated after t**9 / 9!), then eight
    doublings ``E(2t) = 2 E(t) + E(t)**2``.
    """
    th = rh * _EXP_SCALE
    tl = rl * _EXP_SCALE
    p = _EXP_TAIL[len(_EXP_TAIL) - 1]
    for i in range(len(_EXP_TAIL) - 2, -1, -1):
        p = _EXP_TAIL[i] + th * p
    ph, pl = p, 0.0
    for i in range(len(_EXP_HI) - 1, -1, -1):
        mh, ml = dd_mul(ph, pl, th, tl)
        ph, pl = dd_add(mh, ml, _EXP_HI[i], _EXP_LO[i])
    eh, el = dd_mul(ph, pl, th, tl)
    for _ in range(_EXP_HALVINGS):
        sh, sl = dd_mul(eh, el, eh, el)
        eh, el = dd_add(eh + eh, el + el, sh, sl)
    return eh, el


@jitable
def _reduce(xh, xl, k, c1, c2, c3):
    """``x - k c`` for an integer-valued float k and ``c = c1 + c2 + c3`` a
    triple-double, accurate to a few u**2 of the result."""
    a1, b1 = two_prod(k, c1)
    a2, b2 = two_prod(k, c2)
    sh, sl = two_sum(xh, -a1)
    sh, sl = dd_add_d(sh, sl, xl)
    sh, sl = dd_add_d(sh, sl, -b1)
    sh, sl = dd_add_d(sh, sl, -a2)
    return dd_add_d(sh, sl, -(b2 + k * c3))


@jitable
def dd_exp(ah, al):
    """``exp(a)``: ``a = k ln 2 + r``, ``exp(a) = 2**k (1 + expm1(r))``.

    Relative error a few u**2 (a few 1e-32); ``(inf, 0)`` above 709.79,
    ``(0, 0)`` below -745.2 (subnormal results are rounded to a double).
    """
    if ah != ah:
        return _NAN, _NAN
    if ah > _EXP_MAX:
        return _INF, 0.0
    if ah < _EXP_MIN:
        return 0.0, 0.0
    k = (ah * _INV_LN2 + _ROUND) - _ROUND
    rh, rl = _reduce(ah, al, k, _LN2_1, _LN2_2, _LN2_3)
    eh, el = _expm1_reduced(rh, rl)
    yh, yl = dd_add_d(eh, el, 1.0)
    n = int(k)
    if n > 1023:  # 2**n itself overflows, the result may not
        zh = math.ldexp(yh, n - 1) * 2.0
        if not math.isfinite(zh):
            return _INF, 0.0
        return zh, math.ldexp(yl, n - 1) * 2.0
    return math.ldexp(yh, n), math.ldexp(yl, n)


@jitable
def dd_log(ah, al):
    """``log(a)`` for a > 0.

    ``a = 2**e f`` with ``sqrt(1/2) <= f < sqrt(2)``; ``y0 = log(fh) + fl/fh``
    in double, then one Newton step ``y = y0 + f exp(-y0) - 1`` with
    ``f exp(-y0) - 1 = d + E + d E`` (``d = f - 1`` exact, ``E = expm1(-y0)``),
    accurate relative to y also near ``a = 1``; then ``y + e ln 2``.  Relative
    error a few u**2.  ``log(0) = (-inf, 0)``; a negative a gives
    ``(nan, nan)``.
    """
    if not ah > 0.0:
        if ah == 0.0:
            return -_INF, 0.0
        return _NAN, _NAN
    if ah == _INF:
        return _INF, 0.0
    e = math.frexp(ah)[1]
    if math.ldexp(ah, -e) < _SQRT_HALF:
        e -= 1
    fh = math.ldexp(ah, -e)
    fl = math.ldexp(al, -e)
    y0 = math.log(fh) + fl / fh
    eh, el = _expm1_reduced(-y0, 0.0)
    dh, dl = two_sum(fh - 1.0, fl)  # fh - 1 is exact
    th, tl = dd_add(dh, dl, eh, el)
    mh, ml = dd_mul(dh, dl, eh, el)
    rh, rl = dd_add(th, tl, mh, ml)
    yh, yl = dd_add_d(rh, rl, y0)
    if e == 0:
        return yh, yl
    ef = float(e)
    k1, k2 = two_prod(ef, _LN2_1)
    k3, k4 = two_prod(ef, _LN2_2)
    sh, sl = dd_add(k1, k2, k3, k4 + ef * _LN2_3)
    return dd_add(sh, sl, yh, yl)


@jitable
def _reduce_pio2(xh, xl):
    """``x = k pi/2 + r`` with ``|r| <= pi/4``: ``(rh, rl, k mod 4)``, r to an
    absolute error of a few 1e-33 for ``|x| <= 2**50``."""
    if -_PIO4 <= xh <= _PIO4:
        return xh, xl, 0
    k = (xh * _TWO_OVER_PI + _ROUND) - _ROUND
    rh, rl = _reduce(xh, xl, k, _PIO2_1, _PIO2_2, _PIO2_3)
    return rh, rl, int(k) & 3


@jitable
def _sin_taylor(rh, rl, zh, zl):
    """``sin(r)`` for ``|r| <= pi/4``, given ``z = r**2``."""
    p = _SIN_TAIL[len(_SIN_TAIL) - 1]
    for i in range(len(_SIN_TAIL) - 2, -1, -1):
        p = _SIN_TAIL[i] + zh * p
    ph, pl = p, 0.0
    for i in range(len(_SIN_HI) - 1, -1, -1):
        mh, ml = dd_mul(ph, pl, zh, zl)
        ph, pl = dd_add(mh, ml, _SIN_HI[i], _SIN_LO[i])
    mh, ml = dd_mul(ph, pl, zh, zl)
    mh, ml = dd_mul(mh, ml, rh, rl)
    return dd_add(rh, rl, mh, ml)


@jitable
def _cos_taylor(zh, zl):
    """``cos(r)`` for ``|r| <= pi/4``, given ``z = r**2``."""
    p = _COS_TAIL[len(_COS_TAIL) - 1]
    for i in range(len(_COS_TAIL) - 2, -1, -1):
        p = _COS_TAIL[i] + zh * p
    ph, pl = p, 0.0
    for i in range(len(_COS_HI) - 1, -1, -1):
        mh, ml = dd_mul(ph, pl, zh, zl)
        ph, pl = dd_add(mh, ml, _COS_HI[i], _COS_LO[i])
    mh, ml = dd_mul(ph, pl, zh, zl)
    return dd_add_d(mh, ml, 1.0)


@jitable
def dd_sincos(ah, al):
    """``(sin a, cos a)`` as ``(sh, sl, ch, cl)``, sharing the reduction.

    Reduction by pi/2 (a triple-double), Taylor series on ``|r| <= pi/4``.
    Relative error a few u**2, absolute a few 1e-33 near the zeros, for
    ``|a| <= 2**50``; beyond that the double values ``math.sin(ah)``,
    ``math.cos(ah)`` with zero low words; ``(nan, nan)`` for inf or nan.
    """
    if not math.isfinite(ah):
        return _NAN, _NAN, _NAN, _NAN
    if not -_TRIG_MAX <= ah <= _TRIG_MAX:
        return math.sin(ah), 0.0, math.cos(ah), 0.0
    rh, rl, q = _reduce_pio2(ah, al)
    zh, zl = dd_mul(rh, rl, rh, rl)
    sh, sl = _sin_taylor(rh, rl, zh, zl)
    ch, cl = _cos_taylor(zh, zl)
    if q == 0:
        return sh, sl, ch, cl
    if q == 1:
        return ch, cl, -sh, -sl
    if q == 2:
        return -sh, -sl, -ch, -cl
    return -ch, -cl, sh, sl


@jitable
def _sin_from_quadrant(ah, al, shift):
    """``sin(a + shift pi/2)`` for ``shift`` 0 (sine) or 1 (cosine): the
    reduced argument's series for the quadrant ``q + shift`` of ``a``."""
    if not math.isfinite(ah):
        return _NAN, _NAN
    if not -_TRIG_MAX <= ah <= _TRIG_MAX:
        return (math.sin(ah) if shift == 0 else math.cos(ah)), 0.0
    rh, rl, q = _reduce_pio2(ah, al)
    q = (q + shift) & 3
    zh, zl = dd_mul(rh, rl, rh, rl)
    if q & 1:
        vh, vl = _cos_taylor(zh, zl)
    else:
        vh, vl = _sin_taylor(rh, rl, zh, zl)
    if q >= 2:
        return -vh, -vl
    return vh, vl


@jitable
def dd_sin(ah, al):
    """``sin(a)``; accuracy and special values as :func:`dd_sincos`."""
    return _sin_from_quadrant(ah, al, 0)


@jitable
def dd_cos(ah, al):
    """``cos(a)``; accuracy and special values as :func:`dd_sincos`."""
    return _sin_from_quadrant(ah, al, 1)


@jitable
def dd_pow(ah, al, bh, bl):
    """``a ** b = exp(b log a)`` for a >= 0.

    Relative error a few u**2 times ``max(1, |b log a|)``.  ``a ** 0 = 1``
    and ``1 ** b = 1`` for every b; ``0 ** b`` is 0 for b > 0 and inf for
    b < 0; a negative base or a NaN gives ``(nan, nan)``.

    Parameters
    ----------
    ah, al : float
        The base a.
    bh, bl : float
        The exponent b.

    Returns
    -------
    (hi, lo) : tuple of float
    """
    if bh == 0.0 or (ah == 1.0 and al == 0.0):
        return 1.0, 0.0
    if ah != ah or bh != bh or ah < 0.0:
        return _NAN, _NAN
    if ah == 0.0:
        if bh > 0.0:
            return 0.0, 0.0
        return _INF, 0.0
    lh, ll = dd_log(ah, al)
    mh, ml = dd_mul(bh, bl, lh, ll)
    return dd_exp(mh, ml)
