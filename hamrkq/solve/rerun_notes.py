"""What ``method="auto"``'s discarded runs did (:func:`rerun_note`), or a
member's first run before it ran again with the rounding witness: the note
:func:`hamrkq.solve.solve` appends to the returned run's message
(:mod:`hamrkq.solve.messages`).
"""

from __future__ import annotations

import math

from hamrkq.result import Status
from hamrkq.rkq.auto_rules import EXPONENTIAL_GROWTH
from hamrkq.rkq.driver import RunOutput
from hamrkq.rkq.layout import ST_ABANDONED
from hamrkq.rkq.witness_rules import (
    T_SQUARED_GROWTH,
    amplification_factor,
    close_approach_factor,
)
from hamrkq.solve.auto import reruns_for_rounding
from hamrkq.solve.dispatch import Task, member_of, uses_witness
from hamrkq.solve.growth import early_growth, growth

__all__ = ["rerun_note"]


def rerun_note(
    task: Task,
    discarded: list[tuple[Task, RunOutput]],
    evaluations: int,
    auto: bool = True,
    later: int = 0,
) -> str:
    """What the discarded runs (``(their task, run)``, with ``evaluations``
    between them) of ``method="auto"`` (``auto``) or of a member run again
    with the rounding witness did, for the message; the last ``later`` of
    them were made after the run returned, which reached further
    (:func:`hamrkq.solve.auto.returned_run`)."""
    notes = []
    for index, (earlier, run) in enumerate(discarded):
        if run.status == Status.SUCCESS.code:
            what = (
                f"reached t = {run.t_last!r}, the quencher's estimated error at most "
                f"{run.max_ratio:.3g} x the tolerance"
            )
        elif run.status == ST_ABANDONED:
            what = (
                f"was abandoned at t = {run.t_last!r}, where the quencher's estimated error, "
                f"growing like t^2, was on course for {run.projected:.3g} x the tolerance "
                "at t_end"
            )
        elif run.saturated:
            what = (
                f"stopped after t = {run.t_last!r}, where its shadow track had moved "
                f"{run.saturated:.3g} of the orbit's size from the quencher (saturated: "
                "Gamma from the tangent flow has no shadow, more quencher steps do not help)"
            )
        elif run.event_failure is not None:
            what = (
                f"stopped before the state of event {run.event_failure.label!r} at t = "
                f"{run.t_last!r}, where the quencher's estimated error and rounding reached "
                f"{run.max_ratio:.3g} x the tolerance"
            )
            if run.at_rounding_floor:
                what += f" ({run.floor_ratio:.3g} of it rounding: double precision's floor)"
        elif run.at_rounding_floor:
            what = (
                f"stopped at t = {run.t_last!r}, where the quencher's estimated error "
                f"reached {run.max_ratio:.3g} x the tolerance, of which its rounding "
                f"(measured by the witness) is {run.floor_ratio:.3g}: double precision's floor"
            )
        else:
            what = (
                f"stopped at t = {run.t_last!r}, where the quencher's "
                f"estimated error reached {run.max_ratio:.3g} x the tolerance"
            )
        factor = growth(run, earlier)
        if factor > EXPONENTIAL_GROWTH:
            what += (
                f"; the estimate had grown {factor:.3g}-fold over the second half of its "
                "interval, faster than a periodic orbit's t^2: where that is exponential "
                "growth, the rounding grows alike, which Gamma does not see (the "
                "witness measures it)"
            )
        elif earlier.grew_exponentially and reruns_for_rounding(earlier, run, math.inf):
            what += (
                "; the run before it had read an exponential growth of the estimate: more "
                "quencher steps shrink the truncation error and leave the rounding, amplified "
                "alike and unseen by Gamma, where it was: run again with the witness"
            )
        elif reruns_for_rounding(earlier, run, factor):
            what += _rounding_reach(earlier, run)
        after = "after it, " if index == len(discarded) - later else ""
        notes.append(f"{after}the run {_quencher_setting(earlier)} {what}")
    method = task.options.method
    if later:
        ran = f"method='auto' returns its run of {method} that reached furthest,"
    elif auto:
        ran = f"method='auto' ran {method}"
    else:
        ran = f"This is {method}'s second run"
    return (
        f" {ran} {_quencher_setting(task)}: "
        f"{'; '.join(notes)} "
        f"({evaluations} evaluations: stats['discarded_evaluations'], not in nfev/njev)."
    )


def _rounding_reach(task: Task, run: RunOutput) -> str:
    """Why a finished run's rounding could reach the tolerance
    (:func:`hamrkq.solve.auto.reruns_for_rounding`): its length, its
    state's size, close approaches or the orbit's amplification
    (:func:`hamrkq.rkq.witness_rules.beyond_length_factor`)."""
    approaches = ""
    early = early_growth(run, task)
    amplified = amplification_factor(early)
    if amplified > 1.0 and amplified >= close_approach_factor(run.step_range):
        approaches = (
            f", and with the orbit's amplification: the estimate grew {early:.3g}-fold "
            "from the first sixteenth of the interval to its end, "
            f"{early / T_SQUARED_GROWTH:.3g} times a regular orbit's t^2"
        )
    elif close_approach_factor(run.step_range) > 1.0:
        approaches = f", and with close approaches: its steps ranged {run.step_range:.3g}-fold"
    return (
        f"; over its {run.stats.get('steps', 0)} steps the quencher's rounding, "
        "which Gamma does not see (it grows like the square of a run's length, and "
        f"with the state's size{approaches}), could reach the tolerance: run again "
        "with the witness"
    )


def _quencher_setting(task: Task) -> str:
    """``with z_substeps=3`` (and ``, the quencher in double-double``,
    ``, Gamma from the tangent flow`` or ``and the rounding witness``)."""
    options = task.options
    extended = ", the quencher in double-double" if options.double_double else ""
    witness = " and the rounding witness" if uses_witness(task) else ""
    tangent = (
        ", Gamma from the tangent flow (global_error_estimate='tangent')"
        if task.auto and options.gamma_name == "tangent"
        else ""
    )
    return f"with z_substeps={member_of(task).z_substeps}{tangent}{extended}{witness}"
