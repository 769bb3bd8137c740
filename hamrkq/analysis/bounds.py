"""The tolerance and the paper's bounds, as functions of plain arrays.

Arrays are time-major, columns ``q`` then ``p``.  Errors follow the paper's
sign, numerical minus exact.  The bounds are those of J.S.C. Prentice,
arXiv:1111.6996, Section 3: if every component of the global error is at
most ``delta_k``, then to first order

- energy:     ``|H(y~) - H(y)| <= sum_k |dH/dy_k| delta_k``
- trajectory: ``||y~ - y||_2 <= sqrt(sum_k delta_k**2)`` (``sqrt(2) delta`` in 2-D)

with ``delta_k = max(atol_k, rtol_k |y_k|)`` at each node (or the paper's
scalar rule ``min_k max(atol, rtol |y_k|)`` when the run used
``tolerance_rule="prentice"``).

The trajectory bound is the paper's yardstick, not hamrkq's promise: hamrkq
promises ``|e_k| <= delta_k`` in every component, which
:func:`component_ratio` measures.  The Euclidean ratio can stay below 1 while
one component is many tolerances off, since a component whose tolerance is
small (``atol`` where it passes through zero) weighs nothing beside one with
a large ``rtol |y_k|``: on Kepler e = 0.85 the ratio read 0.47 while p1 was
5.8 tolerances off (found by QA).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hamrkq._tolerance import component_tolerance

__all__ = [
    "bound_ratio",
    "component_ratio",
    "energy_bound",
    "tolerance",
    "trajectory_bound",
    "trajectory_error",
]


def tolerance(y: np.ndarray, atol: Any, rtol: Any, rule: str = "componentwise") -> np.ndarray:
    """The tolerance ``delta`` at every node, shape (N, 2n).

    ``rule="componentwise"`` (hamrkq's default): ``max(atol_k, rtol_k |y_k|)``;
    ``rule="prentice"``: the paper's scalar ``min_k max(atol, rtol |y_k|)``,
    the same for every component of a node.
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    delta = component_tolerance(np.asarray(atol, dtype=float), np.asarray(rtol, dtype=float), y)
    if rule == "prentice":
        delta = np.broadcast_to(delta.min(axis=1, keepdims=True), y.shape).copy()
    return delta


def trajectory_error(error: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of ``error`` (N, 2n): the distance in phase space."""
    return np.sqrt(np.sum(np.square(np.asarray(error, dtype=float)), axis=1))


def trajectory_bound(delta: np.ndarray) -> np.ndarray:
    """``sqrt(sum_k delta_k**2)`` per node: ``sqrt(2) delta`` in the paper's case."""
    return trajectory_error(delta)


def energy_bound(gradient: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``sum_k |dH/dy_k| delta_k`` per node (the paper's ``(|q'| + |p'|) delta``)."""
    return np.sum(np.abs(np.asarray(gradient, dtype=float)) * delta, axis=1)


def bound_ratio(observed: np.ndarray, bound: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Largest ``observed / bound`` over the nodes, and the time where it occurs.

    Nodes where both are zero are skipped (the initial node); an error where the
    bound is zero counts as an infinite ratio.  Where there is no bound (NaN:
    a fixed-step run has no tolerance) there is no ratio (NaN; the table read
    "max inf", found by QA).
    """
    ratio = _ratio(np.abs(observed), np.asarray(bound, dtype=float))
    if np.all(np.isnan(ratio)):
        return float("nan"), float("nan")
    i = int(np.nanargmax(ratio))
    return float(ratio[i]), float(t[i])


def component_ratio(
    error: np.ndarray, delta: np.ndarray, t: np.ndarray
) -> tuple[float, float, int]:
    """Largest ``|error_k| / delta_k`` over nodes and components: hamrkq's
    promise (at most 1, 1.05 with the quencher's own error) measured.

    Parameters
    ----------
    error : ndarray, shape (N, 2n)
        Global error at every node.
    delta : ndarray, shape (N, 2n)
        The tolerance at every node (:func:`tolerance`).
    t : ndarray, shape (N,)
        The node times.

    Returns
    -------
    (ratio, t, component) : tuple of float, float, int
        The largest ratio, the time of its node and the index of its
        component; ``(nan, nan, -1)`` where no component has a tolerance.
        Zero over zero is skipped and an error where the tolerance is zero
        is an infinite ratio, as in :func:`bound_ratio`.
    """
    error = np.abs(np.atleast_2d(np.asarray(error, dtype=float)))
    ratio = _ratio(error, np.broadcast_to(np.asarray(delta, dtype=float), error.shape))
    if ratio.size == 0 or np.all(np.isnan(ratio)):
        return float("nan"), float("nan"), -1
    node, component = np.unravel_index(int(np.nanargmax(ratio)), ratio.shape)
    return float(ratio[node, component]), float(np.asarray(t)[node]), int(component)


def _ratio(observed: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """``observed / bound`` elementwise (``observed`` non-negative), where
    both ratios above read it: nan where both are zero (the initial node) or
    the bound is NaN (no tolerance), inf for an error where the bound is zero."""
    with np.errstate(divide="ignore", invalid="ignore"):
        unbounded = np.where((bound == 0) & (observed > 0), np.inf, np.nan)
        return np.where(bound > 0, observed / bound, unbounded)
