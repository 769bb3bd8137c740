"""``method="auto"``'s runs again: how many quencher steps a step it tries next.

``solve`` runs auto's member (:func:`hamrkq.rkq.auto_rules.auto_member`) with
two quencher steps a step, and runs it again with more (:func:`rerun`) when
the kernel abandoned the run on its projection (:func:`projects` says which
runs are projected) or the run stopped on the quencher's truncation error;
the rules are :func:`hamrkq.rkq.auto_rules.auto_abandon_substeps` and
:func:`hamrkq.rkq.auto_rules.auto_retry_substeps` (docs/algorithm.md).  A
finished run runs again once with the rounding witness where its rounding,
amplified by an exponential growth of the estimate (an unstable orbit,
:func:`hamrkq.rkq.auto_rules.error_growth`), by the run's length, by a
state grown beyond its start or by close approaches, could reach the tolerance
(:func:`witness_rerun_needed`, for every member with the shadow estimate,
and for ``rk34q8``'s tangent estimate where its state outgrew its start);
two exponential runs in a row allow no more quencher steps.  A run cut where
its shadow track saturated (:func:`hamrkq.solve.shadow.within_linear_shadow`)
runs again with the tangent estimate (:func:`_with_tangent`).  How a run's
estimate grew is read in :mod:`hamrkq.solve.growth`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from hamrkq._floats import EPS
from hamrkq._tolerance import component_tolerance
from hamrkq.options import SolveOptions
from hamrkq.result import Solution, Status
from hamrkq.rkq.auto_rules import (
    AUTO_MAX_SUBSTEPS,
    EXPONENTIAL_GROWTH,
    auto_abandon_substeps,
    auto_retry_substeps,
)
from hamrkq.rkq.layout import ST_ABANDONED
from hamrkq.solve.dispatch import (
    METHODS,
    Task,
    can_witness,
    member_of,
    run_rk,
    time_rounding_limits,
    uses_witness,
)
from hamrkq.solve.event_check import stored_rounding_limits
from hamrkq.solve.growth import early_growth, growth, growth_between
from hamrkq.solve.member_rules import witness_rerun_needed_per_row
from hamrkq.solve.output_times import output_rounding_limits
from hamrkq.solve.shadow import largest_state

__all__ = [
    "FURTHER_BY",
    "double_double_can_help",
    "projects",
    "reading_with_the_run_before",
    "rerun",
    "reruns_for_rounding",
    "reruns_with_witness",
    "retry_substeps",
    "returned_run",
    "tangent_follows_saturation",
    "witness_rerun_needed",
]


def projects(requested: SolveOptions, task: Task) -> bool:
    """Whether ``method="auto"`` chooses the quencher's steps, and its run is
    abandoned when its projection fails (:func:`rerun`).  Not where the
    rounding witness runs: near double precision's floor more quencher steps
    shrink the truncation error, not the rounding (prentice2011 at 1e-12, the
    quencher in double, stops at the floor at t = 80, 201, 54 and 60 in 2,
    3, 4 and 6 steps a step, ``benchmarks/algorithm_facts.txt``); a run that
    stops on the quencher's truncation error there still runs again."""
    return (
        requested.method == "auto"
        and requested.z_substeps is None
        and METHODS[task.options.method].run is run_rk
        and task.options.member().z_substeps < AUTO_MAX_SUBSTEPS
        and not uses_witness(task)
    )


def rerun(requested: SolveOptions, task: Task, out: Any) -> Task | None:
    """The next run of a task, or None: for every member with the shadow
    estimate, the same run with the rounding witness when its estimate grew
    exponentially and the witness did not run (the nodes it returned rest on
    a Gamma blind to the amplified rounding); for ``method="auto"``, also
    the next run with more quencher steps per step, when this one was
    abandoned on its projection
    (:func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`) or stopped on the
    quencher's truncation error before ``t_end``
    (:func:`hamrkq.rkq.auto_rules.auto_retry_substeps`).  Each next run's
    options are checked as the caller's are
    (:meth:`hamrkq.options.SolveOptions.check_combination`): its rules build
    them with :func:`dataclasses.replace`, past that check, which is how the
    tangent estimate and the quencher in double-double came together once
    (701e72c)."""
    following = _next_run(requested, task, out)
    if following is not None:
        following.options.check_combination()
    return following


