"""`solve`: the one public entry for integrating a Hamiltonian system.

:func:`solve` validates its whole input first (every message names the
parameter and the value; :class:`~hamrkq.options.SolveOptions` holds the
options' vocabulary and checks), fills in defaults from a catalogue
:class:`~hamrkq.catalogue.problems.Problem`, only then chooses and prepares a
backend (which may compile), dispatches to a method through a small table
(:data:`METHODS`) and packs the result into a :class:`~hamrkq.result.Solution`.
The numerics live elsewhere: the RKQ kernel in :mod:`hamrkq.rkq`, the
fixed-step baselines in :mod:`hamrkq.fixed_step`, the SciPy baselines in
:mod:`hamrkq.baselines`.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from hamrkq import events as _events
from hamrkq._validate import real as _real
from hamrkq._validate import show as _show
from hamrkq._validate import span as _span
from hamrkq._validate import tolerance as _tolerance
from hamrkq.backends.numeric import numeric_of
from hamrkq.baselines.scipy_ivp import PREFIX as SCIPY_PREFIX
from hamrkq.baselines.scipy_ivp import SCIPY_METHODS, solve_scipy
from hamrkq.catalogue.problems import Problem
from hamrkq.errors import InputError, InputTypeError, OptionError, warn
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS, solve_fixed
from hamrkq.options import (
    BACKENDS,
    DEFAULT_GAMMA_LIMIT,
    DEFAULT_MAX_STEPS,
    GAMMA_MODES,
    MIN_ATOL,
    MIN_RTOL,
    QUENCH_MODES,
    TOLERANCE_RULES,
    Z_METHOD_NAMES,
    SolveOptions,
)
from hamrkq.result import Solution, Status
from hamrkq.rkq.driver import BUDGET, Integration, RunOutput, Settings, python_functions
from hamrkq.rkq.family import MEMBERS
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "BACKENDS",
    "DEFAULT_GAMMA_LIMIT",
    "DEFAULT_MAX_STEPS",
    "GAMMA_MODES",
    "METHODS",
    "MIN_RTOL",
    "QUENCH_MODES",
    "TOLERANCE_RULES",
    "Z_METHODS",
    "MethodSpec",
    "Task",
    "solve",
]

Z_METHODS = Z_METHOD_NAMES
#: Step attempts between checks for a terminal event.
TERMINAL_BUDGET = 64


@dataclass(frozen=True)
class Task:
    """A validated integration request, handed to a method's runner."""

    ham: Hamiltonian
    params: np.ndarray
    t0: float
    t_end: float
    y0: np.ndarray
    atol: np.ndarray
    rtol: np.ndarray
    options: SolveOptions
    t_eval: np.ndarray | None
    progress: Callable[[float, float], None] | None
    stop: Callable[[np.ndarray, np.ndarray], bool] | None = None


@dataclass(frozen=True)
class MethodSpec:
    """A method :func:`solve` can dispatch to.

    ``run(task, backend) -> RunOutput`` (or a finished
    :class:`~hamrkq.result.Solution`, for the baselines); ``rk8`` says whether
    the method produces the quencher track (``z``, ``gamma``, ``quenched``).
    """

    name: str
    summary: str
    run: Callable[[Task, str], RunOutput | Solution]
    backends: tuple[str, ...]
    rk8: bool


def _member(task: Task):
    return task.options.member()


def _run_rk(task: Task, backend: str) -> RunOutput:
    o = task.options
    member = _member(task)
    settings = Settings(
        **o.codes(),
        safety=o.safety,
        theta=o.quench_threshold,
        max_step=o.max_step,
        max_steps=o.max_steps,
        gamma_limit=o.gamma_limit,
        keep_every=o.keep_every,
        t_eval=task.t_eval,
        first_step=o.first_step,
    )
    if backend == "numba":
        from hamrkq.backends import compiled

        functions = compiled.kernel_functions(task.ham)
    else:
        numeric = numeric_of(task.ham)
        functions = python_functions(_inplace(numeric.rhs, False), _inplace(numeric.jac, True))
    run = Integration(
        functions,
        member,
        task.params,
        task.t0,
        task.y0,
        task.t_end,
        task.atol,
        task.rtol,
        settings,
    )
    # With a terminal event, shorter chunks: the run stops soon after the event.
    out = run.run(task.progress, budget=TERMINAL_BUDGET if task.stop else BUDGET, stop=task.stop)
    out.stats["integrate_s"] = run.integrate_s
    return out


