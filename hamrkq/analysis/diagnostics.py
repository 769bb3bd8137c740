"""What a run achieved: energy drift, global and trajectory errors, the paper's bounds.

:func:`diagnose` applies the array functions of :mod:`hamrkq.analysis.bounds`
to a :class:`~hamrkq.result.Solution`, measures its error against a
reference (exact, independent, or the run's own RK8 track) and returns one
frozen :class:`~hamrkq.analysis.summaries.Diagnostics`, whose
:meth:`~hamrkq.analysis.summaries.Diagnostics.to_dict` is plain numbers (for
``summary.json``) and :meth:`~hamrkq.analysis.summaries.Diagnostics.table` a
text report.  The bounds and the records are importable from here too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from hamrkq._floats import EPS
from hamrkq.analysis.adequacy import reference_is_close
from hamrkq.analysis.bounds import (
    bound_ratio,
    component_ratio,
    energy_bound,
    tolerance,
    trajectory_bound,
    trajectory_error,
)
from hamrkq.analysis.reference import Reference, hamiltonian_reference
from hamrkq.analysis.summaries import (
    Diagnostics,
    DriftSummary,
    ErrorSummary,
    drift_summary,
    error_summary,
)
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.exact import builtin_exact_of, exact_accuracy
from hamrkq.catalogue.problem_file import energy_name_error
from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.result import Solution
from hamrkq.rkq.family import track_name
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "REFERENCE_KINDS",
    "Diagnostics",
    "DriftSummary",
    "ErrorSummary",
    "bound_ratio",
    "component_ratio",
    "diagnose",
    "drift_summary",
    "energy_bound",
    "error_summary",
    "exact_solution_accuracy",
    "tolerance",
    "trajectory_bound",
    "trajectory_error",
]

#: What a true error is measured against (``diagnose``'s ``reference``, ``hamrkq
#: run --reference``).  ``auto``: the exact solution where the catalogue has one,
#: otherwise an independent DOP853 reference (hamrkq.analysis.reference);
#: ``extended``: heyoka in extended precision (hamrkq.analysis.extended_reference).
REFERENCE_KINDS = ("auto", "exact", "independent", "extended", "rk8", "none")
#: Gamma below this many ulps of the RK8 track is rounding, not truncation.
GAMMA_ROUNDOFF_ULPS = 100


def _check_arguments(solution: Any, problem: Any) -> None:
    """Typed errors for arguments of the wrong kind or for another system."""
    if not isinstance(solution, Solution):
        raise InputTypeError(
            f"diagnose: solution must be a hamrkq.Solution, got {type(solution).__name__}"
        )
    if problem is None:
        return
    ham = getattr(problem, "hamiltonian", problem)
    if not isinstance(ham, Hamiltonian):
        raise InputTypeError(
            "diagnose: problem must be a hamrkq.Problem or a hamrkq.Hamiltonian, "
            f"got {type(problem).__name__}"
        )
    if ham.names != tuple(solution.names):
        raise InputError(
            "diagnose: the solution is not of this problem: its state is "
            f"({', '.join(solution.names)}), the problem's is ({', '.join(ham.names)})"
        )


def _from_start(t: np.ndarray, y: np.ndarray, start: tuple | None) -> tuple:
    """The nodes ``(t, y)`` with the run's initial state ``start = (t0, y0)``
    before them where it is not a node (a run with ``t_eval``), so that an
    error along the run is measured from where the run started: the first
    returned node was the baseline, and a pendulum's energy error from t = 50
    on read 18 % low, its end value with the wrong sign (found by QA)."""
    if start is None:
        return t, y
    first = np.asarray(start[1], dtype=float)[None, ...]  # a state, or one value
    return np.concatenate([[start[0]], t]), np.concatenate([first, y])


def _drifts(
    t: np.ndarray, y: np.ndarray, invariants: Mapping[str, Callable], start: tuple | None = None
) -> tuple:
    """Each invariant's drift summary along the run, from its initial state
    ``start`` where that is not a node (:func:`_from_start`).

    Raises
    ------
    InputError
        An invariant named like the energy (``"H"``, ``"energy"``), refused as
        in a problem file: its rows would replace or double the energy's.
    """
    for name in invariants:
        reason = energy_name_error(name)
        if reason:
            raise InputError(f"diagnose: invariants: {reason}")
    t, y = _from_start(t, y, start)
    return tuple(
        drift_summary(name, t, np.asarray(f(t, y), dtype=float).reshape(t.shape))
        for name, f in invariants.items()
    )


def _system(problem: Any, params: Any, sol: Any):
    """(problem, hamiltonian, params array) from a Problem, a Hamiltonian or
    nothing, at the parameters ``params`` (a mapping or an array) or, by
    default, the run's own (``sol.options["parameters"]``: a run made with
    ``solve(..., parameters=...)`` is measured at those, not at the
    problem's defaults).  A Problem comes back at those parameters too
    (:meth:`~hamrkq.catalogue.problem.Problem.with_parameters`), so that
    its exact solution, invariants and gradient are the run's system's."""
    if problem is None:
        return None, None, params
    ham = getattr(problem, "hamiltonian", problem)
    if params is None:
        params = (getattr(sol, "options", None) or {}).get("parameters")
    if params is None:
        values = (
            problem.parameter_array
            if hasattr(problem, "parameter_array")
            else ham.parameter_values()
        )
    elif isinstance(params, Mapping):
        values = ham.parameter_values(params)
    else:
        values = np.asarray(params, dtype=np.float64)
    if hasattr(problem, "with_parameters") and ham.parameters:
        named = {s.name: float(v) for s, v in zip(ham.parameters, values, strict=True)}
        if named != dict(problem.parameters):
            problem = problem.with_parameters(**named)
    return problem, ham, values


def _initial(sol) -> tuple[float, np.ndarray]:
    """Where the run started: ``t_span[0]`` and ``y0`` of its options (a run
    with ``t_eval`` need not return its initial state as a node), else its
    first node."""
    options = getattr(sol, "options", None) or {}
    y0, span = options.get("y0"), options.get("t_span")
    if y0 is not None and span is not None and len(y0) == sol.y.shape[1]:
        return float(span[0]), np.asarray(y0, dtype=float)
    return float(sol.t[0]), sol.y[0]


def _kept_nodes_note(sol) -> list[str]:
    """A note where the run returned some of its nodes only (``keep_every``
    or ``t_eval``): every number is measured at those (found by QA: the
    report did not say so)."""
    options = getattr(sol, "options", None) or {}
    keep = options.get("keep_every") or 1
    if keep > 1:
        how = f"keep_every={keep}"
    elif options.get("t_eval") is not None:
        how = "t_eval"
    else:
        return []
    return [f"measured at the {sol.t.size} nodes returned ({how}), not at the steps between them"]


def _energy(sol, ham, params, notes: list[str]) -> tuple:
    """``(start, H(y_i) - H(y0) at the nodes, its DriftSummary)``, ``start``
    as :func:`_start` gives it."""
    start, energy0 = _start(sol, ham, params, notes)
    if start is None:
        return start, sol.energy - energy0, drift_summary("energy", sol.t, sol.energy)
    summary = drift_summary("energy", *_from_start(sol.t, sol.energy, (start[0], energy0)))
    return start, sol.energy - energy0, summary


def _start(sol, ham, params, notes: list[str]) -> tuple[tuple | None, float]:
    """``((t0, y0), H(t0, y0))`` where the run's initial state is not its
    first node (a run with ``t_eval``), ``(None, H at the first node)``
    where it is; without the system to evaluate H at y0, the first node,
    with a note."""
    t0, y0 = _initial(sol)
    if sol.t.size and sol.t[0] == t0 and np.array_equal(sol.y[0], y0):
        return None, float(sol.energy[0])
    if ham is None:
        notes.append(
            f"the energy error is measured from the first returned node (t = "
            f"{float(sol.t[0])!r}), not from the initial state at t = {t0!r}: give the "
            "problem or Hamiltonian to measure it from there"
        )
        return None, float(sol.energy[0])
    energy0 = numeric_of(ham).energy(np.array([t0]), y0[None, :], params)
    return (t0, y0), float(np.asarray(energy0).ravel()[0])


def exact_solution_accuracy(states, times, ham, params, exact_from=(None, None)) -> float:
    """What an exact solution's ``states`` at ``times`` are accurate to
    (:func:`~hamrkq.catalogue.exact.exact_accuracy`): a built-in solution's
    own (``exact_from`` = ``(name, y0)``, :func:`~hamrkq.catalogue.exact.builtin_exact_of`),
    and for one written in t, whose phase rounds, a term in ``|t| |f|`` with
    ``f`` the right-hand side of ``ham`` (None: left out).  What diagnose and
    compare state."""
    builtin, start = exact_from
    rates = None
    if builtin is None and ham is not None:
        with np.errstate(all="ignore"):
            rates = numeric_of(ham).rhs_many(times, states, params)
    return exact_accuracy(states, builtin, start, times, rates)


def _no_exact_solution(problem: Any) -> str:
    """Why ``reference="exact"`` cannot be had: the problem given has none
    (a problem file without an ``[exact]`` table), or none was given."""
    name = getattr(problem, "name", None)
    if hasattr(problem, "exact") and name:
        return (
            f"reference='exact': problem {name!r} has no exact solution; use "
            "reference='independent', or pass exact= (a function of t)"
        )
    return (
        "reference='exact' needs an exact solution: pass exact= (a function of t) or a "
        "problem that has one"
    )


def _reference_states(sol, kind, ham, params, exact, periodic, exact_from=(None, None)):
    """(states, source, description, accuracy) for a reference kind or object;
    the independent references start from where the run started
    (:func:`_initial`).  ``exact_from`` is ``(builtin name, y0)`` where
    ``exact`` is a problem's built-in solution, whose accuracy it states
    (:func:`~hamrkq.catalogue.exact.exact_accuracy`); any other exact
    solution's accuracy grows with ``|t| |f|``, its phase's rounding, where
    ``ham`` gives ``f``."""
    t0, y0 = _initial(sol)
    if isinstance(kind, Reference):
        if kind.y.shape != sol.y.shape or not np.array_equal(kind.t, sol.t):
            raise InputError("reference must be computed at the solution's node times")
        return kind.y, "independent", kind.method, kind.estimated_error
    if kind == "rk8":
        if sol.z is None:
            raise InputError(
                f"reference='rk8' needs a quencher track; method {sol.method!r} has none"
            )
        gamma = float(np.max(np.abs(sol.gamma))) if sol.gamma is not None else float("nan")
        return sol.z, "rk8", _own_track(sol), gamma
    if kind == "exact":
        if exact is None:
            raise InputError(_no_exact_solution(None))
        states = np.asarray(exact(sol.t), dtype=float).reshape(sol.y.shape)
        if sol.t.size and t0 == sol.t[0]:
            _check_exact_start(states[0], sol.y[0])
        else:  # a run with t_eval: its initial state is not a node
            _check_exact_start(_exact_at(exact, t0), y0)
        accuracy = exact_solution_accuracy(states, sol.t, ham, params, exact_from)
        return states, "exact", "exact solution", accuracy
    if kind == "independent":
        if ham is None:
            raise InputError("reference='independent' needs a problem or a Hamiltonian")
        ref = hamiltonian_reference(ham, y0, sol.t, params=params, t0=t0, periodic=periodic)
        return ref.y, "independent", ref.method, ref.estimated_error
    if kind == "extended":
        if ham is None:
            raise InputError("reference='extended' needs a problem or a Hamiltonian")
        from hamrkq.analysis.extended_reference import extended_reference

        ref = extended_reference(ham, params, y0, sol.t, t0=t0)
        return ref.y, "extended", ref.method, ref.estimated_error
    raise OptionError(f"reference must be one of {REFERENCE_KINDS} or a Reference, got {kind!r}")


def _exact_at(exact: Callable, t0: float) -> np.ndarray:
    """The exact solution's state at ``t0``."""
    return np.asarray(exact(np.array([t0])), dtype=float).reshape(-1)


