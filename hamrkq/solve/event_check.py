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

An interrupted run (Ctrl-C, or SIGTERM on the command line, in its step
loop or while its events are located) keeps its nodes, and its events are
located for :data:`INTERRUPTED_LOCATE_S` more, from the start of the run in
windows of nodes: the events among its first nodes are kept, and the
solution says up to which ``t`` (:attr:`Located.note`).  Locating every
event can take far longer than the run (95 000 events on a 587 000-node
orbit: 50 s with brentq, 6 s vectorised), so an interruption never waits
for it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from hamrkq import events as _events
from hamrkq.backends.numeric import numeric_of
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import DenseOutput, attainability
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve import output_times
from hamrkq.solve.dispatch import MethodSpec, Task, dense_tolerance, member_of

__all__ = [
    "INTERRUPTED_LOCATE_S",
    "INTERRUPTED_WINDOW",
    "EventFailure",
    "Located",
    "certificate",
    "certified_at_events",
    "interrupted",
    "run_certified",
    "stored_rounding_limits",
    "with_events",
]

#: Seconds an interrupted run's events are still located (from the start of
#: the run, :data:`INTERRUPTED_WINDOW` nodes at a time): the command line
#: exits within about a second of SIGTERM, partial results written.
INTERRUPTED_LOCATE_S = 0.5
#: Nodes per window when an interrupted run's events are located: a window
#: of 4096 nodes of a two-degree-of-freedom orbit with two event functions
#: takes about 0.04 s (0.2 s with brentq's one root at a time).
INTERRUPTED_WINDOW = 4096


class Located(NamedTuple):
    """What :func:`certified_at_events` found along a run, for
    :func:`hamrkq.events.apply`."""

    #: the dense output through every node of the run
    dense: DenseOutput
    #: :func:`hamrkq.events.locate_all`'s roots, event function by event function
    found: _events.Found
    #: the event function whose terminal occurrence ends the run, or -1
    stop_by: int
    #: None when the events were located along every node; else why and up
    #: to which ``t`` they were (an interrupted run), a sentence for the
    #: message and the record (``sol.options["events_not_located"]``)
    note: str | None = None


