"""The preparation of a call of :func:`hamrkq.solve.solve`: validate its
arguments, fill in a problem's defaults, choose and prepare the backend, and
hold the result as a :class:`Prepared` (the :class:`~hamrkq.solve.dispatch.Task`,
the method's :class:`~hamrkq.solve.dispatch.MethodSpec`, the events).
:func:`hamrkq.solve.solve` runs from it, and :func:`hamrkq.ensemble` runs its
members from it (:func:`prepare`), so that a member is the same run as
``solve`` alone."""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass
from typing import Any

from hamrkq import events as _events
from hamrkq._validate import span as _span
from hamrkq.catalogue.problems import Problem
from hamrkq.errors import InputError, OptionError, warn
from hamrkq.options import SolveOptions
from hamrkq.rkq.auto_rules import auto_tolerance
from hamrkq.solve import arguments, auto, smoothness
from hamrkq.solve.dispatch import (
    METHODS,
    MethodSpec,
    Task,
    resolve_backend,
    run_rk,
    start_background,
)
from hamrkq.symbolic.kinks import kinks


@dataclass(frozen=True)
class Prepared:
    """A validated call of :func:`solve`, ready to run: the :class:`Task`,
    the method's :class:`MethodSpec`, the backend chosen (and prepared:
    ``compile_s`` seconds), the event specifications and the options as
    requested (``method="auto"`` not yet resolved: the task's options are
    resolved for its ``y0``)."""

    task: Task
    spec: MethodSpec
    backend: str
    compile_s: float
    events: list
    requested: SolveOptions
    #: Why a problem file's events are left out of the run (the warning's
    #: words), or None: they are located, or there are none.
    events_note: str | None = None
    #: Whether ``events=`` was given (an empty list returns empty
    #: ``t_events``, as SciPy's ``solve_ivp`` does).
    events_given: bool = False


def prepare(
    system_or_problem: Any, q0: Any = None, p0: Any = None, t_span: Any = None, **keywords: Any
) -> Prepared:
    """Everything :func:`solve` does before it integrates: validate the
    arguments (the same names and checks; an unknown keyword is a
    ``TypeError``), fill in a problem's defaults, choose and prepare the
    backend.  :func:`hamrkq.ensemble` runs its members from this, so that a
    member is the same run as :func:`solve` alone.

    Returns
    -------
    Prepared
    """
    from hamrkq.solve import solve  # (the package imports this module: bind at call time)

    bound = inspect.signature(solve).bind(system_or_problem, q0, p0, t_span, **keywords)
    bound.apply_defaults()
    return prepare_by_name(**bound.arguments)


