"""The RKQ step loop: RK3/RK4 local extrapolation, an RK8 track, quenching.

This module is the numerical core behind :func:`hamrkq.solve` for the methods
``"rk34q8"`` and ``"rk34"``.  It implements Prentice's RKQ algorithm
(J.S.C. Prentice, arXiv:1111.6996; ``docs/algorithm.md`` explains it in plain
words) exactly as ``RKQ.md`` specifies.

Everything above :func:`run` is written in the subset of Python that
``numba.njit`` compiles: functions over float64 arrays, ints and floats; no
objects, closures, exceptions or allocation inside the loop; method
coefficients come in as arrays; the right-hand side and the Jacobian are
functions with in-place outputs, ``rhs(t, y, params, out)`` and
``jac(t, y, params, out)``.  The state between calls is explicit (the arrays
``X``, ``fstate``, ``istate``), so :func:`advance` runs in chunks: it returns
when the interval is done, when its output buffer is full, or when its step
budget for the call is used, and :func:`run` (plain Python) grows the output,
reports progress and turns Ctrl-C into :attr:`Status.INTERRUPTED`.

Evaluations of ``f`` per accepted step (``"rk34q8"``, DOP853 track): 5 for
RK3 + RK4 (they share two stages), 12 for the RK8 step, 23 for the two RK8
half steps of the Richardson estimate (the first half step's first stage is
the full step's), so 40; plus 12 Jacobians for the ``"tangent"`` propagation
(1 for ``"paper"``).  A rejected attempt costs 4 (``f(t, u)`` is kept).
``"rk34"`` costs 5 per accepted step and 4 per rejection.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RunOutput",
    "Workspace",
    "advance",
    "evaluations_per_step",
    "initial_step",
    "run",
    "workspace",
]

EPS = 2.220446049250313e-16  # float64 machine epsilon

# Step-size control (Hairer, Norsett & Wanner, Solving ODEs I, II.4).
MIN_FACTOR = 0.2  # never shrink by more than 5x on one rejection
MAX_FACTOR = 5.0  # never grow by more than 5x on one acceptance
# A Richardson difference within this many ulps of the increments it is taken
# from is rounding, not truncation (each increment carries about one ulp).
ROUNDOFF_ULPS = 1.0

# Rows of the work array X (n_rows x 2n): the carried state, then scratch.
U, ZHI, ZLO, GAM, RHO2, K1 = 0, 1, 2, 3, 4, 5
W4, INC4, INC3, YT, DEL, TMP, TMP2 = 6, 7, 8, 9, 10, 11, 12
INCH, INCA, INCB, MHI, MLO, NHI, NLO, GNEW, DY, DINC, NOISE = range(13, 24)
X_ROWS = 24

# fstate (float64): carried scalars.
FS_T, FS_TLO, FS_H, FS_RATIO, FS_CACHE_H, FS_FAIL_H = range(6)
FS_SIZE = 6
# istate (int64): counters and flags.
(
    IS_STEPS,
    IS_REJECTED,
    IS_QUENCHES,
    IS_NFEV,
    IS_NJEV,
    IS_NOUT,
    IS_STATUS,
    IS_K1_VALID,
    IS_SINCE_KEPT,
    IS_EVAL_INDEX,
    IS_LAST_QUENCHED,
    IS_LAST_WRITTEN,
    IS_ROUNDOFF_STEPS,
    IS_LAST_NONFINITE,
    IS_REDO,
    IS_CACHED,
    IS_CACHE_ROUNDOFF,
    IS_PREV_REJECTED,
) = range(18)
IS_SIZE = 18
# iopt (int64): options.
IO_QUENCH, IO_RULE, IO_GAMMA, IO_RK8, IO_KEEP, IO_MAX_STEPS, IO_SHARED, IO_TEVAL, IO_REL = range(9)
IO_SIZE = 9
# fopt (float64): options.
FO_SAFETY, FO_THETA, FO_MAX_STEP, FO_GAMMA_LIMIT, FO_T_END, FO_RICHARDSON = range(6)
FO_SIZE = 6

# Option codes.
QUENCH_NODE, QUENCH_REDO = 0, 1
RULE_COMPONENTWISE, RULE_PRENTICE = 0, 1
GAMMA_OFF, GAMMA_TANGENT, GAMMA_PAPER = 0, 1, 2

# Status codes (values of hamrkq.result.Status) and return codes of advance.
ST_RUNNING, ST_SUCCESS, ST_UNDERFLOW, ST_NON_FINITE, ST_MAX_STEPS = -1, 0, 1, 2, 3
ST_UNATTAINABLE = 5
RET_DONE, RET_BUFFER_FULL, RET_BUDGET = 0, 1, 2


def evaluations_per_step(method: str, gamma: str, rk8_stages: int = 12) -> tuple[int, int]:
    """Right-hand-side and Jacobian evaluations of one accepted step.

    Parameters
    ----------
    method : {"rk34q8", "rk34"}
    gamma : {"tangent", "paper", "off"}
        The ``global_error_estimate`` option.
    rk8_stages : int
        Stages of the RK8 track (12 for DOP853, 11 for Cooper-Verner).

    Returns
    -------
    (nfev, njev) : tuple of int
        ``5`` for ``"rk34"``; for ``"rk34q8"``, ``5 + s`` plus ``2 s - 1``
        (Richardson) unless Gamma is off, and ``s`` Jacobians for
        ``"tangent"``, 1 for ``"paper"``.
    """
    if method == "rk34":
        return 5, 0
    nfev = 5 + rk8_stages
    if gamma == "off":
        return nfev, 0
    return nfev + 2 * rk8_stages - 1, rk8_stages if gamma == "tangent" else 1


# -- small array kernels (allocation-free, numba-compatible) -------------------


def _finite(x):
    # One reduction instead of an isfinite temporary: inf/nan poison the sum.
    return math.isfinite(x.sum())


def _stage_sum(a, K, out):
    """out = sum_l a[l] K[l], added in the order l = 0, 1, ...: NumPy reduces
    over the outer axis of a C array row by row (``np.dot`` adds in BLAS's
    order instead), so the compiled backend's element loops, which add in the
    same order, give the same bits (hamrkq.backends.compiled.PRIMITIVES)."""
    np.add.reduce(np.multiply(a[:, None], K, order="C"), axis=0, out=out)


def _matvec(M, v, out):
    """out = M @ v, each row added in the order k = 0, 1, ... (see _stage_sum)."""
    np.add.reduce(np.multiply(M.T, v[:, None], order="C"), axis=0, out=out)


def _max(x):
    """x.max() (NaN if any element is NaN)."""
    return x.max()


def _copy(src, out):
    """out[:] = src.  (A function, so that the compiled backend can swap in an
    element loop: numba's slice assignment allocates a temporary when it
    cannot rule out overlap, and the compiled loop runs without numba's
    allocator.)"""
    out[:] = src


def _combine(base, lo, h, A, j, K, out):
    """out = base + (lo + h * sum_{l<j} A[j, l] K[l])  (lo: low-order part)."""
    if j == 0:
        np.add(base, lo, out)
    else:
        _stage_sum(A[j, :j], K[:j], out)
        np.multiply(out, h, out)
        np.add(out, lo, out)
        np.add(out, base, out)


def _plain(base, h, A, j, K, out):
    """out = base + h * sum_{l<j} A[j, l] K[l]."""
    if j == 0:
        out[:] = base
    else:
        _stage_sum(A[j, :j], K[:j], out)
        np.multiply(out, h, out)
        np.add(out, base, out)


def _increment(h, b, K, out):
    """out = h * sum_j b[j] K[j]."""
    _stage_sum(b, K, out)
    np.multiply(out, h, out)


def _two_sum(hi, lo, inc, out_hi, out_lo, tmp, tmp2):
    """(out_hi, out_lo) = (hi, lo) + inc, compensated (Knuth's TwoSum, which
    unlike Kahan's Fast2Sum stays exact when a component crosses zero)."""
    np.add(inc, lo, tmp)  # b
    np.add(hi, tmp, out_hi)  # s = a + b
    np.subtract(out_hi, hi, out_lo)  # bb = s - a
    np.subtract(tmp, out_lo, tmp2)  # b - bb
    np.subtract(out_hi, out_lo, out_lo)  # s - bb
    np.subtract(hi, out_lo, out_lo)  # a - (s - bb)
    np.add(out_lo, tmp2, out_lo)


def _delta(atol, rtol, a, b, rel, rule, out, tmp):
    """Tolerance per component: max(atol, rtol * max(|a|, |b|)); the paper's
    scalar rule then takes the minimum over the components."""
    if rel:
        np.abs(a, out)
        np.abs(b, tmp)
        np.fmax(out, tmp, out)  # fmax: np.maximum deprecates a positional out
        np.multiply(out, rtol, out)
        np.fmax(out, atol, out)
    else:
        out[:] = atol
    if rule == RULE_PRENTICE:
        out[:] = out.min()


def _wnorm(e, delta, tmp):
    """Weighted max norm max_k |e_k| / delta_k."""
    np.abs(e, tmp)
    np.divide(tmp, delta, tmp)
    return _max(tmp)


def _rk_increment(rhs, t, hi, lo, h, A, b, c, params, K, yt, out, first_done):
    """Stages of one explicit RK step from the compensated state (hi, lo);
    K[0] is reused when ``first_done``.  Returns the f-evaluations made."""
    nfev = 0
    for j in range(b.shape[0]):
        if j == 0 and first_done:
            continue
        _combine(hi, lo, h, A, j, K, yt)
        rhs(t + c[j] * h, yt, params, K[j])
        nfev += 1
    _increment(h, b, K, out)
    return nfev


def _tangent(rhs, jac):
    """``tangent(t, y, params, v, out, dout, JM)``: ``rhs`` into ``out`` and
    J(t, y) v into ``dout``, from ``jac`` (into the scratch ``JM``) and
    :func:`_matvec`.  The compiled backend passes instead a generated
    function that computes the same bits (``rhs_jvp`` of
    :mod:`hamrkq.backends.codegen`, in one call for small systems)."""

    def tangent(t, y, params, v, out, dout, JM):
        rhs(t, y, params, out)
        jac(t, y, params, JM)
        _matvec(JM, v, dout)

    return tangent


def _rk8_tangent(tangent, t, hi, lo, h, A, b, c, params, K, dK, yt, dy, JM, gam, out, dout):
    """One RK8 step (increment into ``out``) and, alongside, its exact
    linearisation applied to ``gam`` (into ``dout``): dY_j = gam + h sum a dK,
    dK_j = J(t + c_j h, Y_j) dY_j, with ``tangent`` (see :func:`_tangent`)
    giving K_j and dK_j in one call.  Returns the Jacobian(-vector product)
    evaluations made."""
    for j in range(b.shape[0]):
        _combine(hi, lo, h, A, j, K, yt)
        _plain(gam, h, A, j, dK, dy)
        tangent(t + c[j] * h, yt, params, dy, K[j], dK[j], JM)
    _increment(h, b, K, out)
    _increment(h, b, dK, dout)
    np.add(dout, gam, dout)
    return b.shape[0]


def _write(X, t, quenched, istate, out_t, out_y, out_z, out_gamma, out_q, rk8):
    n = istate[IS_NOUT]
    out_t[n] = t
    _copy(X[U], out_y[n])
    if rk8:
        _copy(X[ZHI], out_z[n])
        _copy(X[GAM], out_gamma[n])
        out_q[n] = quenched
    # Count the node only once it is complete: an interrupt never leaves half a row.
    istate[IS_NOUT] = n + 1
    istate[IS_LAST_WRITTEN] = 1


def _stop(status, X, fstate, istate, out_t, out_y, out_z, out_gamma, out_q, rk8, use_teval):
    """End the run at the last accepted node, which is kept (with t_eval only
    the requested times are kept)."""
    if not istate[IS_LAST_WRITTEN] and not use_teval:
        quenched = 1 if (istate[IS_LAST_QUENCHED] or istate[IS_REDO]) else 0
        _write(X, fstate[FS_T], quenched, istate, out_t, out_y, out_z, out_gamma, out_q, rk8)
    istate[IS_STATUS] = status
    return RET_DONE


def initial_step(rhs, t0, y0, f0, t_end, atol, rtol, rel, rule, order, max_step, params, work):
    """First step size by the heuristic of Hairer, Norsett & Wanner (Solving
    ODEs I, II.4), as in SciPy's ``select_initial_step``, for a method of
    order ``order``, with hamrkq's weighted max norm.

    Costs one evaluation of ``rhs`` (``f0 = f(t0, y0)`` is given).  ``work``
    is a (3, 2n) scratch array.  Returns a positive step size.
    """
    interval = abs(t_end - t0)
    direction = 1.0 if t_end >= t0 else -1.0
    delta, y1, tmp = work[0], work[1], work[2]
    _delta(atol, rtol, y0, y0, rel, rule, delta, tmp)
    d0 = _wnorm(y0, delta, tmp)
    d1 = _wnorm(f0, delta, tmp)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    np.multiply(f0, direction * h0, y1)
    np.add(y1, y0, y1)
    rhs(t0 + direction * h0, y1, params, tmp)
    np.subtract(tmp, f0, tmp)
    d2 = _wnorm(tmp, delta, y1) / h0
    if not math.isfinite(d2):
        h1 = h0
    elif max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100.0 * h0, h1, interval, max_step)