def _next_run(requested: SolveOptions, task: Task, out: Any) -> Task | None:
    """:func:`rerun` before its check."""
    if isinstance(out, Solution):
        return None
    member = member_of(task)
    factor = growth(out, task)
    exponential = factor > EXPONENTIAL_GROWTH
    if reruns_for_rounding(task, out, reading_with_the_run_before(task, factor)):
        # Gamma without the witness sees the quencher's truncation error, not
        # its rounding, which an unstable orbit, a long run, a grown state or
        # close approaches amplify: explicit members returned SUCCESS on the
        # Arenstorf orbit over three periods at 1e-8 with true errors of 17
        # to 62 times the tolerance, auto on prentice2011 to t = 170 000 at
        # 1e-8 2.7 times.
        witnessed = _with_witness(requested, task)
        if witnessed is not None:
            # The same run again: its growth will read the same, which is
            # not a second reading (task.grew_exponentially keeps the one
            # before): prentice2011 at 1e-4, whose estimate grows faster
            # than t^2 over its first few periods, read 1120-fold on four
            # output times, stopped on the quencher's truncation error with
            # the witness too, and was not run with more quencher steps.
            return witnessed
    if out.saturated:
        # More quencher steps do not move the shadow back: its error is the
        # quencher's in one step a step, whatever m; and shorter steps do
        # not make it honest again (_with_tangent).
        return _with_tangent(requested, task)
    # Exponential growth in two runs in a row (one alone can be a burst: a
    # Kepler orbit's pericentre passages early in a run): more quencher steps
    # only push the stop a little later and carry the shadow out of its
    # linear regime, and the rounding grows alike.
    if exponential and task.options.double_double and task.ham.equations_time_dependent:
        # Its stage times are doubles, their rounding amplified like the
        # rest and measured by no witness there: a forced pendulum (H =
        # p^2/2 - cos q - 1.2 q cos(2t/3), from q = 0.5 at 1e-10) went to
        # double-double at the floor at t = 34.9 before any exponential
        # reading, read one there and stopped at t = 84.8, its nodes from
        # t = 70 up to 2451 delta off (QA).  The run in double with the
        # witness, whose stage times are rounded stochastically, stands.
        return _in_double_with_witness(requested, task)
    if out.status not in (ST_ABANDONED, Status.TOLERANCE_UNATTAINABLE.code):
        return None  # finished, or ended where no rerun helps
    unstable = exponential and reads_growth_again(task, out)
    reading_before = task.exponential_until
    # for the next run's decision
    task = replace(task, exponential_until=out.t_last if exponential else None)
    if out.status == ST_ABANDONED:
        if unstable:
            # The rounding measured, or (the quencher in double-double, where
            # it is small) the same run to where its estimate stops it.
            return _with_witness(requested, task) or replace(task, project=False)
        substeps = auto_abandon_substeps(
            member.z_substeps, member.z_order, out.projected, task.options.gamma_limit
        )
        assert substeps is not None  # only a run that can run again projects
        return _with_substeps(requested, task, substeps)
    return _after_a_stop(requested, task, out, factor if unstable else None, reading_before)


#: A second exponential reading counts only from a run that reached at least
#: this many times as far from ``t0`` as the one that read the first
#: (:func:`reads_growth_again`).
READING_REACH = 1.05


#: The growth over the second half of a run, its last tenth left out, above
#: which an exponential reading counts a second time
#: (:func:`reads_growth_again`): an exponential growth read over the second
#: half (at least :data:`~hamrkq.rkq.auto_rules.EXPONENTIAL_GROWTH`) grows by
#: its 0.8th power there; this leaves a factor of its 0.4th power (4.8) for
#: noise.
INTERIOR_GROWTH = EXPONENTIAL_GROWTH**0.4


