"""The start of a run: the first node, ``f(t0, y0)`` and the first step size.

Kernel code (``@jitable``, see :mod:`hamrkq.rkq.loop` for the conventions):
the step loop's :func:`~hamrkq.rkq.loop.advance` calls :func:`begin` on a
run's first call, compiled with it (the driver called it interpreted before,
about 20 us of a tiny problem's 0.38 ms call), and the batch loop
(:mod:`hamrkq.rkq.batch`) calls it for every member, so a member of an
ensemble starts exactly as the same run alone.  :func:`write_node`, which
writes the first node and every later one, lives here so that the loop can
import this module.
"""

from __future__ import annotations

import math

from hamrkq._floats import EPS
from hamrkq.rkq import arith
from hamrkq.rkq.jit import jitable
from hamrkq.rkq.layout import (
    CAND,
    DELTA,
    FLOOR,
    GAM,
    K1,
    RHO2,
    ST_NON_FINITE,
    ST_RUNNING,
    ST_SUCCESS,
    TMP,
    ZHI,
    U,
)

__all__ = ["FLOOR_ULPS", "begin", "initial_step", "write_node", "write_rounding"]

#: A step shorter than this many ulps of t cannot advance t reliably.
FLOOR_ULPS = 10.0


@jitable
def write_node(t, quenched, work, out, state, use_z):
    """Append the current node to the output buffers."""
    n = state["nout"]
    out.t[n] = t
    arith.copy(work.V[U], out.y[n])
    if use_z:
        arith.copy(work.V[ZHI], out.z[n])
        arith.copy(work.V[GAM], out.gamma[n])
        out.quenched[n] = quenched
        write_rounding(work, out.rounding[n])
    # Count the node only once it is complete: an interrupt never leaves half a row.
    state["nout"] = n + 1
    state["last_written"] = 1


@jitable
def write_rounding(work, row):
    """The quencher's rounding now, modelled and measured (``sqrt(RHO2) +
    FLOOR``), into ``row`` of :attr:`~hamrkq.rkq.layout.Output.rounding`."""
    V = work.V
    for i in range(row.shape[0]):
        row[i] = math.sqrt(V[RHO2, i]) + V[FLOOR, i]


@jitable
def initial_step(rhs, t0, t_end, problem, c, work):
    """First step size by the heuristic of Hairer, Norsett & Wanner (Solving
    ODEs I, II.4), as in SciPy's ``select_initial_step``, with hamrkq's
    weighted max norm, from ``V[U]`` with ``V[K1] = f(t0, u)`` given, for a
    method whose error exponent is ``c["error_exponent"]`` (``1 / (order + 1)``),
    at most ``c["max_step"]``.  Costs one evaluation of ``rhs``; uses the rows
    ``DELTA``, ``CAND`` and ``TMP`` as scratch.  Returns a positive step size."""
    V = work.V
    y0, f0, delta, y1, f1 = V[U], V[K1], V[DELTA], V[CAND], V[TMP]
    interval = abs(t_end - t0)
    direction = 1.0 if t_end >= t0 else -1.0
    arith.tolerance(problem.atol, problem.rtol, y0, y0, c["relative"], c["rule"], delta)
    d0 = arith.weighted_norm(y0, delta)
    d1 = arith.weighted_norm(f0, delta)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    if not (h0 > 0.0 and math.isfinite(h0)):
        # |y| / delta beyond the largest double (|y| ~ 1e307 at atol 1e-8):
        # inf / inf gave a NaN first step, which every attempt rejected
        # without shrinking it, until max_steps (found by QA).  The ratio of
        # the unweighted sizes instead (delta cancels where it is one value).
        h0 = 0.01 * arith.max_abs(y0) / arith.max_abs(f0)
        if not (h0 > 0.0 and math.isfinite(h0)):
            h0 = 1e-6
    h0 = min(h0, interval)
    for i in range(y0.shape[0]):
        y1[i] = f0[i] * (direction * h0) + y0[i]
    rhs(t0 + direction * h0, y1, problem.params, f1)
    for i in range(y0.shape[0]):
        f1[i] = f1[i] - f0[i]
    d2 = arith.weighted_norm(f1, delta) / h0
    if not math.isfinite(d2):
        h1 = h0
    elif max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** c["error_exponent"]
    # No shorter than twice the step the loop's roundoff floor refuses (10
    # eps |t|): a component at zero under a tiny atol gave 1e-15, below the
    # floor at t0 = -50, and the run ended on its first step with
    # STEP_SIZE_UNDERFLOW; a longer step is only rejected and shortened.
    floor = 2.0 * FLOOR_ULPS * EPS * abs(t0)
    h = min(max(min(100.0 * h0, h1), floor), interval, c["max_step"])
    # never a NaN (no attempt would shrink it): a long trial step is only
    # rejected and shortened
    return h if h > 0.0 else min(interval, c["max_step"])


@jitable
def begin(rhs, problem, c, s, work, out):
    """Start the run held in the state record ``s`` (at ``s["t"]``, with
    ``V[U] = y0``): write the first node unless ``t_eval`` skips it, evaluate
    ``f(t0, y0)`` and set the first step (``c["first_step"]``, or the
    heuristic when it is 0).  Sets and returns the status (``ST_RUNNING`` to
    go on)."""
    t0 = s["t"]
    t_end = c["t_end"]
    use_t_eval = c["use_t_eval"]
    t_eval = problem.t_eval
    if not use_t_eval or (t_eval.shape[0] > 0 and t_eval[0] == t0):
        write_node(t0, 0, work, out, s, c["use_z"])
        s["eval_index"] = use_t_eval
    if t0 == t_end:
        s["status"] = ST_SUCCESS
        return ST_SUCCESS
    V = work.V
    rhs(t0, V[U], problem.params, V[K1])
    s["nfev"] += 1
    if not arith.all_finite(V[K1]):
        s["bad_component"] = arith.first_nonfinite(V[K1])
        s["status"] = ST_NON_FINITE
        return ST_NON_FINITE
    s["k1_valid"] = 1
    h0 = c["first_step"]
    if h0 == 0.0:
        h0 = initial_step(rhs, t0, t_end, problem, c, work)
        s["nfev"] += 1
    s["h"] = h0 if t_end > t0 else -h0
    s["first_h"] = h0
    return ST_RUNNING