def advance(
    rhs, jac, params, A3, b3, c3, A4, b4, c4, A8, b8, c8, t_eval, atol, rtol,
    iopt, fopt, fstate, istate, X, K4, K3, K8, dK8, JM,
    out_t, out_y, out_z, out_gamma, out_q, budget,
):  # fmt: skip
    """Advance the RKQ integration from the state in ``X``/``fstate``/``istate``.

    Writes output nodes into ``out_*`` from row ``istate[IS_NOUT]`` on and
    returns ``RET_DONE`` (the run ended; ``istate[IS_STATUS]`` says why),
    ``RET_BUFFER_FULL`` or ``RET_BUDGET`` (``budget`` step attempts made).
    Call again with the same state (and ``IS_NOUT`` reset for a fresh buffer)
    to continue.  See the module docstring for the conventions.
    """
    return _advance(
        rhs, jac, _tangent(rhs, jac), params, A3, b3, c3, A4, b4, c4, A8, b8, c8,
        t_eval, atol, rtol, iopt, fopt, fstate, istate, X, K4, K3, K8, dK8, JM,
        out_t, out_y, out_z, out_gamma, out_q, budget,
    )  # fmt: skip


def _advance(
    rhs, jac, tangent, params, A3, b3, c3, A4, b4, c4, A8, b8, c8, t_eval, atol, rtol,
    iopt, fopt, fstate, istate, X, K4, K3, K8, dK8, JM,
    out_t, out_y, out_z, out_gamma, out_q, budget,
):  # fmt: skip
    """:func:`advance` with the fused ``tangent(t, y, params, v, out, dout)``
    (see :func:`_tangent`); this is the function the compiled backend compiles."""
    quench_mode = iopt[IO_QUENCH]
    rule = iopt[IO_RULE]
    gmode = iopt[IO_GAMMA]
    rk8 = iopt[IO_RK8]
    keep = iopt[IO_KEEP]
    max_steps = iopt[IO_MAX_STEPS]
    shared = iopt[IO_SHARED]
    use_teval = iopt[IO_TEVAL]
    rel = iopt[IO_REL]
    safety = fopt[FO_SAFETY]
    theta = fopt[FO_THETA]
    max_step = fopt[FO_MAX_STEP]
    gamma_limit = fopt[FO_GAMMA_LIMIT]
    t_end = fopt[FO_T_END]
    rich = fopt[FO_RICHARDSON]
    cap = out_t.shape[0]
    s3 = b3.shape[0]
    s4 = b4.shape[0]
    s8 = b8.shape[0]
    direction = 1.0 if t_end > fstate[FS_T] else -1.0
    u = X[U]
    zhi = X[ZHI]
    zlo = X[ZLO]
    gam = X[GAM]
    # Views of the scratch rows, made once per call: under numba each view
    # made inside the loop costs two atomic reference-count updates.
    k1, yt, inc4, inc3, w4 = X[K1], X[YT], X[INC4], X[INC3], X[W4]
    tmp, tmp2, dlt, dy, inch, dinc = X[TMP], X[TMP2], X[DEL], X[DY], X[INCH], X[DINC]
    nhi, nlo, gnew, noise, rho2 = X[NHI], X[NLO], X[GNEW], X[NOISE], X[RHO2]
    attempts = 0
    while True:
        if istate[IS_NOUT] >= cap:
            return RET_BUFFER_FULL
        if attempts >= budget:
            return RET_BUDGET
        if istate[IS_STEPS] + istate[IS_REJECTED] >= max_steps:
            return _stop(ST_MAX_STEPS, X, fstate, istate, out_t, out_y, out_z, out_gamma,
                         out_q, rk8, use_teval)  # fmt: skip
        t = fstate[FS_T]
        target = t_end
        if use_teval and istate[IS_EVAL_INDEX] < t_eval.shape[0]:
            target = t_eval[istate[IS_EVAL_INDEX]]
        remaining = target - t
        h_free = fstate[FS_H]
        if abs(h_free) > max_step:
            h_free = direction * max_step
        h = h_free
        clipped = False
        # Land exactly on the target, and never leave a sliver below the floor.
        if abs(h) >= abs(remaining) or abs(remaining) - abs(h) < 10.0 * EPS * abs(target):
            h = remaining
            clipped = True
        if not clipped and abs(h) < 10.0 * EPS * abs(t):
            fstate[FS_FAIL_H] = h
            status = ST_NON_FINITE if istate[IS_LAST_NONFINITE] else ST_UNDERFLOW
            return _stop(status, X, fstate, istate, out_t, out_y, out_z, out_gamma, out_q,
                         rk8, use_teval)  # fmt: skip
        attempts += 1

        # 1. Local extrapolation: RK3 and RK4 from u, sharing their first stages.
        if not istate[IS_K1_VALID]:
            rhs(t, u, params, k1)
            istate[IS_NFEV] += 1
            if not _finite(k1):
                fstate[FS_FAIL_H] = h
                return _stop(ST_NON_FINITE, X, fstate, istate, out_t, out_y, out_z,
                             out_gamma, out_q, rk8, use_teval)  # fmt: skip
            istate[IS_K1_VALID] = 1
        _copy(k1, K4[0])
        for j in range(1, s4):
            _plain(u, h, A4, j, K4, yt)
            rhs(t + c4[j] * h, yt, params, K4[j])
        for j in range(shared):
            _copy(K4[j], K3[j])
        for j in range(shared, s3):
            _plain(u, h, A3, j, K3, yt)
            rhs(t + c3[j] * h, yt, params, K3[j])
        istate[IS_NFEV] += s4 - 1 + s3 - shared
        _increment(h, b4, K4, inc4)
        _increment(h, b3, K3, inc3)
        np.add(u, inc4, w4)
        np.subtract(inc3, inc4, tmp2)  # e = w3 - w4, from the increments
        if not (_finite(tmp2) and _finite(w4)):
            fstate[FS_H] = h * MIN_FACTOR
            istate[IS_REJECTED] += 1
            istate[IS_PREV_REJECTED] = 1
            istate[IS_LAST_NONFINITE] = 1
            continue
        _delta(atol, rtol, u, w4, rel, rule, dlt, tmp)
        err = _wnorm(tmp2, dlt, tmp)
        if err > 1.0:
            fstate[FS_H] = h * max(MIN_FACTOR, safety * err**-0.25)
            istate[IS_REJECTED] += 1
            istate[IS_PREV_REJECTED] = 1
            istate[IS_LAST_NONFINITE] = 0
            continue
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, safety * err**-0.25)
        if istate[IS_PREV_REJECTED]:
            factor = min(1.0, factor)  # no growth right after a rejection
        h_next = h * factor
        if clipped and abs(h_next) < abs(h_free):
            h_next = h_free  # a step clipped to land says nothing against the free step

        quenched = 0
        if rk8:
            # 2. The RK8 track from its own previous value (cached across a redo).
            if not (istate[IS_CACHED] and fstate[FS_CACHE_H] == h):
                if gmode == GAMMA_TANGENT:
                    istate[IS_NJEV] += _rk8_tangent(
                        tangent, t, zhi, zlo, h, A8, b8, c8, params, K8, dK8, yt,
                        dy, JM, gam, inch, dinc,
                    )  # fmt: skip
                    istate[IS_NFEV] += s8
                else:
                    istate[IS_NFEV] += _rk_increment(
                        rhs, t, zhi, zlo, h, A8, b8, c8, params, K8, yt, inch, False
                    )
                _two_sum(zhi, zlo, inch, nhi, nlo, tmp, tmp2)
                if not _finite(nhi):
                    fstate[FS_H] = h * MIN_FACTOR
                    istate[IS_REJECTED] += 1
                    istate[IS_PREV_REJECTED] = 1
                    istate[IS_LAST_NONFINITE] = 1
                    continue
                _rk8_gamma(rhs, jac, t, h, A8, b8, c8, params, K8, X, JM, gmode, rich, istate)
                istate[IS_CACHED] = 1
                fstate[FS_CACHE_H] = h
            # 3.-4. Global error of the candidate at the new node; quench.
            np.subtract(w4, nhi, tmp2)
            _delta(atol, rtol, w4, w4, rel, rule, dlt, tmp)
            gnorm = _wnorm(tmp2, dlt, tmp)
            if gnorm > theta:
                if quench_mode == QUENCH_REDO and not istate[IS_REDO]:
                    # Restart the same step from the RK8 value at t_i.
                    _copy(zhi, u)
                    istate[IS_REDO] = 1
                    istate[IS_QUENCHES] += 1
                    istate[IS_K1_VALID] = 0
                    fstate[FS_H] = h_free
                    continue
                _copy(nhi, u)
                quenched = 1
                istate[IS_QUENCHES] += 1
            else:
                _copy(w4, u)
                quenched = istate[IS_REDO]
            _copy(nhi, zhi)
            _copy(nlo, zlo)
            _copy(gnew, gam)
            np.multiply(noise, noise, tmp)
            np.add(rho2, tmp, rho2)
            istate[IS_ROUNDOFF_STEPS] += istate[IS_CACHE_ROUNDOFF]
            istate[IS_CACHED] = 0
        else:
            _copy(w4, u)
        istate[IS_REDO] = 0

        # 5. The new node: time by compensated summation, or exactly the target.
        if clipped:
            t_new = target
            fstate[FS_TLO] = 0.0
        else:
            b = h + fstate[FS_TLO]
            t_new = t + b
            bb = t_new - t
            fstate[FS_TLO] = (t - (t_new - bb)) + (b - bb)
        fstate[FS_T] = t_new
        fstate[FS_H] = h_next
        istate[IS_STEPS] += 1
        istate[IS_K1_VALID] = 0
        istate[IS_PREV_REJECTED] = 0
        istate[IS_LAST_NONFINITE] = 0
        istate[IS_LAST_QUENCHED] = quenched
        istate[IS_LAST_WRITTEN] = 0
        done = clipped and target == t_end
        status = ST_RUNNING
        if rk8:
            ratio = _attainability(X, atol, rtol, rel, rule)
            if ratio > fstate[FS_RATIO]:
                fstate[FS_RATIO] = ratio
            if ratio > gamma_limit:
                status = ST_UNATTAINABLE
        if use_teval:
            if clipped and istate[IS_EVAL_INDEX] < t_eval.shape[0]:
                if target == t_eval[istate[IS_EVAL_INDEX]]:
                    _write(X, t_new, quenched, istate, out_t, out_y, out_z, out_gamma, out_q, rk8)
                    istate[IS_EVAL_INDEX] += 1
        else:
            istate[IS_SINCE_KEPT] += 1
            if istate[IS_SINCE_KEPT] >= keep or done or status != ST_RUNNING:
                _write(X, t_new, quenched, istate, out_t, out_y, out_z, out_gamma, out_q, rk8)
                istate[IS_SINCE_KEPT] = 0
        if done and status == ST_RUNNING:
            status = ST_SUCCESS
        if status != ST_RUNNING:
            istate[IS_STATUS] = status
            return RET_DONE


