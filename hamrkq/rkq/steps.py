"""One step of each track: the reported pair, the quencher, and Gamma.

The functions take the right-hand side as ``rhs(t, y, params, out)`` and,
for the tangent propagation, ``tangent(t, y, params, v, out, dout, JM)``
(``f`` into ``out`` and ``J v`` into ``dout`` at one point); see
:mod:`hamrkq.rkq.loop` for the conventions.  They return the number of
evaluations they made, and the caller counts them.
"""

from __future__ import annotations

import math

from hamrkq._floats import EPS
from hamrkq.rkq import arith, ddarith
from hamrkq.rkq.jit import jitable
from hamrkq.rkq.layout import (
    CAND,
    DELTA,
    DHI,
    DINC,
    DLO,
    DY,
    ERR,
    FLOOR,
    GAM,
    GAMMA_OFF,
    GAMMA_PAPER,
    GAMMA_SHADOW,
    GAMMA_TANGENT,
    GNEW,
    INC,
    INC_LO,
    INCA,
    INCB,
    K1,
    MHI,
    MLO,
    NFLOOR,
    NHI,
    NLO,
    NOISE,
    NSHI,
    NSLO,
    NWHI,
    NWLO,
    SHI,
    SLO,
    TMP,
    WHI,
    WLO,
    YT,
    ZHI,
    ZLO,
    U,
)

#: A Richardson difference within this many ulps of the increments it is taken
#: from is rounding, not truncation (each increment carries about one ulp).
ROUNDOFF_ULPS = 1.0


@jitable
def pair_step(rhs, t, h, tab, params, work):
    """The reported pair from ``V[U]`` (``V[K1] = f(t, u)`` given): the
    candidate ``V[CAND] = u + h sum b K`` and the error estimate
    ``V[ERR] = h sum b_err K - h sum b K``.  Returns the evaluations."""
    V, K = work.V, work.K
    u, y, inc, inc_lo = V[U], V[YT], V[INC], V[INC_LO]
    s = tab.b.shape[0]
    arith.copy(V[K1], K[0])
    for j in range(1, s):
        arith.stage_value(u, h, tab.A, j, K, y)
        rhs(t + tab.c[j] * h, y, params, K[j])
    arith.increment(h, tab.b, K, inc)
    arith.increment(h, tab.b_err, K, inc_lo)
    for i in range(u.shape[0]):
        V[CAND, i] = u[i] + inc[i]
        V[ERR, i] = inc_lo[i] - inc[i]
    return s - 1


@jitable
def explicit_increment(  # noqa: PLR0913 - the kernel's convention: arrays, no objects
    rhs, t, hi, lo, h, tab, params, work, out, first_done, reverse=False, seed=-1.0,
    time_seed=-1.0,
):  # fmt: skip
    """Stages of one quencher step of size ``h`` from the compensated state
    ``(hi, lo)`` into ``work.Kz`` and the increment into ``out``;
    ``work.Kz[0]`` is reused when ``first_done``; ``reverse`` sums the stages
    the other way round and ``seed >= 0`` rounds the stage values
    stochastically (the rounding witness; seeds ``seed``, ``seed + 1``, ...
    over the stages and components), ``time_seed >= 0`` the stage times
    ``t + c_j h`` (seeds ``time_seed + j``).  Returns the evaluations."""
    Kz, y = work.Kz, work.V[YT]
    nfev = 0
    for j in range(tab.bz.shape[0]):
        if j == 0 and first_done:
            continue
        stage_seed = seed + j * y.shape[0] if seed >= 0.0 else -1.0
        arith.stage_value_compensated(hi, lo, h, tab.Az, tab.Az_low, j, Kz, y, reverse, stage_seed)
        stage_time = t + tab.cz[j] * h
        if time_seed >= 0.0:
            u = arith.uniform(time_seed + j)
            stage_time = arith.round_stochastically(t, tab.cz[j] * h, u)
        rhs(stage_time, y, params, Kz[j])
        nfev += 1
    arith.increment_compensated(h, tab.bz, tab.bz_low, Kz, out, reverse)
    return nfev