def _inplace(fun: Callable, matrix: bool) -> Callable:
    """``fun(t, y, params) -> array`` as ``fun(t, y, params, out)``."""
    if matrix:

        def wrapped(t, y, params, out):
            out[:, :] = fun(t, y, params)

    else:

        def wrapped(t, y, params, out):
            out[:] = fun(t, y, params)

    return wrapped


def _resolve_backend(backend: str, ham: Hamiltonian, spec: MethodSpec) -> str:
    """``"auto"`` -> ``"numba"`` when the method has a compiled runner and
    numba can be used (else ``"python"``, with one HamrkqWarning when numba
    was expected but cannot be used)."""
    if backend == "python" or "numba" not in spec.backends:
        return "python" if backend == "auto" else backend
    from hamrkq.backends import compiled

    return compiled.resolve_backend(backend, ham)


def _run_fixed(task: Task, backend: str) -> Solution:
    o = task.options
    return solve_fixed(
        task.ham,
        task.y0,
        (task.t0, task.t_end),
        o.method,
        o.step,
        task.params,
        keep_every=o.keep_every,
        max_steps=o.max_steps,
    )


#: Options of :func:`solve` that hamrkq's RK34Q8 takes in its SciPy form too.
_RKQ_OPTIONS = (
    "quench",
    "quench_threshold",
    "safety",
    "tolerance_rule",
    "global_error_estimate",
    "z_method",
    "gamma_limit",
)


def _run_scipy(task: Task, backend: str) -> Solution:
    o = task.options
    name = o.method[len(SCIPY_PREFIX) :]
    return solve_scipy(
        task.ham,
        task.y0,
        (task.t0, task.t_end),
        name,
        task.params,
        atol=task.atol,
        rtol=task.rtol,
        first_step=o.first_step,
        max_step=o.max_step,
        max_steps=o.max_steps,
        keep_every=o.keep_every,
        t_eval=task.t_eval,
        progress=task.progress,
        options={k: getattr(o, k) for k in _RKQ_OPTIONS} if name == "RK34Q8" else None,
    )


_FIXED_SUMMARIES = {
    "midpoint": "implicit midpoint rule, fixed step (symplectic, order 2)",
    "gauss4": "2-stage Gauss-Legendre collocation, fixed step (symplectic, order 4)",
    "gauss6": "3-stage Gauss-Legendre collocation, fixed step (symplectic, order 6)",
    "verlet": "Stormer-Verlet, fixed step (symplectic, order 2; separable H only)",
    "yoshida4": "Yoshida's triple jump of Verlet, fixed step (symplectic, order 4; separable H)",
}

#: Dispatch table: method name -> :class:`MethodSpec`.
METHODS: dict[str, MethodSpec] = {
    **{
        name: MethodSpec(name, member.summary, _run_rk, ("python", "numba"), member.use_z)
        for name, member in MEMBERS.items()
    },
    **{
        name: MethodSpec(name, _FIXED_SUMMARIES[name], _run_fixed, ("python",), rk8=False)
        for name in FIXED_STEP_METHODS
    },
    **{
        SCIPY_PREFIX + name: MethodSpec(
            SCIPY_PREFIX + name,
            f"SciPy solver {SCIPY_METHODS[name].__module__.split('._')[0]}.{name}",
            _run_scipy,
            ("python",),
            rk8=name == "RK34Q8",
        )
        for name in SCIPY_METHODS
    },
}


