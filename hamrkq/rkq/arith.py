"""Vector arithmetic of the step kernel, as element loops.

Every function here runs as written in the interpreter and compiles under
``numba.njit`` unchanged (:mod:`hamrkq.backends.compiled`): one source for
both backends.  Element loops are the right shape for the compiled kernel
(a NumPy call on a vector of a few elements costs more than the arithmetic)
and they fix the order of every sum, so the two backends compute the same
bits.  Nothing here allocates.
"""

from __future__ import annotations

import math

from hamrkq._floats import EPS
from hamrkq.rkq.jit import jitable
from hamrkq.rkq.layout import RULE_PRENTICE


@jitable
def fmax(x, y):
    """``np.fmax`` for two floats: the larger, ignoring a NaN."""
    return x if (x >= y or y != y) else y


@jitable
def all_finite(x) -> bool:
    """Whether every element is finite (inf and nan poison the sum)."""
    total = 0.0
    for i in range(x.shape[0]):
        total += x[i]
    return math.isfinite(total)


@jitable
def first_nonfinite(x) -> int:
    """Index of the first inf or nan element, or -1."""
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return i
    return -1


@jitable
def copy(src, out):
    """``out[:] = src``."""
    for i in range(out.shape[0]):
        out[i] = src[i]


@jitable
def vmax(x):
    """The largest element; NaN if any element is NaN (as ``ndarray.max``)."""
    top = -math.inf
    for i in range(x.shape[0]):
        value = x[i]
        if value != value:
            return value
        if value > top:
            top = value
    return top


@jitable
def stage_value(base, h, A, j, K, out):
    """``out = base + h sum_{l<j} A[j, l] K[l]``, each component's sum added
    in the order l = 0, 1, ..."""
    for i in range(out.shape[0]):
        acc = 0.0
        for m in range(j):
            acc += A[j, m] * K[m, i]
        out[i] = acc * h + base[i] if j else base[i]


#: The fractional part of the golden ratio: ``frac(n GOLDEN)``, n = 0, 1,
#: ..., is Weyl's equidistributed sequence in [0, 1).
GOLDEN = 0.6180339887498949


@jitable
def uniform(seed):
    """A number in [0, 1) for the integer ``seed`` (a float): Weyl's
    sequence, the same on every backend."""
    x = seed * GOLDEN
    return x - math.floor(x)


@jitable
def round_stochastically(big, small, u):
    """``big + small`` rounded to one of the two doubles around it, the
    farther with probability its distance over their spacing, decided by
    ``u`` in [0, 1): stochastic rounding, an unbiased rounding independent of
    round-to-nearest's."""
    nearest = big + small
    back = nearest - big
    residual = (big - (nearest - back)) + (small - back)  # exact (TwoSum)
    if residual == 0.0 or not math.isfinite(nearest):
        return nearest
    # The neighbour on the residual's side: 0.75 eps |nearest| is between
    # 0.75 and 1.5 of its spacing, so the sum rounds to the next double (a
    # call of nextafter here made the outer solar system's run 70 % slower).
    step = 0.75 * EPS * abs(nearest)
    other = nearest + (step if residual > 0.0 else -step)
    if u * abs(other - nearest) < abs(residual):
        return other
    return nearest


@jitable
def stage_value_compensated(base, lo, h, A, A_low, j, K, out, reverse=False, seed=-1.0):
    """``out = base + (lo + h sum_{l<j} (A + A_low)[j, l] K[l])``: a stage
    from the compensated state ``(base, lo)`` with double-double
    coefficients (the low words summed apart, then added once); the sum runs
    over l = 0, 1, ... or, with ``reverse``, the other way (another rounding
    of the same value: the rounding witness's).  With ``seed >= 0`` each
    component is rounded stochastically (:func:`round_stochastically`, the
    seeds ``seed + i``): rounded to nearest, two tracks whose exact stage
    values differ by less than an ulp get the same double, so the witness
    would share the quencher's rounding of every stage value, which is what
    dominates where ``h J`` is large and the weights are (DOP853's absolute
    weights sum to 12.9: the Arenstorf orbit near the Moon).

    Four (or two) components' sums run side by side, in accumulators the
    processor adds in parallel (one component's sum alone waits on each
    addition), and zero coefficients are skipped (a zero term adds an exact
    zero); each component's sum is the same sequence of roundings either
    way (``tests/test_rkq_core.py``).  Measured on whole runs
    (``benchmarks/stage_sums.txt``): the outer solar system's ``auto`` 1.3
    times faster, prentice2011's 1.1 to 1.3.  The sums are written out
    here: a helper returning them and sums kept in arrays were slower in
    the kernel, a vectorised loop over whole rows no faster
    (docs/performance.md).  The pair's plain :func:`stage_value`, a smaller
    share of the work, measured the same either way and stays simple."""
    d = out.shape[0]
    i = 0
    while i < d:
        if i + 4 <= d:
            s0 = s1 = s2 = s3 = 0.0
            t0 = t1 = t2 = t3 = 0.0
            for k in range(j):
                m = j - 1 - k if reverse else k
                a = A[j, m]
                if a != 0.0:
                    a_low = A_low[j, m]
                    k0, k1, k2, k3 = K[m, i], K[m, i + 1], K[m, i + 2], K[m, i + 3]
                    s0 += a * k0
                    s1 += a * k1
                    s2 += a * k2
                    s3 += a * k3
                    t0 += a_low * k0
                    t1 += a_low * k1
                    t2 += a_low * k2
                    t3 += a_low * k3
            _finish_stage(base, lo, h, j, out, i, s0, t0, seed)
            _finish_stage(base, lo, h, j, out, i + 1, s1, t1, seed)
            _finish_stage(base, lo, h, j, out, i + 2, s2, t2, seed)
            _finish_stage(base, lo, h, j, out, i + 3, s3, t3, seed)
            i += 4
        elif i + 2 <= d:
            s0 = s1 = 0.0
            t0 = t1 = 0.0
            for k in range(j):
                m = j - 1 - k if reverse else k
                a = A[j, m]
                if a != 0.0:
                    a_low = A_low[j, m]
                    k0, k1 = K[m, i], K[m, i + 1]
                    s0 += a * k0
                    s1 += a * k1
                    t0 += a_low * k0
                    t1 += a_low * k1
            _finish_stage(base, lo, h, j, out, i, s0, t0, seed)
            _finish_stage(base, lo, h, j, out, i + 1, s1, t1, seed)
            i += 2
        else:
            acc = 0.0
            low = 0.0
            for k in range(j):
                m = j - 1 - k if reverse else k
                acc += A[j, m] * K[m, i]
                low += A_low[j, m] * K[m, i]
            _finish_stage(base, lo, h, j, out, i, acc, low, seed)
            i += 1


