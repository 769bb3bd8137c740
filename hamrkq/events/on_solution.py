"""A run's dense output (:func:`dense_output`, on the backend the run used)
and what its events put on its :class:`~hamrkq.result.Solution`
(:func:`apply`: ``t_events``, ``y_events``, ``event_bound``, ``sol``, and a
terminal event's stop, ``Status.TERMINAL_EVENT``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from hamrkq._tolerance import component_tolerance
from hamrkq.backends.numeric import numeric_of
from hamrkq.events.crossings import Found, locate_all
from hamrkq.events.specs import EventSpec
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import DenseOutput, dense_tableaus, evaluate, prepare_work
from hamrkq.rkq.family import Member
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["apply", "dense_output"]


def dense_output(
    ham: Hamiltonian,
    member: Member,
    backend: str,
    params: np.ndarray,
    t: np.ndarray,
    y: np.ndarray,
    z: np.ndarray | None = None,
    tolerance: tuple | None = None,
    certificate: tuple | None = None,
) -> DenseOutput:
    """The continuous solution through the nodes ``(t, y)`` of a run of
    ``member`` on ``backend`` (``"numba"`` compiles the evaluation), stepped
    from the quencher track ``z`` at the same nodes where there is one
    (:mod:`hamrkq.rkq.dense`); ``tolerance``: the run's ``(atol, rtol,
    rule)``, ``certificate`` its ``(gamma, rounding, gamma_limit)``
    (:class:`~hamrkq.rkq.dense.DenseOutput`)."""
    tab = dense_tableaus(member)
    params = np.require(params, np.float64, ("C", "W"))
    t = np.array(t, dtype=np.float64)
    y = np.array(y, dtype=np.float64)
    recipe = (_rebuilt, (ham, member, backend, params, tolerance))
    if backend == "numba":
        from hamrkq.backends import compiled, extras

        rhs = compiled.compile_system(ham).rhs
        d = y.shape[1]
        work = prepare_work(d, tab)
        args = (rhs, tab, params, t, y, y, np.zeros(1, np.int64), np.zeros(1),
                np.ones(d), np.zeros(d), np.zeros(3), work, np.zeros((1, d)))  # fmt: skip
        fast = extras.compiled_helper(evaluate, ("rhs",), *args)
        return DenseOutput(t, y, z, rhs, tab, params, fast, recipe, tolerance, certificate)
    numeric = numeric_of(ham)

    def rhs(t, y, params, out):
        out[:] = numeric.rhs(t, y, params)

    return DenseOutput(t, y, z, rhs, tab, params, None, recipe, tolerance, certificate)


def _rebuilt(ham, member, backend, params, tolerance, t, y, z, certificate=None) -> DenseOutput:
    """A pickled :func:`dense_output` rebuilt (its recipe)."""
    return dense_output(ham, member, backend, params, t, y, z, tolerance, certificate)


def _cut(certificate: tuple | None, keep: np.ndarray) -> tuple | None:
    """A dense output's certificate for its nodes ``keep`` and a terminal
    event's state after them (Gamma and rounding of the last node kept,
    carried, as the solution's ``gamma``)."""
    if certificate is None:
        return None
    gamma, rounding, limit = certificate
    gamma = np.vstack([gamma[keep], gamma[keep][-1:]])
    if rounding is not None:
        rounding = np.vstack([rounding[keep], rounding[keep][-1:]])
    return gamma, rounding, limit


def _bound(sol: Solution, states: np.ndarray) -> np.ndarray:
    """RKQ's promise at the event states: delta_k = max(atol_k, rtol_k |y_k|)."""
    return component_tolerance(sol.atol, sol.rtol, states)


def apply(
    sol: Solution,
    specs: list[EventSpec],
    dense: DenseOutput,
    energy: Callable[[np.ndarray, np.ndarray], np.ndarray],
    z_dense: DenseOutput | None,
    keep_dense: bool,
    located: tuple[Found, int] | None = None,
) -> Solution:
    """Events (and ``sol``) on the solution; a terminal event ends it.
    ``located``: :func:`locate_all` on ``dense`` already."""
    found, stop_by = located if located is not None else locate_all(specs, dense)
    changes: dict[str, Any] = {}
    if stop_by >= 0:
        t_stop = found[stop_by][0][specs[stop_by].terminal - 1]
        key = 1.0 if dense.t[-1] >= dense.t[0] else -1.0
        stop_at = key * t_stop
        keep = key * sol.t < stop_at
        y_stop = dense.values_unchecked([t_stop])
        t_new = np.append(sol.t[keep], t_stop)
        y_new = np.vstack([sol.y[keep], y_stop])
        changes.update(t=t_new, y=y_new, energy=energy(t_new, y_new))
        if sol.z is not None and z_dense is not None:
            z_new = np.vstack([sol.z[keep], z_dense.values_unchecked([t_stop])])
            changes.update(z=z_new, global_error=y_new - z_new)
        if sol.gamma is not None:
            # Gamma is not re-stepped: the last node's estimate, carried.
            changes["gamma"] = np.vstack([sol.gamma[keep], sol.gamma[keep][-1:]])
        if sol.quenched is not None:
            changes["quenched"] = np.append(sol.quenched[keep], False)
        changes.update(
            status=Status.TERMINAL_EVENT,
            message=(
                f"stopped by terminal event {stop_by} ({specs[stop_by].label}) "
                f"at t = {float(t_stop)!r}"
            ),
        )
        if keep_dense:
            dense = dense.through(t_new, y_new, changes.get("z"), _cut(dense.certificate, keep))
    changes.update(
        t_events=[times for times, _ in found],
        y_events=[states for _, states in found],
        event_bound=[_bound(sol, states) for _, states in found],
        event_labels=[spec.label for spec in specs],
    )
    if keep_dense:
        changes["sol"] = dense
    return sol.replace(**changes)