def _check_exact_start(start: np.ndarray, y0: np.ndarray) -> None:
    """An InputError unless the exact solution's state ``start`` at the
    run's initial time is the run's initial state ``y0`` (a run from other
    initial values, or from another t0, is not the exact solution's)."""
    scale = max(float(np.max(np.abs(start))), float(np.max(np.abs(y0))))
    if np.max(np.abs(start - y0)) > 1e-9 * (1.0 + scale):
        raise InputError(
            f"the exact solution starts at {start.tolist()}, not at the run's "
            f"initial state {y0.tolist()}; use reference='independent'"
        )


def _auto_reference(sol: Any, exact: Callable | None, notes: list[str]) -> str:
    """``reference="auto"``: the exact solution where it applies to this run
    (it starts at the run's initial state), else the run's own track, else
    none; a note says why an exact solution was passed over."""
    fallback = "rk8" if sol.z is not None else "none"
    if exact is None:
        return fallback
    try:
        t0, y0 = _initial(sol)
        _check_exact_start(_exact_at(exact, t0), y0)
    except InputError as exc:
        notes.append(f"the exact solution does not apply ({exc}); reference {fallback!r}")
        return fallback
    return "exact"


def _gamma_max(sol: Any, series: dict, notes: list[str]) -> float:
    """Largest ``|Gamma|`` (nan without one), with a note when it is rounding."""
    if sol.gamma is None:
        return float("nan")
    series["gamma"] = sol.gamma
    gamma_max = float(np.max(np.abs(sol.gamma)))
    track = sol.z if sol.z is not None else sol.y
    roundoff = GAMMA_ROUNDOFF_ULPS * EPS * float(np.max(np.abs(track)))
    options = sol.options or {}
    # a double-double quencher's rounding is some 1e-30 of its size, far below
    if gamma_max < roundoff and options.get("quencher_precision") != "double-double":
        estimate = options.get("global_error_estimate", "tangent")
        notes.append(
            f"max |Gamma| = {gamma_max:.1e} is at the roundoff level of the "
            f"{track_name(sol.method)}: the {estimate} estimate measures rounding, not "
            "truncation"
        )
    return gamma_max