def _rk8_gamma(rhs, jac, t, h, A8, b8, c8, params, K8, X, JM, gmode, rich, istate):
    """Gamma at the new node into X[GNEW], the roundoff level of this step
    into X[NOISE], and whether the Richardson difference is pure rounding."""
    zhi = X[ZHI]
    zlo = X[ZLO]
    gam = X[GAM]
    scale = ROUNDOFF_ULPS * EPS
    yt, inca, incb, mhi, mlo = X[YT], X[INCA], X[INCB], X[MHI], X[MLO]
    tmp, tmp2, inch, dinc, gnew, noise = X[TMP], X[TMP2], X[INCH], X[DINC], X[GNEW], X[NOISE]
    if gmode == GAMMA_OFF:
        np.abs(inch, noise)
        np.multiply(noise, scale, noise)
        gnew[:] = 0.0
        istate[IS_CACHE_ROUNDOFF] = 0
        return
    # Richardson: two half steps from z_i (K8[0] = f(t, z_i) is the full step's).
    half = 0.5 * h
    istate[IS_NFEV] += _rk_increment(
        rhs, t, zhi, zlo, half, A8, b8, c8, params, K8, yt, inca, True
    )
    _two_sum(zhi, zlo, inca, mhi, mlo, tmp, tmp2)
    istate[IS_NFEV] += _rk_increment(
        rhs, t + half, mhi, mlo, half, A8, b8, c8, params, K8, yt, incb, False
    )
    d = tmp
    np.subtract(inch, inca, d)
    np.subtract(d, incb, d)  # y_h - y_{h/2,h/2}, free of the rounding of |z|
    np.abs(inch, noise)
    np.abs(inca, tmp2)
    np.add(noise, tmp2, noise)
    np.abs(incb, tmp2)
    np.add(noise, tmp2, noise)
    np.multiply(noise, scale, noise)
    np.abs(d, tmp2)
    np.subtract(tmp2, noise, tmp2)
    istate[IS_CACHE_ROUNDOFF] = 1 if _max(tmp2) <= 0.0 else 0
    np.multiply(d, rich, d)  # the local error of the h step, numerical minus exact
    if gmode == GAMMA_TANGENT:
        np.add(d, dinc, gnew)
    else:
        # The paper's propagation: (I + h J(t_i, z_i)) Gamma_i.
        np.add(zhi, zlo, yt)
        jac(t, yt, params, JM)
        istate[IS_NJEV] += 1
        _matvec(JM, gam, gnew)
        np.multiply(gnew, h, gnew)
        np.add(gnew, gam, gnew)
        np.add(gnew, d, gnew)


