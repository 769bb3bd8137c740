"""The tangent (variational) sweep along a finished run, for chaos indicators.

:func:`sweep` carries a unit tangent vector ``v`` from node to node with the
exact linearisation of the quencher's steps (:func:`hamrkq.rkq.steps.tangent_increment`
from the node ``y_i`` over ``h_i = t_{i+1} - t_i``, in as many steps as the
run's quencher took, or more where the tangent changes too much over one of
them, :data:`MAX_TANGENT_CHANGE`; the callers pass the quencher track's
nodes where there are), renormalising it every step and
recording ``log|v_{i+1}| - log|v_i|``: the maximal Lyapunov exponent and MEGNO
are sums over these (:mod:`hamrkq.analysis.chaos`).  ``@jitable``: interpreted,
or compiled by numba with the compiled ``rhs_jvp``.
"""

from __future__ import annotations

import math

from hamrkq.rkq import arith, steps
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import DINC, INC, MHI, MLO, TMP, ZHI, ZLO

__all__ = ["MAX_TANGENT_CHANGE", "sweep"]


#: The largest change ``|v' - v| / |v|`` of the tangent vector over one of
#: the sweep's steps.  Over a step ``h`` the quencher's tangent map is
#: ``R(h J)``, its stability function of ``h J``, which follows the flow's
#: ``exp(h J)`` to ``|h lambda|^(z+1) / (z+1)!``: 5e-9 at ``|h lambda| = 0.5``
#: for an order ``z >= 8``.  An orbit's steps keep that size where its own
#: error depends on ``J``, but not where the orbit hardly moves: at the
#: pendulum's rest point the steps grew to 694 time units, and the
#: tangent map of such a step (``|R(694 i)|``, enormous) made the Lyapunov
#: exponent 1.57 and MEGNO 78.7 at t = 100 where both are 0 (found by QA).
#: An interval whose change exceeds this is swept again in twice the steps.
MAX_TANGENT_CHANGE = 0.5
#: At most this many doublings of an interval's steps (a millionfold).
MAX_DOUBLINGS = 20


@jitable
def sweep(tangent, tab, params, t_nodes, y_nodes, substeps, v, work, log_growth):
    """``log_growth[i] = log(|v_{i+1}| / |v_i|)`` along the nodes, each
    interval in ``substeps`` quencher steps (the run's own: the tangent map
    of one step over an interval its quencher took in three read 1.3e-2 off
    in log|v| on a linear oscillator at atol 1e-2, 3.2e-7 in three; found by
    QA), or in as many more, doubling, as keep the tangent's change within
    :data:`MAX_TANGENT_CHANGE` a step; ``v`` (unit length on entry)
    renormalised after every interval and left holding the final direction.
    Returns the Jacobian-vector products made."""
    tab, work = borrow(tab), borrow(work)
    d = y_nodes.shape[1]
    njev = 0
    for i in range(t_nodes.shape[0] - 1):
        m = substeps
        for c in range(d):
            work.V[TMP, c] = v[c]  # the interval's start, for a second sweep
        for _ in range(MAX_DOUBLINGS + 1):
            change, products = _interval(tangent, tab, params, t_nodes, y_nodes, i, m, v, work)
            njev += products
            if change <= MAX_TANGENT_CHANGE or not math.isfinite(change):
                break
            m *= 2
            for c in range(d):
                v[c] = work.V[TMP, c]
        norm = 0.0
        for c in range(d):
            norm += work.V[DINC, c] * work.V[DINC, c]
        norm = math.sqrt(norm)
        log_growth[i] = math.log(norm)
        for c in range(d):
            v[c] = work.V[DINC, c] / norm
    return njev


@jitable
def _interval(tangent, tab, params, t_nodes, y_nodes, i, m, v, work):
    """The tangent ``v`` from node ``i`` to node ``i + 1`` in ``m`` quencher
    steps (into ``V[DINC]``; ``v`` is overwritten); returns the largest
    relative change of the tangent over one step, and the Jacobian-vector
    products made."""
    d = y_nodes.shape[1]
    h = (t_nodes[i + 1] - t_nodes[i]) / m
    for c in range(d):
        work.V[ZHI, c] = y_nodes[i, c]
        work.V[ZLO, c] = 0.0
    change = 0.0
    njev = 0
    for k in range(m):
        if k > 0:
            # on from the substep's end, compensated, with its tangent
            arith.two_sum(work.V[ZHI], work.V[ZLO], work.V[INC], work.V[MHI], work.V[MLO])
            for c in range(d):
                work.V[ZHI, c] = work.V[MHI, c]
                work.V[ZLO, c] = work.V[MLO, c]
                v[c] = work.V[DINC, c]
        njev += steps.tangent_increment(
            tangent, t_nodes[i] + k * h, work.V[ZHI], work.V[ZLO], h, tab, params, work, v
        )
        moved = 0.0
        size = 0.0
        for c in range(d):
            moved += (work.V[DINC, c] - v[c]) ** 2
            size += v[c] * v[c]
        if size > 0.0:
            change = max(change, math.sqrt(moved / size))
    return change, njev
