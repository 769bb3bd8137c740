"""Integrating a chunk of an ensemble: the one place where members run.

:func:`run_chunk` integrates the members of a :class:`~hamrkq.ensemble.request.Request`
and returns a :class:`ChunkResult` (what a chunk of members gives back, as
plain arrays that cross process boundaries cheaply); the local pools
and the Dask path all call it on :meth:`~hamrkq.ensemble.request.Request.subset`
slices.  It takes one of two paths, with the same numbers:

- :func:`run_batched`: every member in one call of the compiled batch loop
  (:func:`hamrkq.rkq.batch.run_members`): no Python runs between members, and
  the call releases the GIL, so a thread pool keeps every core busy.  Each
  member runs exactly as :func:`hamrkq.solve` would run it alone (the same
  validated options, :func:`hamrkq.solve.prepare`; the same start and step
  loop), so its numbers are the same bits.  It applies to an RKQ-family
  method on the compiled backend, with options that are the same for every
  member, and without events or dense output.  Where ``y0`` decides an
  option (``method="auto"``'s member from the tolerance and the state's
  size, and whether the rounding witness runs), :func:`batch_groups` splits
  the chunk into groups that agree, each batched.  A member that fails is
  run again alone for its message, and so is one whose estimate of Gamma
  grew exponentially, which ``solve`` alone runs again with the rounding
  witness.
- :func:`solve_members`: :func:`hamrkq.solve` once per member, for
  everything else (the baselines, the interpreted backend).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hamrkq.backends.numeric import numeric_of
from hamrkq.ensemble.request import Request
from hamrkq.result import Status
from hamrkq.rkq.auto_rules import (
    SHADOW_SATURATION,
    auto_member_per_row,
    auto_tolerance_per_row,
)
from hamrkq.rkq.batch import allocate_batch, run_members
from hamrkq.rkq.layout import allocate_output
from hamrkq.rkq.witness_rules import needs_witness_per_row
from hamrkq.solve import prepare, solve
from hamrkq.solve.auto import reruns_with_witness
from hamrkq.solve.dispatch import (
    integration,
    run_rk,
    witness_rule_arguments,
)
from hamrkq.solve.growth import MIN_GROWTH_STEPS
from hamrkq.solve.member_rules import folded_growth_per_row, witness_rerun_needed_per_row
from hamrkq.solve.shadow import shadow_departures
from hamrkq.symbolic.assumptions import declares_checked
from hamrkq.symbolic.kinks import kinks

__all__ = [
    "BUFFER_ROWS",
    "STATS",
    "ChunkResult",
    "batch_groups",
    "decided_by_y0",
    "run_batched",
    "run_chunk",
    "solve_members",
]

#: Per-member counters kept by an ensemble (0 where a method has no such counter).
STATS = ("steps", "rejected", "quenches", "nfev", "njev")


@dataclass(frozen=True, eq=False)
class ChunkResult:
    """The outcome of :func:`run_chunk` for ``m`` members, as arrays.

    ``y`` is (m, T, 2n), NaN at kept times a failed member never reached;
    ``t_last`` the last time each member reached; ``status`` the
    :class:`~hamrkq.result.Status` codes; ``messages`` the message of every
    member that failed, by index in the chunk; ``stats`` (m, len(STATS)).
    """

    start: int
    y: np.ndarray
    t_last: np.ndarray
    status: np.ndarray
    max_global_error: np.ndarray
    energy0: np.ndarray
    energy_drift: np.ndarray
    stats: np.ndarray
    messages: dict[int, str]

    @property
    def size(self) -> int:
        """Number of members."""
        return int(self.status.size)


#: Nodes buffered per member between folds when only the last state is kept.
BUFFER_ROWS = 256
#: The kinds of the function arguments of run_members.
_KINDS = ("rhs", "rhs_jvp", "jac", "energy")


def run_chunk(request: Request) -> ChunkResult:
    """Integrate every member of ``request``; one failure never stops the others.

    Members whose options resolve differently at their ``y0`` (``auto``'s
    member, the rounding witness: :func:`batch_groups`) run as groups, each
    through the batch loop.
    """
    prepared = _batch_prepared(request)
    if prepared is None:
        return solve_members(request)
    groups = batch_groups(request, prepared)
    if len(groups) > 1:
        result = _empty_result(request)
        for indices in groups:
            _put(result, indices, run_chunk(request.take(indices)))
        return result
    return _batch(request, prepared)


def batch_groups(request: Request, prepared: Any = None) -> list[np.ndarray]:
    """The members' indices, grouped by what their ``y0`` decides of the
    options (:func:`decided_by_y0`); one group where the batch loop cannot
    be used anyway.  ``prepared``: member 0's :func:`hamrkq.solve.prepare`,
    if already made."""
    if prepared is None:
        prepared = _batch_prepared(request)
    if prepared is None:
        return [np.arange(request.size)]
    auto, witness = decided_by_y0(prepared, request.ham.dim, request.y0)
    # one group per distinct pair, in the order of each pair's first member
    keys = np.char.add(auto, np.where(witness, "+witness", ""))
    _, first, group_of = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first)
    return [np.flatnonzero(group_of == group) for group in order]


def decided_by_y0(prepared: Any, dim: int, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What each member's ``y0`` (the rows of ``states``) decides of options
    that are otherwise member 0's ``prepared``: ``method="auto"``'s member
    (from the tolerance over the state's size,
    :func:`hamrkq.rkq.auto_rules.auto_tolerance`; "" for another method)
    and whether the rounding witness runs (each component's tolerance against
    its size, :func:`hamrkq.rkq.witness_rules.needs_witness`, with
    :func:`hamrkq.solve.dispatch.witness_rule_arguments`; False where the
    estimate cannot run it).  One array over the members for each, in
    whole-array operations: the same decisions as those functions member by
    member (``tests/test_ensemble_rules.py``)."""
    task = prepared.task
    m = states.shape[0]
    auto = np.full(m, "")
    if prepared.requested.method == "auto":
        auto = auto_member_per_row(dim, auto_tolerance_per_row(task.atol, task.rtol, states))
    witness = np.zeros(m, dtype=bool)
    rule = witness_rule_arguments(task)
    if rule is not None:
        witness = needs_witness_per_row(task.atol, task.rtol, states, **rule)
    return auto, witness