def reads_growth_again(task: Task, out: Any) -> bool:
    """Whether a run whose estimate grew exponentially is the second such
    run in a row (``task.exponential_until``, the first's end) and reached
    further than it, by :data:`READING_REACH`: on a chaotic orbit more
    quencher steps push the stop later by ``log(m'^z / m^z) / lambda``, a
    good part of the time reached, whereas a burst read over the same
    stretch of the orbit twice says nothing more.  Kepler at e = 0.9 over
    ten orbits at ``rtol`` 1e-7 (``atol`` 1e-13) with the event ``p1``: the
    pericentre at t = 2 pi read as a 2 040-fold growth in the run abandoned
    at t = 6.2738 and in the next, with three quencher steps, stopped at
    the event state there (t = 6.2832, where ``p1``'s tolerance is
    ``atol``); auto gave up, its message saying more quencher steps only
    delay the stop, where six carry it to the end (QA)."""
    if task.exponential_until is None:
        return False
    before = abs(task.exponential_until - task.t0)
    if abs(out.t_last - task.t0) < READING_REACH * before:
        return False
    # A burst at the end of the run reads as a growth over its second half
    # whatever the orbit: Kepler at e = 0.999 from its pericentre over five
    # periods at rtol 1e-8 (atol 1e-10) with a pericentre event read 329-fold
    # at the first pericentre and 1.34e3-fold in the run stopped at the
    # second (t = 4 pi), its estimate flat between them (1.0-fold from 0.5
    # to 0.9 of the run), and auto gave up where eight quencher steps in
    # double-double reach the end (nodes 0.995 delta, event states 0.037;
    # QA).  An exponential growth shows before the run's last tenth too.
    return growth_between(out, task, 0.5, 0.9) > INTERIOR_GROWTH


def _after_a_stop(
    requested: SolveOptions,
    task: Task,
    out: Any,
    growth: float | None,
    reading_before: float | None = None,
) -> Task | None:
    """:func:`rerun` of a run stopped with ``TOLERANCE_UNATTAINABLE`` (not
    abandoned): ``method="auto"`` with more quencher steps, or the quencher
    in double-double, where that can help; ``growth``: the estimate's
    growth where it was exponential twice in a row, else None;
    ``reading_before``: where the run before this one ended if it read an
    exponential growth (what the run in double-double, the same quencher
    steps again, carries on: its reading is not a second one)."""
    if requested.method != "auto" or requested.z_substeps is not None:
        return None
    if out.gamma is None:
        return None
    # (no node kept: the run stopped before the first output time)
    last = out.y[-1] if out.y.shape[0] else largest_state(out)
    if float(np.max(EPS * np.abs(last) / component_tolerance(task.atol, task.rtol, last))) >= (
        0.5 * task.options.gamma_limit
    ):
        return None  # the stored values' own rounding: more substeps cannot help
    if stored_rounding_limits(out.event_failure, task.options.gamma_limit):
        return None  # the same at an event state
    if output_rounding_limits(out, task):
        return None  # and at an output time inside a step
    if out.at_rounding_floor:
        # Double precision's floor for this orbit: the quencher in
        # double-double goes below it, where f has a double-double form.
        # The same quencher steps again read the same growth, which is not a
        # second reading: Kepler at e = 0.995 over 50 periods at 1e-8, whose
        # first pericentre after the start reads as an exponential burst,
        # stopped there in double-double without trying more quencher steps,
        # which carry it to the end (QA; tests/test_family.py).
        dd = _in_double_double(requested, task)
        if dd is None:
            return None
        return replace(dd, exponential_until=reading_before, double_floor_at=out.t_last)
    # After two exponential readings more quencher steps only push the stop
    # a little later, and the shadow's error, m^z times the quencher's,
    # leaves the linear regime (the estimate saturates at the orbit's size
    # over m^z); the rounding, amplified alike, was measured already (above).
    # Unless the stop was close enough to the end that the growth, projected,
    # leaves it within reach (the Arenstorf orbit at rtol 1e-6, stopped at
    # 0.99998 of its period).
    substeps = retry_substeps(out, task, growth=growth)
    if substeps is None:
        return None
    return _with_substeps(requested, task, substeps)


