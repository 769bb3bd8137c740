"""``t_eval`` beside events or dense output: every node kept, the values at
the output times from the dense output.

Events and ``sol.sol`` are found on the dense output between consecutive
nodes, so a run that has them keeps every node; the kernel's ``t_eval``
keeps only the output times.  With both, the run keeps every node (the
task's ``t_eval`` is None, its :attr:`~hamrkq.solve.dispatch.Task.output_times`
the caller's), and afterwards

- :func:`first_failure` checks each output time's value as the kernel checks
  an output time inside a step (:func:`hamrkq.rkq.dense.attainability`:
  Gamma interpolated between the nodes around it, the quencher's rounding,
  the value's own), so that a run fails, and ``method="auto"`` runs again,
  where the kernel's ``t_eval`` would (:func:`hamrkq.solve.event_check.certified_at_events`);
- :func:`sampled` makes the output times the solution's rows, as SciPy's
  ``solve_ivp`` returns ``t_eval`` with its events and ``sol``: those up to
  the last node (a terminal event's time included).

The values are those of ``sol.sol`` (the dense value the kernel writes at an
output time inside a step, :func:`hamrkq.rkq.steps.dense_value`); the steps
are not shortened to land on the times, as the kernel's ``t_eval`` does for
a time far into a step.  Memory grows with the nodes, as without ``t_eval``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from hamrkq._floats import EPS
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import DenseOutput, attainability
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.dispatch import Task, dense_tolerance
from hamrkq.solve.shadow import largest_state

__all__ = [
    "OutputFailure",
    "atol_above_output_rounding",
    "cut_before",
    "first_failure",
    "output_rounding",
    "output_rounding_limits",
    "sampled",
    "within_run",
]


class OutputFailure(NamedTuple):
    """The first output time whose value the run cannot certify: its time,
    the quencher's estimated error and rounding over the tolerance there,
    the rounding's part of that, and the value's own rounding alone."""

    t: float
    ratio: float
    rounding_ratio: float
    stored_ratio: float


def _key(t: np.ndarray) -> float:
    return 1.0 if t[-1] >= t[0] else -1.0


def within_run(times: np.ndarray, t_nodes: np.ndarray, t0: float) -> np.ndarray:
    """The output times from the run's start up to its last node ``t_nodes[-1]``."""
    key = 1.0 if t_nodes.size < 2 else _key(t_nodes)
    last = t_nodes[-1] if t_nodes.size else t0
    return times[(key * times >= key * t0) & (key * times <= key * last)]


def first_failure(
    task: Task, out: RunOutput, dense: DenseOutput, until: float | None = None
) -> OutputFailure | None:
    """The first output time (up to ``until``, a terminal event's time) where
    the value's estimated error and rounding exceed ``gamma_limit`` of the
    tolerance there, or None.  Nothing is checked without the run's Gamma or
    with ``gamma_limit=inf``."""
    limit = task.options.gamma_limit
    if out.gamma is None or not limit < np.inf or out.t.shape[0] < 2:
        return None
    times = within_run(task.output_times, out.t, task.t0)
    if until is not None:
        times = times[_key(out.t) * times <= _key(out.t) * until]
    values = dense.values_unchecked(times)
    ratios, rounding, _, stored = attainability(
        times, values, out.t, out.z, out.gamma, dense_tolerance(task), out.rounding
    )
    bad = np.flatnonzero(~(ratios <= limit))
    if bad.size == 0:
        return None
    j = int(bad[0])
    return OutputFailure(float(times[j]), float(ratios[j]), float(rounding[j]), float(stored[j]))


def output_rounding(out: RunOutput, task: Task) -> float:
    """For a run that ended at an output time inside a step (``t_eval``, by
    the kernel or sampled here): the value's own rounding over the
    tolerance there, ``max_k eps u_k / delta_k`` with ``u_k`` the larger of
    the value and the two nodes' quencher values around it
    (:attr:`RunOutput.stored_ratio`); 0 for a run that did not.  The value
    is stepped with the quencher's stages in double (whatever the
    quencher's precision), so its rounding is an ulp of the state's size
    there, and where a component passes zero under ``rtol`` its tolerance
    there is ``atol`` alone: no quencher goes below that, a larger ``atol``
    does."""
    times = task.requested_times
    if (
        times is None
        or out.status != Status.TOLERANCE_UNATTAINABLE.code
        or not np.any(times == out.t_last)
    ):
        return 0.0
    return out.stored_ratio


