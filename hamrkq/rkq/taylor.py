"""Taylor coefficients of a solution, by running a system's tape.

:func:`taylor_coefficients` runs a :class:`~hamrkq.symbolic.taylor.TaylorTape`
(the right-hand side broken into elementary operations) order by order: the
k-th coefficient of every operation from the lower ones of its arguments,
then the state's ``Y_{k+1} = F_k / (k + 1)``.  :func:`taylor_increment` sums
the series at a step.  Both are kernel functions (:func:`~hamrkq.rkq.jit.jitable`):
the interpreter runs them as written, numba compiles them once for every
system (the system is data), and they add in the same order on both, so they
give the same bits.

The recurrences, for ``w = op(a, b)`` with coefficients ``a_k``, ``b_k``,
``w_k`` (Moore 1966; Jorba & Zou 2005, section 3; each is the coefficient of
``x^k`` in a product, or of ``x^(k-1)`` in ``w' = a' g``):

- product ``w_k = sum_{j=0..k} a_j b_(k-j)``; quotient
  ``w_k = (a_k - sum_{j=1..k} b_j w_(k-j)) / b_0``;
- power ``w = a^r``: ``w_k = sum_{j=0..k-1} (r (k - j) - j) a_(k-j) w_j / (k a_0)``;
  square root ``w_k = (a_k - sum_{j=1..k-1} w_j w_(k-j)) / (2 w_0)``;
- ``exp``: ``w_k = sum_{j=1..k} j a_j w_(k-j) / k``; ``log``:
  ``w_k = (a_k - sum_{j=1..k-1} j w_j a_(k-j) / k) / a_0``;
- ``sin`` and ``cos`` together: ``s_k = sum j a_j c_(k-j) / k``,
  ``c_k = -sum j a_j s_(k-j) / k`` (``sinh``, ``cosh`` without the minus);
- ``tan``: ``w' = a' (1 + w^2)``; ``tanh``: ``w' = a' (1 - w^2)``, the
  square kept in a second slot;
- ``asin``, ``acos``, ``atan``, ``asinh``, ``acosh``, ``atanh``:
  ``w' = a' g`` with ``g`` (``(1 - a^2)^(-1/2)``, ...) on the tape.

Where a recurrence divides by a zero leading coefficient (a power or
logarithm of a series through zero) the coefficients are NaN, checked rather
than left to the arithmetic, so both backends give NaN.
"""

from __future__ import annotations

import math

from hamrkq.rkq.jit import borrow, jitable, jitable_inline
from hamrkq.symbolic.taylor import (
    ABS,
    ACOS,
    ACOSH,
    ADD,
    ADDC,
    ASIN,
    ASINH,
    ATAN,
    CONST,
    DIV,
    EXP,
    INTEGRAL,
    LOG,
    MUL,
    MULC,
    PARAM,
    POW,
    SIGN,
    SINCOS,
    SINHCOSH,
    SQRT,
    SQUARE,
    SUB,
    TAN,
    TANH,
)

# Beyond these math.exp, sinh and cosh overflow (Python raises, IEEE gives inf).
_EXP_MAX = 709.782712893384
_COSH_MAX = 710.4758600739439


@jitable
def _quotient(x, d):
    """``x / d``, NaN where ``d`` is zero (Python would raise)."""
    if d == 0.0:
        return math.nan
    return x / d


@jitable
def _exp(x):
    if x > _EXP_MAX:
        return math.inf
    return math.exp(x)


@jitable
def _log(x):
    if x > 0.0:
        return math.log(x)
    return -math.inf if x == 0.0 else math.nan


@jitable
def _sqrt(x):
    return math.sqrt(x) if x >= 0.0 else math.nan


@jitable
def _power(x, r):
    """``x ** r`` for a real ``r``: NaN for a negative ``x`` unless ``r`` is
    an integer, an infinity where it overflows (Python raises)."""
    if x == 0.0:
        if r > 0.0:
            return 0.0
        return math.nan if r == 0.0 else math.inf
    if x < 0.0 and r != math.floor(r):
        return math.nan
    magnitude = r * math.log(abs(x))
    if magnitude > _EXP_MAX:
        odd = x < 0.0 and (r - 2.0 * math.floor(r / 2.0)) != 0.0
        sign = -1.0 if odd else 1.0
        return sign * math.inf
    return math.pow(x, r)


