"""Integrating a chunk of an ensemble: the one place where members run.

:func:`run_chunk` integrates the members of a :class:`~hamrkq.ensemble.request.Request`
and returns a :class:`~hamrkq.ensemble.request.ChunkResult`; the local pools
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
  run again alone for its message.
- :func:`solve_members`: :func:`hamrkq.solve` once per member, for
  everything else (the baselines, the interpreted backend).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hamrkq.backends.numeric import numeric_of
from hamrkq.ensemble.request import STATS, ChunkResult, Request
from hamrkq.result import Status
from hamrkq.rkq.auto_rules import auto_member, auto_tolerance
from hamrkq.rkq.batch import allocate_batch, run_members
from hamrkq.rkq.layout import allocate_output
from hamrkq.rkq.witness_rules import needs_witness
from hamrkq.solve import prepare, solve
from hamrkq.solve.dispatch import integration, run_rk, uses_witness

__all__ = ["BUFFER_ROWS", "batch_groups", "run_batched", "run_chunk", "solve_members"]

#: Nodes buffered per member between folds when only the last state is kept.
BUFFER_ROWS = 256
#: The kinds of the function arguments of run_members.
_KINDS = ("rhs", "rhs_jvp", "jac", "energy")


def run_chunk(request: Request) -> ChunkResult:
    """Integrate every member of ``request``; one failure never stops the others.

    Members whose options resolve differently at their ``y0`` (``auto``'s
    member, the rounding witness: :func:`batch_groups`) run as groups, each
    through the batch loop where it applies.
    """
    groups = batch_groups(request)
    if len(groups) > 1:
        result = _empty_result(request)
        for indices in groups:
            _put(result, indices, run_chunk(request.take(indices)))
        return result
    batched = run_batched(request)
    return batched if batched is not None else solve_members(request)


def batch_groups(request: Request) -> list[np.ndarray]:
    """The members' indices, grouped by what their ``y0`` decides of the
    options (``method="auto"``'s member by
    :func:`hamrkq.rkq.auto_rules.auto_tolerance`, and whether the rounding
    witness runs, :func:`hamrkq.rkq.witness_rules.needs_witness`); one group
    where the batch loop cannot be used anyway."""
    everyone = [np.arange(request.size)]
    if request.size < 2:
        return everyone
    kwargs = request.member_kwargs(0)
    if kwargs.get("events") or kwargs.get("dense_output"):
        return everyone
    prepared = prepare(request.ham, **kwargs)
    if prepared.spec.run is not run_rk or prepared.backend != "numba":
        return everyone
    task, dim = prepared.task, request.ham.dim
    groups: dict[tuple, list[int]] = {}
    for i, y0 in enumerate(request.y0):
        auto = None
        if prepared.requested.method == "auto":
            auto = auto_member(dim, auto_tolerance(task.atol, task.rtol, y0))
        witness = None
        if task.options.gamma_name == "shadow":
            witness = needs_witness(task.atol, task.rtol, y0)
        groups.setdefault((auto, witness), []).append(i)
    return [np.array(indices) for indices in groups.values()]


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


def run_batched(request: Request) -> ChunkResult | None:
    """The members of ``request`` through the batch loop, or None where it
    does not apply (see the module docstring)."""
    if request.size == 0:
        return None
    kwargs = request.member_kwargs(0)
    if kwargs.get("events") or kwargs.get("dense_output"):
        return None
    prepared = prepare(request.ham, **kwargs)
    task = prepared.task
    if prepared.spec.run is not run_rk or prepared.backend != "numba" or task.stop:
        return None
    if task.options.double_double:  # the batch loop passes rhs_jvp, not rhs_dd
        return None
    if not _same_options(prepared, request):
        return None
    from hamrkq.backends import compiled, extras

    run = integration(task, "numba")
    system = compiled.compile_system(request.ham)
    times = request.times
    rows = times.size if request.t_eval is not None else BUFFER_ROWS
    out = allocate_output(rows, request.ham.dim, run.member.use_z)
    params = request.params.reshape(request.size, -1)
    batch = allocate_batch(request.y0, params, task.t0, times.size, out)
    args = (
        system.rhs,
        system.rhs_jvp,
        system.jac,
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
    # loop does not (solve alone is the definition of a member's result).
    for i in np.flatnonzero(batch.status != Status.SUCCESS.code).tolist():
        _store(result, request, i, solve(request.ham, **request.member_kwargs(i)))
    return result


def _same_options(prepared, request: Request) -> bool:
    """Whether every member resolves to the task's options: whether the
    rounding witness runs depends on each component's tolerance and size at
    ``y0`` (:func:`hamrkq.rkq.witness_rules.needs_witness`), and so does
    ``method="auto"``'s member (:func:`hamrkq.rkq.auto_rules.auto_tolerance`),
    which can differ between members."""
    task = prepared.task
    if prepared.requested.method == "auto":
        dim = request.ham.dim
        chosen = auto_member(dim, auto_tolerance(task.atol, task.rtol, request.y0[0]))
        if any(
            auto_member(dim, auto_tolerance(task.atol, task.rtol, y0)) != chosen
            for y0 in request.y0
        ):
            return False
    # The rounding witness runs by each member's tolerance and y0 too.
    witness = uses_witness(task)
    if task.options.gamma_name == "shadow" and any(
        needs_witness(task.atol, task.rtol, y0) != witness for y0 in request.y0
    ):
        return False
    return True


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
    result.t_last[i] = result.max_global_error[i] = np.nan
    result.energy0[i] = result.energy_drift[i] = np.nan
    if sol.t.size == 0:
        return
    result.t_last[i] = sol.t[-1]
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
