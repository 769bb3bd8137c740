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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hamrkq._tolerance import component_tolerance

__all__ = ["bound_ratio", "energy_bound", "tolerance", "trajectory_bound", "trajectory_error"]


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
    observed, bound = np.abs(observed), np.asarray(bound, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        unbounded = np.where((bound == 0) & (observed > 0), np.inf, np.nan)
        ratio = np.where(bound > 0, observed / bound, unbounded)
    if np.all(np.isnan(ratio)):
        return float("nan"), float("nan")
    i = int(np.nanargmax(ratio))
    return float(ratio[i]), float(t[i])