def atol_above_output_rounding(out: RunOutput, task: Task) -> float:
    """The ``atol`` at which the value's own rounding at any output time is
    at most a quarter of ``gamma_limit``, leaving the rest for the
    quencher's error: the remedy the message names.  From each component's
    largest size over the run, not the size where it failed
    (:func:`output_rounding`): the run with that ``atol`` passes later zero
    crossings, whose values around may be larger."""
    size = np.maximum(np.abs(task.y0), largest_state(out))
    return 4.0 * EPS * float(np.max(size)) / task.options.gamma_limit


def output_rounding_limits(out: RunOutput, task: Task) -> bool:
    """Whether a run ended at an output time on the value's own rounding
    (:func:`output_rounding` at least half of ``gamma_limit``), which no
    rerun reduces: what ``method="auto"`` does not run again for, and what
    the message then says (the same for an event state:
    :func:`hamrkq.solve.event_check.stored_rounding_limits`)."""
    return output_rounding(out, task) >= 0.5 * task.options.gamma_limit


def cut_before(out: RunOutput, failure: OutputFailure) -> RunOutput:
    """``out`` ended at its last node before ``failure``'s time, as the
    kernel ends a run at an output time it cannot certify: status
    ``TOLERANCE_UNATTAINABLE``, ``t_last`` the time, ``max_ratio`` and
    ``floor_ratio`` the ratio there and its rounding's part."""
    key = _key(out.t)
    return replace(
        out.rows(key * out.t < key * failure.t),
        status=Status.TOLERANCE_UNATTAINABLE.code,
        t_last=failure.t,
        max_ratio=failure.ratio,
        floor_ratio=failure.rounding_ratio,
        stored_ratio=failure.stored_ratio,
    )


def sampled(
    sol: Solution, task: Task, dense: DenseOutput, z_dense: DenseOutput | None, energy
) -> Solution:
    """``sol`` (every node, and a terminal event's state as its last row)
    with the output times up to its last row as its rows: ``y`` and ``z``
    from the dense output, Gamma interpolated linearly between the nodes
    around each time (as the kernel writes it at an output time), quenched
    where the value is the quencher's (``y == z``; at a node, the node's
    flag).  ``energy(t, y)`` gives H at the rows.  The dense output's
    evaluations are added to ``stats["nfev"]``."""
    times = within_run(task.output_times, sol.t, task.t0)
    before = dense.nfev + (0 if z_dense is None else z_dense.nfev)
    y = dense.values_unchecked(times)
    if sol.status is Status.INTERRUPTED:
        # not checked by first_failure (an interrupted run is neither cut
        # nor run again): the times up to the first that fails are kept
        kept = _certified_prefix(times, y, dense, task)
        times, y = times[:kept], y[:kept]
    changes: dict = {"t": times, "y": y, "energy": energy(times, y)}
    key = _key(sol.t) if sol.t.size > 1 else 1.0
    at_node = np.minimum(np.searchsorted(key * sol.t, key * times), sol.t.size - 1)
    is_node = sol.t[at_node] == times
    if sol.z is not None and z_dense is not None:
        z = z_dense.values_unchecked(times)
        changes.update(z=z, global_error=y - z)
        if sol.quenched is not None:
            changes["quenched"] = np.where(is_node, sol.quenched[at_node], np.all(y == z, axis=1))
    elif sol.quenched is not None:
        changes["quenched"] = np.where(is_node, sol.quenched[at_node], False)
    if sol.gamma is not None:
        changes["gamma"] = _interpolated(sol.t, sol.gamma, times)
    after = dense.nfev + (0 if z_dense is None else z_dense.nfev)
    stats = {**sol.stats, "nfev": int(sol.stats.get("nfev", 0)) + after - before}
    return sol.replace(stats=stats, **changes)


def _certified_prefix(
    times: np.ndarray, values: np.ndarray, dense: DenseOutput, task: Task
) -> int:
    """How many of the first ``values`` pass the dense output's certificate."""
    if dense.certificate is None or dense.t.size < 2:
        return times.size
    gamma, rounding, limit = dense.certificate
    nodes = dense.y if dense.z is None else dense.z
    ratios = attainability(times, values, dense.t, nodes, gamma, dense_tolerance(task), rounding)[
        0
    ]
    bad = np.flatnonzero(~(ratios <= limit))
    return times.size if bad.size == 0 else int(bad[0])


def _interpolated(t_nodes: np.ndarray, rows: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``rows`` at the nodes, interpolated linearly at ``times`` (column by column)."""
    key = _key(t_nodes) if t_nodes.size > 1 else 1.0
    return np.column_stack(
        [np.interp(key * times, key * t_nodes, column) for column in rows.T]
    ).reshape(times.size, rows.shape[1])