def retry_substeps(out: Any, task: Task, growth: float | None = None) -> int | None:
    """The quencher steps per step that carry a run of ``task`` stopped on
    its quencher's truncation error to its end
    (:func:`hamrkq.rkq.auto_rules.auto_retry_substeps`, with ``growth`` where
    the estimate grew exponentially), or None: what auto runs again with,
    and what the message of a stopped run offers.  The ratio that stopped
    the run counts less the rounding the witness measured (the last node
    kept may be an earlier t_eval time, with a smaller Gamma)."""
    member = member_of(task)
    reached = (out.t_last - task.t0) / (task.t_end - task.t0)
    return auto_retry_substeps(
        member.z_substeps, member.z_order, out.max_ratio - out.floor_ratio,
        task.options.gamma_limit, reached, growth=growth,
    )  # fmt: skip


def _in_double_double(requested: SolveOptions, task: Task) -> Task | None:
    """``task`` with its quencher in double-double, or None when the caller
    refused it (``quencher_precision="double"``) or
    :func:`double_double_can_help` says no."""
    if requested.quencher_precision is not None or not double_double_can_help(task):
        return None
    task = replace(task, options=replace(task.options, quencher_precision="double-double"))
    return replace(task, project=projects(requested, task))


def double_double_can_help(task: Task, under_cap: bool = False) -> bool:
    """Whether the quencher in double-double could carry ``task`` below
    double precision's floor: not where it runs so already, with another
    estimate than the shadow's (its only Gamma in double-double: after
    auto's run with the tangent estimate, :func:`_with_tangent`, a run in
    double-double with a Gamma neither computed returned nodes 1.52 delta
    off on Kepler at e = 0.95, rtol 1e-5, atol 1e-8, over 100 periods), where
    ``f`` has no double-double form (``DD_UNSUPPORTED`` of the generated
    module), or where the rounding of its stage times, which stay doubles,
    could reach the tolerance: by the time's size
    (:func:`~hamrkq.solve.dispatch.time_rounding_limits`), or amplified by
    an exponential growth where ``H`` depends on the time.  What auto runs
    (:func:`_in_double_double`) and what a stop's message offers.

    ``under_cap``: the tangent estimate that a caller's ``max_step`` made
    the default counts too (:attr:`~hamrkq.options.SolveOptions.capped_default`):
    the caller's ``quencher_precision="double-double"`` brings the shadow
    back there, which a stop's message offers and auto does not run by
    itself (QA: auto and ``rk45q12`` with ``max_step=1e3`` on Kepler at
    atol 1e-12 stopped at the floor, the message naming only a looser
    tolerance; in double-double they reach the end within the tolerance)."""
    from hamrkq.backends import codegen

    options = task.options
    if options.double_double:
        return False
    if options.gamma_name != "shadow" and not (under_cap and options.capped_default):
        return False
    if codegen.double_double_unsupported(task.ham) or time_rounding_limits(task):
        return False
    # A chaotic forced pendulum (H = p^2/2 - cos q - 1.2 q cos(2t/3), from
    # q = 0.5 at 1e-10), whose witness run stopped at the floor at t = 48.6,
    # ran on in double-double to t = 73.7 returning nodes 4.58 times the
    # tolerance off, Gamma blind to the stage times' rounding and no witness
    # (QA; tests/test_rounding_floor.py); and one that read the growth in
    # double-double only (Task.stage_times_amplified).  The witness's stop,
    # its stage times rounded stochastically, stands.
    return not (
        task.stage_times_amplified
        or (task.grew_exponentially and task.ham.equations_time_dependent)
    )


def reading_with_the_run_before(task: Task, factor: float) -> float:
    """The growth a finished run's rounding is judged by: its own
    (``factor``), or, where the run before it read an exponential growth
    (``task.grew_exponentially``), infinite.  More quencher steps after such
    a reading push the truncation error down and leave the rounding, which
    the orbit amplifies alike, where it was; the run that follows may read
    a slower growth over its second half.  Kepler's orbit at e = 0.99 with
    ``atol`` 1e-8: the first run read a 973-fold growth and was abandoned,
    the next, with three quencher steps, read less, returned SUCCESS without
    the witness, and was 2.9 times the tolerance off at a pericentre
    (rounding: 0.01 of it with the quencher in double-double)."""
    return math.inf if task.grew_exponentially else factor


