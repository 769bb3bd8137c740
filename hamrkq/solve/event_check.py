"""Events on a run: located, each state checked against the tolerance
there, the run ended before the first where it fails
(:func:`run_certified`), and the events and dense output put on the
finished solution (:func:`with_events`).

An event state is a dense-output value between two nodes (:mod:`hamrkq.events`).
Its tolerance is that of the state itself, ``max(atol, rtol |y_k|)``, and
an event is very often where a component crosses zero (``q = 0`` on a
Poincare section, ``p1 = 0`` at a turning point), where that is ``atol``
alone while the nodes on either side have ``rtol |y_k|``.  The kernel
checks nodes and ``t_eval`` times (:mod:`hamrkq.rkq.certify`); events are
found after the run, so they are checked here, on the run's output, before
``method="auto"`` decides whether to run again: a run that fails at an event
ends at the last node before it, ``TOLERANCE_UNATTAINABLE``, like a run that
fails at an output time, and auto runs again with more quencher steps (or
the quencher in double-double) as it does there.  The pendulum at ``rtol``
1e-6, ``atol`` 1e-12, event ``q``: the event states were up to 135 times
their bound (the quencher's own error, 1e-11 at t = 20, against ``atol``);
now auto runs again in four quencher steps a step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from hamrkq import events as _events
from hamrkq.backends.numeric import numeric_of
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import DenseOutput, attainability
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.dispatch import MethodSpec, Task, dense_tolerance, member_of

__all__ = [
    "EventFailure",
    "Located",
    "certificate",
    "certified_at_events",
    "run_certified",
    "stored_rounding_limits",
    "with_events",
]

#: What :func:`certified_at_events` found along a run, for
#: :func:`hamrkq.events.apply`: the dense output it located them on, and
#: :func:`hamrkq.events.locate_all`'s result.
Located = tuple[DenseOutput, _events.Found, int]


@dataclass(frozen=True)
class EventFailure:
    """Where a run's promise failed at an event state: the event function's
    ``label``, its time ``t``, the ``state`` there and ``ratio``, the
    quencher's estimated error and rounding over the tolerance at its worst
    ``component`` (``rounding_ratio`` the rounding's part)."""

    label: str
    t: float
    state: np.ndarray
    ratio: float
    rounding_ratio: float  # the quencher's rounding's part of ``ratio``
    component: int
    #: the value's own rounding alone over the tolerance (stepped in double
    #: from a stored node): what neither more quencher steps nor the
    #: quencher in double-double reduce
    stored_ratio: float


def certified_at_events(
    task: Task, out: RunOutput, specs: list, backend: str
) -> tuple[RunOutput, Located | None]:
    """``out``, or its nodes before the first event state where the
    quencher's estimated error and rounding exceed ``gamma_limit`` of the
    tolerance
    (:func:`hamrkq.rkq.dense.attainability`): status
    ``TOLERANCE_UNATTAINABLE``, ``t_last`` the event's time, ``max_ratio``
    the ratio there, ``floor_ratio`` the rounding's part of it and
    ``event_failure`` saying where.  Also the events
    located on the run as returned (None where there is nothing to locate:
    no events, no nodes), which :func:`hamrkq.events.apply` reuses.  Runs
    without a quencher track or with ``gamma_limit=inf`` (the certificate
    turned off) are returned as they are."""
    if not specs or out.t.shape[0] < 2:
        return out, None
    dense = _events.dense_output(
        task.ham, member_of(task), backend, task.params, out.t, out.y, out.z,
        dense_tolerance(task), certificate(task, out),
    )  # fmt: skip
    found, stop_by = _events.locate_all(specs, dense)
    located = (dense, found, stop_by)
    limit = task.options.gamma_limit
    if out.gamma is None or not limit < math.inf:
        return out, located
    failure = _first_failure(task, out, specs, found, limit)
    if failure is None:
        return out, located
    key = 1.0 if out.t[-1] >= out.t[0] else -1.0
    kept = key * out.t < key * failure.t
    truncated = replace(
        out.rows(kept),
        status=Status.TOLERANCE_UNATTAINABLE.code,
        t_last=failure.t,
        max_ratio=failure.ratio,
        # the rounding's part: where it is most of the ratio, auto runs the
        # quencher in double-double rather than in more steps
        floor_ratio=failure.rounding_ratio,
        event_failure=failure,
    )
    return truncated, None


def certificate(task: Task, out: RunOutput) -> tuple | None:
    """What ``sol.sol``'s values are checked against (the run's Gamma and
    rounding at its nodes, and ``gamma_limit``;
    :class:`hamrkq.rkq.dense.DenseOutput`), or None: no quencher track."""
    if out.gamma is None:
        return None
    return out.gamma, out.rounding, task.options.gamma_limit


def _first_failure(task, out, specs, found, limit) -> EventFailure | None:
    """The earliest event state whose ratio exceeds ``limit``, or None."""
    tolerance = dense_tolerance(task)
    key = 1.0 if out.t[-1] >= out.t[0] else -1.0
    first = None
    for spec, (times, states) in zip(specs, found, strict=True):
        ratios, rounding, component, stored = attainability(
            times, states, out.t, out.z, out.gamma, tolerance, out.rounding
        )
        bad = np.flatnonzero(~(ratios <= limit))
        if bad.size == 0:
            continue
        j = int(bad[0])
        if first is None or key * times[j] < key * first.t:
            first = EventFailure(
                spec.label, float(times[j]), states[j], float(ratios[j]), float(rounding[j]),
                int(component[j]), float(stored[j]),
            )  # fmt: skip
    return first


def stored_rounding_limits(failure: EventFailure | None, gamma_limit: float) -> bool:
    """Whether an event state failed on its own rounding (stepped in double
    from a node stored in double), which no rerun reduces: what ``auto``
    does not run again for, and what the message then says."""
    return failure is not None and failure.stored_ratio >= 0.5 * gamma_limit


def run_certified(
    task: Task, spec: MethodSpec, specs: list, backend: str
) -> tuple[RunOutput | Solution, Located | None]:
    """One run of ``task`` by ``spec``, ended before the first event state
    where its promise fails (:func:`certified_at_events`; not the baselines,
    which return a finished :class:`~hamrkq.result.Solution`), and the
    events located on it."""
    out = spec.run(task, backend)
    if isinstance(out, Solution) or not specs:
        return out, None
    return certified_at_events(task, out, specs, backend)


def with_events(
    task: Task,
    sol: Solution,
    backend: str,
    specs,
    keep_dense: bool,
    located: Located | None,
    checked: tuple | None,
) -> Solution:
    """Dense output and events (:mod:`hamrkq.events`) on a finished RKQ run
    (``located``: the events found on its nodes already, and the dense
    output they were found on; ``checked``: the certificate its values are
    checked against, :func:`certificate`)."""
    found = None
    if located is not None:
        dense, roots, stop_by = located
        found = (roots, stop_by)
    else:
        dense = _events.dense_output(
            task.ham, member_of(task), backend, task.params, sol.t, sol.y, sol.z,
            dense_tolerance(task), checked,
        )  # fmt: skip
    if not specs:
        return sol.replace(sol=dense)
    z_dense = None if sol.z is None else dense.through(sol.t, sol.z, None)

    def energy(t, Y):
        return numeric_of(task.ham).energy(t, Y, task.params)

    return _events.apply(sol, specs, dense, energy, z_dense, keep_dense, found)