@jitable
def dense_substeps(h, span, m):
    """How many quencher steps a dense value ``h`` from its node takes inside
    an interval ``span`` between two nodes whose quencher took ``m`` steps:
    none longer than the quencher's own (``ceil(m |h| / |span|)``, at least
    one)."""
    if span == 0.0:
        return 1
    # a value a rounding error past a whole number of quencher steps (h = span
    # / 2 with m odd: 1.5; with m even: m / 2 exactly, or a hair above) takes
    # no extra step for it
    return max(1, math.ceil(m * abs(h / span) - 1e-12))


@jitable
def dense_value(  # noqa: PLR0913 - the kernel's convention: arrays, no objects
    rhs, t, hi, lo, h, substeps, tab, params, gap, atol, rtol, relative, rule, theta, work,
    out_y, out_z,
):  # fmt: skip
    """One value between two nodes (:mod:`hamrkq.rkq.dense`): the quencher's
    value ``z`` from the compensated state ``(hi, lo)`` at ``t``, ``substeps``
    steps of ``h / substeps`` (:func:`dense_substeps`), into ``out_z``, and
    ``out_y = z + gap``, ``gap`` the reported solution's difference to the
    quencher interpolated between the nodes, or ``z`` itself where ``gap`` is
    more than ``theta`` times the tolerance at ``z`` (as a node is
    quenched).  That happens where a component passes near zero under
    ``rtol`` between two nodes: the tolerance there is below the nodes', and
    their differences, interpolated, were up to 46 times it (the FPU chain
    at ``rtol`` 1e-6, ``benchmarks/dense_error_rtol.md``; 2 times at an
    output time of ``t_eval``).  The quencher's steps are no longer than its
    own in the run: in one step over half a step of the pair, which the
    quencher had taken in ``m`` (up to 6 after ``auto``'s reruns), the
    value's truncation error was ``(m/2)^(z+1)`` times a quencher step's, and
    nothing checked it (the Toda lattice at ``rtol`` 1e-6, ``atol`` 1e-12,
    in six: event states 8.7e-12 off where the quencher's nodes were
    1e-16).  Returns ``(evaluations, quenched)``."""
    V = work.V
    dhi, dlo, inc = V[DHI], V[DLO], V[INC]
    arith.copy(hi, dhi)
    arith.copy(lo, dlo)
    hs = h / substeps
    nfev = 0
    for k in range(substeps):
        nfev += explicit_increment(rhs, t + k * hs, dhi, dlo, hs, tab, params, work, inc, False)
        arith.two_sum(dhi, dlo, inc, dhi, dlo)
    cover_shortfall(dhi, dlo, inc, substep_shortfall(h, hs, substeps), hs, work.Kz[0])
    for i in range(out_z.shape[0]):
        out_z[i] = dhi[i] + dlo[i]
    arith.tolerance(atol, rtol, out_z, out_z, relative, rule, V[DELTA])
    quenched = arith.weighted_norm(gap, V[DELTA]) > theta
    for i in range(out_y.shape[0]):
        out_y[i] = out_z[i] if quenched else out_z[i] + gap[i]
    return nfev, quenched


@jitable
def double_double_increment(rhs_dd, t, hi, lo, h, tab, params, work, out_hi, out_lo):
    """One quencher step of size ``h`` from the double-double state ``(hi,
    lo)`` with every stage and ``f`` in double-double
    (:mod:`hamrkq.rkq.ddarith`; ``rhs_dd(t, y, params, ylo, out, outlo, JM)``,
    :mod:`hamrkq.backends.dd_printer`): the stages into ``work.Kz`` and
    their low words into ``work.dKz`` (free: there is no tangent then), the
    increment into ``(out_hi, out_lo)``.  The step size and the stage times
    stay doubles.  Returns the evaluations."""
    V, Kz, Kzlo = work.V, work.Kz, work.dKz
    y, ylo = V[YT], V[DY]
    s = tab.bz.shape[0]
    for j in range(s):
        for i in range(y.shape[0]):
            acc, acc_lo = dd_weighted_sum(tab.Az[j], tab.Az_low[j], Kz, Kzlo, j, i)
            acc, acc_lo = ddarith.dd_mul_d(acc, acc_lo, h)
            y[i], ylo[i] = ddarith.dd_add(hi[i], lo[i], acc, acc_lo)
        rhs_dd(t + tab.cz[j] * h, y, params, ylo, Kz[j], Kzlo[j], work.JM)
    for i in range(y.shape[0]):
        acc, acc_lo = dd_weighted_sum(tab.bz, tab.bz_low, Kz, Kzlo, s, i)
        out_hi[i], out_lo[i] = ddarith.dd_mul_d(acc, acc_lo, h)
    return s


