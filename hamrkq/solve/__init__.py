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

The package's modules:

- :mod:`hamrkq.solve.preparation`: :func:`prepare`, a call validated and its
  backend chosen (:class:`Prepared`), everything before the run;
- :mod:`hamrkq.solve.arguments`: the checks of the arguments that need the
  system (tolerances, ``step``, ``t_eval``, ``progress``) and the defaults a
  Problem supplies;
- :mod:`hamrkq.solve.dispatch`: :class:`Task`, :class:`MethodSpec` and the
  dispatch table :data:`METHODS` with each method's runner;
- :mod:`hamrkq.solve.outcome`: the Solution of an RKQ-family run, and
  :mod:`hamrkq.solve.messages` its message, naming what ended it and what
  helps (for an unattainable tolerance, :mod:`hamrkq.solve.unattainable`);
- :mod:`hamrkq.solve.assumptions`, :mod:`hamrkq.solve.smoothness` and
  :mod:`hamrkq.solve.output_times`: the checks after a run (declared
  assumptions, kinks of H, output times sampled beside events).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from hamrkq._progress import ProgressBar
from hamrkq.options import (
    BACKENDS,
    DEFAULT_GAMMA_LIMIT,
    DEFAULT_MAX_STEPS,
    GAMMA_MODES,
    MIN_RTOL,
    QUENCH_MODES,
    TOLERANCE_RULES,
    Z_METHOD_NAMES,
)
from hamrkq.result import Solution
from hamrkq.solve import assumptions, auto, outcome, rerun_notes, smoothness
from hamrkq.solve.dispatch import METHODS, MethodSpec, Task
from hamrkq.solve.event_check import (
    certificate,
    certified_at_events,
    interrupted,
    run_certified,
    with_events,
)
from hamrkq.solve.preparation import Prepared, prepare, prepare_by_name

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
    "Prepared",
    "Task",
    "prepare",
    "solve",
]