@jitable
def _inverse(which, x):
    """The inverse function number ``which`` at ``x`` (NaN outside its domain)."""
    if which == ATAN:
        return math.atan(x)
    if which == ASINH:
        return math.asinh(x)
    if which == ASIN or which == ACOS:
        if abs(x) > 1.0:
            return math.nan
        return math.asin(x) if which == ASIN else math.acos(x)
    if which == ACOSH:
        return math.acosh(x) if x >= 1.0 else math.nan
    # ATANH
    if abs(x) < 1.0:
        return math.atanh(x)
    return math.copysign(math.inf, x) if abs(x) == 1.0 else math.nan


@jitable_inline
def _order_zero(op, code, consts, row, U, params):  # noqa: C901, PLR0912 - one case per operation
    """Row ``row``'s coefficient of order 0 (its value at the point)."""
    out, a, b, c = code[row, 1], code[row, 2], code[row, 3], code[row, 4]
    if op == CONST:
        U[out, 0] = consts[row]
    elif op == PARAM:
        U[out, 0] = params[a]
    elif op == ADD or op == ADDC:
        U[out, 0] = U[a, 0] + U[b, 0]
    elif op == SUB:
        U[out, 0] = U[a, 0] - U[b, 0]
    elif op == MUL or op == MULC:
        U[out, 0] = U[a, 0] * U[b, 0]
    elif op == DIV:
        U[out, 0] = _quotient(U[a, 0], U[b, 0])
    elif op == SQUARE:
        U[out, 0] = U[a, 0] * U[a, 0]
    elif op == SQRT:
        U[out, 0] = _sqrt(U[a, 0])
    elif op == POW:
        U[out, 0] = _power(U[a, 0], U[b, 0])
    elif op == EXP:
        U[out, 0] = _exp(U[a, 0])
    elif op == LOG:
        U[out, 0] = _log(U[a, 0])
    elif op == SINCOS:
        U[out, 0] = math.sin(U[a, 0])
        U[b, 0] = math.cos(U[a, 0])
    elif op == SINHCOSH:
        x = U[a, 0]
        if abs(x) > _COSH_MAX:
            U[out, 0] = math.copysign(math.inf, x)
            U[b, 0] = math.inf
        else:
            U[out, 0] = math.sinh(x)
            U[b, 0] = math.cosh(x)
    elif op == TAN or op == TANH:
        w = math.tan(U[a, 0]) if op == TAN else math.tanh(U[a, 0])
        U[out, 0] = w
        U[b, 0] = w * w
    elif op == INTEGRAL:
        U[out, 0] = _inverse(c, U[a, 0])
    elif op == ABS:
        U[out, 0] = abs(U[a, 0])
    elif op == SIGN:
        x = U[a, 0]
        U[out, 0] = 0.0 if x == 0.0 else math.copysign(1.0, x)


