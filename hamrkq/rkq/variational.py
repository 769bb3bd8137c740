"""The tangent (variational) sweep along a finished run, for chaos indicators.

:func:`sweep` carries a unit tangent vector ``v`` from node to node with the
exact linearisation of the quencher's steps (:func:`hamrkq.rkq.steps.tangent_increment`
from the node ``y_i`` over ``h_i = t_{i+1} - t_i``, in as many steps as the
run's quencher took; the callers pass the quencher track's nodes where there
are), renormalising it every step and
recording ``log|v_{i+1}| - log|v_i|``: the maximal Lyapunov exponent and MEGNO
are sums over these (:mod:`hamrkq.analysis.chaos`).  ``@jitable``: interpreted,
or compiled by numba with the compiled ``rhs_jvp``.
"""

from __future__ import annotations

import math

from hamrkq.rkq import arith, steps
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import DINC, INC, MHI, MLO, ZHI, ZLO

__all__ = ["sweep"]


@jitable
def sweep(tangent, tab, params, t_nodes, y_nodes, substeps, v, work, log_growth):
    """``log_growth[i] = log(|v_{i+1}| / |v_i|)`` along the nodes, each
    interval in ``substeps`` quencher steps (the run's own: the tangent map
    of one step over an interval its quencher took in three read 1.3e-2 off
    in log|v| on a linear oscillator at atol 1e-2, 3.2e-7 in three; found by
    QA), ``v`` (unit length on entry) renormalised after every interval and
    left holding the final direction.  Returns the Jacobian-vector products
    made."""
    tab, work = borrow(tab), borrow(work)
    d = y_nodes.shape[1]
    njev = 0
    for i in range(t_nodes.shape[0] - 1):
        h = (t_nodes[i + 1] - t_nodes[i]) / substeps
        for c in range(d):
            work.V[ZHI, c] = y_nodes[i, c]
            work.V[ZLO, c] = 0.0
        for k in range(substeps):
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
        norm = 0.0
        for c in range(d):
            norm += work.V[DINC, c] * work.V[DINC, c]
        norm = math.sqrt(norm)
        log_growth[i] = math.log(norm)
        for c in range(d):
            v[c] = work.V[DINC, c] / norm
    return njev