def _batch_prepared(request: Request) -> Any:
    """Member 0's :func:`hamrkq.solve.prepare` where the batch loop applies
    to the request (an RKQ-family method, compiled, in double, without
    events or dense output), else None."""
    if request.size == 0:
        return None
    kwargs = request.member_kwargs(0)
    if kwargs.get("events") or kwargs.get("dense_output"):
        return None
    if declares_checked((*request.ham.q, *request.ham.p)) or kinks(request.ham.H):
        # solve checks every node against the symbols' declared assumptions
        # (Status.ASSUMPTION_VIOLATED) and the kinks of H (hamrkq.solve.smoothness);
        # the batch loop keeps no nodes to check
        return None
    prepared = prepare(request.ham, **kwargs)
    task = prepared.task
    if prepared.spec.run is not run_rk or prepared.backend != "numba" or task.stop:
        return None
    if task.options.double_double:  # the batch loop passes rhs_jvp, not rhs_dd
        return None
    return prepared


def _empty_result(request: Request) -> ChunkResult:
    """A result for every member of ``request``, nothing run yet."""
    m, dim = request.size, request.ham.dim
    return ChunkResult(
        request.start,
        np.full((m, request.times.size, dim), np.nan),
        np.full(m, np.nan),
        np.zeros(m, dtype=np.int8),
        np.full(m, np.nan),
        np.full(m, np.nan),
        np.full(m, np.nan),
        np.zeros((m, len(STATS)), dtype=np.int64),
        {},
    )


