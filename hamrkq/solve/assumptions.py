"""Runs end where their state contradicts an assumption declared on its
symbols.

:func:`within_assumptions` (an RKQ-family run) and
:func:`solution_within_assumptions` (a baseline's finished Solution) end a run
at the last node before the first whose state contradicts an assumption
declared on its symbols (``Symbol("x", positive=True)`` reaching x < 0),
status ``ASSUMPTION_VIOLATED``: SymPy simplified H under the assumption
(``sqrt(x**2)`` is ``x``), so past that node the equations integrated are not
those of the H written, and the nodes would be silently wrong.  The initial
values are refused for the same reason
(:func:`hamrkq.symbolic.values.bind_state`), the time span in
:func:`hamrkq.solve.arguments.check_time_assumptions`; every run, of every
method, passes through one of the two before its Solution is returned.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from hamrkq._interruption import interrupted_near
from hamrkq.events import terminal_cut
from hamrkq.result import Solution, Status, kept_nodes_note
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.dispatch import Task
from hamrkq.solve.event_check import Located, certificate
from hamrkq.symbolic.assumptions import first_conflict

__all__ = [
    "Breach",
    "breach_message",
    "first_rows",
    "located_within",
    "solution_within_assumptions",
    "within_assumptions",
]


class Breach(NamedTuple):
    """The first node of a run whose state contradicts an assumption
    declared on its symbols: its ``row``, the component's ``name`` and
    ``value`` there, the ``assumption`` as declared (``"positive=True"``),
    the time ``t``, and for an interrupted run where it was interrupted
    (``interrupted_near``, else None)."""

    row: int
    name: str
    value: float
    assumption: str
    t: float
    interrupted_near: float | None = None


def _breach(task: Task, t: np.ndarray, y: np.ndarray) -> Breach | None:
    """Where the nodes ``(t, y)`` first contradict a declared assumption
    (:func:`hamrkq.symbolic.assumptions.first_conflict`: one comparison per
    column that declares a sign), or None."""
    ham = task.ham
    conflict = first_conflict((*ham.q, *ham.p), y)
    if conflict is None:
        return None
    row, column = conflict.row, conflict.column
    return Breach(
        row, ham.names[column], float(y[row, column]),
        f"{conflict.assumption}={conflict.declared}", float(t[row]),
    )  # fmt: skip


def within_assumptions(
    task: Task, out: RunOutput, located: Located | None, specs: list
) -> tuple[RunOutput, Located | None, Breach | None]:
    """``out`` and the events ``located`` on it, or, where a node
    contradicts a declared assumption, both ended at the last node before
    it, status ``ASSUMPTION_VIOLATED`` (an interrupted run stays
    ``INTERRUPTED``: an ensemble stops on it), and the :class:`Breach`.

    The events among the nodes kept stay located (a terminal one among
    them still ends the run, before the breach), and the dense output ends
    with the nodes: nothing is located again.
    """
    breach = _breach(task, out.t, out.y)
    if breach is None:
        return out, located, None
    cut = out.rows(slice(breach.row))
    if out.status == Status.INTERRUPTED.code:
        breach = breach._replace(interrupted_near=float(out.t_last))
    else:
        cut = replace(cut, status=Status.ASSUMPTION_VIOLATED.code, t_last=breach.t)
    return cut, located_within(task, located, cut, specs), breach


def located_within(
    task: Task, located: Located | None, out: RunOutput, specs: list
) -> Located | None:
    """``located`` on the nodes ``out`` kept of the run it was found on:
    the events up to its last node, the terminal one among them, and the
    dense output through them (as :func:`hamrkq.events.apply` cuts a run at
    a terminal event).  None where the run kept fewer than two nodes:
    :func:`hamrkq.solve.event_check.with_events` builds what those have."""
    if located is None or out.t.shape[0] < 2:
        return None
    key = 1.0 if out.t[-1] >= out.t[0] else -1.0
    end = key * out.t[-1]
    found = [
        (times[key * times <= end], states[key * times <= end]) for times, states in located.found
    ]
    found, stop_by = terminal_cut(specs, found, key)
    dense = located.dense.through(out.t, out.y, out.z, certificate(task, out))
    return located._replace(dense=dense, found=found, stop_by=stop_by)


def solution_within_assumptions(task: Task, sol: Solution) -> Solution:
    """A baseline's finished ``sol`` (SciPy's solvers, the fixed-step
    methods), or, where a node contradicts a declared assumption, ``sol``
    ended at the last node before it as :func:`within_assumptions` ends an
    RKQ-family run.  Baselines locate no events and have no dense output:
    the arrays of nodes are all there is to cut."""
    breach = _breach(task, sol.t, sol.y)
    if breach is None:
        return sol
    arrays = first_rows(sol, breach.row)
    status = Status.ASSUMPTION_VIOLATED
    if sol.status is Status.INTERRUPTED:
        status = Status.INTERRUPTED
        breach = breach._replace(interrupted_near=float(sol.t[-1]))
    return sol.replace(**arrays, status=status, message=breach_message(breach, arrays["t"]))


def first_rows(sol: Solution, count: int) -> dict:
    """The arrays of ``sol``'s first ``count`` nodes, by field name (those
    it has): what a check after a baseline's run keeps when it cuts it."""
    keep = slice(count)
    return {
        name: getattr(sol, name)[keep]
        for name in ("t", "y", "energy", "z", "global_error", "gamma", "quenched")
        if getattr(sol, name) is not None
    }


def breach_message(breach: Breach, t_kept: np.ndarray) -> str:
    """What ended a run at ``breach`` and what to do (``t_kept``: the times
    of the nodes kept)."""
    name = breach.name
    kind = breach.assumption.removeprefix("extended_")
    # what such an assumption does to H, where one example says it
    example = {
        "positive=True": name, "nonnegative=True": name,
        "negative=True": f"-{name}", "nonpositive=True": f"-{name}",
    }.get(kind)  # fmt: skip
    how = f" (sqrt({name}**2), say, became {example})" if example else ""
    text = (
        f"At t = {breach.t!r} the run reached {name} = {breach.value!r}, which contradicts "
        f"the assumption {breach.assumption} declared on the symbol {name}. SymPy simplified H "
        f"under it when the Hamiltonian was built{how}, so from there the equations integrated "
        "are not Hamilton's equations of the H written and every later node would be silently "
        "wrong; the run ends at the last node before it"
    )
    text += f" (t = {float(t_kept[-1])!r})." if len(t_kept) else "."
    text += (
        f" If {name} may go there, declare its symbol real (Symbol({name!r}, real=True)) and "
        f"write H for the whole line (Abs({name}), or sqrt({name}**2) of a real {name}, whose "
        f"kink at {name} = 0 a certified run does not cross: integrate each side with its own "
        "H, or pass gamma_limit=numpy.inf); if it may not, the model or the initial values "
        "carry it out of its domain."
    )
    if breach.interrupted_near is not None:
        text = f"{interrupted_near(breach.interrupted_near)} {text}"
    return text + kept_nodes_note(len(t_kept))
