"""The arguments of :func:`hamrkq.solve` that need the system to be checked.

The system and the defaults a catalogue Problem supplies, the tolerances as
arrays of the state's size, the rules that tie ``step`` to the fixed-step
methods, ``t_eval`` and ``progress``.  Every message names the parameter and
the value (:mod:`hamrkq._validate`); the options that do not depend on the
system are checked by :class:`~hamrkq.options.SolveOptions`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import sympy as sp

from hamrkq._floats import EPS
from hamrkq._progress import ProgressBar
from hamrkq._validate import plain_number
from hamrkq._validate import real as _real
from hamrkq._validate import show as _show
from hamrkq._validate import tolerance as _tolerance
from hamrkq.catalogue.problems import Problem
from hamrkq.errors import InputError, InputTypeError, OptionError, warn
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS
from hamrkq.options import MIN_ATOL, MIN_RTOL, SolveOptions
from hamrkq.rkq.start import FLOOR_ULPS
from hamrkq.rkq.witness_rules import time_rounding_matters
from hamrkq.symbolic.assumptions import assumption_conflict, declares_checked
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "check_time_assumptions",
    "check_time_rounding",
    "eval_times",
    "progress_callback",
    "step_rules",
    "system",
    "tolerances",
]


def _above_roundoff_floor(options: SolveOptions, t0: float, t_end: float) -> None:
    """``first_step`` and ``max_step`` no shorter than the steps the loop's
    roundoff floor refuses (``FLOOR_ULPS`` eps |t|, at t0 and at the span's
    largest |t|): first_step=1e-9 from t0 = 1e8 ended on its first step with
    'The step size 0 fell below the roundoff floor', naming neither."""
    for name, value, at in (
        ("first_step", options.first_step, abs(t0)),
        ("max_step", options.max_step, max(abs(t0), abs(t_end))),
    ):
        floor = FLOOR_ULPS * EPS * at
        if value is not None and value < floor:
            raise InputError(
                f"{name}={value!r} is below the shortest step the time's rounding allows "
                f"at |t| = {at:.6g} ({FLOOR_ULPS:g} eps |t| = {floor:.3g}); give a longer "
                f"{name}, or an interval nearer t = 0"
            )


def step_rules(options: SolveOptions, step, atol, rtol, first_step, t_eval, t0, t_end):
    """``step`` is required by the fixed-step methods and refused by the others;
    tolerances, ``first_step`` and ``t_eval`` mean nothing to a fixed step."""
    if not options.is_fixed_step:
        if step is not None:
            raise OptionError(
                f"step={_show(step)} applies only to the fixed-step methods "
                f"({', '.join(map(repr, FIXED_STEP_METHODS))}); method {options.method!r} "
                "chooses its own steps (see first_step and max_step)"
            )
        if options.first_step is not None and t_end != t0:
            if options.first_step > abs(t_end - t0):
                raise InputError(
                    f"first_step={options.first_step!r} exceeds the length of t_span "
                    f"({abs(t_end - t0)!r})"
                )
        _above_roundoff_floor(options, t0, t_end)
        return
    if options.step is None:
        raise InputError(
            f"method {options.method!r} is a fixed-step method: step (h) must be given"
        )
    for name, other in (
        ("atol", atol),
        ("rtol", rtol),
        ("first_step", first_step),
        ("t_eval", t_eval),
    ):
        if other is not None:
            raise OptionError(
                f"{name} does not apply to the fixed-step method {options.method!r} (it has "
                "no error control and no dense output); give step only"
            )


def check_time_assumptions(ham: Hamiltonian, t0: float, t_end: float) -> None:
    """The time span against the assumptions declared on ``ham``'s time
    symbol, as initial values against theirs: a ``positive=True`` t in
    ``sqrt(t**2)``, made ``t`` by SymPy, integrated another H for t < 0
    with SUCCESS (found by QA).  Both ends are checked (a sign holds between
    them where it holds at both), and a ``nonzero`` t must not reach 0."""
    symbol = ham.t
    if symbol is None or not declares_checked((symbol,)):
        return  # (most: a plain t costs a solve nothing here)
    for label, value in (("t_span[0]", t0), ("t_span[1]", t_end)):
        conflict = assumption_conflict(symbol, value)
        if conflict is not None:
            raise InputError(f"{label}: {conflict}")
    if min(t0, t_end) < 0.0 < max(t0, t_end):
        conflict = assumption_conflict(symbol, 0.0)
        if conflict is not None:
            raise InputError(f"t_span ({t0!r}, {t_end!r}) passes t = 0: {conflict}")


def check_time_rounding(
    options: SolveOptions, ham: Hamiltonian, atol, rtol, y0, t0: float, t_end: float
) -> None:
    """The quencher in double-double, asked for, where the rounding of the
    time could reach the tolerance: refused, for it does not go below that
    floor (its stage times are doubles) and runs no witness that would see
    it (:func:`hamrkq.rkq.witness_rules.time_rounding_matters`)."""
    if not (options.double_double and ham.equations_time_dependent):
        return
    scale = max(abs(t0), abs(t_end))
    if time_rounding_matters(atol, rtol, y0, scale):
        raise OptionError(
            f"quencher_precision='double-double' cannot go below the rounding of the time: H "
            f"depends on t, and at |t| up to {scale:.6g} an ulp of t is "
            f"{float(np.spacing(scale)):.2g}, which the double stage times carry into the "
            "forcing; integrate from t = 0 (t_span shifted, H's phases moved by w t0 computed "
            "once), or loosen the tolerance"
        )


def tolerances(dim: int, defaults: Mapping[str, Any], atol: Any, rtol: Any):
    """``atol`` and ``rtol`` as arrays of ``dim`` values (keyword, else the
    problem's, else 1e-6 and 0); an rtol below 100 eps is raised to it."""
    atol_given = atol if atol is not None else defaults.get("atol", 1e-6)
    rtol_given = rtol if rtol is not None else defaults.get("rtol", 0.0)
    atol_number, rtol_number = plain_number(atol_given), plain_number(rtol_given)
    if (
        atol_number is not None
        and rtol_number is not None
        and MIN_ATOL <= atol_number < math.inf
        and (rtol_number == 0.0 or MIN_RTOL <= rtol_number < math.inf)
    ):
        # two numbers that pass every check below, the common case, without
        # its reductions (every solve pays this): the same arrays
        return np.full(dim, atol_number), np.full(dim, rtol_number)
    atol_v = _tolerance("atol", atol_given, dim, positive=True)
    rtol_v = _tolerance("rtol", rtol_given, dim, positive=False)
    # (one reduction each where nothing is wrong: every solve pays these)
    if atol_v.min(initial=np.inf) < MIN_ATOL:
        raise InputError(
            f"atol={_show(atol_given)} is below {MIN_ATOL:g}, which no double-precision "
            "step can resolve; use a larger atol (or rtol for relative control)"
        )
    if rtol_v.max(initial=0.0) > 0.0 and np.any((rtol_v > 0) & (rtol_v < MIN_RTOL)):
        warn(f"rtol={_show(rtol_given)} is below 100 eps and is raised to {MIN_RTOL:.3g}")
        rtol_v = np.where((rtol_v > 0) & (rtol_v < MIN_RTOL), MIN_RTOL, rtol_v)
    return atol_v, rtol_v


def system(obj: Any, q0: Any, p0: Any, t_span: Any, parameters: Any):
    """The Hamiltonian and the defaults a Problem supplies: its initial values
    (those a mapping ``q0``/``p0`` does not bind, by name), time span,
    parameters and ``[integration]`` settings."""
    if parameters is not None and not isinstance(parameters, Mapping):
        raise InputTypeError(
            f"parameters must be a mapping of names or symbols to numbers, got {parameters!r}"
        )
    if isinstance(obj, Hamiltonian):
        missing = [name for name, v in (("q0", q0), ("p0", p0), ("t_span", t_span)) if v is None]
        if missing:
            raise InputError(f"{', '.join(missing)} must be given when solving a Hamiltonian")
        return obj, {}, q0, p0, t_span, parameters
    if isinstance(obj, Problem):
        problem = obj
        if parameters:
            names = {(k.name if isinstance(k, sp.Symbol) else k): v for k, v in parameters.items()}
            problem = problem.with_parameters(**names)
        merged = {**problem.parameters, **(parameters or {})}
        ham = problem.hamiltonian
        return (
            ham,
            dict(problem.integration),
            _initial(q0, ham.q, problem.q0),
            _initial(p0, ham.p, problem.p0),
            problem.t_span if t_span is None else t_span,
            merged,
        )
    raise InputTypeError(
        "system_or_problem must be a hamrkq.Hamiltonian or a hamrkq.Problem, "
        f"got {type(obj).__name__}"
    )


def _initial(given: Any, symbols: tuple[sp.Symbol, ...], defaults: np.ndarray) -> Any:
    """A Problem's initial values with ``given`` over them: all of them for
    None, a mapping's names (or symbols) over the rest, a sequence as it is.
    (For a Hamiltonian a mapping binds every name: it has no defaults.)"""
    if given is None:
        return defaults
    if not isinstance(given, Mapping):
        return given
    rest = {s.name: float(v) for s, v in zip(symbols, defaults, strict=True)}
    for symbol in symbols:
        if symbol.name in given or symbol in given:
            del rest[symbol.name]
    return {**rest, **given}


def eval_times(t_eval: Any, t0: float, t_end: float) -> np.ndarray | None:
    if t_eval is None:
        return None
    try:
        times = np.array([_real("t_eval", v) for v in np.ravel(np.asarray(t_eval, dtype=object))])
    except TypeError:
        raise InputTypeError(f"t_eval must be an array of numbers, got {_show(t_eval)}") from None
    return checked_eval_times(times, t_eval, t0, t_end)


def checked_eval_times(times: np.ndarray, t_eval: Any, t0: float, t_end: float) -> np.ndarray:
    """``times`` (``t_eval`` as floats) if they are a non-empty 1-D array
    inside ``[t0, t_end]``, monotonic in the direction of integration."""
    if np.ndim(t_eval) != 1 or times.size == 0:
        raise InputError(f"t_eval must be a non-empty 1-D array, got {_show(t_eval)}")
    lo, hi = min(t0, t_end), max(t0, t_end)
    if not np.all(np.isfinite(times)) or times.min() < lo or times.max() > hi:
        raise InputError(
            f"t_eval must lie within t_span ({t0!r}, {t_end!r}){_outside(times, lo, hi)}"
        )
    steps = np.diff(times) * (1.0 if t_end >= t0 else -1.0)
    if np.any(steps <= 0):
        raise InputError("t_eval must be strictly monotonic in the direction of integration")
    return times


#: A value of ``t_eval`` this many ulps or fewer past an end of ``t_span`` is
#: named as rounding (``np.arange(4) * 0.1`` ends at 0.30000000000000004).
ROUNDING_ULPS = 4


def _outside(times: np.ndarray, lo: float, hi: float) -> str:
    """The first value of ``times`` outside ``[lo, hi]``, for the message;
    a few ulps past an end is said to be a rounding, with what avoids it."""
    bad = np.flatnonzero(~np.isfinite(times) | (times < lo) | (times > hi))
    k = int(bad[0])
    value = float(times[k])
    end = lo if value < lo else hi
    if not math.isfinite(value) or value == end:
        return f": t_eval[{k}] = {value!r}"
    ulps = abs(value - end) / np.spacing(abs(end)) if end != 0.0 else math.inf
    if ulps > ROUNDING_ULPS:
        return f": t_eval[{k}] = {value!r}"
    return (
        f": t_eval[{k}] = {value!r} is {ulps:.0f} ulp{'s' if ulps > 1 else ''} past {end!r}, "
        "a rounding (of np.arange's steps, say): np.linspace(t0, t_end, n) ends on t_end "
        "exactly, or clip the values to the span"
    )


def progress_callback(progress: Any, label: str) -> Callable[[float, float], None] | None:
    """``progress`` as the driver's callback: None for no reports, a
    :class:`~hamrkq._progress.ProgressBar` named ``label`` for True (only when
    stderr is a terminal), or the caller's own callable."""
    if progress is None or progress is False:
        return None
    if progress is True:
        bar = ProgressBar(label, delay=0.0)
        return bar if bar.enabled else None
    if callable(progress):
        return progress
    raise InputTypeError(f"progress must be a bool or a callable, got {_show(progress)}")