def _attainability(X, atol, rtol, rel, rule):
    """max_k (|Gamma_k| + rho_k + eps |z_k|) / delta_k at the current node:
    the RK8 track's estimated error, its accumulated rounding, and the
    rounding of the stored value, against the tolerance."""
    tmp, tmp2 = X[TMP], X[TMP2]
    np.sqrt(X[RHO2], tmp)
    np.abs(X[ZHI], tmp2)
    np.multiply(tmp2, EPS, tmp2)
    np.add(tmp, tmp2, tmp)
    np.abs(X[GAM], tmp2)
    np.add(tmp, tmp2, tmp)
    _delta(atol, rtol, X[U], X[U], rel, rule, X[DEL], tmp2)
    np.divide(tmp, X[DEL], tmp)
    return _max(tmp)


# -- the Python driver ---------------------------------------------------------


@dataclass(frozen=True)
class RunOutput:
    """Raw result of :func:`run`: the kept nodes and the final counters."""

    t: np.ndarray
    y: np.ndarray
    z: np.ndarray | None
    gamma: np.ndarray | None
    quenched: np.ndarray | None
    status: int  # a Status code (0 success, ...), or 4 for an interrupt
    t_last: float  # time of the last accepted node
    h_fail: float  # step size that failed (step-size underflow)
    first_step: float
    max_ratio: float  # max over nodes of the attainability ratio
    stats: dict