def reruns_for_rounding(task: Task, out: Any, factor: float) -> bool:
    """Whether a run of ``task`` (``out``, its estimate grown ``factor``-fold)
    runs again with the rounding witness: it finished (SUCCESS, or stopped
    on its estimate) and :func:`witness_rerun_needed` says so at its largest
    state and its steps.  :func:`rerun` makes the run; the message says why
    (:func:`hamrkq.solve.rerun_notes.rerun_note`)."""
    finished = out.status in (Status.SUCCESS.code, Status.TOLERANCE_UNATTAINABLE.code)
    if not (finished and reruns_with_witness(task)):
        return False
    steps = out.stats.get("steps", 0)
    return witness_rerun_needed(
        task, task.y0, largest_state(out), factor, steps, out.step_range, early_growth(out, task)
    )


def witness_rerun_needed(
    task: Task,
    y0: np.ndarray,
    y_size: np.ndarray,
    factor: float,
    steps: int,
    step_range: float = 1.0,
    early: float = 1.0,
) -> bool:
    """Whether a finished run of ``task`` from ``y0`` (an ensemble member's),
    whose largest ``|y_k|`` over its nodes are ``y_size``, whose estimate
    grew ``factor``-fold over the second half of its ``steps`` steps and
    ``early``-fold from the first sixteenth to the end
    (:func:`hamrkq.solve.growth.early_growth`), and whose free steps ranged
    over ``step_range`` (the largest over the smallest), runs again with the
    rounding witness: the witness did not run and can
    (:func:`reruns_with_witness`), and the rounding, amplified by an
    exponential growth, by a long run, by close approaches or by the orbit's
    sensitivity (an early growth beyond ``t^2``), could reach the tolerance
    (:func:`hamrkq.rkq.witness_rules.needs_witness_after_run`) at the run's
    largest state, not only at ``y0``: a pendulum going over the top from
    q = 0 at 1e-8 reached q = 13 000 by t = 5000 (an ulp of q there is
    1.8e-12) and returned nodes 1.08 times the tolerance off.  For the
    tangent estimate only a state grown far beyond its start counts
    (:func:`hamrkq.rkq.witness_rules.state_outgrew_its_start`).  The rule
    after ``reruns_with_witness`` has its one home in
    :func:`hamrkq.solve.member_rules.witness_rerun_needed_per_row`, which
    decides it for an ensemble's members at once."""
    if not reruns_with_witness(task):
        return False
    needed = witness_rerun_needed_per_row(task, y0, y_size, factor, steps, step_range, early)
    return bool(needed)


def reruns_with_witness(task: Task) -> bool:
    """Whether a run of ``task`` can run again with the rounding witness
    where its rounding calls for it (:func:`rerun`): the shadow's or the
    tangent's estimate, without the witness, the quencher in double."""
    # without building the task (every finished run asks)
    return can_witness(task.options) and not uses_witness(task)


def _in_double_with_witness(requested: SolveOptions, task: Task) -> Task:
    """``task`` with its quencher in double again and the witness, not
    projected, never again in double-double
    (``Task.stage_times_amplified``)."""
    options = replace(task.options, quencher_precision=requested.quencher_precision)
    return replace(task, options=options, witness=True, stage_times_amplified=True, project=False)


def _witnessed(task: Task) -> Task | None:
    """``task`` with the rounding witness; None where the witness ran
    already or cannot (the paper's estimate, or the quencher in
    double-double)."""
    return replace(task, witness=True) if reruns_with_witness(task) else None


def _with_witness(requested: SolveOptions, task: Task) -> Task | None:
    """``task`` again with the rounding witness (an orbit whose error grows
    exponentially: its rounding grows alike), not projected; None where
    :func:`_witnessed` says it cannot."""
    task = _witnessed(task)
    return None if task is None else replace(task, project=projects(requested, task))


def tangent_follows_saturation(task: Task) -> bool:
    """Whether ``method="auto"`` runs a run of ``task`` cut where its shadow
    saturated again with the tangent estimate (:func:`_with_tangent`): auto's
    shadow estimate (``task.options`` names none, and no ``max_step`` made
    the tangent one the default), not the quencher in double-double.  What auto runs and what
    the saturated run's message leaves out of its remedies."""
    options = task.options
    return (
        task.auto
        and options.global_error_estimate is None
        and options.gamma_name == "shadow"
        and not options.double_double
    )


