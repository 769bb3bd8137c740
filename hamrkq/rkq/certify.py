"""Whether the promise can still be certified: the quencher's estimated
error, its rounding and the rounding of the node's time against
``gamma_limit`` of the tolerance, at a node (:func:`attainability`) and at
an output time inside a step (:func:`dense_attainability`); and the
projection ``method="auto"`` abandons a run on (:func:`projected_ratio`).
Part of the compiled kernel (:data:`hamrkq.backends.kernel.KERNEL_MODULES`);
the conventions of :mod:`hamrkq.rkq.loop`."""

from __future__ import annotations

import math

from hamrkq._floats import EPS
from hamrkq.rkq import arith
from hamrkq.rkq.jit import jitable
from hamrkq.rkq.layout import DELTA, FLOOR, GNEW, K1, NFLOOR, NHI, NOISE, RHO2, TMP2, ZHI, ZOLD, U

__all__ = [
    "attainability",
    "dense_attainability",
    "projected_ratio",
    "quencher_share",
    "record_ratio",
    "stored_share",
    "time_rounding",
]


@jitable
def attainability(work, problem, cfg, unew, t_lo, h):
    """max_k (|Gamma_k| + rho_k + eps |z_k| + floor_k + tau_k) / delta_k at
    the candidate node: the quencher's estimated error, its accumulated
    rounding (modelled, and measured by the witness when it runs), the
    rounding of the stored value and that of the node's time
    (:func:`time_rounding`), against the tolerance at the new solution
    ``unew``, reached by a step of ``h`` whose time has the low word ``t_lo``."""
    V = work.V
    delta, ratios = V[DELTA], V[TMP2]
    arith.tolerance(problem.atol, problem.rtol, unew, unew, cfg["relative"], cfg["rule"], delta)
    for i in range(unew.shape[0]):
        value = quencher_share(V[RHO2, i] + V[NOISE, i], V[NHI, i], V[GNEW, i], V[NFLOOR, i])
        ratios[i] = (value + time_rounding(work, unew, i, t_lo, h)) / delta[i]
    return arith.vmax(ratios)


@jitable
def quencher_share(rho2, z, gamma, floor):
    """``|Gamma| + rho + eps |z| + floor`` of one component: what the
    quencher's value may be off by (its estimated error, its rounding,
    modelled and measured, and the rounding of the stored value, ``z``
    its size)."""
    return ((math.sqrt(rho2) + abs(z) * EPS) + abs(gamma)) + floor


@jitable
def dense_attainability(work, z, gamma):
    """:func:`attainability` at a dense value between two nodes (``z`` the
    quencher's value there, ``gamma`` its Gamma interpolated), against the
    tolerance at ``z`` that :func:`hamrkq.rkq.steps.dense_value` left in
    ``V[DELTA]``: where a component passes near zero under ``rtol``, that
    tolerance falls below the nodes' on either side, which the check at the
    nodes does not see.  Kepler at ``rtol`` 1e-6 (``atol`` 1e-9) with
    ``rk78q12``, asked for the pericentre times: the value there, where
    ``p1 = 0`` and the tolerance is ``atol``, was 1.63 tolerances off, the
    quencher's own error, where the run with those times as nodes stopped.

    The value's own rounding is an ulp of the larger of it and the two
    nodes' quencher values (``V[ZOLD]``, ``V[ZHI]``), as
    :func:`hamrkq.rkq.dense.attainability` takes it: the value is stepped
    with the quencher's stages in double, whose rounding is the state's
    size's, not the value's where a component crosses zero.  With the
    quencher in double-double, whose modelled rounding is far below it,
    an output time at a zero of a component under ``atol`` 1e-20 returned
    SUCCESS 1120 times the tolerance off (``tests/test_t_eval_dense.py``)."""
    V = work.V
    ratios = V[TMP2]
    for i in range(z.shape[0]):
        size = max(abs(z[i]), abs(V[ZOLD, i]), abs(V[ZHI, i]))
        ratios[i] = quencher_share(V[RHO2, i], size, gamma[i], V[FLOOR, i]) / V[DELTA, i]
    return arith.vmax(ratios)


@jitable
def stored_share(work, z):
    """``max_k eps u_k / delta_k`` at a dense value (``u_k`` the larger of it
    and the two nodes' quencher values, as :func:`dense_attainability` takes
    it, ``delta`` as that left it in ``V[DELTA]``): the value's own rounding
    alone, which neither more quencher steps nor the quencher in
    double-double reduce.  Measured where the value is, not over the run:
    the double pendulum at ``rtol`` 1e-10 (``atol`` 1e-13), whose angle
    grows to 48, failed at ``t = 9.45`` where ``p2`` crosses zero between
    nodes of size 1.1 and 1.2 (0.003 of ``atol``); the angle's largest size
    over ``atol`` (0.108) made ``auto`` give up instead of running the
    quencher in double-double, which succeeds (since the weights sum to 1
    that run succeeds in double; ``tests/test_t_eval_dense.py``'s case is
    the same pendulum at ``rtol`` 3e-11, stopping in double at t = 7.0)."""
    V = work.V
    top = 0.0
    for i in range(z.shape[0]):
        size = max(abs(z[i]), abs(V[ZOLD, i]), abs(V[ZHI, i]))
        top = max(top, EPS * size / V[DELTA, i])
    return top


@jitable
def time_rounding(work, unew, i, t_lo, h):
    """How far component ``i`` of the exact solution moves between the new
    node's reported time, a double, and the time of its state, ``t_lo``
    later (the low word of the compensated time after the step,
    :func:`hamrkq.rkq.clock.time_low_word`): ``|t_lo|`` times the component's rate of change
    at the new node, the step's mean slope or, where larger, that slope
    extrapolated from the slope at the step's start.  Zero where the step
    lands on a double (:func:`hamrkq.rkq.clock.representable_step`), as nearly every step
    does; what a step longer than ``t`` or a clipped one leaves is counted
    here, against the tolerance, with the quencher's own errors."""
    if t_lo == 0.0:
        return 0.0
    V = work.V
    slope = (unew[i] - V[U, i]) / h
    rate = max(abs(slope), abs(2.0 * slope - V[K1, i]))
    return abs(t_lo) * rate


@jitable
def projected_ratio(work, cfg, t_new):
    """``max_k |Gamma_k| / delta_k`` at the candidate node projected to
    ``t_end`` as growing like ``t^2`` (a periodic orbit's phase error), from
    a node between ``project_from`` and ``project_until`` of the interval;
    -1 elsewhere (:func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`).  Uses
    ``V[DELTA]`` as :func:`attainability` left it."""
    reached = (t_new - cfg["t_start"]) / (cfg["t_end"] - cfg["t_start"])
    if not (cfg["project_from"] <= reached <= cfg["project_until"]):
        return -1.0
    V = work.V
    top = 0.0
    for i in range(V.shape[1]):
        value = abs(V[GNEW, i]) / V[DELTA, i]
        if value > top:
            top = value
    return top / (reached * reached)


@jitable
def record_ratio(state, cfg, ratio, floor, delta):
    """Fold ``ratio`` (:func:`attainability` or :func:`dense_attainability`)
    into the state's largest; False, with the witness's share of it (from
    ``floor`` against ``delta``) recorded, where it is above
    ``gamma_limit``: the promise cannot be kept there."""
    if ratio > state["max_ratio"] or ratio != ratio:
        state["max_ratio"] = ratio
    if ratio <= cfg["gamma_limit"]:
        return True
    state["floor_ratio"] = arith.weighted_norm(floor, delta)
    return False