def _own_track(sol: Any) -> str:
    return f"the run's own {track_name(sol.method)} (the paper's yardstick)"


def diagnose(
    solution: Any,
    problem: Any = None,
    *,
    reference: str | Reference = "auto",
    params: Any = None,
    gradient: Callable[[Any, np.ndarray], np.ndarray] | None = None,
    invariants: Mapping[str, Callable[[Any, np.ndarray], np.ndarray]] | None = None,
    exact: Callable[[Any], np.ndarray] | None = None,
    periodic: bool | None = None,
) -> Diagnostics:
    """Energy drift, global errors and the paper's bounds for one solution.

    Parameters
    ----------
    solution : Solution
        Any run (a partial one too: its nodes so far are diagnosed).
    problem : Problem or Hamiltonian, optional
        Supplies the gradient of H, the invariants, the exact solution and the
        right-hand side for an independent reference.
    reference : {"auto", "exact", "independent", "extended", "rk8", "none"} or Reference
        What the true error is measured against.  ``"auto"``: the exact
        solution if there is one and it applies (it starts at the run's
        initial state), else the run's RK8 track, else nothing (an
        independent reference costs a tight integration, so it is never
        chosen silently).  ``"extended"``: heyoka's Taylor integrator in
        extended precision (:mod:`hamrkq.analysis.extended_reference`; the
        ``bench`` extra), for tolerances below what ``"independent"`` reaches.
        A :class:`~hamrkq.analysis.reference.Reference` computed at
        ``solution.t`` can be passed directly (to share it between runs).
    params : array_like or mapping, optional
        Parameter values; default the run's own (``solution.options
        ["parameters"]``), else the problem's.  The problem's exact solution,
        invariants and gradient are taken at these.
    gradient : callable, optional
        ``gradient(t, Y) -> (N, 2n)``, dH/dy at the rows of Y; default from
        the problem.  Without it the energy bound is not evaluated.
    invariants : mapping, optional
        ``name -> f(t, Y) -> (N,)``; default the problem's invariants.
    exact : callable, optional
        ``exact(t) -> (N, 2n)``; default the problem's exact solution.
    periodic : bool, optional
        Passed to :func:`hamrkq.analysis.reference.hamiltonian_reference`.

    Returns
    -------
    Diagnostics

    Raises
    ------
    InputTypeError
        ``solution`` is not a :class:`~hamrkq.result.Solution`, or ``problem``
        is neither a Problem nor a Hamiltonian.
    InputError
        ``problem`` is not the system ``solution`` was computed for (another
        number or other names of state components), or an invariant is named
        ``"H"`` or ``"energy"`` (the energy's own rows).
    """
    _check_arguments(solution, problem)
    sol = solution
    problem, ham, params = _system(problem, params, sol)
    exact_from: tuple[str | None, Any] = (None, None)  # (builtin name, its y0)
    if ham is not None:
        if gradient is None:
            gradient = lambda t, Y: numeric_of(ham).gradient(t, Y, params)  # noqa: E731
        if invariants is None and hasattr(problem, "invariant_functions"):
            invariants = problem.invariant_functions()
        if exact is None and getattr(problem, "exact", None) is not None:
            exact = problem.exact
            exact_from = builtin_exact_of(problem)
    notes: list[str] = _kept_nodes_note(sol)
    kind = reference
    if isinstance(kind, str) and kind == "auto":
        kind = _auto_reference(sol, exact, notes)
    if isinstance(kind, str) and kind == "exact" and exact is None:
        raise InputError(_no_exact_solution(problem))
    t, y = sol.t, sol.y
    rule = str(sol.options.get("tolerance_rule", "componentwise"))
    delta = tolerance(y, sol.atol, sol.rtol, rule)
    start, energy_error, energy = _energy(sol, ham, params, notes)
    series: dict[str, np.ndarray] = {
        "t": t,
        "delta": delta,
        "trajectory_bound": trajectory_bound(delta),
        "energy_error": energy_error,
    }
    ratio = t_ratio = float("nan")
    if gradient is not None:
        series["energy_bound"] = energy_bound(gradient(t, y), delta)
        ratio, t_ratio = bound_ratio(series["energy_error"], series["energy_bound"], t)
    if ham is not None and ham.time_dependent:
        notes.append(
            "H depends on t explicitly: the energy is not conserved, its error is no "
            "measure of accuracy"
        )
    drifts = _drifts(t, y, invariants or {}, start)
    names = tuple(sol.names)
    estimated = None
    if sol.global_error is not None:
        series["estimated_error"] = sol.global_error
        accuracy = float(np.max(np.abs(sol.gamma))) if sol.gamma is not None else float("nan")
        estimated = error_summary(
            t,
            sol.global_error,
            delta,
            source="rk8",
            reference_accuracy=accuracy,
            names=names,
            description=_own_track(sol),
        )
    error = None
    track_error = float("nan")
    if not (isinstance(kind, str) and kind == "none"):
        states, source, description, accuracy = _reference_states(
            sol, kind, ham, params, exact, periodic, exact_from
        )
        series["reference"] = states
        series["error"] = y - states
        if source == "rk8" and estimated is not None:
            error = estimated
        else:
            if sol.z is not None and source != "rk8":
                # what Gamma estimates, measured: |Gamma| read 4.7e-09 on Kepler
                # e = 0.85 where the quencher track was 5.8e-07 off (QA)
                track_error = float(np.max(np.abs(sol.z - states), initial=0.0))
            error = error_summary(
                t,
                series["error"],
                delta,
                source=source,
                description=description,
                reference_accuracy=accuracy,
                names=names,
            )
        notes += _error_notes(sol, error, accuracy, delta)
    gamma_max = _gamma_max(sol, series, notes)
    if not sol.success:
        notes.append(f"partial run: {sol.message}")
    for name, value in series.items():
        series[name] = np.array(value, dtype=float)
        series[name].setflags(write=False)
    return Diagnostics(
        method=sol.method,
        status=sol.status.name,
        message=sol.message,
        nodes=int(t.size),
        stats=dict(sol.stats),
        tolerance_rule=rule,
        energy=energy,
        energy_bound_ratio=ratio,
        t_energy_bound_ratio=t_ratio,
        invariants=drifts,
        estimated=estimated,
        error=error,
        gamma_max=gamma_max,
        notes=tuple(notes),
        series=dict(series),
        time_dependent=bool(ham is not None and ham.time_dependent),
        track_error=track_error,
    )