def prepare_by_name(  # noqa: PLR0913 - solve's arguments, by name
    system_or_problem: Any,
    q0: Any,
    p0: Any,
    t_span: Any,
    *,
    atol: Any,
    rtol: Any,
    parameters: Any,
    t_eval: Any,
    progress: Any,
    dense_output: bool,
    events: Any,
    background: bool = False,
    **given: Any,
) -> Prepared:
    """:func:`prepare` with every argument of :func:`solve` given by name
    (``given`` holds the options of :class:`~hamrkq.options.SolveOptions`).
    ``background``: on a first use with ``backend="auto"``, compile in a
    helper process and start the run interpreted
    (:mod:`hamrkq.backends.background`)."""
    ham, defaults, q0, p0, t_span, parameters = arguments.system(
        system_or_problem, q0, p0, t_span, parameters
    )
    options = SolveOptions.resolve(given, defaults)
    # Everything is validated before a backend is chosen: choosing numba may compile.
    params = ham.parameter_values(parameters)
    y0 = ham.state_values(q0, p0)
    t0, t_end = _span(t_span)
    t_eval_v = arguments.eval_times(t_eval, t0, t_end)
    arguments.step_rules(
        options, given["step"], atol, rtol, given["first_step"], t_eval_v, t0, t_end
    )
    atol_v, rtol_v = arguments.tolerances(ham.dim, defaults, atol, rtol)
    arguments.check_time_assumptions(ham, t0, t_end)
    arguments.check_time_rounding(options, ham, atol_v, rtol_v, y0, t0, t_end)
    requested = options
    if options.method == "auto":  # (the tolerance it reads is not needed otherwise)
        options = options.with_auto(ham.dim, auto_tolerance(atol_v, rtol_v, y0))
    spec = METHODS[options.method]
    if t_eval_v is not None and options.keep_every != 1:
        raise InputError(
            f"keep_every={options.keep_every!r} and t_eval cannot be combined: t_eval already "
            "chooses the nodes that are kept"
        )
    located = spec.run is run_rk and options.keep_every == 1
    # A file's events are a default: with t_eval they are left out, so that
    # t_eval keeps memory flat unless events are asked for (every node kept).
    files_located = located and (t_eval_v is None or events is not None)
    event_list, events_note = _event_list(events, system_or_problem, ham, params, files_located)
    if (dense_output or event_list) and not located:
        # the caller's method (auto, not the member it chose), and the remedy
        # that applies: a family member only needs every node kept
        remedy = (
            "keep every node (keep_every=1)"
            if spec.run is run_rk
            else "run auto, rk34q8 or another family member"
        )
        raise InputError(
            "dense_output and events need an RKQ-family method with every node kept "
            f"(method={requested.method!r}, keep_every={options.keep_every!r}): they are "
            f"found on the dense output between consecutive nodes; {remedy}, and thin "
            "the nodes afterwards (sol.t[::k], or t_eval)"
        )
    output_times = None
    kinked = smoothness.checks_kinks(ham, options.gamma_limit, spec.run is run_rk and spec.rk8)
    if kinked and options.keep_every != 1:
        raise InputError(
            f"keep_every={options.keep_every!r} would hide where the run crosses a kink of H "
            f"({', '.join(k.term for k in kinks(ham.H))}), beyond which its tolerance cannot "
            "be certified: keep every node and thin them afterwards (sol.t[::k]), or pass "
            "gamma_limit=numpy.inf to run without the certificate"
        )
    if t_eval_v is not None and (dense_output or event_list or kinked):
        # every node kept (for the dense output, or to see a kink crossed
        # between output times); t_eval's values from the dense output
        output_times, t_eval_v = t_eval_v, None
    bar = arguments.progress_callback(progress, options.method)
    started = time.perf_counter()
    if options.double_double:
        _require_double_double(ham)
        background = False  # the helper compiles the double functions only
    compiling = (
        start_background(options.backend, ham, spec, options.gamma_name) if background else None
    )
    chosen = (
        "numba"
        if compiling is not None
        else resolve_backend(options.backend, ham, spec, options.gamma_name)
    )
    compile_s = time.perf_counter() - started
    if chosen not in spec.backends:
        raise OptionError(
            f"backend={chosen!r} is not available for method {options.method!r}; "
            f"valid: {', '.join(map(repr, spec.backends))}"
        )
    watch = _events.terminal_watch(event_list)
    task = Task(
        ham, params, t0, t_end, y0, atol_v, rtol_v, options, t_eval_v, bar, watch, compiling,
        auto=requested.method == "auto", output_times=output_times,
    )  # fmt: skip
    if auto.projects(requested, task):  # (a copy of the task only where it projects)
        task = task.projecting()
    return Prepared(
        task, spec, chosen, compile_s, event_list, requested, events_note, events is not None
    )


def _event_list(events, system_or_problem, ham, params, located: bool) -> tuple[list, str | None]:
    """The event specifications of ``events=``, or else of the problem
    file's ``[[events]]``, and why the file's are left out (None: they are
    not).  The file's events are a default: where the run cannot locate
    events (a method outside the RKQ family, thinned nodes) they are left
    out with a warning, so that the problem still runs with every method
    (``hamrkq compare``, SciPy's and the symplectic baselines); events given
    to ``solve`` are never left out.  The warning's words are also kept in
    ``sol.options["events_not_located"]``: a warning can be filtered away,
    and a saved solution or a command's summary.json must still say it."""
    if events is not None or not isinstance(system_or_problem, Problem):
        return _events.event_specs(events, ham, params), None
    specs = _events.event_specs(list(system_or_problem.events) or None, ham, params)
    if specs and not located:
        labels = ", ".join(repr(spec.label) for spec in specs)
        terminal = [repr(spec.label) for spec in specs if spec.terminal]
        note = (
            f"the events of problem {system_or_problem.name!r} ({labels}) are not "
            "located in this run: events need an RKQ-family method with every node "
            "kept (solve(..., events=[]) runs without them, and without this warning)"
        )
        if terminal:
            note += (
                f"; the terminal event {', '.join(terminal)} does not end it, so it runs to t_end"
            )
        warn(note)
        return [], note
    return specs, None


def _require_double_double(ham) -> None:
    """Raise :class:`OptionError` when ``f`` has no double-double form."""
    from hamrkq.backends import codegen

    unsupported = codegen.double_double_unsupported(ham)
    if unsupported:
        raise OptionError(f"quencher_precision='double-double' is not available: {unsupported}")