@jitable
def double_double_step(rhs_dd, t, h, tab, params, work):
    """The quencher's candidate ``(V[NHI], V[NLO])`` advanced by one step of
    :func:`double_double_increment`.  Returns the evaluations."""
    V = work.V
    nhi, nlo, inc, inc_lo = V[NHI], V[NLO], V[INC], V[INC_LO]
    nfev = double_double_increment(rhs_dd, t, nhi, nlo, h, tab, params, work, inc, inc_lo)
    for i in range(nhi.shape[0]):
        nhi[i], nlo[i] = ddarith.dd_add(nhi[i], nlo[i], inc[i], inc_lo[i])
    return nfev


@jitable
def dd_weighted_sum(w, w_low, K, Klo, count, i):
    """``sum_{m < count} (w + w_low)[m] (K + Klo)[m, i]`` in double-double."""
    acc, acc_lo = 0.0, 0.0
    for m in range(count):
        term, term_lo = ddarith.dd_mul(w[m], w_low[m], K[m, i], Klo[m, i])
        acc, acc_lo = ddarith.dd_add(acc, acc_lo, term, term_lo)
    return acc, acc_lo


@jitable
def tangent_increment(tangent, t, hi, lo, h, tab, params, work, gam):
    """One quencher step (increment into ``V[INC]``) and its exact
    linearisation applied to ``gam`` (``gam + h sum b dK`` into ``V[DINC]``):
    ``dY_j = gam + h sum_l a_jl dK_l``, ``dK_j = J(t + c_j h, Y_j) dY_j``.
    Returns the Jacobian-vector products (one per stage)."""
    V, Kz, dKz = work.V, work.Kz, work.dKz
    y, dy, dinc = V[YT], V[DY], V[DINC]
    s = tab.bz.shape[0]
    for j in range(s):
        arith.stage_value_compensated(hi, lo, h, tab.Az, tab.Az_low, j, Kz, y)
        arith.stage_value(gam, h, tab.Az, j, dKz, dy)
        tangent(t + tab.cz[j] * h, y, params, dy, Kz[j], dKz[j], work.JM)
    arith.increment_compensated(h, tab.bz, tab.bz_low, Kz, V[INC])
    arith.increment(h, tab.bz, dKz, dinc)
    for i in range(gam.shape[0]):
        dinc[i] += gam[i]
    return s


@jitable
def richardson(rhs, t, hi, lo, h, tab, params, work, richardson_factor):
    """The local error of the quencher's step of size ``h`` from ``(hi, lo)``
    (whose increment is in ``V[INC]``, and ``work.Kz[0] = f(t, hi + lo)``),
    by two half steps: into ``V[TMP]``, numerical minus exact.  Adds this
    step's rounding level squared to ``V[NOISE]``.  Returns the evaluations
    and whether the difference is only rounding (as ``nfev * 2 + flag``)."""
    V = work.V
    inc, inca, incb, mhi, mlo = V[INC], V[INCA], V[INCB], V[MHI], V[MLO]
    half = 0.5 * h
    nfev = explicit_increment(rhs, t, hi, lo, half, tab, params, work, inca, True)
    arith.two_sum(hi, lo, inca, mhi, mlo)
    nfev += explicit_increment(rhs, t + half, mhi, mlo, half, tab, params, work, incb, False)
    scale = ROUNDOFF_ULPS * EPS
    rounding_only = 1
    for i in range(hi.shape[0]):
        d = (inc[i] - inca[i]) - incb[i]  # free of the rounding of |z|
        noise = ((abs(inc[i]) + abs(inca[i])) + abs(incb[i])) * scale
        if abs(d) - noise > 0.0:
            rounding_only = 0
        V[NOISE, i] += noise * noise
        V[TMP, i] = d * richardson_factor
    return nfev * 2 + rounding_only