Z_METHODS = Z_METHOD_NAMES


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
    quencher_precision: str | None = None,
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
    q0, p0 : sequence of n numbers, or mapping
        Initial coordinates and momenta: numbers, SymPy numbers or SymPy
        expressions without free symbols, 1-D.  A mapping binds values by
        name or symbol (``{"x": 0.4}``): with a Problem it may bind some
        names, the others keeping the problem's initial values; with a
        Hamiltonian it must bind every name.
    t_span : (t0, t_end)
        Two finite numbers; ``t_end < t0`` integrates backward, ``t_end ==
        t0`` returns the single initial node.
    method : str
        ``"auto"`` (default): the RKQ family's member for the tolerance and
        the dimension (4.5 to 12.4 times fewer evaluations plus Jacobian
        products than ``"rk34q8"`` at 1e-6 to 1e-9, ``benchmarks/family.md``,
        and it certifies 1e-10 to 1e-12, where ``"rk34q8"`` cannot;
        ``docs/algorithm.md``, "Why auto is the default"):
        Verner's 7(6) pair with Verner's 9th-order quencher (``"rk67q9"``) at tolerances of 1e-7
        or looser and from 12 state variables on, Verner's 8(7) with
        Feagin's 12th-order quencher (``"rk78q12"``) for smaller systems at
        tighter tolerances, whose quencher steps per step
        (``z_substeps``) are learned from the run: it starts with 2 and runs
        again with more when its projection or its stop says so
        (``docs/algorithm.md``, "The RKQ family and method='auto'").
        ``"rk34q8"``: Prentice's RKQ as the paper ran it (RK3/RK4 with local
        extrapolation, DOP853 as the quencher, Gamma by the tangent flow;
        ``hamrkq reproduce`` and the catalogue's prentice2011 run it).  Other
        family members ``"rk{r}{v}q{z}"`` (``"rk45q12"``, ``"rk67q9"``, ...;
        :data:`hamrkq.rkq.family.MEMBERS`) pair an embedded r(v) method with
        a quencher of order z.  ``"rk34"``: RK3/RK4 local
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
        theta, positive: a node is quenched where its estimated error
        exceeds theta times the tolerance, so above 1 the returned nodes
        may be about theta delta off (docs/algorithm.md).
    safety : float, default 0.9
        Safety factor of the step-size controller, in (0, 1].
    tolerance_rule : {"componentwise", "prentice"}, default "componentwise"
        ``delta_k = max(atol_k, rtol_k |y_k|)`` per component, or the paper's
        scalar ``delta = min_k max(atol_k, rtol_k |y_k|)``.
    global_error_estimate : {"tangent", "paper", "shadow", "off"}, optional
        How Gamma (the quencher track's global error) is estimated: the exact
        linearisation of the quencher's step (the default of ``rk34q8``),
        the paper's ``(I + h J)``, global extrapolation from a shadow track
        on a mesh ``z_substeps`` times coarser (the default of the other
        family members, unless ``max_step`` is given), or not at all (then
        ``gamma`` is None, and nothing certifies the tolerance: the promise
        is yours to check).
    z_method : {"dop853", "cooper_verner"}, optional
        The 8th-order quencher of ``rk34q8``, ``rk45q8`` and ``rk56q8``
        (default DOP853's); an ``OptionError`` for any other method.
        ``sol.options["z_method"]`` names the quencher a run used
        (``"feagin12"`` for ``rk78q12``, say).
    z_substeps : int, optional
        Quencher steps per step of the pair (family members; the member's
        default, 2, or, with ``method="auto"``, learned from the run).  A
        value given here is kept: ``"auto"`` then never runs again.
    quencher_precision : {"double", "double-double"}, optional
        The quencher's arithmetic.  ``"double-double"`` evaluates its stages
        and ``f`` in double-double (about 32 digits, generated like the
        rest), for tolerances below double precision's rounding floor of the
        orbit (prentice2011 at 1e-12); it needs the shadow estimate of Gamma
        and costs 5 to 7 times as much per evaluation.  ``method="auto"``
        switches to it by itself when a run stops at the floor and every
        function of ``f`` has a double-double form (docs/algorithm.md).
    first_step : float, optional
        Initial step size; by default Hairer-Norsett-Wanner's heuristic for
        order 3 (as SciPy's ``select_initial_step``).
    max_step : float, default inf
        Largest step size.  With no estimate chosen and the quencher in
        double, a finite ``max_step`` selects the tangent estimate of Gamma
        (``method="auto"`` and every member whose default is the shadow): on
        a very eccentric orbit at a loose tolerance a cap well below the
        pair's steps away from the pericentre leaves the shadow estimate
        blind (SUCCESS with nodes several tolerances off; docs/algorithm.md,
        "A max_step given by the caller").  ``global_error_estimate="shadow"``
        named keeps the shadow, and that limit.
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
        direction of integration).  A step lands on a time far into it; a
        time near the step's start is passed, and its value is dense output
        (one quencher step from the nearer node, as ``sol.sol`` gives it,
        within the same bound), so times denser than the steps cost one
        quencher step each, not a step each (``docs/algorithm.md``).  With
        ``dense_output`` or ``events`` every node is kept and the values at
        these times come from the dense output, checked alike
        (:mod:`hamrkq.solve.output_times`).
    backend : {"auto", "numba", "python"}, default "auto"
        Where the step loop of ``rk34q8``/``rk34`` runs: ``"numba"``
        compiles it with the generated functions (cached on disk, see
        :mod:`hamrkq.backends.compiled`); ``"python"`` interprets it; ``"auto"`` uses
        numba when it can (``HAMRKQ_DISABLE_NUMBA=1`` turns it off) and
        otherwise Python with one :class:`~hamrkq.errors.HamrkqWarning`.
        Both give the same nodes and values, bit for bit.  On a first use,
        ``"auto"`` compiles in helper processes while the run starts
        interpreted and switches to the compiled code when it is ready
        (:mod:`hamrkq.backends.background`; ``HAMRKQ_COMPILE=wait``
        compiles first instead); ``sol.stats["interpreted_steps"]`` counts
        the steps run before the switch.
    progress : bool or callable, optional
        True: a progress bar (tqdm) on stderr when it is a terminal, with the
        share of the time span done and the current ``t``.  A callable is
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
    prepared = prepare_by_name(**locals(), background=True)  # every argument, by name
    task, spec, chosen = prepared.task, prepared.spec, prepared.backend
    # A failure is reported by the status; NumPy's RuntimeWarnings from the
    # rejected trial steps that found it (sqrt(-1), overflow), or from H at a
    # singular initial node, would only be noise.
    with np.errstate(all="ignore"):
        started = time.perf_counter()
        # every run made: (its task, run, events located); method="auto"'s
        # run again (more quencher steps, the rounding witness, the quencher
        # in double-double, the tangent estimate)
        runs: list[tuple[Task, Any, Any]] = []
        try:
            out, located = run_certified(task, spec, prepared.events, chosen)
            runs.append((task, out, located))
            while (rerun := auto.rerun(prepared.requested, task, out)) is not None:
                task = rerun
                out, located = run_certified(task, spec, prepared.events, chosen)
                runs.append((task, out, located))
            returned = auto.returned_run([(t, r) for t, r, _ in runs])
            task, out, located = runs[returned]
        except KeyboardInterrupt:
            # Ctrl-C or SIGTERM outside a step loop and outside the location
            # of events, which handle it themselves: while a run was set up
            # (a rerun's f compiled in double-double) or its nodes gathered.
            # The last run made stands, marked interrupted; before the
            # first, there is nothing to keep.
            if not runs:
                raise
            returned = len(runs) - 1
            task, out, located = runs[returned]
            out, located = _interrupted(task, out, located, prepared.events, chosen)
        finally:
            if progress is True and isinstance(task.progress, ProgressBar):
                task.progress.close()  # its own bar (not a caller's): leave it on its own line
        elapsed = time.perf_counter() - started
        if isinstance(out, Solution):  # the baselines build their own
            # compile_s and integrate_s in every run's stats, as the RKQ
            # family's (a baseline runs in Python: what it compiled is f).
            timing = {"integrate_s": elapsed, "compile_s": prepared.compile_s}
            out = assumptions.solution_within_assumptions(task, out)
            out = smoothness.solution_within_smooth_region(task, out, prepared.spec.rk8)
            return _with_events_note(out.replace(stats={**out.stats, **timing}), prepared)
        out.stats.setdefault("integrate_s", elapsed)
        # Loading the compiled code mid-run (a background compile), or
        # compiling f in double-double for a rerun, counts as compiling, in
        # every run made; a run that ended before the code was ready ran in
        # Python.
        later = len(runs) - 1 - returned  # runs made after the one returned
        discarded = [(t, r) for i, (t, r, _) in enumerate(runs) if i != returned]
        out.stats["compile_s"] = prepared.compile_s + sum(
            r.stats.pop("compile_wait_s", 0.0) for _, r, _ in runs
        )
        if task.compiling is not None and not task.compiling.loaded:
            chosen = "python"
        if discarded:
            out.stats["discarded_evaluations"] = sum(
                r.stats["nfev"] + r.stats["njev"] for _, r in discarded
            )
            out.stats["discarded_s"] = sum(r.stats["integrate_s"] for _, r in discarded)
        try:
            sol = _solution(prepared, task, out, located, discarded, chosen, dense_output, later)
        except KeyboardInterrupt:
            # Landed while the solution was put together (H at the nodes,
            # the events of a run cut at an event state located again): the
            # same, marked interrupted, once more.
            out, located = _interrupted(task, out, located, prepared.events, chosen)
            sol = _solution(prepared, task, out, located, discarded, chosen, dense_output, later)
        return _with_events_note(sol, prepared)


def _interrupted(task: Task, out: Any, located: Any, specs: list, backend: str) -> tuple:
    """A run and its events after Ctrl-C or SIGTERM outside its step loop:
    the run marked interrupted, and its events as located already, or
    else as many as are found in a short time
    (:func:`hamrkq.solve.event_check.certified_at_events`)."""
    if isinstance(out, Solution):
        return out, None
    if located is not None:
        return interrupted(out), located
    return certified_at_events(task, interrupted(out), specs, backend)


def _solution(
    prepared: Prepared,
    task: Task,
    out: Any,
    located: Any,
    discarded: list,
    chosen: str,
    dense_output: bool,
    later: int = 0,
) -> Solution:
    """The :class:`Solution` of an RKQ-family run ``out`` of ``task``: its
    message with the runs ``discarded`` (the last ``later`` of them made
    after it), and its events; ended
    before the first node whose state contradicts an assumption declared on
    its symbols (:func:`assumptions.within_assumptions`), as a baseline's is."""
    out, located, breach = assumptions.within_assumptions(task, out, located, prepared.events)
    out, located, crossing = smoothness.within_smooth_region(task, out, located, prepared.events)
    sol = outcome.solution(task, prepared.spec, out, chosen, breach)
    if crossing is not None and breach is None:
        sol = sol.replace(message=smoothness.crossing_message(crossing, task.ham, out.t))
    if discarded:
        note = rerun_notes.rerun_note(
            task,
            discarded,
            out.stats["discarded_evaluations"],
            auto=prepared.requested.method == "auto",
            later=later,
        )
        sol = sol.replace(message=sol.message + note)
    if dense_output or prepared.events or task.output_times is not None:
        sol = with_events(
            task, sol, chosen, prepared.events, dense_output, located, certificate(task, out)
        )
    return sol


def _with_events_note(sol: Solution, prepared: Prepared) -> Solution:
    """``sol`` with ``options["events_not_located"]``: why a problem file's
    events were left out of the run (the words of the warning), so that a
    saved solution and the command line's summary say it too; and with
    empty ``t_events`` and ``y_events`` where ``events=[]`` was given (SciPy's
    ``solve_ivp`` returns ``[]`` there, None only without ``events``)."""
    if prepared.events_given and not prepared.events and sol.t_events is None:
        sol = sol.replace(t_events=[], y_events=[], event_bound=[])
    if prepared.events_note is None:
        return sol
    return sol.replace(options={**sol.options, "events_not_located": prepared.events_note})