def solve(  # noqa: PLR0913 - SciPy-style keyword options, one per documented setting
    system_or_problem: Any,
    q0: Any = None,
    p0: Any = None,
    t_span: Any = None,
    *,
    method: str | None = None,
    atol: Any = None,
    rtol: Any = None,
    parameters: Mapping[Any, Any] | None = None,
    quench: str | None = None,
    quench_threshold: float | None = None,
    safety: float | None = None,
    tolerance_rule: str | None = None,
    global_error_estimate: str | None = None,
    z_method: str | None = None,
    z_substeps: int | None = None,
    first_step: float | None = None,
    max_step: float | None = None,
    step: float | None = None,
    max_steps: int | None = None,
    gamma_limit: float | None = None,
    keep_every: int = 1,
    t_eval: Any = None,
    backend: str = "auto",
    progress: bool | Callable[[float, float], None] | None = None,
    dense_output: bool = False,
    events: Any = None,
) -> Solution:
    """Integrate Hamilton's equations with RKQ (or RK34) and return the nodes.

    Parameters
    ----------
    system_or_problem : Hamiltonian or Problem
        The system.  With a catalogue :class:`~hamrkq.catalogue.problems.Problem`, its
        ``q0``, ``p0``, ``t_span`` and ``integration`` settings are the
        defaults and the keywords below override them.
    q0, p0 : sequence of n numbers
        Initial coordinates and momenta: numbers, SymPy numbers or SymPy
        expressions without free symbols.
    t_span : (t0, t_end)
        Two finite numbers; ``t_end < t0`` integrates backward, ``t_end ==
        t0`` returns the single initial node.
    method : str
        ``"rk34q8"`` (default): Prentice's RKQ.  ``"rk34"``: RK3/RK4 local
        extrapolation only (no RK8 track: ``z``, ``global_error``, ``gamma``
        and ``quenched`` are None).  Fixed-step symplectic baselines
        (:mod:`hamrkq.fixed_step.symplectic`, they need ``step``): ``"midpoint"``,
        ``"gauss4"``, ``"gauss6"``, ``"verlet"`` and ``"yoshida4"`` (the last
        two for separable H only).  SciPy baselines (:mod:`hamrkq.baselines.scipy_ivp`):
        ``"scipy:RK23"``, ``"scipy:RK45"``, ``"scipy:DOP853"``,
        ``"scipy:Radau"``, ``"scipy:BDF"``, ``"scipy:LSODA"`` (the symbolic
        Jacobian goes to the last three) and ``"scipy:RK34Q8"`` (this RKQ
        through SciPy's solver interface, :class:`hamrkq.RK34Q8`).
    atol : float or array of 2n floats, default 1e-6
        Absolute tolerance, positive.
    rtol : float or array of 2n floats, default 0
        Relative tolerance, zero or positive; values below 100 eps are
        raised to 100 eps with a :class:`~hamrkq.errors.HamrkqWarning`.
    parameters : mapping, optional
        Parameter values by symbol or name, overriding the defaults (with a
        Problem whose initial values depend on them, those follow).
    quench : {"node", "redo"}, default "node"
        ``"node"``: where ``|y - z| > theta delta`` replace the node by the
        RK8 value.  ``"redo"``: restart that step from the RK8 value at its
        start (once; if it fails again, quench the node).
    quench_threshold : float, default 1
        theta, positive.
    safety : float, default 0.9
        Safety factor of the step-size controller, in (0, 1].
    tolerance_rule : {"componentwise", "prentice"}, default "componentwise"
        ``delta_k = max(atol_k, rtol_k |y_k|)`` per component, or the paper's
        scalar ``delta = min_k max(atol_k, rtol_k |y_k|)``.
    global_error_estimate : {"tangent", "paper", "off"}, default "tangent"
        How Gamma (the RK8 track's global error) is propagated: the exact
        linearisation of the RK8 step, the paper's ``(I + h J)``, or not at
        all (then ``gamma`` is None).
    z_method : {"dop853", "cooper_verner"}, default "dop853"
        The RK8 tableau of the track.
    first_step : float, optional
        Initial step size; by default Hairer-Norsett-Wanner's heuristic for
        order 3 (as SciPy's ``select_initial_step``).
    max_step : float, default inf
        Largest step size.
    step : float
        The step size h of a fixed-step method (required there, and an error
        for any other method).  The last step is shortened to land on
        ``t_end``.
    max_steps : int, default 1 000 000
        Limit on step attempts (accepted plus rejected).
    gamma_limit : float, default 0.05
        The run stops with ``Status.TOLERANCE_UNATTAINABLE`` at the first node
        where ``max_k (|Gamma_k| + rounding_k) / delta_k`` exceeds it (``inf``
        disables the check); see ``docs/algorithm.md``.
    keep_every : int, default 1
        Keep every k-th accepted node (and the first and last).
    t_eval : array, optional
        Keep only these times (inside ``t_span``, strictly monotonic in the
        direction of integration); steps are clipped to land on them.
    backend : {"auto", "numba", "python"}, default "auto"
        Where the step loop of ``rk34q8``/``rk34`` runs: ``"numba"``
        compiles it with the generated functions (cached on disk, see
        :mod:`hamrkq.backends.compiled`); ``"python"`` interprets it; ``"auto"`` uses
        numba when it can (``HAMRKQ_DISABLE_NUMBA=1`` turns it off) and
        otherwise Python with one :class:`~hamrkq.errors.HamrkqWarning`.
        Both give the same nodes and values, bit for bit.
    progress : bool or callable, optional
        True: a progress bar on stderr when it is a terminal.  A callable is
        called as ``progress(fraction, t)`` every few thousand steps.
    dense_output : bool, default False
        Attach the continuous solution ``sol.sol(t)`` (RKQ family only; one
        quencher step from the node before ``t``, see ``docs/events.md``).
    events : callable, expression, str, or a list of them, optional
        Event functions ``g(t, y)`` (SciPy's convention, with ``terminal``
        and ``direction`` attributes), SymPy expressions or strings in the
        system's names; roots go to ``sol.t_events``/``sol.y_events`` and a
        terminal one ends the run with ``Status.TERMINAL_EVENT``.  A
        Problem's ``[[events]]`` are the default.  See :mod:`hamrkq.events`.

    Returns
    -------
    Solution
        Nodes, error estimates, energy, counters and the status.  Numerical
        failures (step-size underflow, non-finite values, the step limit, an
        unattainable tolerance, Ctrl-C) are not raised: the nodes computed so
        far come back with ``success=False`` and a message naming ``t``.

    Raises
    ------
    InputError, InputTypeError, OptionError
        Bad input, with the parameter and value named.

    References
    ----------
    J.S.C. Prentice, "Global Error Control in the Runge-Kutta Solution of a
    Hamiltonian System using the RKQ Algorithm", arXiv:1111.6996 (2011).
    """
    ham, defaults, q0, p0, t_span, parameters = _system(
        system_or_problem, q0, p0, t_span, parameters
    )
    given = dict(
        method=method,
        quench=quench,
        quench_threshold=quench_threshold,
        safety=safety,
        tolerance_rule=tolerance_rule,
        global_error_estimate=global_error_estimate,
        z_method=z_method,
        z_substeps=z_substeps,
        first_step=first_step,
        max_step=max_step,
        step=step,
        max_steps=max_steps,
        gamma_limit=gamma_limit,
        keep_every=keep_every,
        backend=backend,
    )
    options = SolveOptions.resolve(given, defaults)
    # Everything is validated before a backend is chosen: choosing numba may compile.
    params = ham.parameter_values(parameters)
    y0 = ham.state_values(q0, p0)
    t0, t_end = _span(t_span)
    t_eval_v = _t_eval(t_eval, t0, t_end)
    _step_rules(options, step, atol, rtol, first_step, t_eval_v, t0, t_end)
    atol_v, rtol_v = _tolerances(ham.dim, defaults, atol, rtol)
    options = options.with_auto(float(np.min(np.maximum(atol_v, rtol_v * np.abs(y0)))))
    spec = METHODS[options.method]
    if t_eval_v is not None and options.keep_every != 1:
        raise InputError(
            f"keep_every={options.keep_every!r} and t_eval cannot be combined: t_eval already "
            "chooses the nodes that are kept"
        )
    if events is None and isinstance(system_or_problem, Problem):
        events = list(system_or_problem.events) or None
    event_list = _events.event_specs(events, ham, params)
    if (dense_output or event_list) and (
        spec.run is not _run_rk or options.keep_every != 1 or t_eval_v is not None
    ):
        raise InputError(
            "dense_output and events need an RKQ-family method with every node kept "
            f"(method={options.method!r}, keep_every={options.keep_every!r}, "
            f"t_eval {'given' if t_eval_v is not None else 'not given'})"
        )
    bar = _progress(progress)
    started = time.perf_counter()
    chosen = _resolve_backend(options.backend, ham, spec)
    compile_s = time.perf_counter() - started
    if chosen not in spec.backends:
        raise OptionError(
            f"backend={chosen!r} is not available for method {options.method!r}; "
            f"valid: {', '.join(map(repr, spec.backends))}"
        )
    watch = _events.terminal_watch(event_list)
    task = Task(ham, params, t0, t_end, y0, atol_v, rtol_v, options, t_eval_v, bar, watch)
    # A failure is reported by the status; NumPy's RuntimeWarnings from the
    # rejected trial steps that found it (sqrt(-1), overflow), or from H at a
    # singular initial node, would only be noise.
    with np.errstate(all="ignore"):
        started = time.perf_counter()
        out = spec.run(task, chosen)
        elapsed = time.perf_counter() - started
        if bar is not None and progress is True:
            sys.stderr.write("\n")  # leave the finished bar on its own line
        if isinstance(out, Solution):  # the baselines build their own
            return out
        out.stats.setdefault("integrate_s", elapsed)
        out.stats["compile_s"] = compile_s
        sol = _solution(task, spec, out, chosen)
        if dense_output or event_list:
            sol = _with_events(task, sol, chosen, event_list, dense_output)
        return sol