def interrupted(out: RunOutput) -> RunOutput:
    """``out`` marked interrupted: its nodes kept, status ``INTERRUPTED``."""
    return replace(out, status=Status.INTERRUPTED.code)


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
    turned off) are returned as they are.  An interrupted run, or one whose
    events are being located when Ctrl-C or SIGTERM lands, is returned with
    status ``INTERRUPTED`` and the events :func:`_located_in_time` finds."""
    sampled = task.output_times is not None
    if not (specs or sampled) or out.t.shape[0] < 2:
        return out, None
    if out.status == Status.INTERRUPTED.code:
        return out, _located_in_time(task, out, specs, backend)
    try:
        dense = _events.dense_output(
            task.ham, member_of(task), backend, task.params, out.t, out.y, out.z,
            dense_tolerance(task), certificate(task, out),
        )  # fmt: skip
        found, stop_by = _events.locate_all(specs, dense)
        located = Located(dense, found, stop_by)
        limit = task.options.gamma_limit
        if out.gamma is None or not limit < math.inf:
            return out, located
        failure = _first_failure(task, out, specs, found, limit)
        if sampled:
            # the output times up to a terminal event's (SciPy's t_eval)
            stop = found[stop_by][0][-1] if stop_by >= 0 else None
            at_output = output_times.first_failure(task, out, dense, stop)
            key = 1.0 if out.t[-1] >= out.t[0] else -1.0
            if at_output is not None and (failure is None or key * at_output.t < key * failure.t):
                return output_times.cut_before(out, at_output), None
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM while the events of a run (finished or not) were
        # located: the nodes stand, and the events among the first of them.
        out = interrupted(out)
        return out, _located_in_time(task, out, specs, backend)
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


def _located_in_time(task: Task, out: RunOutput, specs: list, backend: str) -> Located:
    """The events of an interrupted run among its first nodes: located
    window by window (:data:`INTERRUPTED_WINDOW` nodes) from its start for at
    most :data:`INTERRUPTED_LOCATE_S` seconds, or until another interrupt.

    Each window's events are complete, so those kept are every event up to
    the end of the last window done.  Their states are checked against the
    tolerance as a finished run's are (:func:`_first_failure`), and those
    from the first that fails on are left out with the rest: an
    interrupted run is neither cut nor run again.  ``note`` says up to which
    ``t`` they were located, unless that is the whole run (or a terminal
    event among them ends it)."""
    deadline = time.perf_counter() + INTERRUPTED_LOCATE_S
    n = out.t.shape[0]
    member, tolerance = member_of(task), dense_tolerance(task)

    def dense(a: int, b: int, checked: tuple | None = None) -> DenseOutput:
        z = None if out.z is None else out.z[a:b]
        return _events.dense_output(
            task.ham, member, backend, task.params, out.t[a:b], out.y[a:b], z, tolerance, checked
        )

    everywhere = dense(0, n, certificate(task, out))  # for sol.sol and a terminal event's state
    key = 1.0 if out.t[-1] >= out.t[0] else -1.0
    pieces: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in specs]
    found: _events.Found = [(np.empty(0), np.empty((0, out.y.shape[1]))) for _ in specs]
    done, stop_by = 0, -1  # the last node up to which every event is located
    try:
        while done < n - 1 and stop_by < 0 and time.perf_counter() < deadline:
            end = min(done + INTERRUPTED_WINDOW, n - 1)
            # The windows share their end nodes: a root on a shared node is
            # counted in the window it ends, never in the one it starts.
            window, _ = _events.locate_all(specs, dense(done, end + 1))
            for kept, (times, states) in zip(pieces, window, strict=True):
                kept.append((times, states))
            found = [
                (np.concatenate([p[0] for p in kept]), np.concatenate([p[1] for p in kept]))
                for kept in pieces
            ]
            found, stop_by = _events.terminal_cut(specs, found, key)
            done = end
    except KeyboardInterrupt:
        pass  # another interrupt: the windows done are kept
    until = float(out.t[done])
    reason = "the run was interrupted"
    limit = task.options.gamma_limit
    if out.gamma is not None and limit < math.inf:
        failure = _first_failure(task, out, specs, found, limit)
        if failure is not None and key * failure.t <= key * until:
            until, stop_by = failure.t, -1
            reason += (
                f" and the state of event {failure.label!r} there is not within the tolerance "
                f"({failure.ratio:.3g} x it)"
            )
            found = [
                (times[key * times < key * until], states[key * times < key * until])
                for times, states in found
            ]
    if stop_by >= 0 or (done == n - 1 and until == float(out.t[-1])):
        return Located(everywhere, found, stop_by)
    note = (
        f"Its events were located up to t = {until!r} only ({reason}); later ones are not reported"
    )
    terminal = [repr(spec.label) for spec in specs if spec.terminal]
    if terminal:
        note += (
            f", and the nodes after it may go past the terminal event {', '.join(terminal)}, "
            "which was not looked for there"
        )
    return Located(everywhere, found, -1, note + ".")


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
    if isinstance(out, Solution) or not (specs or task.output_times is not None):
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
    checked against, :func:`certificate`).  Where the events were located
    along part of the run only (:attr:`Located.note`), the message says so
    and ``sol.options["events_not_located"]`` holds the same sentence."""
    found = None
    if located is not None:
        dense, roots, stop_by, note = located
        found = (roots, stop_by)
        if note is not None and specs:
            sol = sol.replace(
                message=f"{sol.message} {note}",
                options={**sol.options, "events_not_located": note},
            )
    else:
        dense = _events.dense_output(
            task.ham, member_of(task), backend, task.params, sol.t, sol.y, sol.z,
            dense_tolerance(task), checked,
        )  # fmt: skip
    z_dense = None if sol.z is None else dense.through(sol.t, sol.z, None)

    def energy(t, Y):
        return numeric_of(task.ham).energy(t, Y, task.params)

    if specs:
        sol = _events.apply(sol, specs, dense, energy, z_dense, keep_dense, found)
    elif keep_dense:
        sol = sol.replace(sol=dense)
    if task.output_times is None:
        return sol
    return output_times.sampled(sol, task, dense, z_dense, energy)