@jitable
def substep_shortfall(h, hs, m):
    """``h - m hs``: what ``m`` substeps of ``hs = fl(h / m)`` leave of the
    step ``h`` (zero where ``m`` is a power of two), with ``m hs`` summed
    exactly (TwoSum) and ``h`` minus it exact by Sterbenz's lemma."""
    hi, lo = hs, 0.0
    for _ in range(m - 1):
        hi, error = ddarith.two_sum(hi, hs)
        lo += error
    return (h - hi) - lo


@jitable
def cover_shortfall(hi, lo, inc, shortfall, hs, start_slope):
    """``(hi, lo)`` advanced over ``shortfall`` at the slope at the end of the
    last substep, whose increment is ``inc`` (overwritten) and whose slope
    at its start is ``start_slope`` (its first stage, ``work.Kz[0]``): the
    end slope extrapolated linearly, ``2 inc / hs - start_slope``.  The
    track then ends at the node's time.  Without it, the tracks of ``m``
    substeps fell behind or ahead of the nodes by the roundings of ``h /
    m``, a few 1e-17 in time over a run, which near the collision of ``H =
    p^2/2 - 1/q`` (``dp/dt`` up to 1e11) put the quencher in double-double
    1.7e-6 off the exact solution, 37 times its Gamma, and ``auto``
    returned nodes 1.78 times ``atol = 1e-6`` off.  (Covered at the
    substep's mean slope instead, the quencher in double-double kept a
    floor where ``m`` is not a power of two: prentice2011 to t = 1000 was
    1.5e-15 to 1.5e-14 off with m = 3, 5, 6, 7, 12 and exact to double with
    4, 8, 16, which Gamma, at 1e-16 to 1e-24, did not see.)"""
    if shortfall == 0.0:
        return
    for i in range(inc.shape[0]):
        inc[i] = shortfall * (2.0 * inc[i] / hs - start_slope[i])
    arith.two_sum(hi, lo, inc, hi, lo)


@jitable
def cover_shortfall_exactly(rhs_dd, t, hi, lo, shortfall, params, work):
    """The double-double state ``(hi, lo)`` advanced over ``shortfall`` (the
    part of the step its substeps left, :func:`substep_shortfall`) at its
    own slope ``f(t, hi + lo)``, in double-double: one evaluation, where the
    shortfall is not zero.  Returns the evaluations.

    :func:`cover_shortfall`'s slope, extrapolated from the last substep, is
    off by ``O(hs^2)``, and so moved the track off its energy surface by
    ``shortfall hs^2`` a step (1e-20): nothing in double, whose rounding is
    larger, but in double-double near a separatrix, where an energy error
    of 1e-20 shifts the phase by 1e-10 a period, the quencher of a pendulum
    1e-5 below it was 1.9e-9 off at t = 31 with 6 substeps, 4.8e-10 with
    12, 1.2e-10 with 24 and exact to double with 8 and 16 (no shortfall),
    where Gamma read 1e-13 (``benchmarks/separatrix_rounding.py``)."""
    if shortfall == 0.0:
        return 0
    slope, slope_lo = work.Kz[0], work.dKz[0]
    rhs_dd(t, hi, params, lo, slope, slope_lo, work.JM)
    for i in range(hi.shape[0]):
        step, step_lo = ddarith.dd_mul_d(slope[i], slope_lo[i], shortfall)
        hi[i], lo[i] = ddarith.dd_add(hi[i], lo[i], step, step_lo)
    return 1