def _with_events(task: Task, sol: Solution, backend: str, specs, keep_dense: bool) -> Solution:
    """Dense output and events (:mod:`hamrkq.events`) on a finished RKQ run."""
    member = _member(task)
    dense = _events.dense_output(task.ham, member, backend, task.params, sol.t, sol.y)
    if not specs:
        return sol.replace(sol=dense)
    z_dense = None if sol.z is None else dense.through(sol.t, sol.z)

    def energy(t, Y):
        return numeric_of(task.ham).energy(t, Y, task.params)

    return _events.apply(sol, specs, dense, energy, z_dense, keep_dense)


# -- validation ------------------------------------------------------------------


def _step_rules(options: SolveOptions, step, atol, rtol, first_step, t_eval, t0, t_end):
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


def _tolerances(dim: int, defaults: Mapping[str, Any], atol: Any, rtol: Any):
    """``atol`` and ``rtol`` as arrays of ``dim`` values (keyword, else the
    problem's, else 1e-6 and 0); an rtol below 100 eps is raised to it."""
    atol_given = atol if atol is not None else defaults.get("atol", 1e-6)
    rtol_given = rtol if rtol is not None else defaults.get("rtol", 0.0)
    atol_v = _tolerance("atol", atol_given, dim, positive=True)
    rtol_v = _tolerance("rtol", rtol_given, dim, positive=False)
    if np.any(atol_v < MIN_ATOL):
        raise InputError(
            f"atol={_show(atol_given)} is below {MIN_ATOL:g}, which no double-precision "
            "step can resolve; use a larger atol (or rtol for relative control)"
        )
    if np.any((rtol_v > 0) & (rtol_v < MIN_RTOL)):
        warn(f"rtol={_show(rtol_given)} is below 100 eps and is raised to {MIN_RTOL:.3g}")
        rtol_v = np.where((rtol_v > 0) & (rtol_v < MIN_RTOL), MIN_RTOL, rtol_v)
    return atol_v, rtol_v