@jitable
def _finish_stage(base, lo, h, j, out, i, acc, low, seed):
    """``out[i]`` of :func:`stage_value_compensated` from its sums."""
    small = lo[i] + (acc + low) * h if j else lo[i]
    if seed >= 0.0:
        out[i] = round_stochastically(base[i], small, uniform(seed + i))
    else:
        out[i] = base[i] + small


@jitable
def increment(h, b, K, out):
    """``out = h sum_j b[j] K[j]``."""
    for i in range(out.shape[0]):
        acc = 0.0
        for m in range(b.shape[0]):
            acc += b[m] * K[m, i]
        out[i] = acc * h


@jitable
def increment_compensated(h, b, b_low, K, out, reverse=False):
    """``out = h sum_j (b + b_low)[j] K[j]``, the weights double-doubles,
    summed forward or, with ``reverse``, backward."""
    s = b.shape[0]
    for i in range(out.shape[0]):
        acc = 0.0
        low = 0.0
        for k in range(s):
            m = s - 1 - k if reverse else k
            acc += b[m] * K[m, i]
            low += b_low[m] * K[m, i]
        out[i] = (acc + low) * h


@jitable
def nudge(values, out):
    """``out = values (1 + eps)``: each nonzero value moved by one or two
    ulps, away from zero."""
    for i in range(out.shape[0]):
        out[i] = values[i] + values[i] * EPS


@jitable
def matvec(M, v, out):
    """``out = M v``, each row added in the order k = 0, 1, ..."""
    for i in range(out.shape[0]):
        acc = 0.0
        for k in range(v.shape[0]):
            acc += M[i, k] * v[k]
        out[i] = acc


@jitable
def two_sum(hi, lo, inc, out_hi, out_lo):
    """``(out_hi, out_lo) = (hi, lo) + inc``, compensated (Knuth's TwoSum,
    which unlike Fast2Sum stays exact when a component crosses zero)."""
    for i in range(hi.shape[0]):
        b = inc[i] + lo[i]
        s = hi[i] + b
        bb = s - hi[i]
        out_lo[i] = (hi[i] - (s - bb)) + (b - bb)
        out_hi[i] = s


@jitable
def tolerance(atol, rtol, a, b, relative, rule, out):
    """Tolerance per component, ``max(atol, rtol max(|a|, |b|))``; the paper's
    scalar rule then takes the minimum over the components."""
    low = math.inf
    for i in range(out.shape[0]):
        if relative:
            value = fmax(fmax(abs(a[i]), abs(b[i])) * rtol[i], atol[i])
        else:
            value = atol[i]
        out[i] = value
        if value < low or (value != value and low == low):  # NaN wins, as in min
            low = value
    if rule == RULE_PRENTICE:
        for i in range(out.shape[0]):
            out[i] = low


@jitable
def max_abs(x):
    """``max_k |x_k|`` (0 for no components; NaN if any is NaN)."""
    top = 0.0
    for i in range(x.shape[0]):
        value = abs(x[i])
        if value != value:
            return value
        if value > top:
            top = value
    return top


@jitable
def weighted_norm(e, delta):
    """``max_k |e_k| / delta_k`` (NaN if any term is NaN)."""
    top = -math.inf
    for i in range(e.shape[0]):
        value = abs(e[i]) / delta[i]
        if value != value:
            return value
        if value > top:
            top = value
    return top


@jitable
def scaled_difference(a_hi, a_lo, b_hi, b_lo, scale, out):
    """``out = ((a_hi - b_hi) + (a_lo - b_lo)) / scale``: the difference of
    two compensated tracks that are close together."""
    for i in range(out.shape[0]):
        out[i] = ((a_hi[i] - b_hi[i]) + (a_lo[i] - b_lo[i])) / scale
