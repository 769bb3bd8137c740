"""Certified runs end before the first step across a kink of H.

Where H has a kink (``Abs``, ``sign``) or a branch cut (``atan2``),
Hamilton's equations jump there (:mod:`hamrkq.symbolic.kinks`), and a step
across it is off by far more than the pair's estimate, the quencher or Gamma
say: ``H = p^2/2 + |q|`` with ``auto`` at 1e-8 returned SUCCESS with nodes 84
times the tolerance off, ``atan2(y, x) px / 50`` in a Kepler problem 562
times (measured at 6724968, before this check, against heyoka in 113-bit
floats; ``tests/test_smoothness.py`` checks the runs now end before the
kink, within the tolerance).  :func:`within_smooth_region` ends such
a run at the last node before the first step whose two nodes lie on either
side of a kink (or one on it), status ``TOLERANCE_UNATTAINABLE``, and says
what works: integrating piecewise, each piece with the smooth H of its
side, ending at the kink with a terminal event.  Runs without the
certificate (``gamma_limit=inf``, or no quencher) are not cut.

A step that crosses a kink twice (an orbit grazing it between two nodes)
leaves both nodes on one side and is not seen.  Output times (``t_eval``) and
``keep_every`` would hide crossings between kept rows, so a certified run of
a kinked H keeps every node (:mod:`hamrkq.solve.output_times`) and refuses
``keep_every``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from hamrkq._interruption import interrupted_near
from hamrkq.backends.numeric import numeric_of
from hamrkq.result import Solution, Status, kept_nodes_note
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.assumptions import first_rows, located_within
from hamrkq.solve.dispatch import Task
from hamrkq.solve.event_check import Located
from hamrkq.symbolic.hamiltonian import Hamiltonian
from hamrkq.symbolic.kinks import Kink, kinks

__all__ = [
    "Crossing",
    "checks_kinks",
    "crossing_message",
    "solution_within_smooth_region",
    "within_smooth_region",
]


class Crossing(NamedTuple):
    """The first step of a run across a kink: the ``row`` of the node before
    it, the times of its two nodes, the :class:`~hamrkq.symbolic.kinks.Kink`,
    and for an interrupted run where it was interrupted."""

    row: int
    t_before: float
    t_after: float
    kink: Kink
    interrupted_near: float | None = None


def checks_kinks(ham: Hamiltonian, gamma_limit: float, certified: bool) -> bool:
    """Whether a run of ``ham`` is cut at kinks: H has one, and the run is
    certified (a quencher, ``gamma_limit`` finite)."""
    return certified and gamma_limit < math.inf and bool(kinks(ham.H))


def _first_crossing(task: Task, t: np.ndarray, y: np.ndarray) -> Crossing | None:
    """The first step between consecutive nodes ``(t, y)`` across a kink."""
    if t.shape[0] < 2:
        return None
    found = kinks(task.ham.H)
    values = numeric_of(task.ham).switching(t, y, task.params)
    count = len(found)
    a, guard = values[:, :count], values[:, count:]
    # A sign change, or one node on the kink and the other off it (f there
    # is sign(0) = 0, neither side's).
    across = (a[:-1] * a[1:] < 0) | ((a[:-1] == 0) != (a[1:] == 0))
    across &= (guard[:-1] < 0) | (guard[1:] < 0)
    rows, kinds = np.nonzero(across)
    if rows.size == 0:
        return None
    j = int(rows[0])
    return Crossing(j, float(t[j]), float(t[j + 1]), found[int(kinds[0])])


def within_smooth_region(
    task: Task, out: RunOutput, located: Located | None, specs: list
) -> tuple[RunOutput, Located | None, Crossing | None]:
    """``out`` and the events ``located`` on it, or, where a step crosses a
    kink of H, both ended at the node before it, status
    ``TOLERANCE_UNATTAINABLE`` (an interrupted run stays ``INTERRUPTED``),
    and the :class:`Crossing`.  Only certified runs
    (:func:`checks_kinks`)."""
    if not checks_kinks(task.ham, task.options.gamma_limit, out.gamma is not None):
        return out, located, None
    crossing = _first_crossing(task, out.t, out.y)
    if crossing is None:
        return out, located, None
    cut = out.rows(slice(crossing.row + 1))
    if out.status == Status.INTERRUPTED.code:
        crossing = crossing._replace(interrupted_near=float(out.t_last))
    else:
        cut = replace(cut, status=Status.TOLERANCE_UNATTAINABLE.code, t_last=crossing.t_before)
    return cut, located_within(task, located, cut, specs), crossing


def solution_within_smooth_region(task: Task, sol: Solution, certified: bool) -> Solution:
    """A baseline's finished ``sol`` (SciPy's ``RK34Q8`` is certified, the
    others are not: ``certified``), ended before its first step across a
    kink as :func:`within_smooth_region` ends an RKQ-family run."""
    if not checks_kinks(task.ham, task.options.gamma_limit, certified):
        return sol
    crossing = _first_crossing(task, sol.t, sol.y)
    if crossing is None:
        return sol
    arrays = first_rows(sol, crossing.row + 1)
    status = Status.TOLERANCE_UNATTAINABLE
    if sol.status is Status.INTERRUPTED:
        status = Status.INTERRUPTED
        crossing = crossing._replace(interrupted_near=float(sol.t[-1]))
    message = crossing_message(crossing, task.ham, arrays["t"])
    return sol.replace(**arrays, status=status, message=message)


def crossing_message(crossing: Crossing, ham: Hamiltonian, t_kept: np.ndarray) -> str:
    """What ended a run at ``crossing``, and what works."""
    kink = crossing.kink
    where = f"{kink.argument} = 0" + ("" if kink.guard is None else f" with {kink.guard} < 0")
    text = (
        f"The step from t = {crossing.t_before!r} to t = {crossing.t_after!r} crosses "
        f"{where}, where H is not smooth ({kink.term}): Hamilton's equations jump there, "
        "and the error estimates of a step across it (the pair's, the quencher's order, "
        "Gamma) do not hold, so the tolerance cannot be certified beyond it; the run ends "
        "at the node before it. What works: integrate piecewise, each piece with the smooth "
        f"H of its side ({kink.term} written out for that side), ending at the crossing "
        f"with a terminal event (events={{'expression': '{kink.argument}', 'terminal': "
        "True}) and the next piece starting from its state; or gamma_limit=numpy.inf to "
        "run on without the certificate."
    )
    if crossing.interrupted_near is not None:
        text = f"{interrupted_near(crossing.interrupted_near)} {text}"
    return text + kept_nodes_note(len(t_kept))
