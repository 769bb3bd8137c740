"""How a run's estimate of Gamma grew: the readings auto's reruns, a stop's
message and the notes of a rerun judge a run by.

:func:`growth` is the growth over the second half of the interval a run
reached (:func:`hamrkq.rkq.auto_rules.error_growth` of it says whether it
was exponential), :func:`growth_between` the growth between two fractions
of it; both from the returned rows, or from the kernel's checkpoints where
the rows are thinned.  :func:`folded_growth` is the one rule over each
component's maxima (its home for many runs at once is
:func:`hamrkq.solve.member_rules.folded_growth_per_row`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hamrkq._tolerance import component_tolerance
from hamrkq.rkq.auto_rules import middle_of
from hamrkq.rkq.layout import checkpoint_fractions
from hamrkq.rkq.witness_rules import EARLY_FRACTION
from hamrkq.solve.dispatch import Task
from hamrkq.solve.member_rules import folded_growth_per_row
from hamrkq.solve.shadow import largest_state

__all__ = [
    "JUMP_RATIO",
    "MIN_GROWTH_STEPS",
    "early_growth",
    "folded_growth",
    "growth",
    "growth_between",
    "one_step_jump",
]


#: Fewer accepted steps than this say nothing about how the estimate grows
#: (a run of a dozen steps starts from an estimate of nearly nothing).  It
#: was 50: the pendulum 1e-9 below its separatrix over [0, 20], whose
#: estimate grows like e^t past the unstable top, takes 28 to 37 steps with
#: ``rk78q12``, and auto returned SUCCESS 1.30 and 5.17 times the tolerance
#: off at atol 1e-8 and atol = rtol = 1e-9, no witness run (QA, session 18;
#: ``tests/test_rounding_floor.py``).  The batch loop of an ensemble reads
#: it alike (:mod:`hamrkq.ensemble.chunk`).
MIN_GROWTH_STEPS = 20


def growth(out: Any, task: Task) -> float:
    """:func:`hamrkq.rkq.auto_rules.error_growth` of a run's estimate of Gamma
    over the second half of its interval (1 without one, or for a run of
    fewer than :data:`MIN_GROWTH_STEPS` steps)."""
    if out.gamma is None or out.stats.get("steps", 0) < MIN_GROWTH_STEPS:
        return 1.0
    if out.thinned and out.gamma_checkpoints is not None:
        return _growth_over_every_node(out, task)
    if out.t.shape[0] < 3:
        return 1.0
    middle, direction = middle_of(out.t[0], out.t[-1])
    gamma = np.abs(out.gamma)
    before = gamma[(out.t - middle) * direction <= 0.0]
    return folded_growth(task, before.max(axis=0), gamma.max(axis=0), largest_state(out))


def _growth_over_every_node(out: Any, task: Task) -> float:
    """:func:`growth` of a run whose returned rows are thinned (``t_eval``,
    ``keep_every``), from the kernel's maxima over every node: the largest
    ``|Gamma|`` up to the last checkpoint at or before the middle of the
    interval reached, and over the whole run.  A checkpoint before the middle
    reads a smaller maximum there, so a growth at least as large: the
    Henon-Heiles chaotic orbit asked for t = 150 and 300 only read no growth
    from its two rows and returned SUCCESS 94 times the tolerance off."""
    to_middle = _checkpoint_until(out, task, 0.5)
    if to_middle is None:
        return 1.0
    return folded_growth(task, to_middle, out.gamma_max, largest_state(out))


def _checkpoint_until(out: Any, task: Task, fraction: float) -> np.ndarray | None:
    """The kernel's largest ``|Gamma_k|`` up to its last checkpoint at or
    before ``fraction`` of the interval a run reached (None: no such
    checkpoint).  A checkpoint before that point reads a smaller maximum."""
    span = task.t_end - task.t0
    reached = (out.t_last - task.t0) / span if span else 1.0
    fractions = checkpoint_fractions()
    passed = (fractions <= fraction * reached) & np.isfinite(out.gamma_checkpoints[:, 0])
    if not passed.any():
        return None
    return out.gamma_checkpoints[np.flatnonzero(passed)[-1]]


def growth_between(out: Any, task: Task, low: float, high: float) -> float:
    """The growth of a run's estimate from the fraction ``low`` of the
    interval it reached to ``high`` (:func:`folded_growth` of the largest
    ``|Gamma_k|`` up to each); from the kernel's checkpoints where the
    returned rows are thinned (:func:`_checkpoint_until`), and ``inf`` where
    no node or checkpoint lies at or before ``low`` (no evidence against a
    growth)."""
    if out.gamma is None:
        return math.inf
    if out.thinned and out.gamma_checkpoints is not None:
        to_low = _checkpoint_until(out, task, low)
        to_high = _checkpoint_until(out, task, high)
    else:
        reached = out.t_last - task.t0
        where = (out.t - task.t0) / reached if reached else np.zeros(out.t.shape)
        gamma = np.abs(out.gamma)
        to_low = gamma[where <= low].max(axis=0) if (where <= low).any() else None
        to_high = gamma[where <= high].max(axis=0)
    if to_low is None:
        return math.inf
    return folded_growth(task, to_low, to_high, largest_state(out))


def early_growth(out: Any, task: Task) -> float:
    """The growth of a run's estimate from
    :data:`~hamrkq.rkq.witness_rules.EARLY_FRACTION` of the interval it
    reached to its end (:func:`growth_between`), which
    :func:`hamrkq.rkq.witness_rules.amplification_factor` reads as the
    orbit's amplification of the quencher's rounding; 1 for a run of fewer
    than :data:`MIN_GROWTH_STEPS` steps (as :func:`growth`)."""
    if out.gamma is None or out.stats.get("steps", 0) < MIN_GROWTH_STEPS:
        return 1.0
    if out.thinned and out.gamma_checkpoints is not None:
        # the kernel's maxima over every node (the ensemble's batch loop
        # reads the same: hamrkq.rkq.batch.fold_every_node)
        to_early = _checkpoint_until(out, task, EARLY_FRACTION)
        if to_early is None:
            return 1.0
        return folded_growth(task, to_early, out.gamma_max, largest_state(out))
    return growth_between(out, task, EARLY_FRACTION, 1.0)


def folded_growth(
    task: Task, to_middle: np.ndarray, to_end: np.ndarray, y_size: np.ndarray
) -> float:
    """:func:`growth` from each component's largest ``|Gamma_k|`` over the
    nodes up to the middle and over all of them, and its largest ``|y_k|``
    (what the ensemble's batch loop folds): the rule's one home is
    :func:`hamrkq.solve.member_rules.folded_growth_per_row`."""
    return float(folded_growth_per_row(task, to_middle, to_end, y_size))


#: A stop whose ratio is above this many times ``gamma_limit``, reached in
#: one step from a node below half the limit, is a jump
#: (:func:`one_step_jump`).
JUMP_RATIO = 100.0


def one_step_jump(out: Any, task: Task) -> float | None:
    """The estimate's ratio at the last node where one step carried it from
    there (below half of ``gamma_limit``) to more than :data:`JUMP_RATIO`
    times the limit, the run's stop; None otherwise.  Its stages met what
    the steps before them did not: a free particle kicked by a pulse
    ``q exp(-((t - 50)/0.5)^2)`` at atol 1e-4 stopped at t = 12.2, the step
    across the pulse reading 5 100 tolerances, and its message said the
    quencher had reached double precision's floor (before the pulse its
    Richardson differences were rounding: nothing moves); ``max_step=0.2``
    reaches the end within the tolerance (QA).  The message names that
    (:mod:`hamrkq.solve.unattainable`).  (auto's first run there, two
    quencher steps a step, stops at the same node at 0.074 of the
    tolerance, not a jump: auto still runs it again with more.)"""
    if out.gamma is None or out.y.shape[0] < 2 or float(out.t[-1]) != float(out.t_last):
        return None
    limit = task.options.gamma_limit
    if not out.max_ratio > JUMP_RATIO * limit:
        return None
    last = component_tolerance(task.atol, task.rtol, out.y[-1])
    before = float(np.max(np.abs(out.gamma[-1]) / last))
    return before if before < 0.5 * limit else None