ST_INTERRUPTED = 4


def _inplace(fun: Callable, matrix: bool) -> Callable:
    """Wrap ``fun(t, y, params) -> array`` as ``fun(t, y, params, out)``."""
    if matrix:

        def wrapped(t, y, params, out):
            out[:, :] = fun(t, y, params)

    else:

        def wrapped(t, y, params, out):
            out[:] = fun(t, y, params)

    return wrapped


def _float_array(values) -> np.ndarray:
    return np.array(values, dtype=np.float64, order="C", copy=True)


@dataclass(frozen=True, eq=False)
class Workspace:
    """The arrays of one integration in progress, as :func:`advance` takes them.

    Built by :func:`workspace`; the state at ``t0`` is loaded, nothing is
    evaluated yet.  :func:`run` drives it in chunks; the SciPy solver
    :class:`hamrkq.RK34Q8` drives it one accepted step at a time.
    """

    coefficients: tuple[np.ndarray, ...]  # A3, b3, c3, A4, b4, c4, A8, b8, c8
    t_eval: np.ndarray
    atol: np.ndarray
    rtol: np.ndarray
    iopt: np.ndarray
    fopt: np.ndarray
    fstate: np.ndarray
    istate: np.ndarray
    X: np.ndarray
    K4: np.ndarray
    K3: np.ndarray
    K8: np.ndarray
    dK8: np.ndarray
    JM: np.ndarray

    def advance_args(self) -> tuple[np.ndarray, ...]:
        """The arguments of :func:`advance` between ``params`` and the outputs."""
        return (
            *self.coefficients, self.t_eval, self.atol, self.rtol, self.iopt, self.fopt,
            self.fstate, self.istate, self.X, self.K4, self.K3, self.K8, self.dK8, self.JM,
        )  # fmt: skip