def _system(obj: Any, q0: Any, p0: Any, t_span: Any, parameters: Any):
    """The Hamiltonian and the defaults a Problem supplies."""
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
        return (
            problem.hamiltonian,
            dict(problem.integration),
            problem.q0 if q0 is None else q0,
            problem.p0 if p0 is None else p0,
            problem.t_span if t_span is None else t_span,
            merged,
        )
    raise InputTypeError(
        "system_or_problem must be a hamrkq.Hamiltonian or a hamrkq.Problem, "
        f"got {type(obj).__name__}"
    )


def _t_eval(t_eval: Any, t0: float, t_end: float) -> np.ndarray | None:
    if t_eval is None:
        return None
    try:
        times = np.array([_real("t_eval", v) for v in np.ravel(np.asarray(t_eval, dtype=object))])
    except TypeError:
        raise InputTypeError(f"t_eval must be an array of numbers, got {_show(t_eval)}") from None
    if np.ndim(t_eval) != 1 or times.size == 0:
        raise InputError(f"t_eval must be a non-empty 1-D array, got {_show(t_eval)}")
    lo, hi = min(t0, t_end), max(t0, t_end)
    if not np.all(np.isfinite(times)) or times.min() < lo or times.max() > hi:
        raise InputError(f"t_eval must lie within t_span ({t0!r}, {t_end!r})")
    steps = np.diff(times) * (1.0 if t_end >= t0 else -1.0)
    if np.any(steps <= 0):
        raise InputError("t_eval must be strictly monotonic in the direction of integration")
    return times