@jitable
def _self_product(U, s, k, first):
    """``sum_{j=first..k-first} U[s, j] U[s, k-j]``: each pair ``j < k - j``
    once, doubled, and the middle term once."""
    acc = 0.0
    for j in range(first, (k + 1) // 2):
        acc += U[s, j] * U[s, k - j]
    acc = 2.0 * acc
    if k % 2 == 0 and k // 2 >= first:
        acc += U[s, k // 2] * U[s, k // 2]
    return acc


@jitable_inline
def _order_k(op, code, row, U, k):  # noqa: C901, PLR0912 - one case per operation
    """Row ``row``'s coefficient of order ``k >= 1``."""
    out, a, b = code[row, 1], code[row, 2], code[row, 3]
    if op == ADD:
        U[out, k] = U[a, k] + U[b, k]
    elif op == SUB:
        U[out, k] = U[a, k] - U[b, k]
    elif op == ADDC:
        U[out, k] = U[a, k]
    elif op == MULC:
        U[out, k] = U[a, k] * U[b, 0]
    elif op == MUL:
        acc = 0.0
        for j in range(k + 1):
            acc += U[a, j] * U[b, k - j]
        U[out, k] = acc
    elif op == SQUARE:
        U[out, k] = _self_product(U, a, k, 0)
    elif op == DIV:
        acc = U[a, k]
        for j in range(1, k + 1):
            acc -= U[b, j] * U[out, k - j]
        U[out, k] = _quotient(acc, U[b, 0])
    elif op == SQRT:
        U[out, k] = _quotient(U[a, k] - _self_product(U, out, k, 1), 2.0 * U[out, 0])
    elif op == POW:
        r = U[b, 0]
        acc = 0.0
        for j in range(k):
            acc += (r * (k - j) - j) * U[a, k - j] * U[out, j]
        U[out, k] = _quotient(acc, k * U[a, 0])
    elif op == EXP or op == INTEGRAL:
        # w' = a' g, with g = w for exp
        g = out if op == EXP else b
        acc = 0.0
        for j in range(1, k + 1):
            acc += j * U[a, j] * U[g, k - j]
        U[out, k] = acc / k
    elif op == LOG:
        acc = 0.0
        for j in range(1, k):
            acc += j * U[out, j] * U[a, k - j]
        U[out, k] = _quotient(U[a, k] - acc / k, U[a, 0])
    elif op == SINCOS or op == SINHCOSH:
        s_acc = 0.0
        c_acc = 0.0
        for j in range(1, k + 1):
            ja = j * U[a, j]
            s_acc += ja * U[b, k - j]
            c_acc += ja * U[out, k - j]
        U[out, k] = s_acc / k
        U[b, k] = (-c_acc if op == SINCOS else c_acc) / k
    elif op == TAN or op == TANH:
        # w' = a' (1 +- w^2), the square's coefficients in slot b
        sign = 1.0 if op == TAN else -1.0
        acc = 0.0
        for j in range(1, k + 1):
            g = sign * U[b, k - j]
            if j == k:
                g += 1.0
            acc += j * U[a, j] * g
        U[out, k] = acc / k
        U[b, k] = _self_product(U, out, k, 0)
    elif op == ABS:
        x = U[a, 0]
        U[out, k] = -U[a, k] if x < 0.0 else U[a, k]
    # CONST, PARAM, SIGN: constant, their higher coefficients stay zero


@jitable
def taylor_coefficients(code, consts, setup, outputs, t, y, params, order, U):
    """The normalized Taylor coefficients of the solution through ``(t, y)``.

    Parameters
    ----------
    code, consts, setup, outputs
        A :class:`~hamrkq.symbolic.taylor.TaylorTape`'s arrays and setup count.
    t : float
        The time.
    y, params : ndarray
        The state and the parameters' values.
    order : int
        The highest order wanted.
    U : ndarray, shape (slots, >= order + 1)
        Overwritten: ``U[i, k]`` is the coefficient of ``h^k`` in
        ``y_i(t + h)`` for the state's slots ``i < n``; the other slots hold
        the operations' coefficients (up to ``order - 1``).
    """
    n = y.shape[0]
    for s in range(U.shape[0]):
        for k in range(order + 1):
            U[s, k] = 0.0
    for i in range(n):
        U[i, 0] = y[i]
    U[n, 0] = t
    if order >= 1:
        U[n, 1] = 1.0
    code, consts, U, params = borrow((code, consts, U, params))
    rows = code.shape[0]
    for row in range(rows):
        _order_zero(code[row, 0], code, consts, row, U, params)
    for k in range(order):
        if k > 0:
            for row in range(setup, rows):
                _order_k(code[row, 0], code, row, U, k)
        for i in range(n):
            U[i, k + 1] = U[outputs[i], k] / (k + 1)


@jitable
def taylor_increment(U, order, h, out):
    """``out[i] = sum_{k=1..order} U[i, k] h^k`` by Horner's rule, for the
    state's ``out.shape[0]`` components (the increment of a Taylor step)."""
    for i in range(out.shape[0]):
        acc = U[i, order]
        for k in range(order - 1, 0, -1):
            acc = acc * h + U[i, k]
        out[i] = acc * h