@jitable
def close_substeps(rhs_dd, t, h, hs, m, double_double, params, work):
    """The quencher's candidate ``(V[NHI], V[NLO])`` after ``m`` substeps of
    ``hs`` carried over what they left of the step ``h``: at its own slope
    in double-double (:func:`cover_shortfall_exactly`), else at the slope
    extrapolated from the last substep (:func:`cover_shortfall`, whose
    increment is ``V[INC]``).  Returns the evaluations."""
    V = work.V
    shortfall = substep_shortfall(h, hs, m)
    if double_double:
        return cover_shortfall_exactly(rhs_dd, t + h, V[NHI], V[NLO], shortfall, params, work)
    cover_shortfall(V[NHI], V[NLO], V[INC], shortfall, hs, work.Kz[0])
    return 0


@jitable
def quencher_step(rhs, tangent, jac, t, h, tab, cfg, problem, work, state):
    """The quencher over one step of the pair: ``cfg.z_substeps`` steps of
    ``h / m`` from ``(V[ZHI], V[ZLO])`` into ``(V[NHI], V[NLO])``, Gamma's
    candidate into ``V[GNEW]`` and the rounding variance of the step into
    ``V[NOISE]``.  Counts evaluations in ``state``; sets
    ``state.cached_roundoff``."""
    params = problem.params
    V = work.V
    nhi, nlo, gnew, noise, inc = V[NHI], V[NLO], V[GNEW], V[NOISE], V[INC]
    mode = cfg["gamma_mode"]
    m = cfg["z_substeps"]
    hs = h / m
    arith.copy(V[ZHI], nhi)
    arith.copy(V[ZLO], nlo)
    arith.copy(V[GAM], gnew)
    for i in range(noise.shape[0]):
        noise[i] = 0.0
    rounding_steps = 0
    for k in range(m):
        ts = t + k * hs
        if cfg["z_double_double"]:
            # ``tangent`` is f in double-double here (the shadow's Gamma
            # needs no tangent); rounding is ~1e-32, so no noise is counted.
            state["nfev"] += double_double_step(tangent, ts, hs, tab, params, work)
            continue
        if mode == GAMMA_TANGENT:
            state["njev"] += tangent_increment(tangent, ts, nhi, nlo, hs, tab, params, work, gnew)
            state["nfev"] += tab.bz.shape[0]
        else:
            state["nfev"] += explicit_increment(
                rhs, ts, nhi, nlo, hs, tab, params, work, inc, False
            )
        if mode == GAMMA_TANGENT or mode == GAMMA_PAPER:
            packed = richardson(rhs, ts, nhi, nlo, hs, tab, params, work, cfg["richardson"])
            state["nfev"] += packed // 2
            rounding_steps += packed % 2
            if mode == GAMMA_TANGENT:
                for i in range(gnew.shape[0]):
                    gnew[i] = V[TMP, i] + V[DINC, i]
            else:
                state["njev"] += paper_propagation(jac, ts, hs, params, work)
        else:
            for i in range(noise.shape[0]):
                level = abs(inc[i]) * (ROUNDOFF_ULPS * EPS)
                noise[i] += level * level
        arith.two_sum(nhi, nlo, inc, nhi, nlo)
    state["nfev"] += close_substeps(tangent, t, h, hs, m, cfg["z_double_double"], params, work)
    if mode == GAMMA_SHADOW:
        shi, slo, nshi, nslo = V[SHI], V[SLO], V[NSHI], V[NSLO]
        state["nfev"] += explicit_increment(rhs, t, shi, slo, h, tab, params, work, inc, False)
        arith.two_sum(shi, slo, inc, nshi, nslo)
        arith.scaled_difference(nshi, nslo, nhi, nlo, cfg["shadow_scale"], gnew)
    elif mode == GAMMA_OFF:
        for i in range(gnew.shape[0]):
            gnew[i] = 0.0
    if cfg["witness"]:  # the shadow's or the tangent's estimate (driver.Integration)
        attempt = float(state["steps"] + state["rejected"])
        state["nfev"] += witness_step(rhs, t, h, tab, cfg, problem.witness_params, work, attempt)
    state["cached_roundoff"] = 1 if (rounding_steps == m and mode != GAMMA_OFF) else 0


