"""Many members of an ensemble through one call of the kernel.

:func:`run_members` integrates member after member (initial state and
parameter values per member, everything else shared) without returning to
Python: each starts from a fresh state exactly as :class:`~hamrkq.rkq.driver.Integration`
starts a single run (:func:`hamrkq.rkq.start.begin`), then runs the same step
loop (:func:`hamrkq.rkq.loop.advance`), so a member's numbers are the bits of
the same run alone.  What an ensemble keeps of each member is folded in as the
output buffer fills: the states at the ``t_eval`` times (or the last node), the
largest ``|y - z|`` and the largest energy drift over the nodes a single run
would keep, the last time reached, the status and the counters.

Kernel code (``@jitable``; see :mod:`hamrkq.rkq.loop` for the conventions).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hamrkq.rkq import arith
from hamrkq.rkq.auto_rules import middle_of
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import (
    CHK0,
    GMAX,
    RET_DONE,
    SHI,
    ST_RUNNING,
    WHI,
    YMAX,
    ZHI,
    Output,
    U,
    checkpoint_fraction,
    new_state,
)
from hamrkq.rkq.loop import advance, step_range
from hamrkq.rkq.start import begin
from hamrkq.rkq.witness_rules import EARLY_FRACTION

__all__ = ["COUNTERS", "Batch", "allocate_batch", "run_members"]

#: The counters kept per member, in the order of :attr:`Batch.stats`' columns.
COUNTERS = ("steps", "rejected", "quenches", "nfev", "njev")
#: Step attempts per call of ``advance`` inside the batch: the run's own
#: ``max_steps`` is the limit that matters.
_NO_BUDGET = np.iinfo(np.int64).max


class Batch(NamedTuple):
    """The members' inputs and what is kept of them.

    ``y0`` (M, d) and ``params`` (M, P) per member; ``fresh`` a one-row
    :data:`~hamrkq.rkq.layout.STATE` at ``t0``, the state every member starts
    from; ``out`` the node buffer (the ``t_eval`` rows, or a few rows folded
    as they fill); ``middle`` the middle of the interval a member that
    succeeds keeps nodes over and the direction of integration
    (:func:`hamrkq.rkq.auto_rules.middle_of`).  Results: ``y`` (M, T, d)
    the kept states (NaN where a member stopped short), ``t_last``,
    ``status``, ``max_error`` (max ``|y - z|``, NaN without a quencher),
    ``energy0`` and ``energy_drift`` (max ``|H - H(t0)|`` over the kept
    nodes), ``stats`` (M, len(COUNTERS)), and for the growth of the estimate
    of Gamma (:func:`hamrkq.rkq.auto_rules.growth_of_maxima`) each
    component's largest ``|Gamma_k|`` over the kept nodes up to ``middle``
    (``gamma_to_middle``, M x d) and over all of them (``gamma_to_end``),
    up to :data:`~hamrkq.rkq.witness_rules.EARLY_FRACTION` of the interval
    (``gamma_to_early``: over the nodes, or with ``t_eval`` at the kernel's
    checkpoint there, NaN where none was passed;
    :func:`hamrkq.solve.growth.early_growth` reads a single run's alike) and
    its largest ``|y_k|`` (``y_size``); and the ratio of its largest free
    step to its smallest (``step_range``, :func:`hamrkq.rkq.loop.step_range`).
    """

    y0: np.ndarray
    params: np.ndarray
    fresh: np.ndarray
    out: Output
    y: np.ndarray
    t_last: np.ndarray
    status: np.ndarray
    max_error: np.ndarray
    energy0: np.ndarray
    energy_drift: np.ndarray
    stats: np.ndarray
    middle: np.ndarray
    gamma_to_middle: np.ndarray
    gamma_to_end: np.ndarray
    gamma_to_early: np.ndarray
    y_size: np.ndarray
    step_range: np.ndarray


def allocate_batch(
    y0, params, t0: float, times: int, out: Output, kept_span: tuple[float, float]
) -> Batch:
    """Result arrays for the members ``y0``/``params`` (NaN-filled), keeping
    ``times`` states each, with the node buffer ``out``; ``kept_span`` the
    times of the first and last node a member that succeeds keeps."""
    m, d = y0.shape
    fresh = new_state(t0)
    return Batch(
        # Writable copies: the compiled functions take writable arrays.
        y0=np.array(y0, dtype=np.float64, order="C"),
        params=np.array(params, dtype=np.float64, order="C"),
        fresh=fresh,
        out=out,
        y=np.full((m, times, d), np.nan),
        t_last=np.full(m, np.nan),
        status=np.zeros(m, dtype=np.int64),
        max_error=np.full(m, np.nan),
        energy0=np.full(m, np.nan),
        energy_drift=np.full(m, np.nan),
        stats=np.zeros((m, len(COUNTERS)), dtype=np.int64),
        middle=np.array(middle_of(*kept_span), dtype=np.float64),
        gamma_to_middle=np.zeros((m, d)),
        gamma_to_end=np.zeros((m, d)),
        gamma_to_early=np.zeros((m, d)),
        y_size=np.zeros((m, d)),
        step_range=np.ones(m),
    )


@jitable
def nan_max(top, value):
    """``max`` as ``ndarray.max`` takes it: a NaN anywhere wins."""
    if top != top or value != value:
        return value if value != value else top
    return value if value > top else top


@jitable
def load_member(problem, state, work, batch, m):
    """Member ``m``'s fresh state, work arrays and parameter values, as a
    single run of it would allocate them."""
    state[0] = batch.fresh[0]
    work.V[:, :] = 0.0
    work.K[:, :] = 0.0
    work.Kz[:, :] = 0.0
    work.dKz[:, :] = 0.0
    work.JM[:, :] = 0.0
    for row in (U, ZHI, SHI, WHI):
        arith.copy(batch.y0[m], work.V[row])
    for i in range(work.V.shape[1]):
        work.V[YMAX, i] = abs(batch.y0[m, i])
    arith.copy(batch.params[m], problem.params)
    arith.nudge(problem.params, problem.witness_params)


@jitable
def fold_nodes(energy, params, c, s, batch, m, kept):
    """Fold the buffer's nodes (rows ``0 .. s.nout``) into member ``m``'s
    results, ``kept`` nodes having been folded before; empties the buffer and
    returns the new count.  The drift is taken against ``energy0``, set from
    the first node (at ``t0``) or before the run when ``t_eval`` skips it."""
    out = batch.out
    n = s["nout"]
    for r in range(n):
        value = abs(energy(out.t[r], out.y[r], params) - batch.energy0[m])
        drift = batch.energy_drift[m]
        batch.energy_drift[m] = value if kept + r == 0 else nan_max(drift, value)
        for k in range(out.y.shape[1]):
            batch.y_size[m, k] = nan_max(batch.y_size[m, k], abs(out.y[r, k]))
        if c["use_z"]:
            top = batch.max_error[m]
            for k in range(out.y.shape[1]):
                err = abs(out.y[r, k] - out.z[r, k])
                top = err if (kept + r == 0 and k == 0) else nan_max(top, err)
            batch.max_error[m] = top
            before = (out.t[r] - batch.middle[0]) * batch.middle[1] <= 0.0
            # with t_eval, from the checkpoint only (fold_every_node), as solve
            early = not c["use_t_eval"] and _fraction(c, out.t[r]) <= EARLY_FRACTION
            for k in range(out.y.shape[1]):
                gamma = abs(out.gamma[r, k])
                batch.gamma_to_end[m, k] = nan_max(batch.gamma_to_end[m, k], gamma)
                if before:
                    batch.gamma_to_middle[m, k] = nan_max(batch.gamma_to_middle[m, k], gamma)
                if early:
                    batch.gamma_to_early[m, k] = nan_max(batch.gamma_to_early[m, k], gamma)
        if c["use_t_eval"]:
            arith.copy(out.y[r], batch.y[m, kept + r])
    if n > 0:
        if not c["use_t_eval"]:
            arith.copy(out.y[n - 1], batch.y[m, 0])
        batch.t_last[m] = out.t[n - 1]
    s["nout"] = 0
    return kept + n


@jitable
def _fraction(c, t):
    """The fraction of the interval at the time ``t``, as
    :func:`hamrkq.solve.growth.growth_between` computes it for a run that
    reached ``t_end`` (the members whose growth is read succeeded)."""
    span = c["t_end"] - c["t_start"]
    return (t - c["t_start"]) / span if span != 0.0 else 0.0


@jitable
def fold_every_node(c, s, work, batch, m):
    """Fold the kernel's maxima over every node of member ``m`` (kept or
    not: with ``t_eval`` the rows are only the output times) into its
    largest ``|y|`` and ``|Gamma|``, up to the middle by the last checkpoint
    at or before it (a smaller maximum there: a growth at least as large;
    :func:`hamrkq.solve.growth.growth` reads a single run's alike)."""
    V = work.V
    span = c["t_end"] - c["t_start"]
    middle = (batch.middle[0] - c["t_start"]) / span if span != 0.0 else 1.0
    row = -1
    early_row = -1
    for k in range(s["checkpoint"]):  # the checkpoints passed, ascending
        if checkpoint_fraction(k) <= middle:
            row = CHK0 + k
        if checkpoint_fraction(k) <= EARLY_FRACTION:
            early_row = CHK0 + k
    reached_middle = (s["t"] - c["t_start"]) / span > middle if span != 0.0 else True
    for i in range(V.shape[1]):
        batch.y_size[m, i] = nan_max(batch.y_size[m, i], V[YMAX, i])
        batch.gamma_to_end[m, i] = nan_max(batch.gamma_to_end[m, i], V[GMAX, i])
        if not reached_middle:
            up_to_middle = V[GMAX, i]
        elif row >= 0:
            up_to_middle = V[row, i]
        else:
            up_to_middle = 0.0
        batch.gamma_to_middle[m, i] = nan_max(batch.gamma_to_middle[m, i], up_to_middle)
        batch.gamma_to_early[m, i] = V[early_row, i] if early_row >= 0 else np.nan


@jitable
def run_members(rhs, tangent, jac, energy, problem, tab, cfg, state, work, batch):
    """Integrate every member of ``batch`` (see the module docstring) with
    the shared ``problem`` (its ``params`` row is overwritten per member),
    tableaus, configuration and work arrays.  Returns the number of members."""
    problem, tab, work, batch = borrow(problem), borrow(tab), borrow(work), borrow(batch)
    cfg, state = borrow(cfg), borrow(state)
    c = cfg[0]
    for m in range(batch.y0.shape[0]):
        load_member(problem, state, work, batch, m)
        s = state[0]
        batch.energy0[m] = energy(s["t"], batch.y0[m], problem.params)
        status = begin(rhs, problem, c, s, work, batch.out)
        kept = 0
        while status == ST_RUNNING:
            ret = advance(rhs, tangent, jac, problem, tab, cfg, state, work, batch.out, _NO_BUDGET)
            if ret == RET_DONE:
                status = s["status"]
            kept = fold_nodes(energy, problem.params, c, s, batch, m, kept)
        kept = fold_nodes(energy, problem.params, c, s, batch, m, kept)
        if c["use_t_eval"] and c["use_z"]:
            fold_every_node(c, s, work, batch, m)
        if kept == 0:
            batch.energy0[m] = np.nan
        batch.status[m] = status
        # In the order of COUNTERS (numba needs the field names as literals).
        batch.stats[m, 0] = s["steps"]
        batch.stats[m, 1] = s["rejected"]
        batch.stats[m, 2] = s["quenches"]
        batch.stats[m, 3] = s["nfev"]
        batch.stats[m, 4] = s["njev"]
        batch.step_range[m] = step_range(s)
    return batch.y0.shape[0]