def _progress(progress: Any) -> Callable[[float, float], None] | None:
    if progress is None or progress is False:
        return None
    if progress is True:
        return _terminal_bar() if sys.stderr is not None and sys.stderr.isatty() else None
    if callable(progress):
        return progress
    raise InputTypeError(f"progress must be a bool or a callable, got {_show(progress)}")


def _terminal_bar(width: int = 40) -> Callable[[float, float], None]:
    def show(fraction: float, t: float) -> None:
        filled = int(width * min(max(fraction, 0.0), 1.0))
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {fraction:6.1%} t={t:.6g}")
        sys.stderr.flush()

    return show


# -- the result ------------------------------------------------------------------

_STATUS_BY_CODE = {status.code: status for status in Status}


def _solution(task: Task, spec: MethodSpec, out: RunOutput, backend: str) -> Solution:
    o = task.options
    member = _member(task)
    gamma_mode = o.gamma_name if spec.rk8 else "off"
    nfev_step, njev_step = member.evaluations_per_step(gamma_mode)
    stats = dict(out.stats)
    status = _STATUS_BY_CODE[out.status]
    if not out.t.size:
        energy = out.t
    elif backend == "numba":
        from hamrkq.backends import compiled

        energy = compiled.energy(task.ham, out.t, out.y, task.params)
    else:
        energy = numeric_of(task.ham).energy(out.t, out.y, task.params)
    options: dict[str, Any] = {
        "method": o.method,
        "backend": backend,
        "t_span": [task.t0, task.t_end],
        "atol": task.atol.tolist(),
        "rtol": task.rtol.tolist(),
        "tolerance_rule": o.tolerance_rule,
        "safety": o.safety,
        "first_step": out.first_step,
        "first_step_rule": "given" if o.first_step is not None else "hairer-norsett-wanner",
        "max_step": None if math.isinf(o.max_step) else o.max_step,
        "max_steps": o.max_steps,
        "keep_every": o.keep_every,
        "t_eval": None if task.t_eval is None else task.t_eval.tolist(),
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
            z_method=o.z_method,
            z_substeps=member.z_substeps,
            gamma_limit=None if math.isinf(o.gamma_limit) else o.gamma_limit,
        )
    has_gamma = spec.rk8 and gamma_mode != "off"
    return Solution(
        t=out.t,
        y=out.y,
        energy=energy,
        status=status,
        message=_message(status, out, task),
        method=o.method,
        n=task.ham.n,
        names=task.ham.names,
        atol=task.atol,
        rtol=task.rtol,
        stats=stats,
        options=options,
        z=out.z,
        global_error=None if out.z is None else out.y - out.z,
        gamma=out.gamma if has_gamma else None,
        quenched=out.quenched,
    )


