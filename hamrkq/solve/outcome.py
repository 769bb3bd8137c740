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
from hamrkq.result import Solution, Status, owned
from hamrkq.rkq.driver import RunOutput
from hamrkq.solve.assumptions import Breach, breach_message
from hamrkq.solve.dispatch import MethodSpec, Task, member_of, uses_witness
from hamrkq.solve.messages import message

__all__ = ["solution"]

_STATUS_BY_CODE = {status.code: status for status in Status}


def solution(
    task: Task, spec: MethodSpec, out: RunOutput, backend: str, breach: Breach | None = None
) -> Solution:
    """The Solution of the run ``out`` of ``task`` (``breach``: where
    :func:`hamrkq.solve.assumptions.within_assumptions` ended it, for the
    message)."""
    o = task.options
    member = member_of(task)
    gamma_mode = o.gamma_name if spec.rk8 else "off"
    witness = spec.rk8 and uses_witness(task)
    nfev_step, njev_step = member.evaluations_per_step(gamma_mode, witness)
    stats = dict(out.stats)
    status = _STATUS_BY_CODE[out.status]
    if not out.t.size:
        energy = out.t.copy()  # (not the array t, owned below)
    elif backend == "numba":
        from hamrkq.backends import compiled

        energy = owned(compiled.energy(task.ham, out.t, out.y, task.params))  # a new array
    else:  # the same generated code as the compiled backend's, interpreted
        energy = numeric_of(task.ham).energy_as_compiled(out.t, out.y, task.params)
    options: dict[str, Any] = {
        "method": o.method,
        "backend": backend,
        "t_span": [task.t0, task.t_end],
        # the initial state, which a run with t_eval need not return as a node
        "y0": task.y0.tolist(),
        "atol": task.atol.tolist(),
        "rtol": task.rtol.tolist(),
        "tolerance_rule": o.tolerance_rule,
        "safety": o.safety,
        "first_step": out.first_step,
        "first_step_rule": "given" if o.first_step is not None else "hairer-norsett-wanner",
        "max_step": None if math.isinf(o.max_step) else o.max_step,
        "max_steps": o.max_steps,
        "keep_every": o.keep_every,
        "t_eval": None if task.requested_times is None else task.requested_times.tolist(),
        "parameters": {
            s.name: float(v) for s, v in zip(task.ham.parameters, task.params, strict=True)
        },
        "nfev_per_step": nfev_step,
        "njev_per_step": njev_step,
    }
    if spec.rk8:
        options.update(
            quench=o.quench,
            quench_threshold=o.quench_threshold,
            global_error_estimate=o.gamma_name,
            z_method=member.quencher.name,
            z_substeps=member.z_substeps,
            quencher_precision="double-double" if o.double_double else "double",
            gamma_limit=None if math.isinf(o.gamma_limit) else o.gamma_limit,
            rounding_witness=witness,
        )
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
        atol=task.atol,
        rtol=task.rtol,
        stats=stats,
        options=options,
        z=None if out.z is None else owned(out.z),
        global_error=None if out.z is None else owned(out.y - out.z),
        gamma=owned(out.gamma) if has_gamma else None,
        quenched=None if out.quenched is None else owned(out.quenched),
    )