def _with_tangent(requested: SolveOptions, task: Task) -> Task | None:
    """``method="auto"``'s next run after its shadow track saturated: the
    same member and quencher steps, Gamma from the tangent flow (each
    quencher step's Richardson error carried by the Jacobian, as ``rk34q8``
    does), which has no shadow to saturate.  Not a shorter ``max_step``,
    which auto ran first until 2026-11-27: it keeps the shadow within its
    limit without making it honest.  On Kepler orbits at loose tolerances
    the shadow's long steps through the pericentre are outside its
    asymptotic regime (its error there is far less than ``m^z`` times the
    quencher's); the long steps elsewhere hid that by saturating it, and a
    shorter ``max_step`` took them away: at e = 0.9, ``atol`` 1e-6, ``rtol``
    1e-3 over 300 periods SUCCESS with the last node 23.5 times the
    tolerance off, Gamma 500 times below the quencher's true error; 8 of
    182 such runs above 1.05 delta, none with the tangent estimate
    (QA; ``benchmarks/kepler_saturation.py``).  None for a named member, an
    estimate the caller chose, or the quencher in double-double (whose
    Gamma is the shadow's)."""
    if not tangent_follows_saturation(task):
        return None
    task = replace(task, options=replace(task.options, global_error_estimate="tangent"))
    return replace(task, project=projects(requested, task))


def _with_substeps(requested: SolveOptions, task: Task, substeps: int) -> Task:
    """``task`` with ``substeps`` quencher steps a step, still projected while
    it could run again with more."""
    task = replace(task, options=replace(task.options, z_substeps=substeps))
    return replace(task, project=projects(requested, task))


#: An earlier run is returned in place of the last only where it reached
#: further by more than this share of the interval (:func:`returned_run`):
#: Kepler runs stopped at the last pericentre of 100 periods, one after the
#: other, 5e-10 apart.
FURTHER_BY = 0.01


def returned_run(runs: list[tuple[Task, Any]]) -> int:
    """Which of ``method="auto"``'s runs ``(their task, run)``, in the order
    made, ``solve`` returns: the last, unless it stopped on its estimate
    (``TOLERANCE_UNATTAINABLE``) short of an earlier run that stopped so too
    and reached further from ``t0`` (by more than :data:`FURTHER_BY` of the
    interval), whose nodes stand: the furthest such run.
    A run's nodes stand where no later run added the rounding witness to
    what it ran without (its Gamma was blind to an amplified rounding: the
    witness's rule, or a time-dependent ``H`` read growing in double-double,
    :func:`_in_double_with_witness`); a run cut where its shadow saturated
    keeps only the nodes before the cut
    (:func:`hamrkq.solve.shadow.within_linear_shadow`).  The double
    pendulum over [0, 100] at ``atol`` = ``rtol`` = 1e-3, when auto ran a
    saturated shadow again with shorter steps first: the run with four
    quencher steps, ``max_step`` 0.04 and the witness reached t = 68.40 (cut
    where its shadow saturated); the runs after it with the tangent
    estimate stopped at t = 43.2 and 54.65, the last of which auto returned
    (QA)."""
    last = len(runs) - 1
    if runs[last][1].status != Status.TOLERANCE_UNATTAINABLE.code:
        return last
    witness_added = [
        any(uses_witness(later) and not uses_witness(task) for later, _ in runs[i + 1 :])
        for i, (task, _) in enumerate(runs)
    ]

    def reach(i: int) -> float:
        task, out = runs[i]
        return abs(out.t_last - task.t0)

    standing = [
        i
        for i, (_, out) in enumerate(runs[:last])
        if out.status == Status.TOLERANCE_UNATTAINABLE.code and not witness_added[i]
    ]
    furthest = max(standing, key=reach, default=last)
    margin = FURTHER_BY * abs(runs[last][0].t_end - runs[last][0].t0)
    return furthest if reach(furthest) > reach(last) + margin else last
