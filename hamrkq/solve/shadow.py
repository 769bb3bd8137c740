"""The check after a run that the shadow estimate of Gamma still holds.

With ``global_error_estimate="shadow"`` a *shadow* track runs the quencher
once per step of the pair from the initial value, never quenched; its global
error is ``m^z`` times the quencher's, so ``Gamma = (shadow - z) / (m^z - 1)``
(docs/algorithm.md, "Gamma by global extrapolation").  That assumes both
errors small and proportional: where the shadow's distance from the quencher
reaches the orbit's size the shadow saturates, and Gamma stops growing with
the quencher's error.  After each run :func:`within_linear_shadow` measures,
at every node returned, that distance over each component's size,
``(m^z - 1) |Gamma_k| / size_k`` (:func:`shadow_departures`), and ends the
run at the last node before it passes
:data:`~hamrkq.rkq.auto_rules.SHADOW_SATURATION` (docs/algorithm.md, "The
shadow's linear regime").  :func:`largest_state` is the size measured against.

Below :mod:`hamrkq.solve.dispatch`, whose runner calls it: it reads a
:class:`~hamrkq.solve.dispatch.Task`'s fields only (the type named for the
hints, not imported at run time).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from hamrkq.result import Status
from hamrkq.rkq.auto_rules import SHADOW_SATURATION, shadow_departure
from hamrkq.rkq.driver import RunOutput, largest_over_nodes
from hamrkq.rkq.scales import component_scales

if TYPE_CHECKING:
    from hamrkq.solve.dispatch import Task

__all__ = ["largest_state", "shadow_departures", "within_linear_shadow"]


def shadow_departures(task: Task, gamma: np.ndarray, y_size: np.ndarray) -> np.ndarray | None:
    """:func:`~hamrkq.rkq.auto_rules.shadow_departure` of the rows of
    ``gamma`` for a run of ``task`` whose largest ``|y_k|`` are ``y_size``;
    None where no limit applies: another estimate than the shadow's, or
    ``gamma_limit=inf`` (the certificate turned off).  The ensemble's batch
    loop asks it with each member's folded maxima."""
    if task.options.gamma_name != "shadow" or not task.options.gamma_limit < math.inf:
        return None
    scale = component_scales(task.atol, y_size)
    return shadow_departure(gamma, scale, task.options.member().shadow_scale)


def largest_state(out: RunOutput) -> np.ndarray:
    """Each component's largest ``|y_k|`` over a run's nodes (zeros for none;
    over every node of the run where the returned rows are thinned): the
    size the rules after a run measure against (read-only; computed once
    per run, :attr:`~hamrkq.rkq.driver.RunOutput.largest_state`, for a
    RunOutput, and here for anything else with its fields)."""
    if type(out) is RunOutput:
        return out.largest_state
    return largest_over_nodes(out)


def within_linear_shadow(task: Task, out: RunOutput) -> RunOutput:
    """``out``, or its nodes before the first where the shadow track had
    moved more than :data:`~hamrkq.rkq.auto_rules.SHADOW_SATURATION` of the
    orbit's size from the quencher (:func:`~hamrkq.rkq.auto_rules.shadow_departure`),
    where Gamma can no longer certify the tolerance: status
    TOLERANCE_UNATTAINABLE, ``saturated`` the departure found.  Not with
    ``gamma_limit=inf``, which turns the certificate off."""
    if out.gamma is None or out.t.shape[0] == 0:
        return out
    if _far_within_linear_shadow(task, out.gamma, largest_state(out)):
        return out
    departure = shadow_departures(task, out.gamma, largest_state(out))
    if departure is None:
        return out
    beyond = np.flatnonzero(departure > SHADOW_SATURATION)
    if beyond.size == 0:
        return out
    # Where the first returned row is beyond already (output times far
    # apart: Henon-Heiles' chaotic orbit with t_eval = [150, 300] returned
    # SUCCESS 94 times the tolerance off at 1e-6), nothing is certified.
    kept = int(beyond[0])
    return replace(
        out.rows(slice(kept)),
        status=Status.TOLERANCE_UNATTAINABLE.code,
        t_last=float(out.t[kept - 1]) if kept else task.t0,
        saturated=float(departure[kept]),
    )


def _far_within_linear_shadow(task: Task, gamma: np.ndarray, y_size: np.ndarray) -> bool:
    """Whether the shadow departures of the rows ``gamma`` (:func:`shadow_departures`)
    are surely at most half of :data:`~hamrkq.rkq.auto_rules.SHADOW_SATURATION`:
    each component's scale is at least its largest ``|y_k|`` (``y_size``), so
    ``m^z - 1`` times each column's largest ``|Gamma_k|`` over ``y_size_k``
    bounds them.  A shadow estimate only (where the departures are read); a
    bound that does not say so (NaN, a component at zero) leaves it to the
    departures themselves, which cost 18 us of a tiny problem's call."""
    if task.options.gamma_name != "shadow":
        return False
    largest = np.abs(gamma).max(axis=0).tolist()
    limit = 0.5 * SHADOW_SATURATION / task.options.member().shadow_scale
    return all(g <= limit * s for g, s in zip(largest, y_size.tolist(), strict=True))
