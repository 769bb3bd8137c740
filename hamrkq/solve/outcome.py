"""The :class:`~hamrkq.result.Solution` a finished RKQ-family run becomes.

:func:`solution` adds H at the nodes, the record of the options the run
actually used, the status and its message (:mod:`hamrkq.solve.messages`).
A run cut where its state contradicts a declared assumption is cut in
:mod:`hamrkq.solve.assumptions` first.
"""

from __future__ import annotations

import math
from typing import Any

from hamrkq.backends.numeric import numeric_of
from hamrkq.options import SolveOptions
from hamrkq.result import Solution, Status, owned
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.assumptions import Breach, breach_message
from hamrkq.solve.dispatch import MethodSpec, Task, uses_witness
from hamrkq.solve.messages import message

__all__ = ["solution"]

_STATUS_BY_CODE = {status.code: status for status in Status}

#: :func:`_options_record` made so far, by the options' id (with the options,
#: so that an id is not reused while it is kept).
_OPTIONS_RECORDS: dict[tuple, tuple[SolveOptions, dict[str, Any]]] = {}


def _options_record(o: SolveOptions, rk8: bool, backend: str, witness: bool) -> dict[str, Any]:
    """The record of the options a run used (``sol.options``), with None where
    the run's own values go (its span, initial state, tolerances, first step,
    output times, parameters), in the record's order.  Options are immutable
    and remembered (:meth:`SolveOptions.resolve`): made once per options and
    backend, not on every call (8 us of a tiny problem's 0.35 ms); the
    caller copies it."""
    key = (id(o), rk8, backend, witness)
    known = _OPTIONS_RECORDS.get(key)
    if known is not None and known[0] is o:
        return known[1]
    member = o.member()
    gamma_mode = o.gamma_name if rk8 else "off"
    nfev_step, njev_step = member.evaluations_per_step(gamma_mode, witness)
    record: dict[str, Any] = {
        "method": o.method,
        "backend": backend,
        "t_span": None,
        "y0": None,
        "atol": None,
        "rtol": None,
        "tolerance_rule": o.tolerance_rule,
        "safety": o.safety,
        "first_step": None,
        "first_step_rule": "given" if o.first_step is not None else "hairer-norsett-wanner",
        "max_step": None if math.isinf(o.max_step) else o.max_step,
        "max_steps": o.max_steps,
        "keep_every": o.keep_every,
        "t_eval": None,
        "parameters": None,
        "nfev_per_step": nfev_step,
        "njev_per_step": njev_step,
    }
    if rk8:
        record.update(
            quench=o.quench,
            quench_threshold=o.quench_threshold,
            global_error_estimate=o.gamma_name,
            z_method=member.quencher.name,
            z_substeps=member.z_substeps,
            quencher_precision="double-double" if o.double_double else "double",
            gamma_limit=None if math.isinf(o.gamma_limit) else o.gamma_limit,
            rounding_witness=witness,
        )
    if len(_OPTIONS_RECORDS) >= 256:  # options made on the fly (auto's reruns): bounded
        _OPTIONS_RECORDS.clear()
    _OPTIONS_RECORDS[key] = (o, record)
    return record


def solution(
    task: Task, spec: MethodSpec, out: RunOutput, backend: str, breach: Breach | None = None
) -> Solution:
    """The Solution of the run ``out`` of ``task`` (``breach``: where
    :func:`hamrkq.solve.assumptions.within_assumptions` ended it, for the
    message)."""
    o = task.options
    gamma_mode = o.gamma_name if spec.rk8 else "off"
    witness = spec.rk8 and uses_witness(task)
    stats = dict(out.stats)
    status = _STATUS_BY_CODE[out.status]
    if not out.t.size:
        energy = out.t.copy()  # (not the array t, owned below)
    elif backend == "numba":
        from hamrkq.backends import compiled

        energy = owned(compiled.energy(task.ham, out.t, out.y, task.params))  # a new array
    else:  # the same generated code as the compiled backend's, interpreted
        energy = numeric_of(task.ham).energy_as_compiled(out.t, out.y, task.params)
    options = dict(_options_record(o, spec.rk8, backend, witness))
    # the run's own values, in the record's places
    options["t_span"] = [task.t0, task.t_end]
    # the initial state, which a run with t_eval need not return as a node
    options["y0"] = task.y0.tolist()
    options["atol"] = task.atol.tolist()
    options["rtol"] = task.rtol.tolist()
    options["first_step"] = out.first_step
    times = task.requested_times
    options["t_eval"] = None if times is None else times.tolist()
    options["parameters"] = {
        s.name: float(v) for s, v in zip(task.ham.parameters, task.params, strict=True)
    }
    has_gamma = spec.rk8 and gamma_mode != "off"
    # The run's arrays are its own copies (hamrkq.rkq.driver), held by no
    # one else once the Solution is made: taken as they are, not copied
    # again (owned() copies nothing it cannot take).
    return Solution(
        t=owned(out.t),
        y=owned(out.y),
        energy=energy,
        status=status,
        message=message(status, out, task) if breach is None else breach_message(breach, out.t),
        method=o.method,
        n=task.ham.n,
        names=task.ham.names,
        # the task's tolerances are its own, written by no one: read-only
        # from here on, and the Solution's without a copy (5 us)
        atol=owned(task.atol),
        rtol=owned(task.rtol),
        stats=stats,
        options=options,
        z=None if out.z is None else owned(out.z),
        global_error=None if out.z is None else owned(out.y - out.z),
        gamma=owned(out.gamma) if has_gamma else None,
        quenched=None if out.quenched is None else owned(out.quenched),
    )
