"""One step of each track: the reported pair, the quencher, and Gamma.

The functions take the right-hand side as ``rhs(t, y, params, out)`` and,
for the tangent propagation, ``tangent(t, y, params, v, out, dout, JM)``
(``f`` into ``out`` and ``J v`` into ``dout`` at one point); see
:mod:`hamrkq.rkq.loop` for the conventions.  They return the number of
evaluations they made, and the caller counts them.
"""

from __future__ import annotations

from hamrkq.rkq import arith
from hamrkq.rkq.jit import jitable
from hamrkq.rkq.layout import EPS, GAMMA_OFF, GAMMA_PAPER, GAMMA_SHADOW, GAMMA_TANGENT

#: A Richardson difference within this many ulps of the increments it is taken
#: from is rounding, not truncation (each increment carries about one ulp).
ROUNDOFF_ULPS = 1.0


@jitable
def pair_step(rhs, t, h, tab, params, work):
    """The reported pair from ``work.u`` (``work.k1 = f(t, u)`` given):
    the candidate ``work.w = u + h sum b K`` and the error estimate
    ``work.err = h sum b_err K - h sum b K``.  Returns the evaluations."""
    K = work.K
    s = tab.b.shape[0]
    arith.copy(work.k1, K[0])
    for j in range(1, s):
        arith.stage_value(work.u, h, tab.A, j, K, work.yt)
        rhs(t + tab.c[j] * h, work.yt, params, K[j])
    arith.increment(h, tab.b, K, work.inc)
    arith.increment(h, tab.b_err, K, work.inc_lo)
    for i in range(work.w.shape[0]):
        work.w[i] = work.u[i] + work.inc[i]
        work.err[i] = work.inc_lo[i] - work.inc[i]
    return s - 1


@jitable
def explicit_increment(rhs, t, hi, lo, h, tab, params, work, out, first_done):
    """Stages of one quencher step of size ``h`` from the compensated state
    ``(hi, lo)`` into ``work.Kz`` and the increment into ``out``;
    ``work.Kz[0]`` is reused when ``first_done``.  Returns the evaluations."""
    nfev = 0
    for j in range(tab.bz.shape[0]):
        if j == 0 and first_done:
            continue
        arith.stage_value_compensated(hi, lo, h, tab.Az, j, work.Kz, work.yt)
        rhs(t + tab.cz[j] * h, work.yt, params, work.Kz[j])
        nfev += 1
    arith.increment(h, tab.bz, work.Kz, out)
    return nfev


@jitable
def tangent_increment(tangent, t, hi, lo, h, tab, params, work, gam):
    """One quencher step (increment into ``work.inc``) and its exact
    linearisation applied to ``gam`` (``gam + h sum b dK`` into
    ``work.dinc``): ``dY_j = gam + h sum_l a_jl dK_l``, ``dK_j = J(t + c_j h,
    Y_j) dY_j``.  Returns the Jacobian-vector products (one per stage)."""
    s = tab.bz.shape[0]
    for j in range(s):
        arith.stage_value_compensated(hi, lo, h, tab.Az, j, work.Kz, work.yt)
        arith.stage_value(gam, h, tab.Az, j, work.dKz, work.dy)
        tangent(t + tab.cz[j] * h, work.yt, params, work.dy, work.Kz[j], work.dKz[j], work.JM)
    arith.increment(h, tab.bz, work.Kz, work.inc)
    arith.increment(h, tab.bz, work.dKz, work.dinc)
    for i in range(gam.shape[0]):
        work.dinc[i] += gam[i]
    return s