def _put(result: ChunkResult, indices: np.ndarray, part: ChunkResult) -> None:
    """A group's results (``part``) into the members ``indices`` of ``result``."""
    for name in ("y", "t_last", "status", "max_global_error", "energy0", "energy_drift", "stats"):
        getattr(result, name)[indices] = getattr(part, name)
    for k, message in part.messages.items():
        result.messages[int(indices[k])] = message


def run_batched(request: Request, prepared: Any = None) -> ChunkResult | None:
    """The members of ``request`` through the batch loop, or None where it
    does not apply (see the module docstring) or the members' options differ
    (:func:`batch_groups`).  ``prepared``: member 0's
    :func:`hamrkq.solve.prepare`, if already made."""
    if prepared is None:
        prepared = _batch_prepared(request)
    if prepared is None or len(batch_groups(request, prepared)) > 1:
        return None
    return _batch(request, prepared)


def _batch(request: Request, prepared: Any) -> ChunkResult:
    """Every member of ``request`` through the batch loop, with member 0's
    ``prepared`` options (the same for every member: :func:`batch_groups`)."""
    task = prepared.task
    from hamrkq.backends import compiled, extras

    run = integration(task, "numba")
    system = compiled.compile_system(request.ham)
    times = request.times
    rows = times.size if request.t_eval is not None else BUFFER_ROWS
    out = allocate_output(rows, request.ham.dim, run.member.use_z)
    params = request.params.reshape(request.size, -1)
    kept_span = (times[0], times[-1]) if request.t_eval is not None else (task.t0, task.t_end)
    batch = allocate_batch(request.y0, params, task.t0, times.size, out, kept_span)
    args = (
        system.rhs,
        # rhs_jvp and jac where the run's estimate of Gamma calls them, else stand-ins
        run.functions.tangent,
        run.functions.jac,
        system.energy,
        run.inputs,
        run.tableaus,
        run.config,
        run.state,
        run.work,
        batch,
    )
    kernel = extras.compiled_helper(run_members, _KINDS, *args)
    with np.errstate(all="ignore"):
        kernel(*args)
    result = ChunkResult(
        request.start,
        batch.y,
        batch.t_last,
        batch.status.astype(np.int8),
        batch.max_error,
        batch.energy0,
        batch.energy_drift,
        batch.stats,
        {},
    )
    # A member that failed is solved alone: for its message, and because
    # method="auto" may run it again with more quencher steps, which the batch
    # loop does not (solve alone is the definition of a member's result); so
    # is one that succeeded where solve alone would not return that run
    # (a saturated shadow, or a rerun with the rounding witness).
    again = (batch.status != Status.SUCCESS.code) | _runs_again_alone(batch, task, request)
    for i in np.flatnonzero(again).tolist():
        _store(result, request, i, solve(request.ham, **request.member_kwargs(i)))
    return result


def _runs_again_alone(batch: Any, task: Any, request: Request) -> np.ndarray:
    """Per member, whether it succeeded in the batch loop where ``solve``
    alone would not return that run: its shadow track left the linear
    regime (:func:`hamrkq.solve.shadow.within_linear_shadow`), or its
    estimate of Gamma grew so that ``solve`` runs it again with the rounding
    witness (:func:`hamrkq.solve.auto.witness_rerun_needed`); from the maxima
    the batch loop folded (members that succeeded keep nodes over the
    interval ``batch.middle`` was taken from)."""
    again = np.zeros(batch.status.shape[0], dtype=bool)
    if task.options.gamma_name not in ("shadow", "tangent"):
        return again
    # the members that succeeded, decided at once (hamrkq.solve.member_rules)
    ok = np.flatnonzero(batch.status == Status.SUCCESS.code)
    if ok.size == 0:
        return again
    y_size = batch.y_size[ok]
    # one row of gamma per member, each with its own row of y_size (the
    # component scales of each row: hamrkq.rkq.scales.component_scales)
    departure = shadow_departures(task, batch.gamma_to_end[ok], y_size)
    if departure is not None:
        again[ok] = departure > SHADOW_SATURATION
    if reruns_with_witness(task):
        steps = batch.stats[ok, 0]
        nodes = request.times.size if task.t_eval is not None else steps + 1
        # as solve.growth.growth: no reading of the growth from a short run
        enough = (steps >= MIN_GROWTH_STEPS) & (nodes >= 3)
        growth = folded_growth_per_row(
            task, batch.gamma_to_middle[ok], batch.gamma_to_end[ok], y_size
        )
        factors = np.where(enough, growth, 1.0)
        early = folded_growth_per_row(
            task, batch.gamma_to_early[ok], batch.gamma_to_end[ok], y_size
        )
        early = np.where(enough, early, 1.0)
        again[ok] |= witness_rerun_needed_per_row(
            task, request.y0[ok], y_size, factors, steps, batch.step_range[ok], early
        )
    return again