@jitable
def witness_step(rhs, t, h, tab, cfg, params, work, attempt):
    """The rounding witness over one step of the pair: the quencher's
    ``z_substeps`` steps from ``(V[WHI], V[WLO])`` into ``(V[NWHI], V[NWLO])``,
    and the floor's candidate ``V[NFLOOR] = max(V[FLOOR], scale |w - z|)``.

    The witness is the quencher track again, from the same initial value on
    the same mesh, with every stage sum and the increment added in the
    opposite order (the same value, rounded differently), its stage values
    rounded stochastically (rounded to nearest, the two tracks share the
    rounding of every stage value, which ``h J`` magnifies: at Kepler's
    pericentres and, with DOP853's weights, near the Moon on the Arenstorf
    orbit; docs/algorithm.md), and the parameters
    moved by about an ulp (``witness_params``: constants formed from them,
    such as products, are rounded the same way at every evaluation, a
    systematic error that differs between the two only this way; a sum such
    as ``1 - mu`` with a small ``mu`` does not move, docs/algorithm.md).
    The two share their truncation error and differ only by how their
    rounding errors have grown along the orbit (the idea of Vignes'
    stochastic arithmetic).  (Starting it one ulp away instead measures how
    the flow amplifies that ulp: near the Moon on the Arenstorf orbit, a
    hundredfold in the first step.)  That divergence is the size of the
    quencher's rounding error, which nothing else in the run sees.  (A
    witness of the shadow, on the coarser mesh, costs less but measured 1.5
    to 20 times the quencher's rounding on prentice2011.)  Returns the
    evaluations."""
    V = work.V
    whi, wlo, nwhi, nwlo, inc = V[WHI], V[WLO], V[NWHI], V[NWLO], V[INC]
    n = cfg["z_substeps"]
    hs = h / n
    arith.copy(whi, nwhi)
    arith.copy(wlo, nwlo)
    nfev = 0
    seeds = float(tab.bz.shape[0] * whi.shape[0])  # per quencher step
    stages = float(tab.bz.shape[0] + 1)
    for k in range(n):
        seed = (attempt * n + k) * seeds
        # Its stage times rounded stochastically too, from a substep's start
        # rounded so: where f depends on the time, their rounding (an ulp of
        # 1.5e-8 at t = 1e8) is the witness's to measure (time_seed).
        time_seed = (attempt * n + k) * stages
        base = arith.round_stochastically(t, k * hs, arith.uniform(time_seed))
        nfev += explicit_increment(
            rhs, base, nwhi, nwlo, hs, tab, params, work, inc, False, True, seed, time_seed + 1
        )
        arith.two_sum(nwhi, nwlo, inc, nwhi, nwlo)
    cover_shortfall(nwhi, nwlo, inc, substep_shortfall(h, hs, n), hs, work.Kz[0])
    scale = cfg["witness_scale"]
    for i in range(whi.shape[0]):
        divergence = abs((nwhi[i] - V[NHI, i]) + (nwlo[i] - V[NLO, i])) * scale
        V[NFLOOR, i] = arith.fmax(V[FLOOR, i], divergence)
    return nfev


@jitable
def paper_propagation(jac, t, h, params, work):
    """The paper's ``Gamma <- (I + h J(t, z)) Gamma + eps`` with the local
    error ``eps`` in ``V[TMP]`` and ``z = V[NHI] + V[NLO]``.  Returns 1
    (Jacobians)."""
    V = work.V
    y, dy, gnew = V[YT], V[DY], V[GNEW]
    for i in range(y.shape[0]):
        y[i] = V[NHI, i] + V[NLO, i]
    jac(t, y, params, work.JM)
    arith.matvec(work.JM, gnew, dy)
    for i in range(gnew.shape[0]):
        gnew[i] = (dy[i] * h + gnew[i]) + V[TMP, i]
    return 1