@jitable
def richardson(rhs, t, hi, lo, h, tab, params, work, richardson_factor):
    """The local error of the quencher's step of size ``h`` from ``(hi, lo)``
    (whose increment is in ``work.inc``, and ``work.Kz[0] = f(t, hi + lo)``),
    by two half steps: into ``work.tmp``, numerical minus exact.  Adds this
    step's rounding level squared to ``work.noise``.  Returns the evaluations
    and whether the difference is only rounding (as ``nfev * 2 + flag``)."""
    half = 0.5 * h
    nfev = explicit_increment(rhs, t, hi, lo, half, tab, params, work, work.inca, True)
    arith.two_sum(hi, lo, work.inca, work.mhi, work.mlo)
    nfev += explicit_increment(
        rhs, t + half, work.mhi, work.mlo, half, tab, params, work, work.incb, False
    )
    scale = ROUNDOFF_ULPS * EPS
    rounding_only = 1
    for i in range(hi.shape[0]):
        d = (work.inc[i] - work.inca[i]) - work.incb[i]  # free of the rounding of |z|
        noise = ((abs(work.inc[i]) + abs(work.inca[i])) + abs(work.incb[i])) * scale
        if abs(d) - noise > 0.0:
            rounding_only = 0
        work.noise[i] += noise * noise
        work.tmp[i] = d * richardson_factor
    return nfev * 2 + rounding_only


@jitable
def quencher_step(rhs, tangent, jac, t, h, tab, cfg, params, work, state):
    """The quencher over one step of the pair: ``cfg.z_substeps`` steps of
    ``h / m`` from ``(zhi, zlo)`` into ``(nhi, nlo)``, Gamma's candidate into
    ``work.gnew`` and the rounding variance of the step into ``work.noise``.
    Counts evaluations in ``state``; sets ``state.cached_roundoff``."""
    mode = cfg["gamma_mode"]
    m = cfg["z_substeps"]
    hs = h / m
    arith.copy(work.zhi, work.nhi)
    arith.copy(work.zlo, work.nlo)
    arith.copy(work.gam, work.gnew)
    for i in range(work.noise.shape[0]):
        work.noise[i] = 0.0
    rounding_steps = 0
    for k in range(m):
        ts = t + k * hs
        if mode == GAMMA_TANGENT:
            state["njev"] += tangent_increment(
                tangent, ts, work.nhi, work.nlo, hs, tab, params, work, work.gnew
            )
            state["nfev"] += tab.bz.shape[0]
        else:
            state["nfev"] += explicit_increment(
                rhs, ts, work.nhi, work.nlo, hs, tab, params, work, work.inc, False
            )
        if mode == GAMMA_TANGENT or mode == GAMMA_PAPER:
            packed = richardson(
                rhs, ts, work.nhi, work.nlo, hs, tab, params, work, cfg["richardson"]
            )
            state["nfev"] += packed // 2
            rounding_steps += packed % 2
            if mode == GAMMA_TANGENT:
                for i in range(work.gnew.shape[0]):
                    work.gnew[i] = work.tmp[i] + work.dinc[i]
            else:
                state["njev"] += paper_propagation(jac, ts, hs, params, work)
        else:
            for i in range(work.noise.shape[0]):
                noise = abs(work.inc[i]) * (ROUNDOFF_ULPS * EPS)
                work.noise[i] += noise * noise
        arith.two_sum(work.nhi, work.nlo, work.inc, work.nhi, work.nlo)
    if mode == GAMMA_SHADOW:
        state["nfev"] += explicit_increment(
            rhs, t, work.shi, work.slo, h, tab, params, work, work.inc, False
        )
        arith.two_sum(work.shi, work.slo, work.inc, work.nshi, work.nslo)
        arith.scaled_difference(
            work.nshi, work.nslo, work.nhi, work.nlo, cfg["shadow_scale"], work.gnew
        )
    elif mode == GAMMA_OFF:
        for i in range(work.gnew.shape[0]):
            work.gnew[i] = 0.0
    state["cached_roundoff"] = 1 if (rounding_steps == m and mode != GAMMA_OFF) else 0


@jitable
def paper_propagation(jac, t, h, params, work):
    """The paper's ``Gamma <- (I + h J(t, z)) Gamma + eps`` with the local
    error ``eps`` in ``work.tmp`` and ``z = nhi + nlo``.  Returns 1 (Jacobians)."""
    for i in range(work.yt.shape[0]):
        work.yt[i] = work.nhi[i] + work.nlo[i]
    jac(t, work.yt, params, work.JM)
    arith.matvec(work.JM, work.gnew, work.dy)
    for i in range(work.gnew.shape[0]):
        work.gnew[i] = (work.dy[i] * h + work.gnew[i]) + work.tmp[i]
    return 1