#: What a certified run promises: every node's true error within this many
#: tolerances (docs/algorithm.md, "The promise").
PROMISE = 1.05


def _error_notes(sol: Any, error: ErrorSummary, accuracy: float, delta: Any) -> list[str]:
    """Notes on the true error measured against a reference of ``accuracy``:
    a reference not far below the tolerance leaves it uncertain; and where
    a run that Gamma certified (an estimate, a finite ``gamma_limit``) has a
    node further from an accurate independent reference than
    :data:`PROMISE` tolerances, a silent failure, which the report must not
    pass over (QA: ``hamrkq run`` printed 1.0916 for such a run, no note,
    exit status 0)."""
    if reference_is_close(accuracy, delta):
        return [
            f"the reference ({error.source}) is accurate only to ~{accuracy:.1e}, not "
            "far below the tolerance: the true error is uncertain by that much"
        ]
    certified = sol.gamma is not None and sol.options.get("gamma_limit") is not None
    ratio = error.component_ratio
    if error.source == "rk8" or not certified or not ratio > PROMISE:
        return []
    return [
        f"the promise is broken: a node is {ratio:.4g} tolerances off "
        f"({error.component_ratio_name}, t = {error.t_component_ratio:.6g}) against the "
        f"reference ({error.source}), above the {PROMISE} that every node of a certified "
        "run keeps: a silent failure of the certificate; please report it with this "
        "run's settings"
    ]