def solve_members(request: Request) -> ChunkResult:
    """Integrate every member of ``request``; one failure never stops the others.

    Each member is integrated by :func:`hamrkq.solve` with the request's
    options, so that it equals the same member solved alone, bit for bit.
    """
    result = _empty_result(request)
    for i in range(request.size):
        _store(result, request, i, solve(request.ham, **request.member_kwargs(i)))
    return result


def _store(result: ChunkResult, request: Request, i: int, sol: Any) -> None:
    """Member ``i``'s row of ``result`` from its Solution (``solve`` alone)."""
    if sol.status is Status.INTERRUPTED:
        # solve turns Ctrl-C into a status; here it must stop the whole
        # ensemble, not just the member that was running.
        raise KeyboardInterrupt
    result.status[i] = sol.status.code
    result.messages.pop(i, None)
    if not sol.success:
        result.messages[i] = sol.message
    result.stats[i] = [int(sol.stats.get(name, 0)) for name in STATS]
    result.y[i] = np.nan
    result.max_global_error[i] = np.nan
    result.energy0[i] = result.energy_drift[i] = np.nan
    result.t_last[i] = _time_reached(request, sol)
    if sol.t.size == 0:
        return
    if request.t_eval is not None:
        result.y[i, : sol.t.size] = sol.y
    else:
        # A member that stopped short of t_end keeps its last state too
        # (t_last says when), as solve keeps the nodes computed so far.
        result.y[i, 0] = sol.y[-1]
    if sol.global_error is not None:
        result.max_global_error[i] = float(np.max(np.abs(sol.global_error)))
    result.energy0[i] = _initial_energy(request, i, sol)
    result.energy_drift[i] = float(np.max(np.abs(sol.energy - result.energy0[i])))


def _time_reached(request: Request, sol: Any) -> float:
    """The last time a member's run reached: where a terminal event ended
    it (its latest root in the direction of the run: with ``t_eval`` the
    last row is an output time before it, found by QA reading 0.0 where the
    event was at 1.43), else its last node (NaN without one)."""
    if sol.status is Status.TERMINAL_EVENT and sol.t_events:
        roots = np.concatenate([np.ravel(times) for times in sol.t_events])
        if roots.size:
            direction = 1.0 if request.t_span[1] >= request.t_span[0] else -1.0
            return float(direction * np.max(direction * roots))
    return float(sol.t[-1]) if sol.t.size else np.nan


def _initial_energy(request: Request, i: int, sol: Any) -> float:
    """H at the member's initial state: the first node when that is t0 (the
    usual case), else evaluated once (``t_eval`` need not contain t0)."""
    t0 = request.t_span[0]
    if sol.t[0] == t0:
        return float(sol.energy[0])
    energy = numeric_of(request.ham).energy(
        np.array([t0]), request.y0[i : i + 1], request.params[i]
    )
    return float(np.asarray(energy).ravel()[0])