def workspace(
    t0: float,
    y0: np.ndarray,
    t_end: float,
    *,
    rk3,
    rk4,
    rk8,
    atol: np.ndarray,
    rtol: np.ndarray,
    quench: int = QUENCH_NODE,
    rule: int = RULE_COMPONENTWISE,
    gamma: int = GAMMA_TANGENT,
    safety: float = 0.9,
    theta: float = 1.0,
    max_step: float = np.inf,
    max_steps: int = 1_000_000,
    gamma_limit: float = 0.05,
    keep_every: int = 1,
    t_eval: np.ndarray | None = None,
) -> Workspace:
    """Allocate the work arrays of an RKQ (``rk8`` a tableau) or RK34
    (``rk8=None``) integration from ``(t0, y0)`` to ``t_end``.

    The options are those of :func:`run` (already validated, as codes).  The
    step size ``fstate[FS_H]`` is left at zero for the caller to set.
    """
    d = y0.shape[0]
    A3, b3, c3 = (_float_array(v) for v in (rk3.A, rk3.b, rk3.c))
    A4, b4, c4 = (_float_array(v) for v in (rk4.A, rk4.b, rk4.c))
    shared = _shared_stages(A3, c3, A4, c4)
    use_rk8 = rk8 is not None
    if use_rk8:
        A8, b8, c8 = (_float_array(v) for v in (rk8.A, rk8.b, rk8.c))
        rich = 2.0**rk8.order / (2.0**rk8.order - 1.0)
    else:
        A8, b8, c8 = np.zeros((1, 1)), np.zeros(1), np.zeros(1)
        rich = 0.0
        gamma = GAMMA_OFF
    s8 = b8.shape[0]
    use_teval = t_eval is not None
    rtol = _float_array(rtol)
    iopt = np.array(
        [quench, rule, gamma, int(use_rk8), keep_every, max_steps, shared, int(use_teval),
         int(np.any(rtol > 0))],
        dtype=np.int64,
    )  # fmt: skip
    fopt = np.array([safety, theta, max_step, gamma_limit, t_end, rich], dtype=np.float64)
    fstate = np.zeros(FS_SIZE)
    istate = np.zeros(IS_SIZE, dtype=np.int64)
    X = np.zeros((X_ROWS, d))
    X[U] = y0
    X[ZHI] = y0
    fstate[FS_T] = t0
    istate[IS_STATUS] = ST_RUNNING
    return Workspace(
        coefficients=(A3, b3, c3, A4, b4, c4, A8, b8, c8),
        t_eval=_float_array(t_eval if use_teval else []),
        atol=_float_array(atol),
        rtol=rtol,
        iopt=iopt,
        fopt=fopt,
        fstate=fstate,
        istate=istate,
        X=X,
        K4=np.zeros((b4.shape[0], d)),
        K3=np.zeros((b3.shape[0], d)),
        K8=np.zeros((s8, d)),
        dK8=np.zeros((s8, d)),
        JM=np.zeros((d, d)),
    )


