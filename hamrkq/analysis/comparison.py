"""The numerics behind ``hamrkq compare``: sweeps, true errors, matched settings.

:func:`compare` runs every method on one problem over a range of settings
(tolerances for the adaptive methods, step sizes for the fixed-step ones),
measures every run against one independent reference, and picks for each
method the run to put in the headline table:

- ``match="error"`` (default): the cheapest run (fewest ``f`` evaluations)
  whose max true global error is at most that of the *anchor*, RKQ
  (``rk34q8``) at the problem's default tolerance;
- ``match="cost"``: the run whose number of ``f`` evaluations is nearest
  (in ratio) to the anchor's.

With ``match="error"`` the sweep is then refined, in up to two rounds: a
method whose sweep does not reach the target gets a run at a setting
extrapolated from its two most accurate runs (error and cost as power laws of
the setting), and one whose cheapest sufficient run has an error below 0.3 of
the target (more than 3.3 times too accurate) gets a run interpolated between
it and the next cheaper run;
none is run when it is predicted to cost more than ten times the anchor (the
notes say so).

Settings.  Adaptive methods get the problem's default ``atol``/``rtol`` times
each factor of the sweep (SciPy reads them with its own norm, see
:mod:`hamrkq.baselines.scipy_ivp`).  A fixed-step method gets ``h_ref`` times each
factor, where ``h_ref`` spends as many ``f`` evaluations as the anchor run:
``h_ref = span * (f per step) / nfev_anchor``, the cost per step measured on a
short pilot run (Newton iterations vary with h and the problem).

The true error of every run is measured against the same reference at its
own nodes: the problem's exact solution where the catalogue has one, else
:func:`hamrkq.analysis.reference.hamiltonian_reference` (a periodic-orbit reference for
one degree of freedom, a tight DOP853 integration otherwise), evaluated once
at the union of all node times.  Runs with many nodes are thinned to about
:data:`MAX_NODES` kept nodes (``keep_every``), which does not change the
integration.  The figures are drawn by :mod:`hamrkq.cli.compare`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hamrkq.analysis.comparison_runs import Comparison, Run, at_reference_floor
from hamrkq.analysis.diagnostics import drift_summary, exact_solution_accuracy
from hamrkq.analysis.reference import hamiltonian_reference
from hamrkq.catalogue.exact import builtin_exact_of
from hamrkq.errors import InputError, OptionError
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS, SPLITTING_SCHEMES, solve_fixed
from hamrkq.result import Solution
from hamrkq.rkq.auto_rules import AUTO_MEMBER
from hamrkq.rkq.family import MEMBERS, has_quencher
from hamrkq.solve import DEFAULT_MAX_STEPS, METHODS, solve

__all__ = [
    "DEFAULT_METHODS",
    "MATCH_MODES",
    "Comparison",
    "Run",
    "at_reference_floor",
    "compare",
    "default_methods",
]

#: Methods compared by default (splitting methods only for separable H):
#: the paper's RKQ, the RKQ family's choice, and the baselines.
DEFAULT_METHODS = ("rk34q8", "auto", "rk34", "scipy:DOP853", "gauss4", "gauss6", "yoshida4")
ANCHOR = "rk34q8"
MATCH_MODES = ("error", "cost")
#: Sweep factors: RKQ's tolerances are the problem's default times these ...
TOL_FACTORS = (1e2, 1e1, 1.0, 1e-1, 1e-2)
QUICK_TOL_FACTORS = (1e1, 1.0, 1e-1)
#: ... the other adaptive methods reach further down: they control the local
#: error only, so they need tighter tolerances for the same global error ...
OTHER_TOL_FACTORS = (1e1, 1.0, 1e-1, 1e-2, 1e-3, 1e-4)
QUICK_OTHER_TOL_FACTORS = (1.0, 1e-2, 1e-4)
#: ... and steps are h_ref (matched cost) times these: RKQ spends about 40 f
#: evaluations a step, so matched-error steps are usually several h_ref.
STEP_FACTORS = (16.0, 8.0, 4.0, 2.0, 1.0, 0.5)
QUICK_STEP_FACTORS = (8.0, 2.0, 0.5)
#: Methods whose tolerance is a bound on the global error besides the RKQ
#: family's members with a quencher and ``auto`` (:func:`_global_control`).
_GLOBAL_CONTROL = ("scipy:RK34Q8",)
#: With match="error", a method whose sweep misses the target error gets up to
#: this many extra runs at an extrapolated setting (see ``_extension``) ...
EXTEND_ROUNDS = 2
#: ... unless the run is predicted to cost more than this many times the anchor.
EXTEND_COST_CAP = 10.0
#: An extrapolation to a coarser setting goes at most this far at once; so
#: far exactly when the runs give no slope to extrapolate (all far below the
#: target, their errors flat: at the reference's floor or at rounding).
MAX_COARSENING = 4.0
#: A headline run whose error is below this fraction of the target gets a
#: note: it meets the target at a cost that is only an upper bound.
FAR_BELOW = 0.1
#: Keep about this many nodes per run (errors are maxima over the kept nodes).
MAX_NODES = 20000
#: Pilot run of a fixed-step method: this many steps, to measure f per step.
PILOT_STEPS = 20
#: Order of the local error each adaptive method controls: estimates how the
#: number of steps grows as the tolerance shrinks (only to choose keep_every).
_CONTROLLED_ORDER = {"scipy:RK23": 2, "scipy:RK45": 4, "scipy:DOP853": 7,
                     "scipy:RK34Q8": 3}  # fmt: skip


def _member(method: str):
    """The RKQ family member a method name runs (auto's first choice), or None."""
    return MEMBERS.get(AUTO_MEMBER if method == "auto" else method)


def _global_control(method: str) -> bool:
    """Whether the method's tolerance bounds the global error (RKQ)."""
    return method in _GLOBAL_CONTROL or has_quencher(method)


def _controlled_order(method: str) -> int:
    """Order of the local error the method's step control sees."""
    member = _member(method)
    return member.error_order if member is not None else _CONTROLLED_ORDER.get(method, 4)


def default_methods(problem: Any) -> list[str]:
    """:data:`DEFAULT_METHODS`, without the splitting methods for a non-separable H."""
    separable = problem.hamiltonian.is_separable
    return [m for m in DEFAULT_METHODS if separable or m not in SPLITTING_SCHEMES]


# -- running -------------------------------------------------------------------------
def _keep_every(estimated_steps: float) -> int:
    return max(1, int(estimated_steps // MAX_NODES))


def _timed(problem, method, t_span, settings, keep_every, backend) -> tuple[Solution, float]:
    # The backend is RKQ's (its loop compiles); solve refuses one it does not have.
    extra: dict[str, Any] = {"backend": backend} if _member(method) is not None else {}
    if "step" in settings:  # solve's default step limit must not cut a fixed-step sweep short
        span = abs(t_span[1] - t_span[0])
        extra["max_steps"] = max(DEFAULT_MAX_STEPS, math.ceil(span / settings["step"]) + 2)
    started = time.perf_counter()
    # events=[]: a problem file's [[events]] are not what is compared (and
    # only RKQ with every node kept could locate them)
    sol = solve(problem, method=method, t_span=t_span, keep_every=keep_every, events=[],
                **settings, **extra)  # fmt: skip
    return sol, time.perf_counter() - started


def _ready_to_time(problem, methods, t_span, backend) -> str:
    """The backend, resolved, with the compiled code compiled or loaded, and
    every method run once, untimed, over a thousandth of the interval.

    A first use would otherwise time the compiler (or, compiling in the
    background, runs on the interpreted loop), and what a method's first
    call pays once (building the numerical functions, the kernel's first
    signature) would land in the first run of its sweep: SciPy's DOP853 on
    the harmonic oscillator took 0.30 s in its first run and 0.013 s in the
    next, tighter one."""
    from hamrkq.backends import first_use

    backend = first_use.resolve_backend(backend, problem.hamiltonian)
    t0, t_end = t_span
    short = (t0, t0 + (t_end - t0) * 1e-3)
    for method in methods:
        if method in FIXED_STEP_METHODS:
            settings = {"step": abs(short[1] - short[0]) / 4}
        else:
            settings = _tolerances(problem, 1.0)
        _timed(problem, method, short, settings, 1, backend)
    return backend


def _tolerances(problem: Any, factor: float) -> dict[str, Any]:
    integration = problem.integration
    atol = np.asarray(integration.get("atol", 1e-6), dtype=float) * factor
    rtol = np.asarray(integration.get("rtol", 0.0), dtype=float) * factor
    return {"atol": atol.tolist() if atol.ndim else float(atol),
            "rtol": rtol.tolist() if rtol.ndim else float(rtol)}  # fmt: skip


def _cost_per_step(problem, method, t_span, h) -> float:
    """f evaluations per step of a fixed-step method, from a short pilot run."""
    t0, t_end = t_span
    length = math.copysign(min(abs(t_end - t0), PILOT_STEPS * h), t_end - t0)
    pilot = solve_fixed(problem.hamiltonian, problem.y0, (t0, t0 + length), method, h,
                        problem.parameter_array)  # fmt: skip
    steps = max(pilot.stats["steps"], 1)
    return max(pilot.nfev / steps, 1.0)


def _checked_methods(problem: Any, methods: Sequence[str] | None, match: str) -> list[str]:
    """The methods to compare, the anchor first; bad names and splitting
    methods on a non-separable H are refused."""
    if match not in MATCH_MODES:
        raise OptionError(f"match={match!r} is not valid; valid values: 'error', 'cost'")
    methods = list(default_methods(problem) if methods is None else methods)
    unknown = [m for m in methods if m not in METHODS and m != "auto"]
    if unknown:
        raise OptionError(
            f"unknown method(s) {', '.join(map(repr, unknown))}; valid: 'auto', "
            f"{', '.join(METHODS)}"
        )
    if not problem.hamiltonian.is_separable:
        refused = [m for m in methods if m in SPLITTING_SCHEMES]
        if refused:
            raise OptionError(
                f"{', '.join(map(repr, refused))} {'needs' if len(refused) == 1 else 'need'} "
                "a separable H = T(p) + V(q); "
                f"problem {problem.name!r} is not separable"
            )
    return [ANCHOR, *[m for m in dict.fromkeys(methods) if m != ANCHOR]]


def _factors(quick: bool, tol_factors, step_factors) -> tuple[tuple[float, ...], ...]:
    """The sweeps: tolerance factors for RKQ and for the other adaptive
    methods, step factors for the fixed-step ones."""
    own = tuple(tol_factors or (QUICK_TOL_FACTORS if quick else TOL_FACTORS))
    other = tuple(tol_factors or (QUICK_OTHER_TOL_FACTORS if quick else OTHER_TOL_FACTORS))
    steps = tuple(step_factors or (QUICK_STEP_FACTORS if quick else STEP_FACTORS))
    if any(not (f > 0 and math.isfinite(f)) for f in (*own, *other, *steps)):
        raise InputError("sweep factors must be positive finite numbers")
    return own, other, steps


def compare(
    problem: Any,
    methods: Sequence[str] | None = None,
    *,
    t_end: float | None = None,
    quick: bool = False,
    match: str = "error",
    tol_factors: Sequence[float] | None = None,
    step_factors: Sequence[float] | None = None,
    backend: str = "auto",
    log: Callable[[str], None] | None = None,
) -> Comparison:
    """Run every method over its sweep and measure each run against one reference.

    Parameters
    ----------
    problem : Problem
        A catalogue problem (its defaults set the base tolerance and interval).
    methods : sequence of str, optional
        Names accepted by :func:`hamrkq.solve`; default :func:`default_methods`.
        The anchor ``rk34q8`` is always run (added first if missing).
    t_end : float, optional
        End of the interval; default the problem's.
    quick : bool
        Three settings per method instead of five.
    match : {"error", "cost"}
        How the headline run of each method is chosen (module docstring).
    tol_factors, step_factors : sequence of float, optional
        Override the sweeps (multiples of the default tolerance for every
        adaptive method, of ``h_ref`` for the fixed-step ones).
    backend : str
        Passed to :func:`hamrkq.solve` for methods that have backends.
    log : callable, optional
        ``log(text)`` after each run (progress for the command line).

    Returns
    -------
    Comparison
    """
    methods = _checked_methods(problem, methods, match)
    t0 = problem.t_span[0]
    t_span = (t0, problem.t_span[1] if t_end is None else float(t_end))
    span = abs(t_span[1] - t_span[0])
    if span == 0:
        raise InputError(f"the interval t_span={t_span} is empty: choose t_end != t0")
    own_factors, other_factors, step_factors = _factors(quick, tol_factors, step_factors)
    note = log or (lambda text: None)
    notes: list[str] = []
    backend = _ready_to_time(problem, methods, t_span, backend)
    anchor_sol, anchor_time = _timed(problem, ANCHOR, t_span, _tolerances(problem, 1.0), 1,
                                     backend)  # fmt: skip
    anchor = Run(ANCHOR, 1.0, _tolerances(problem, 1.0), anchor_sol, anchor_time)
    note(
        f"{ANCHOR} {anchor.describe()}: {anchor_sol.status.name}, {anchor.nfev} f evaluations, "
        f"{anchor_time:.2f} s"
    )
    anchor_steps = max(anchor_sol.stats["steps"], 1)
    h_ref: dict[str, float] = {}

    def run(method: str, factor: float) -> Run:
        if method in FIXED_STEP_METHODS:
            settings = {"step": h_ref[method] * factor}
            estimated = span / settings["step"]
        else:
            settings = _tolerances(problem, factor)
            order = _controlled_order(method)
            estimated = anchor_steps * factor ** (-1.0 / (order + 1))
        sol, wall = _timed(problem, method, t_span, settings, _keep_every(estimated), backend)
        out = Run(method, factor, settings, sol, wall)
        note(f"{method} {out.describe()}: {sol.status.name}, {sol.nfev} f evaluations, "
             f"{wall:.2f} s")  # fmt: skip
        return out

    runs: list[Run] = [anchor]
    for method in methods:
        if method in FIXED_STEP_METHODS:
            per_step = _cost_per_step(problem, method, t_span, span * 2.0 / max(anchor.nfev, 1))
            h_ref[method] = min(span * per_step / max(anchor.nfev, 1), span / 4)
            factors = step_factors
        else:
            factors = own_factors if _global_control(method) else other_factors
        runs += [run(method, f) for f in factors if not (method == ANCHOR and f == 1.0)]

    states, description, accuracy = _reference(problem, runs)
    measured = [_measure(r, states) for r in runs]
    anchor = measured[0]
    if not anchor.success:
        notes.append(f"the anchor run {ANCHOR} did not succeed: {anchor.solution.message}")
    target = anchor.max_error if match == "error" else float(anchor.nfev)
    pending = list(methods)
    for _ in range(EXTEND_ROUNDS if match == "error" else 0):
        extra = []
        for method in pending:
            factor = _extension(method, measured, target, EXTEND_COST_CAP * anchor.nfev, notes)
            if factor is not None:
                extra.append(run(method, factor))
        # Only a method that ran again can be extended again: the others' runs
        # are as they were, and asking again would repeat their answer (and
        # its note, "not run" once a round, twice in comparison.md).
        pending = [r.method for r in extra]
        if not extra:
            break
        more, _, more_accuracy = _reference(problem, extra)
        accuracy = max(accuracy, more_accuracy)
        measured += [_measure(r, more) for r in extra]
    order = {m: i for i, m in enumerate(methods)}
    measured.sort(key=lambda r: (order[r.method], -r.factor))
    measured = _select(measured, methods, match, target, notes)
    notes += _closing_notes(measured, match, target, accuracy, problem)
    anchor = next(r for r in measured if r.method == ANCHOR and r.factor == 1.0)
    return Comparison(
        problem=problem.name,
        t_span=t_span,
        runs=tuple(measured),
        match=match,
        target=target,
        anchor=anchor,
        reference=description,
        reference_accuracy=accuracy,
        backend=backend,
        notes=tuple(notes),
    )


# -- measuring -------------------------------------------------------------------------
def _reference(problem: Any, runs: list[Run]) -> tuple[dict[str, np.ndarray], str, float]:
    """Reference states at every node time of every run, keyed by time."""
    times = np.unique(np.concatenate([run.solution.t for run in runs]))
    if problem.exact is not None:
        states = np.asarray(problem.exact(times), dtype=float).reshape(times.size, -1)
        description = "exact solution"
        accuracy = exact_solution_accuracy(
            states, times, problem.hamiltonian, problem.parameter_array,
            builtin_exact_of(problem),
        )  # fmt: skip
    else:
        ref = hamiltonian_reference(problem, problem.y0, times, t0=problem.t_span[0])
        states, description, accuracy = ref.y, ref.method, ref.estimated_error
    return {"times": times, "states": states}, description, float(accuracy)


def _measure(run: Run, reference: dict[str, np.ndarray]) -> Run:
    sol = run.solution
    if len(sol) < 2:
        return run
    index = np.searchsorted(reference["times"], sol.t)
    error = sol.y - reference["states"][index]
    energy = drift_summary("energy", sol.t, sol.energy)
    finite = np.isfinite(error).all()
    return Run(
        run.method, run.factor, run.settings, sol, run.wall_time,
        max_error=float(np.max(np.abs(error))) if finite else math.inf,
        max_energy_error=energy.max_abs,
        relative_energy_error=energy.relative_max,
        drift=energy.drift,
        drift_stderr=energy.drift_stderr,
    )  # fmt: skip


#: A method's cheapest run that reached the target is refined when its error
#: is below this fraction of the target.
REFINE_BELOW = 0.3


def _extension(method: str, runs: list[Run], target: float, cost_cap: float,
               notes: list[str]) -> float | None:  # fmt: skip
    """The next setting (factor) for a method, so that matched error is matched closely.

    ``log error`` and ``log nfev`` are taken as straight lines in ``log factor``
    through two runs: the two most accurate when no run has reached the
    target (aiming at 0.7 target), or, when the cheapest run that reached it
    is more than 3.3 times too accurate (error below :data:`REFINE_BELOW` of
    the target), that run and the dearest one that
    missed (aiming at 0.8 target, between the two; or beyond the cheapest run,
    at most :data:`MAX_COARSENING` times its setting, when no run missed).
    Where the runs are all far below the target and their errors flat
    (slope below 0.2: both at the reference's floor, or at rounding), there
    is no slope to extrapolate with and the next setting is
    :data:`MAX_COARSENING` times the cheapest run's, coarser and cheaper:
    before, nothing was run and ``compare --quick`` put gauss6 on
    henon_heiles at h = 0.0315 (5727 f evaluations, error 1.7e-13 against
    a target of 1e-8) where h = 0.126 meets the target with 1911.  None when
    there is nothing to do, the error does not fall with the factor where
    it should, or the run would cost more than ``cost_cap`` (then a note
    says so).
    """
    if _global_control(method) or not target > 0:
        return None
    own = [r for r in runs if r.method == method and r.success
           and 0 < r.max_error < math.inf and r.nfev > 0]  # fmt: skip
    reached = [r for r in own if r.max_error <= target]
    bracket = False
    if reached:
        best = min(reached, key=lambda r: r.nfev)
        if best.max_error >= REFINE_BELOW * target:
            return None
        missed = [r for r in own if r.max_error > target and r.nfev < best.nfev]
        dearer = sorted((r for r in own if r.nfev > best.nfev), key=lambda r: r.nfev)
        if missed:  # interpolate between the two
            second, bracket = max(missed, key=lambda r: r.nfev), True
        elif dearer:  # even the cheapest run is too accurate: extrapolate to coarser
            second = dearer[0]
        else:
            return None
        aim = 0.8 * target
    else:
        if len(own) < 2:
            return None
        best, second = sorted(own, key=lambda r: r.max_error)[:2]
        aim = 0.7 * target
    span = math.log(second.factor / best.factor)
    if span == 0:
        return None
    slope = math.log(second.max_error / best.max_error) / span
    if slope < 0.2 and reached and not bracket:
        # far below the target and flat: the errors say nothing of the
        # setting that meets it; a coarser run is cheap and will
        return best.factor * MAX_COARSENING
    if slope < 0.2:  # the error no longer falls with the setting (rounding, instability)
        return None
    factor = best.factor * (aim / best.max_error) ** (1.0 / slope)
    low, high = sorted((best.factor, second.factor))
    if bracket and not low < factor < high:
        return None
    if reached and not bracket:
        factor = min(factor, MAX_COARSENING * best.factor)  # stay near the measured runs
    cost_slope = math.log(second.nfev / best.nfev) / span
    cost = best.nfev * (factor / best.factor) ** cost_slope
    if cost > cost_cap:
        notes.append(
            f"{method}: reaching the target error would take about {cost:.2g} f evaluations "
            f"(over the cap of {cost_cap:.2g}, {EXTEND_COST_CAP:g} x the anchor's); not run"
        )
        return None
    return factor


def _closing_notes(
    runs: list[Run], match: str, target: float, accuracy: float, problem: Any
) -> list[str]:
    """The notes on the chosen runs: headline runs far below the target,
    errors at the reference's floor, a time-dependent H."""
    notes = _far_below(runs, target) if match == "error" else []
    if accuracy > 0.01 * min((r.max_error for r in runs if r.max_error > 0), default=1):
        notes.append(
            f"the reference is accurate to ~{accuracy:.1e}, not far below the smallest "
            "error measured: the smallest errors are uncertain by that much"
            + _floor(runs, accuracy)
        )
    if problem.hamiltonian.time_dependent:
        notes.append("H depends on t: the energy error measures nothing here")
    return notes


def _far_below(runs: list[Run], target: float) -> list[str]:
    """A note for each headline run (but the anchor's) whose error is below
    :data:`FAR_BELOW` of the target: it is more accurate than asked, so its
    f evaluations only bound the cost of matching the target from above."""
    notes = []
    for run in runs:
        if run.selected and run.method != ANCHOR and 0 <= run.max_error < FAR_BELOW * target:
            notes.append(
                f"{run.method}: the headline run ({run.describe()}) has error "
                f"{run.max_error:.2g}, {target / max(run.max_error, 1e-300):.2g} times below the "
                f"target {target:.3g}: no coarser run that meets the target was found, so its "
                f"{run.nfev} f evaluations are an upper bound of the cost at matched error"
            )
    return notes


def _floor(runs: list[Run], accuracy: float) -> str:
    """The runs at the reference's floor (:func:`at_reference_floor`), for
    the note on uncertain errors."""
    low = [r for r in runs if at_reference_floor(r, accuracy)]
    if not low:
        return ""
    shown = ", ".join(f"{r.method} {r.describe()} ({r.max_error:.2g})" for r in low)
    return (
        f"; at or below it, at the reference's floor (the reference's own error, the run's "
        f"is at most about ~{accuracy:.1e}): {shown}"
    )


def _select(runs: list[Run], methods: list[str], match: str, target: float,
            notes: list[str]) -> list[Run]:  # fmt: skip
    chosen: set[int] = set()
    for method in methods:
        own = [(i, r) for i, r in enumerate(runs) if r.method == method and r.success]
        if not own:
            notes.append(f"{method}: no run of the sweep succeeded")
            continue
        if match == "error":
            good = [(i, r) for i, r in own if r.max_error <= target]
            if good:
                i, _ = min(good, key=lambda item: item[1].nfev)
            else:
                i, best = min(own, key=lambda item: item[1].max_error)
                notes.append(
                    f"{method}: no run of the sweep reached the target error {target:.3g}; "
                    f"the most accurate one ({best.max_error:.3g}) is shown"
                )
        else:
            i, _ = min(own, key=lambda item: abs(math.log(max(item[1].nfev, 1) / target)))
        chosen.add(i)
    out = []
    for i, run in enumerate(runs):
        if i in chosen:
            run = Run(**{**run.__dict__, "selected": True})
        out.append(run)
    return out