def _component(task: Task, index: int) -> str:
    """Which derivative a state component's right-hand side is, in words."""
    ham = task.ham
    n = ham.n
    if index < 0:
        return "the right-hand side"
    if index < n:
        return f"d{ham.q[index]}/dt = dH/d{ham.p[index]}"
    return f"d{ham.p[index - n]}/dt = -dH/d{ham.q[index - n]}"


def _unattainable(out: RunOutput, task: Task) -> str:
    o = task.options
    t = out.t_last
    text = (
        f"At t = {t!r} the quencher's estimated global error plus its rounding would reach "
        f"{out.max_ratio:.3g} x the tolerance (gamma_limit = {o.gamma_limit:g}), so the "
        "tolerance can no longer be certified; the run ends at the last node where it held."
    )
    if out.y.size:
        y = np.abs(out.y[-1])
        delta = np.maximum(task.atol, task.rtol * y)
        floor = float(np.max(np.finfo(float).eps * y / delta))
        if floor >= 0.5 * o.gamma_limit:
            return text + (
                f" The tolerance is at double precision's floor for this state (the rounding "
                f"of the stored values alone is {floor:.3g} x the tolerance): loosen atol/rtol."
            )
    steps = out.stats.get("steps", 0)
    rounded = out.stats.get("roundoff_steps", 0)
    if steps and 2 * rounded > steps:
        return text + (
            " The quencher's error has reached double precision's rounding floor here: a "
            "looser tolerance, or a shorter interval (the horizon of double precision for "
            "this orbit), is what works."
        )
    remedies = [f"a smaller max_step (the quencher's error falls like h^{_member(task).z_order})"]
    better = [name for name in MEMBERS if name not in (o.method, "rk34") and MEMBERS[name].use_z]
    if better:
        remedies.append(f"another member of the family ({', '.join(map(repr, better))})")
    remedies.append("a looser tolerance only if the quencher's error grows with the step")
    return text + " What helps: " + "; ".join(remedies) + "."


def _message(status: Status, out: RunOutput, task: Task) -> str:
    t = out.t_last
    if status is Status.SUCCESS:
        text = f"The integration reached the end of the interval (t = {t!r})."
    elif status is Status.STEP_SIZE_UNDERFLOW:
        text = (
            f"The step size {abs(out.h_fail):.3g} fell below the roundoff floor "
            f"(10 eps |t|) at t = {t!r}."
        )
    elif status is Status.NON_FINITE:
        text = (
            f"The state or the right-hand side became non-finite (inf or nan) at t = {t!r}: "
            f"{_component(task, out.bad_component)} could not be evaluated to a finite value "
            "there (a singularity, or H outside its domain)."
        )
    elif status is Status.MAX_STEPS:
        text = f"The step limit max_steps = {task.options.max_steps} was reached at t = {t!r}."
    elif status is Status.INTERRUPTED:
        text = f"Interrupted (KeyboardInterrupt) near t = {t!r}."
    elif status is Status.TOLERANCE_UNATTAINABLE:
        text = _unattainable(out, task)
    else:  # pragma: no cover - other statuses come from other methods
        text = f"{status.description} (t = {t!r})"
    if not status.success:
        text += f" The {out.t.size} nodes computed so far are kept."
    steps = out.stats.get("steps", 0)
    rounded = out.stats.get("roundoff_steps", 0)
    if steps and 2 * rounded > steps and status is not Status.TOLERANCE_UNATTAINABLE:
        text += (
            f" Note: on {rounded} of {steps} steps the quencher's local error was below "
            "double-precision rounding; there the Richardson estimate (and Gamma) "
            "measures rounding, not truncation."
        )
    return text
