"""The rules after a run of :mod:`hamrkq.solve.auto`, for many runs at once.

An ensemble's batch loop (:mod:`hamrkq.ensemble.chunk`) runs its members
with the same options and folds, for each, what ``solve`` alone would read
after the run: the largest ``|Gamma_k|`` up to the middle of the interval
and to its end, the largest ``|y_k|``, its steps and its step range.  These
functions decide for every member at once, in whole-array operations, what
:func:`hamrkq.solve.growth.folded_growth` and
:func:`hamrkq.solve.auto.witness_rerun_needed` decide for one run: the same
decisions, member by member (``tests/test_ensemble_rules.py``).  Given
one run's (1-D rows, numbers), they decide for it alone.
"""

from __future__ import annotations

import numpy as np

from hamrkq._tolerance import component_tolerance
from hamrkq.rkq.auto_rules import EXPONENTIAL_GROWTH, growth_of_maxima_per_row
from hamrkq.rkq.witness_rules import (
    needs_witness_after_run_per_row,
    state_outgrew_its_start_per_row,
)
from hamrkq.solve.dispatch import Task

__all__ = ["folded_growth_per_row", "witness_rerun_needed_per_row"]


def folded_growth_per_row(
    task: Task, to_middle: np.ndarray, to_end: np.ndarray, y_sizes: np.ndarray
) -> np.ndarray:
    """:func:`hamrkq.solve.growth.folded_growth` of each row: the runs of
    ``task`` whose largest ``|Gamma_k|`` up to the middle and to the end are
    the rows of ``to_middle`` and ``to_end``, and whose largest ``|y_k|``
    are the rows of ``y_sizes`` (all of shape ``(m, d)``).

    Returns
    -------
    ndarray, shape ``(m,)``
        Each run's growth of its estimate over the second half of its
        interval (:func:`hamrkq.rkq.auto_rules.growth_of_maxima`).
    """
    # One tolerance per component over the run (at its largest |y_k|), so
    # that a tolerance with rtol, small where a component crosses zero,
    # does not count as growth of the error.
    delta = component_tolerance(task.atol, task.rtol, y_sizes)
    return growth_of_maxima_per_row(to_middle, to_end, delta)


def witness_rerun_needed_per_row(
    task: Task,
    states: np.ndarray,
    y_sizes: np.ndarray,
    factors: np.ndarray,
    steps: np.ndarray,
    step_ranges: np.ndarray,
    early_growths: np.ndarray | float = 1.0,
) -> np.ndarray:
    """:func:`hamrkq.solve.auto.witness_rerun_needed` of each run of ``task``
    (all of which could run again with the witness: the caller asks
    :func:`hamrkq.solve.auto.reruns_with_witness` once), from the rows of
    ``states`` (their ``y0``) and ``y_sizes`` (their largest ``|y_k|``) and
    the elements of ``factors`` (their estimate's growth over the second
    half), ``steps``, ``step_ranges`` and ``early_growths`` (their
    estimate's growth from the first sixteenth of the interval to its end,
    :func:`hamrkq.solve.growth.early_growth`).

    Returns
    -------
    ndarray of bool, shape ``(m,)``
        Whether each run is made again with the rounding witness.
    """
    if task.options.gamma_name == "tangent":
        # the tangent estimate: only a state grown far beyond its start counts
        return state_outgrew_its_start_per_row(task.atol, task.rtol, states, y_sizes)
    # Gamma's growth understates the rounding's on a chaotic orbit:
    # Henon-Heiles at E = 1/6 with auto at 1e-8 read 53-fold, the law
    # (needs_witness_after_run) put the amplified rounding at 0.03 of the
    # tolerance, and the quencher was 0.92 of it off (0.008 in
    # double-double): nodes of 1.53 delta.  So every exponential reading is
    # measured (tests/test_family.py).  A slower growth is a regular
    # orbit's, read noisily (28-fold on prentice2011's periodic orbit): its
    # amplification is the length's (prentice2011 at 1e-9 to t = 4000 with
    # t_eval read 5.6-fold, and would have run again for nothing).
    exponential = np.asarray(factors) > EXPONENTIAL_GROWTH
    regular = needs_witness_after_run_per_row(
        task.atol, task.rtol, states, steps, y_sizes, step_ranges, early_growths
    )
    return exponential | regular