def run(
    rhs: Callable,
    jac: Callable,
    params: np.ndarray,
    t0: float,
    y0: np.ndarray,
    t_end: float,
    *,
    rk3,
    rk4,
    rk8,
    atol: np.ndarray,
    rtol: np.ndarray,
    quench: int = QUENCH_NODE,
    rule: int = RULE_COMPONENTWISE,
    gamma: int = GAMMA_TANGENT,
    safety: float = 0.9,
    theta: float = 1.0,
    max_step: float = np.inf,
    max_steps: int = 1_000_000,
    gamma_limit: float = 0.05,
    keep_every: int = 1,
    t_eval: np.ndarray | None = None,
    first_step: float | None = None,
    progress: Callable[[float, float], None] | None = None,
    budget: int = 2000,
    buffer_rows: int = 4096,
    inplace: bool = False,
) -> RunOutput:
    """Run RKQ (``rk8`` a tableau) or RK34 (``rk8=None``) from ``t0`` to ``t_end``.

    ``rhs``/``jac`` are ``f(t, y, params) -> array`` (or already in-place
    ``f(t, y, params, out)`` when ``inplace``).  ``rk3``, ``rk4``, ``rk8`` are
    :class:`~hamrkq.methods.tableaus.ButcherTableau`.  Options are validated by
    :func:`hamrkq.solve`; the codes are this module's constants.
    ``progress(fraction, t)`` is called between chunks of ``budget`` steps.
    A ``KeyboardInterrupt`` ends the run with the nodes kept so far.
    """
    if not inplace:
        rhs = _inplace(rhs, False)
        jac = _inplace(jac, True)
    ws = workspace(
        t0, y0, t_end, rk3=rk3, rk4=rk4, rk8=rk8, atol=atol, rtol=rtol, quench=quench,
        rule=rule, gamma=gamma, safety=safety, theta=theta, max_step=max_step,
        max_steps=max_steps, gamma_limit=gamma_limit, keep_every=keep_every, t_eval=t_eval,
    )  # fmt: skip
    d = y0.shape[0]
    use_rk8 = rk8 is not None
    gamma = int(ws.iopt[IO_GAMMA])
    use_teval = t_eval is not None
    t_eval, atol, rtol = ws.t_eval, ws.atol, ws.rtol
    rel, rule = int(ws.iopt[IO_REL]), int(ws.iopt[IO_RULE])
    fstate, istate, X = ws.fstate, ws.istate, ws.X

    rows = max(1, buffer_rows)
    chunks: list[tuple[np.ndarray, ...]] = []

    def new_buffers():
        zrows = rows if use_rk8 else 0
        return (
            np.empty(rows),
            np.empty((rows, d)),
            np.empty((zrows, d)),
            np.empty((zrows, d)),
            np.zeros(zrows, dtype=np.int8),
        )

    buffers = new_buffers()
    h0 = 0.0
    status = ST_RUNNING
    try:
        if not use_teval or (t_eval.size and t_eval[0] == t0):
            _write(X, t0, 0, istate, *buffers, use_rk8)
            istate[IS_EVAL_INDEX] = int(use_teval)
        if t0 == t_end:
            status = ST_SUCCESS
        else:
            rhs(t0, X[U], params, X[K1])
            istate[IS_NFEV] += 1
            if not _finite(X[K1]):
                status = ST_NON_FINITE
            else:
                istate[IS_K1_VALID] = 1
                if first_step is None:
                    h0 = initial_step(rhs, t0, X[U], X[K1], t_end, atol, rtol, rel, rule, 3,
                                      max_step, params, np.zeros((3, d)))  # fmt: skip
                    istate[IS_NFEV] += 1
                else:
                    h0 = float(first_step)
                fstate[FS_H] = h0 if t_end > t0 else -h0
        while status == ST_RUNNING:
            ret = advance(rhs, jac, params, *ws.advance_args(), *buffers, budget)
            if ret == RET_DONE:
                status = int(istate[IS_STATUS])
            elif ret == RET_BUFFER_FULL:
                chunks.append(_filled(buffers, istate[IS_NOUT]))
                rows = min(2 * rows, 1 << 16)
                buffers = new_buffers()
                istate[IS_NOUT] = 0
            if progress is not None and status == ST_RUNNING:
                progress(float((fstate[FS_T] - t0) / (t_end - t0)), float(fstate[FS_T]))
    except KeyboardInterrupt:
        status = ST_INTERRUPTED
    chunks.append(_filled(buffers, istate[IS_NOUT]))
    t, y, z, gam, q = (np.concatenate([c[i] for c in chunks]) for i in range(5))
    stats = {
        "steps": int(istate[IS_STEPS]),
        "rejected": int(istate[IS_REJECTED]),
        "quenches": int(istate[IS_QUENCHES]),
        "nfev": int(istate[IS_NFEV]),
        "njev": int(istate[IS_NJEV]),
    }
    if use_rk8 and gamma != GAMMA_OFF:
        stats["roundoff_steps"] = int(istate[IS_ROUNDOFF_STEPS])
    return RunOutput(
        t=t,
        y=y,
        z=z if use_rk8 else None,
        gamma=gam if use_rk8 else None,
        quenched=q.astype(bool) if use_rk8 else None,
        status=status,
        t_last=float(fstate[FS_T]),
        h_fail=float(fstate[FS_FAIL_H]),
        first_step=float(h0),
        max_ratio=float(fstate[FS_RATIO]),
        stats=stats,
    )


def _filled(buffers, n) -> tuple[np.ndarray, ...]:
    t, y, z, g, q = buffers
    nz = n if z.shape[0] else 0
    return t[:n].copy(), y[:n].copy(), z[:nz].copy(), g[:nz].copy(), q[:nz].copy()


def _shared_stages(A3, c3, A4, c4) -> int:
    """Number of leading stages that RK3 and RK4 have in common (2 for
    Kutta's RK3 and the classical RK4), computed once and then reused."""
    shared = 0
    for j in range(min(c3.size, c4.size)):
        if c3[j] != c4[j] or np.any(A3[j, :j] != A4[j, :j]):
            break
        shared = j + 1
    return shared
