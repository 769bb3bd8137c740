"""The message of a finished RKQ-family run: what ended it, at which
``t`` (:func:`message`); :mod:`hamrkq.solve.outcome` puts it on the
:class:`~hamrkq.result.Solution`.  Why a tolerance was unattainable, and
the remedy that works, is :mod:`hamrkq.solve.unattainable`; what
``method="auto"``'s discarded runs did is :mod:`hamrkq.solve.rerun_notes`.
"""

from __future__ import annotations

import math
import sys

from hamrkq._floats import EPS
from hamrkq._interruption import interrupted_near
from hamrkq.result import Status, kept_nodes_note
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.dispatch import (
    Task,
    member_of,
)
from hamrkq.solve.unattainable import NEAR_OVERFLOW, equation_of, state_size, unattainable

__all__ = ["message", "uncertified_note"]


def _steps_needed(out: RunOutput, task: Task) -> str:
    """What a run stopped by ``max_steps`` would need at the pace it went:
    its step attempts over the share of the interval it covered."""
    covered = (float(out.t_last) - task.t0) / (task.t_end - task.t0)
    attempts = out.stats.get("steps", 0) + out.stats.get("rejected", 0)
    if not 0.0 < covered < 1.0 or attempts == 0:
        return ""
    needed = math.ceil(attempts / covered)
    also = (
        f", or a max_step larger than {task.options.max_step:g}"
        if task.options.max_step < math.inf
        else ""
    )
    return (
        f" At that pace the interval needs about {needed:,} steps: a larger max_steps "
        f"lets it finish{also}."
    )


#: A start this many spans or more from t = 0 puts the step's roundoff floor
#: (10 eps |t|) far above what the span alone asks.
FAR_START = 100.0


def _far_from_zero(task: Task, t: float) -> str:
    """The remedy for a step size below the roundoff floor where the floor
    is set by times far from zero, not by the orbit: the span from ``t0``
    shifted to start at 0 (an autonomous H), or H written in ``s = t - t0``
    (QA: Kepler at e = 0.9, atol 1e-10 from t0 = 3e12, whose floor 10 eps
    |t| is 6.7e-3, stopped at its first pericentre with no remedy named)."""
    span = abs(task.t_end - task.t0)
    if not abs(task.t0) > FAR_START * span:
        return ""
    shifted = f"a floor of at most {10.0 * EPS * span:.3g}"
    if task.ham.equations_time_dependent:
        shift = f"H written in s = t - t0 (t0 a parameter): a run from s = 0 has {shifted}"
    else:
        shift = (
            "Hamilton's equations do not depend on t: the same run with t_span = "
            f"(0, {task.t_end - task.t0:.6g}) gives the same states, at the times shifted by "
            f"t0, with {shifted}"
        )
    return (
        f" Here the floor, {10.0 * EPS * abs(t):.3g}, comes from the times' size, not from "
        f"the orbit: the span, {span:.3g} long, is {abs(task.t0):.3g} from t = 0. "
        f"What works: {shift}."
    )


def message(status: Status, out: RunOutput, task: Task) -> str:
    t = out.t_last
    if status is Status.SUCCESS:
        text = f"The integration reached the end of the interval (t = {float(t)!r})."
    elif status is Status.STEP_SIZE_UNDERFLOW:
        text = (
            f"The step size {abs(out.h_fail):.3g} fell below the roundoff floor "
            f"(10 eps |t|) at t = {float(t)!r}."
        ) + _far_from_zero(task, float(t))
    elif status is Status.NON_FINITE:
        text = (
            "The state or the right-hand side became non-finite (inf or nan) at "
            f"t = {float(t)!r}: "
            f"{equation_of(task, out.bad_component)} could not be evaluated to a finite value "
            "there (a singularity, or H outside its domain)."
        )
        size = state_size(out)
        if size >= NEAR_OVERFLOW:
            # The oscillator from q = 1e308: f is finite there, a stage value
            # a step away is not (found by QA).
            text += (
                f" The state's largest component is {size:.3g}, within a factor "
                f"{sys.float_info.max / size:.3g} of the largest double: the step's stage "
                "values overflow there. What works: variables rescaled (q = s Q and "
                "p = s P, with H(s Q, s P) / s^2 as the Hamiltonian: the same t)."
            )
    elif status is Status.MAX_STEPS:
        text = (
            f"The step limit max_steps = {task.options.max_steps} was reached at t = {float(t)!r}."
            + _steps_needed(out, task)
        )
    elif status is Status.INTERRUPTED:
        text = interrupted_near(t)
    elif status is Status.TOLERANCE_UNATTAINABLE:
        text = unattainable(out, task)
    else:  # pragma: no cover - other statuses come from other methods
        text = f"{status.description} (t = {float(t)!r})"
    if not status.success:
        if out.t.size and out.t[-1] != t:
            # Output times (t_eval) end before where the steps reached.
            text += f" The last output time kept is t = {float(out.t[-1])!r}."
        text += kept_nodes_note(out.t.size)
    if status.success:
        text += _uncertified_note(task)
    steps = out.stats.get("steps", 0)
    rounded = out.stats.get("roundoff_steps", 0)
    if steps and 2 * rounded > steps and status is not Status.TOLERANCE_UNATTAINABLE:
        text += (
            f" Note: on {rounded} of {steps} steps the quencher's local error was below "
            "double-precision rounding; there the Richardson estimate (and Gamma) "
            "measures rounding, not truncation."
        )
    return text


def _uncertified_note(task: Task) -> str:
    """:func:`uncertified_note` of a run."""
    options = task.options
    return uncertified_note(member_of(task).use_z, options.gamma_name, options.gamma_limit)


def uncertified_note(uses_quencher: bool, estimate: str | None, gamma_limit: float) -> str:
    """What a successful run of a member with a quencher that nothing
    certified must say: with ``global_error_estimate="off"`` or
    ``gamma_limit=inf`` its nodes are the quencher's where quenched, and the
    quencher's own error is unchecked (QA: Kepler at e = 0.9, atol 1e-12,
    ``rk34q8`` with the estimate off returned SUCCESS 13.8 tolerances off,
    the message saying only that it reached the end).  Empty otherwise.

    Parameters
    ----------
    uses_quencher : bool
        Whether the method has a quencher (an RKQ member, or ``"auto"``).
    estimate : str or None
        The run's ``global_error_estimate``.
    gamma_limit : float
        The run's ``gamma_limit``.
    """
    if not uses_quencher:
        return ""
    if estimate == "off":
        why = "global_error_estimate='off' leaves the quencher's own error unestimated"
    elif gamma_limit == math.inf:
        why = "gamma_limit=inf leaves the quencher's estimated error unchecked"
    else:
        return ""
    return (
        f" Nothing certified the tolerance: {why}, so the nodes may be further from the "
        "solution than the tolerance; the promise is yours to check (hamrkq.diagnose)."
    )
