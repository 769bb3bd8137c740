"""Drive the step loop: allocate, start, run in chunks, collect the nodes.

:class:`Integration` owns the arrays of one run (:mod:`hamrkq.rkq.layout`)
and calls the kernel's ``advance`` (interpreted, or compiled by
:mod:`hamrkq.backends.compiled`) in chunks of ``budget`` step attempts, so that
progress can be reported and Ctrl-C ends the run with the nodes kept so far.
:func:`hamrkq.solve` and the SciPy solver :class:`hamrkq.RK34Q8` both use it.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import MISSING, dataclass, replace
from dataclasses import fields as dataclass_fields
from typing import Any, NamedTuple

import numpy as np

from hamrkq._floats import writable_float64
from hamrkq.rkq import arith, loop
from hamrkq.rkq.config import NATIVE_DOUBLE, Settings, kernel_config
from hamrkq.rkq.family import Member
from hamrkq.rkq.layout import (
    CHECKPOINTS,
    CHK0,
    GAMMA_OFF,
    GAMMA_PAPER,
    GAMMA_TANGENT,
    GMAX,
    RET_BUFFER_FULL,
    RET_DONE,
    ST_INTERRUPTED,
    ST_RUNNING,
    STATE,
    YMAX,
    Inputs,
    Output,
    U,
    allocate_output,
    allocate_work,
    new_state,
)

__all__ = ["Integration", "KernelFunctions", "RunOutput", "largest_over_nodes"]

#: Step attempts per call of the kernel: progress and Ctrl-C are seen between calls.
BUDGET = 2000
#: While a run waits for compiled code (``upgrade``), the interpreted kernel's
#: chunks are sized to last about this long, so the switch comes soon after
#: the code is ready (an interpreted step of a 36-dimensional system takes
#: about 9 ms: 2000 of them would be 18 s).
UPGRADE_CHECK_SECONDS = 0.05
#: The status of a run that ``stop`` ended (Status.TERMINAL_EVENT's code).
ST_STOPPED = 8
#: Output rows of the first buffer; later buffers double up to MAX_BUFFER_ROWS.
FIRST_BUFFER_ROWS = 4096
MAX_BUFFER_ROWS = 1 << 16


class KernelFunctions(NamedTuple):
    """The functions the kernel calls, and the kernel itself.

    ``rhs(t, y, params, out)``, ``tangent(t, y, params, v, out, dout, JM)``,
    ``jac(t, y, params, out)`` and ``advance`` (:func:`hamrkq.rkq.loop.advance`
    or its compiled form).
    """

    rhs: Callable
    tangent: Callable
    jac: Callable
    advance: Callable


def python_functions(rhs: Callable, jac: Callable) -> KernelFunctions:
    """Interpreted kernel functions from in-place ``rhs`` and ``jac``."""

    def tangent(t, y, params, v, out, dout, JM):
        rhs(t, y, params, out)
        jac(t, y, params, JM)
        arith.matvec(JM, v, dout)

    return KernelFunctions(rhs, tangent, jac, loop.advance)


@dataclass(frozen=True)
class RunOutput:
    """Raw result of a run: the kept nodes and the final counters."""

    t: np.ndarray
    y: np.ndarray
    z: np.ndarray | None
    gamma: np.ndarray | None
    quenched: np.ndarray | None
    status: int  # a Status code
    t_last: float  # time of the last accepted node
    h_fail: float  # the step size that failed (underflow, non-finite)
    first_step: float
    max_ratio: float  # largest attainability ratio seen
    floor_ratio: float  # the rounding witness's part of the ratio that ended the run
    bad_component: int  # first non-finite component found, or -1
    stats: dict
    projected: float = 0.0  # |Gamma| / delta projected to t_end (status ST_ABANDONED)
    #: The shadow's departure from the quencher over the orbit's size that
    #: ended the run (hamrkq.rkq.auto_rules.SHADOW_SATURATION), or 0.
    saturated: float = 0.0
    #: Each component's largest ``|y|`` and ``|Gamma|`` over every node of the
    #: run, kept or not, and the largest ``|Gamma|`` up to each checkpoint
    #: (rows by ``hamrkq.rkq.layout.checkpoint_fractions``; those the run did
    #: not pass are NaN): what the rules after a run read when the returned
    #: rows are thinned (``thinned``: ``t_eval`` or ``keep_every``).
    y_max: np.ndarray | None = None
    gamma_max: np.ndarray | None = None
    gamma_checkpoints: np.ndarray | None = None
    thinned: bool = False
    #: Where the run's promise failed at an event state, which ended it
    #: (:class:`hamrkq.solve.event_check.EventFailure`), or None.
    event_failure: object | None = None
    #: The quencher's rounding at each returned node, modelled and measured
    #: (:attr:`hamrkq.rkq.layout.Output.rounding`), or None.
    rounding: np.ndarray | None = None
    #: The ratio of the largest free step to the smallest
    #: (:func:`hamrkq.rkq.loop.step_range`).
    step_range: float = 1.0
    #: Where the run ended at an output time inside a step: the value's own
    #: rounding alone over the tolerance there
    #: (:func:`hamrkq.rkq.certify.stored_share`), else 0.
    stored_ratio: float = 0.0

    def rows(self, kept: Any) -> RunOutput:
        """The same run with only the returned nodes ``kept`` (a slice, an
        index array or a mask): what a check after the run returns when it
        ends the run early."""

        def cut(a):
            return None if a is None else a[kept]

        return replace(
            self, t=self.t[kept], y=self.y[kept], z=cut(self.z), gamma=cut(self.gamma),
            quenched=cut(self.quenched), rounding=cut(self.rounding),
        )  # fmt: skip

    @functools.cached_property
    def largest_state(self) -> np.ndarray:
        """Each component's largest ``|y_k|`` over the run's nodes (zeros
        for none; over every node of the run where the returned rows are
        thinned), read-only: the size the rules after a run measure
        against, computed once (a call of :func:`hamrkq.solve` asked it
        twice or more; :func:`hamrkq.solve.shadow.largest_state`)."""
        return largest_over_nodes(self)

    @property
    def at_rounding_floor(self) -> bool:
        """Whether rounding ended the run: the witness's part is at least half
        the ratio that stopped it (double precision's floor for the orbit)."""
        return self.floor_ratio >= 0.5 * self.max_ratio


def largest_over_nodes(out: Any) -> np.ndarray:
    """Each component's largest ``|y_k|`` over the nodes of a run ``out``
    (a :class:`RunOutput`, or anything with its ``y``, ``thinned`` and
    ``y_max``): zeros for none, over every node of the run where the
    returned rows are thinned; read-only."""
    kept = np.abs(out.y).max(axis=0) if out.y.shape[0] else np.zeros(out.y.shape[1])
    if out.thinned and out.y_max is not None:
        # the kernel's maximum over every node, kept or not
        kept = np.maximum(kept, out.y_max)
    kept.setflags(write=False)
    return kept


#: :class:`RunOutput`'s fields in their order, with their defaults
#: (:data:`dataclasses.MISSING` for those without one; none has a factory).
_RUN_OUTPUT_FIELDS = {f.name: f.default for f in dataclass_fields(RunOutput)}
assert all(f.default_factory is MISSING for f in dataclass_fields(RunOutput))


def _run_output(values: dict[str, Any]) -> RunOutput:
    """``RunOutput(**values)`` without the frozen dataclass's ``__init__``,
    which stores each of its 23 fields through ``object.__setattr__`` (3 us
    of every run): the same instance dictionary, its fields in their order,
    the defaults where ``values`` has none.  ``values`` must hold every
    field without a default (``tests/test_per_call.py`` compares a run's
    with ``dataclasses.replace``, which calls ``__init__``)."""
    out = object.__new__(RunOutput)
    object.__setattr__(out, "__dict__", {**_RUN_OUTPUT_FIELDS, **values})
    return out


#: A new run's state record at t = 0 (:func:`~hamrkq.rkq.layout.new_state`),
#: as its bytes: every run copies them and views the copy as the record
#: (NumPy copies a record array field by field, seven times slower), and
#: where its ``t`` is in them.
_STATE_AT_ZERO = new_state(0.0).tobytes()
_STATE_T = STATE.fields["t"][1]


def _floats(values: Any) -> np.ndarray:
    return np.array(values, dtype=np.float64, order="C", copy=True)


#: Positions of the state record's fields in ``state.item(0)``: the fields
#: read after a run, read at once (a record's field costs as much as the
#: whole tuple).
_AT = {name: k for k, name in enumerate(STATE.names)}


class Integration:
    """One RKQ (or pair-only) integration from ``(t0, y0)`` to ``t_end``.

    Parameters
    ----------
    functions : KernelFunctions
    member : Member
        The pair and the quencher (:mod:`hamrkq.rkq.family`).
    params, t0, y0, t_end, atol, rtol
        The problem, validated (``atol``/``rtol`` arrays of ``y0.size``).
    settings : Settings
    upgrade : callable, optional
        ``upgrade() -> KernelFunctions | None``, asked between chunks while
        it returns None: functions to continue with (the compiled kernel
        once a background compile has finished,
        :mod:`hamrkq.backends.background`).  They must compute the same bits
        as ``functions``; the run's arrays are shared, so the switch is
        invisible in the result.  Until then chunks are short
        (:data:`UPGRADE_CHECK_SECONDS`).
    """

    def __init__(
        self,
        functions: KernelFunctions,
        member: Member,
        params: np.ndarray,
        t0: float,
        y0: np.ndarray,
        t_end: float,
        atol: np.ndarray,
        rtol: np.ndarray,
        settings: Settings,
        upgrade: Callable[[], KernelFunctions | None] | None = None,
    ):
        self.functions = functions
        self.upgrade = upgrade
        #: Steps accepted before the switch to ``upgrade``'s functions (all
        #: of them if it never came); 0 without ``upgrade``.
        self.steps_before_upgrade = 0
        #: Seconds spent in ``upgrade`` (loading the compiled code), and in
        #: the compiled kernel loading or compiling its code for a call.
        self.upgrade_s = 0.0
        self.member = member
        self.t0, self.t_end = float(t0), float(t_end)
        self.settings = settings
        use_teval = settings.t_eval is not None
        params = writable_float64(params)
        witness_params = np.empty_like(params)
        arith.nudge(params, witness_params)
        # (by position, in Inputs' order: keywords cost twice as much)
        self.inputs = Inputs(
            params,
            _floats(atol),
            _floats(rtol),
            # (np.empty(0): the same empty float64 array as _floats([]))
            _floats(settings.t_eval) if use_teval else np.empty(0),
            witness_params,
        )
        self.tableaus = member.tableaus
        gamma = settings.gamma if member.use_z else GAMMA_OFF
        relative = int(self.inputs.rtol.max(initial=0.0) > 0.0)
        #: Whether the estimate of Gamma counts roundoff steps (the
        #: configuration's gamma_mode, known here without reading the record).
        self._roundoff_counted = gamma in (GAMMA_TANGENT, GAMMA_PAPER)
        self.config = kernel_config(
            member, settings, gamma, int(use_teval), relative, self.t0, self.t_end
        )
        # the same record as new_state(t0), from its bytes with t0 packed in
        # (a record field's store costs as much again as the copy)
        state = bytearray(_STATE_AT_ZERO)
        NATIVE_DOUBLE.pack_into(state, _STATE_T, self.t0)
        # (a writable buffer: STATE's alignment is 1, as CONFIG's)
        self.state = np.frombuffer(state, dtype=STATE)
        y0 = _floats(y0)
        self.work = allocate_work(y0, self.tableaus.b.shape[0], self.tableaus.bz.shape[0])
        self.integrate_s = 0.0

    # -- the run -----------------------------------------------------------------

    @property
    def record(self):
        """The state record (``record["t"]``, ``record["steps"]``, ...)."""
        return self.state[0]

    def advance(self, out: Output, budget: int = BUDGET) -> int:
        """Run the kernel once; returns its code (``RET_*``).  The first call
        starts the run: it writes the first node (unless ``t_eval`` skips
        it), evaluates ``f(t0, y0)`` and chooses the first step
        (:func:`hamrkq.rkq.start.begin`)."""
        started = time.perf_counter()
        f = self.functions
        built = getattr(f.advance, "build_seconds", 0.0)
        ret = f.advance(
            f.rhs,
            f.tangent,
            f.jac,
            self.inputs,
            self.tableaus,
            self.config,
            self.state,
            self.work,
            out,
            budget,
        )
        # A compiled kernel loaded or compiled for these arguments' types on
        # this call is compiling, not integration (rk34's 7.6 s was counted
        # as integrate_s; found by QA).
        building = getattr(f.advance, "build_seconds", 0.0) - built
        self.upgrade_s += building
        self.integrate_s += time.perf_counter() - started - building
        return ret

    def run(
        self,
        progress: Callable[[float, float], None] | None = None,
        budget: int = BUDGET,
        buffer_rows: int = FIRST_BUFFER_ROWS,
        stop: Callable[[np.ndarray, np.ndarray], bool] | None = None,
    ) -> RunOutput:
        """Integrate to the end (or a failure, or Ctrl-C) and collect the nodes.

        ``stop(t, y)``, if given, sees every new node after each chunk (in
        order) and ends the run by returning True (status ``ST_STOPPED``).
        """
        s = self.record
        d = self.work.V[U].shape[0]
        use_z = self.member.use_z
        rows = max(1, buffer_rows)
        chunks: list[tuple[np.ndarray, ...]] = []
        out = allocate_output(rows, d, use_z)
        status = ST_RUNNING
        checked = 0  # rows of the current buffer already shown to ``stop``
        chunk = budget if self.upgrade is None else 1
        try:
            while status == ST_RUNNING:
                if self.upgrade is not None:
                    chunk = self._try_upgrade(chunk, budget)
                ret = self.advance(out, chunk)
                if ret == RET_DONE:
                    status = int(s["status"])
                if stop is not None and s["nout"] > checked:
                    if stop(out.t[checked : s["nout"]], out.y[checked : s["nout"]]):
                        status = ST_STOPPED if status == ST_RUNNING else status
                    checked = int(s["nout"])
                if ret == RET_BUFFER_FULL:
                    chunks.append(_filled(out, s["nout"]))
                    rows = min(2 * rows, MAX_BUFFER_ROWS)
                    out = allocate_output(rows, d, use_z)
                    s["nout"] = 0
                    checked = 0
                if progress is not None and status == ST_RUNNING:
                    progress(float((s["t"] - self.t0) / (self.t_end - self.t0)), float(s["t"]))
        except KeyboardInterrupt:
            status = ST_INTERRUPTED
        if self.upgrade is not None:
            self.steps_before_upgrade = int(s["steps"])
        chunks.append(_filled(out, s["nout"]))
        try:
            return self._output(chunks, status)
        except KeyboardInterrupt:
            # Landed while the nodes were gathered (concatenating a long
            # run's chunks takes a moment): they are all here; gather them
            # again, the run marked interrupted.
            return self._output(chunks, ST_INTERRUPTED)

    def _try_upgrade(self, chunk: int, budget: int) -> int:
        """Switch to ``upgrade``'s functions if they are ready; the size of
        the next chunk (``budget`` once switched, else one that lasts about
        :data:`UPGRADE_CHECK_SECONDS` at the pace of the chunks so far)."""
        assert self.upgrade is not None
        started = time.perf_counter()
        functions = self.upgrade()
        self.upgrade_s += time.perf_counter() - started
        if functions is not None:
            self.functions = functions
            self.upgrade = None
            self.steps_before_upgrade = int(self.record["steps"])
            return budget
        attempts = int(self.record["steps"] + self.record["rejected"])
        if attempts == 0 or self.integrate_s <= 0.0:
            return chunk
        per_attempt = self.integrate_s / attempts
        return max(1, min(budget, int(UPGRADE_CHECK_SECONDS / per_attempt)))

    def stats(self) -> dict[str, int]:
        """The counters: steps, rejected, quenches, nfev, njev (and
        roundoff_steps where Gamma is estimated by Richardson)."""
        return self._stats(self.state.item(0))

    def _stats(self, s: tuple) -> dict[str, int]:
        """:meth:`stats` from the state record's values (``state.item(0)``)."""
        stats = {key: s[_AT[key]] for key in ("steps", "rejected", "quenches", "nfev", "njev")}
        if self._roundoff_counted:
            stats["roundoff_steps"] = s[_AT["roundoff_steps"]]
        return stats

    def _output(self, chunks, status: int) -> RunOutput:
        # the record's values as Python floats and ints, read at once (and
        # by position: a dict of its forty fields cost 2 us of every run)
        values = self.state.item(0)
        use_z = self.member.use_z
        if len(chunks) == 1:  # a short run: its one chunk is a copy already
            t, y, z, gam, q, rounding = chunks[0]
        else:
            t, y, z, gam, q, rounding = (np.concatenate([c[i] for c in chunks]) for i in range(6))
        free_steps = {"h_least": values[_AT["h_least"]], "h_most": values[_AT["h_most"]]}
        return _run_output(
            {
                "t": t,
                "y": y,
                "z": z if use_z else None,
                "gamma": gam if use_z else None,
                "quenched": q.astype(bool) if use_z else None,
                "status": status,
                "t_last": values[_AT["t"]],
                "h_fail": values[_AT["failed_h"]],
                "first_step": values[_AT["first_h"]],
                "max_ratio": values[_AT["max_ratio"]],
                "floor_ratio": values[_AT["floor_ratio"]],
                "bad_component": values[_AT["bad_component"]],
                "stats": self._stats(values),
                "projected": values[_AT["projected"]],
                "y_max": self.work.V[YMAX].copy(),
                "gamma_max": self.work.V[GMAX].copy() if use_z else None,
                "gamma_checkpoints": (
                    self._checkpoints(values[_AT["checkpoint"]]) if use_z else None
                ),
                "thinned": bool(self.settings.t_eval is not None or self.settings.keep_every > 1),
                "rounding": rounding if use_z else None,
                "step_range": float(loop.step_range(free_steps)),
                "stored_ratio": values[_AT["stored_ratio"]],
            }
        )

    def _checkpoints(self, passed: int) -> np.ndarray:
        rows = self.work.V[CHK0 : CHK0 + CHECKPOINTS].copy()
        rows[passed:] = np.nan  # not passed
        return rows


def _filled(out: Output, n: int) -> tuple[np.ndarray, ...]:
    nz = n if out.z.shape[0] else 0
    return (
        out.t[:n].copy(),
        out.y[:n].copy(),
        out.z[:nz].copy(),
        out.gamma[:nz].copy(),
        out.quenched[:nz].copy(),
        out.rounding[:nz].copy(),
    )
