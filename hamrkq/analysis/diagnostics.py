"""What a run achieved: energy drift, global and trajectory errors, the paper's bounds.

The core functions work on plain arrays (time-major, columns ``q`` then
``p``); :func:`diagnose` applies them to a :class:`~hamrkq.result.Solution`
and returns one frozen :class:`Diagnostics`, whose :meth:`~Diagnostics.to_dict`
is plain numbers (for ``summary.json``) and :meth:`~Diagnostics.table` a text
report.

Errors follow the paper's sign, numerical minus exact.  The bounds are those
of J.S.C. Prentice, arXiv:1111.6996, Section 3: if every component of the
global error is at most ``delta_k``, then to first order

- energy:     ``|H(y~) - H(y)| <= sum_k |dH/dy_k| delta_k``
- trajectory: ``||y~ - y||_2 <= sqrt(sum_k delta_k**2)`` (``sqrt(2) delta`` in 2-D)

with ``delta_k = max(atol_k, rtol_k |y_k|)`` at each node (or the paper's
scalar rule ``min_k max(atol, rtol |y_k|)`` when the run used
``tolerance_rule="prentice"``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hamrkq.analysis.reference import Reference, hamiltonian_reference
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.result import Solution
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "REFERENCE_KINDS",
    "Diagnostics",
    "DriftSummary",
    "ErrorSummary",
    "bound_ratio",
    "diagnose",
    "drift_summary",
    "energy_bound",
    "error_summary",
    "tolerance",
    "trajectory_bound",
    "trajectory_error",
]

REFERENCE_KINDS = ("auto", "exact", "independent", "rk8", "none")
_EPS = float(np.finfo(float).eps)
#: Gamma below this many ulps of the RK8 track is rounding, not truncation.
GAMMA_ROUNDOFF_ULPS = 100


# -- array functions ---------------------------------------------------------
def tolerance(y: np.ndarray, atol: Any, rtol: Any, rule: str = "componentwise") -> np.ndarray:
    """The tolerance ``delta`` at every node, shape (N, 2n).

    ``rule="componentwise"`` (hamrkq's default): ``max(atol_k, rtol_k |y_k|)``;
    ``rule="prentice"``: the paper's scalar ``min_k max(atol, rtol |y_k|)``,
    the same for every component of a node.
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    delta = np.maximum(np.asarray(atol, dtype=float), np.asarray(rtol, dtype=float) * np.abs(y))
    if rule == "prentice":
        delta = np.broadcast_to(delta.min(axis=1, keepdims=True), y.shape).copy()
    return delta


def trajectory_error(error: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of ``error`` (N, 2n): the distance in phase space."""
    return np.sqrt(np.sum(np.square(np.asarray(error, dtype=float)), axis=1))


def trajectory_bound(delta: np.ndarray) -> np.ndarray:
    """``sqrt(sum_k delta_k**2)`` per node: ``sqrt(2) delta`` in the paper's case."""
    return trajectory_error(delta)


def energy_bound(gradient: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``sum_k |dH/dy_k| delta_k`` per node (the paper's ``(|q'| + |p'|) delta``)."""
    return np.sum(np.abs(np.asarray(gradient, dtype=float)) * delta, axis=1)


def bound_ratio(observed: np.ndarray, bound: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Largest ``observed / bound`` over the nodes, and the time where it occurs.

    Nodes where both are zero are skipped (the initial node); an error where the
    bound is zero counts as an infinite ratio.
    """
    observed, bound = np.abs(observed), np.asarray(bound, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0, observed / bound, np.where(observed > 0, np.inf, np.nan))
    if np.all(np.isnan(ratio)):
        return float("nan"), float("nan")
    i = int(np.nanargmax(ratio))
    return float(ratio[i]), float(t[i])


@dataclass(frozen=True)
class DriftSummary:
    """How a quantity that should be conserved (H, an invariant) changed.

    ``max_abs`` and ``final`` are of ``F(y_i) - F(y_0)``; ``drift`` is the
    slope of its least-squares line in ``t`` and ``drift_stderr`` the slope's
    standard error (which assumes independent residuals, so it understates
    the uncertainty when the error oscillates slowly).
    """

    name: str
    initial: float
    max_abs: float
    t_max: float
    final: float
    drift: float
    drift_stderr: float

    @property
    def relative_max(self) -> float:
        """``max_abs / |initial|`` (nan when the initial value is zero)."""
        return self.max_abs / abs(self.initial) if self.initial else float("nan")

    def to_dict(self) -> dict[str, float]:
        """Plain floats, including ``relative_max``."""
        out = {k: v for k, v in self.__dict__.items() if k != "name"}
        out["relative_max"] = self.relative_max
        return {k: float(v) for k, v in out.items()}


def drift_summary(name: str, t: Any, values: Any) -> DriftSummary:
    """Summarise ``values[i] - values[0]`` along the nodes ``t``."""
    t, values = np.asarray(t, dtype=float), np.asarray(values, dtype=float)
    error = values - values[0]
    i = int(np.argmax(np.abs(error)))
    slope, stderr = float("nan"), float("nan")
    if t.size >= 2:
        centred = t - t.mean()  # centring keeps the normal equations well conditioned
        spread = float(centred @ centred)
        if spread > 0:
            slope = float(centred @ error) / spread
            if t.size >= 3:
                residual = error - error.mean() - slope * centred
                stderr = float(np.sqrt(residual @ residual / (t.size - 2) / spread))
    return DriftSummary(
        name=name,
        initial=float(values[0]),
        max_abs=float(abs(error[i])),
        t_max=float(t[i]),
        final=float(error[-1]),
        drift=slope,
        drift_stderr=stderr,
    )


@dataclass(frozen=True)
class ErrorSummary:
    """Global error of a run against one reference.

    Attributes
    ----------
    source : str
        ``"rk8"`` (the run's own RK8 track, the paper's yardstick), ``"exact"``
        or ``"independent"``.
    description : str
        How the reference was obtained.
    reference_accuracy : float
        Estimated max error of the reference itself (for ``"rk8"`` the largest
        ``|Gamma|``; nan when unknown).
    names : tuple of str
        Component names.
    max_abs : tuple of float
        Largest ``|y_k - ref_k|`` per component.
    max_trajectory, t_max_trajectory, final_trajectory : float
        Largest Euclidean error, where, and at the end.
    bound_ratio, t_bound_ratio : float
        Largest trajectory error over ``sqrt(sum delta_k**2)``, and where.
    """

    source: str
    description: str
    reference_accuracy: float
    names: tuple[str, ...]
    max_abs: tuple[float, ...]
    max_trajectory: float
    t_max_trajectory: float
    final_trajectory: float
    bound_ratio: float
    t_bound_ratio: float

    def to_dict(self) -> dict[str, Any]:
        """Plain values; per-component maxima keyed by component name."""
        out: dict[str, Any] = {"source": self.source, "description": self.description}
        for key in (
            "reference_accuracy",
            "max_trajectory",
            "t_max_trajectory",
            "final_trajectory",
            "bound_ratio",
            "t_bound_ratio",
        ):
            out[key] = float(getattr(self, key))
        out["max_abs"] = {n: float(v) for n, v in zip(self.names, self.max_abs, strict=True)}
        return out


def error_summary(
    t: Any,
    error: Any,
    delta: Any,
    *,
    source: str,
    description: str,
    reference_accuracy: float,
    names: tuple[str, ...],
) -> ErrorSummary:
    """Summarise a global error array (N, 2n) against its tolerance ``delta``."""
    t, error = np.asarray(t, dtype=float), np.asarray(error, dtype=float)
    distance = trajectory_error(error)
    i = int(np.argmax(distance))
    ratio, t_ratio = bound_ratio(distance, trajectory_bound(delta), t)
    return ErrorSummary(
        source=source,
        description=description,
        reference_accuracy=float(reference_accuracy),
        names=tuple(names),
        max_abs=tuple(float(v) for v in np.max(np.abs(error), axis=0)),
        max_trajectory=float(distance[i]),
        t_max_trajectory=float(t[i]),
        final_trajectory=float(distance[-1]),
        bound_ratio=ratio,
        t_bound_ratio=t_ratio,
    )


# -- the whole picture -------------------------------------------------------
#: What the reports say instead of an energy error when H depends on t.
NOT_CONSERVED = "not conserved: H depends on t (its change is no measure of accuracy)"


def unmeasured_error(summary: ErrorSummary, delta: np.ndarray) -> str:
    """Why a true error is not shown: its reference is no more accurate than the
    tolerance, so the difference would be mostly the reference's own error."""
    return (
        f"not measured: the reference ({summary.description}) is accurate only to "
        f"~{summary.reference_accuracy:.1e}, not below the tolerance {float(np.min(delta)):.1e}"
    )


def _plain(value: Any) -> Any:
    """JSON-ready: floats stay floats, nan and inf become None (strict JSON)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, bool | str) or value is None:
        return value
    if isinstance(value, int | np.integer):
        return int(value)
    number = float(value)
    return number if np.isfinite(number) else None


@dataclass(frozen=True, eq=False)
class Diagnostics:
    """Everything :func:`diagnose` found out about one run.

    Attributes
    ----------
    method, status, message : str
        From the solution.
    nodes : int
    stats : mapping
        The solution's counters (steps, rejected, quenches, nfev, ...).
    tolerance_rule : str
        How ``delta`` was formed (``"componentwise"`` or ``"prentice"``).
    energy : DriftSummary or None
        ``H(y_i) - H(y_0)``.
    energy_bound_ratio, t_energy_bound_ratio : float
        Largest ``|H(y_i) - H(y_0)| / sum_k |dH/dy_k| delta_k`` and where (nan
        without a gradient).
    invariants : tuple of DriftSummary
    estimated : ErrorSummary or None
        The run's own estimate ``G = y - z`` (the paper's "global error").
    error : ErrorSummary or None
        Against the chosen reference (``estimated`` itself for ``"rk8"``).
    gamma_max : float
        Largest ``|Gamma|``, the estimated global error of the RK8 track.
    notes : tuple of str
        Caveats a reader should see.
    series : mapping of str to ndarray
        Per-node arrays for plots: ``t``, ``energy_error``, ``energy_bound``,
        ``delta``, ``trajectory_bound`` and, where available,
        ``estimated_error``, ``error``, ``reference``, ``gamma``.
    time_dependent : bool
        H depends on t explicitly: the energy is not conserved, and reports
        say so instead of showing its error (:attr:`energy_note`).
    """

    method: str
    status: str
    message: str
    nodes: int
    stats: Mapping[str, Any]
    tolerance_rule: str
    energy: DriftSummary | None
    energy_bound_ratio: float
    t_energy_bound_ratio: float
    invariants: tuple[DriftSummary, ...]
    estimated: ErrorSummary | None
    error: ErrorSummary | None
    gamma_max: float
    notes: tuple[str, ...]
    series: Mapping[str, np.ndarray]
    time_dependent: bool = False

    @property
    def energy_conserved(self) -> bool:
        """False when H depends on t: its change along the run measures nothing."""
        return not self.time_dependent

    @property
    def error_measured(self) -> bool:
        """True when :attr:`error` is a true error worth showing: measured against a
        reference (not the run's own RK8 track) whose own accuracy is finite and
        below the smallest tolerance.  Otherwise the "true error" would be mostly
        the reference's error."""
        if self.error is None or self.error is self.estimated:
            return False
        accuracy = self.error.reference_accuracy
        return bool(np.isfinite(accuracy) and accuracy < float(np.min(self.series["delta"])))

    @property
    def energy_note(self) -> str | None:
        """What reports show instead of the energy error, or None to show it."""
        return None if self.energy_conserved else NOT_CONSERVED

    @property
    def error_note(self) -> str | None:
        """Why the true error is not shown (its reference is too inaccurate), or None."""
        if self.error is None or self.error is self.estimated or self.error_measured:
            return None
        return unmeasured_error(self.error, self.series["delta"])

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers and strings for ``summary.json`` (nan and inf become None)."""
        return _plain(
            {
                "method": self.method,
                "status": self.status,
                "message": self.message,
                "nodes": self.nodes,
                "stats": dict(self.stats),
                "tolerance_rule": self.tolerance_rule,
                "energy": None if self.energy is None else self.energy.to_dict(),
                "energy_conserved": self.energy_conserved,
                # the bound assumes a conserved H; for H(t) the ratio means nothing
                "energy_bound_ratio": self.energy_bound_ratio if self.energy_conserved else None,
                "t_energy_bound_ratio": self.t_energy_bound_ratio
                if self.energy_conserved
                else None,
                "invariants": {s.name: s.to_dict() for s in self.invariants},
                "estimated_global_error": None
                if self.estimated is None
                else self.estimated.to_dict(),
                "global_error": None if self.error is None else self.error.to_dict(),
                "true_error_measured": self.error_measured,
                "rk8_estimated_global_error_max": self.gamma_max,
                "notes": list(self.notes),
            }
        )

    def table(self) -> str:
        """A text report, one quantity per line."""
        stats = self.stats
        rows = [
            ("run", f"{self.method}: {self.nodes} nodes, {self.status}"),
            (
                "steps",
                f"{stats.get('steps', '?')} accepted, {stats.get('rejected', '?')} "
                f"rejected, {stats.get('quenches', 0)} quenches, "
                f"{stats.get('nfev', '?')} f-evaluations",
            ),
        ]
        delta = self.series["delta"]
        rows.append(
            ("tolerance delta", f"{delta.min():.3e} .. {delta.max():.3e} ({self.tolerance_rule})")
        )
        if self.energy is not None and not self.energy_conserved:
            rows.append(("energy", self.energy_note))
        for summary in (self.energy if self.energy_conserved else None, *self.invariants):
            if summary is not None:
                rows.append(
                    (
                        f"{summary.name} error",
                        f"max {summary.max_abs:.3e} (t={summary.t_max:g}), "
                        f"end {summary.final:+.3e}, drift {summary.drift:+.2e} "
                        f"+/- {summary.drift_stderr:.1e} per unit t",
                    )
                )
        if np.isfinite(self.energy_bound_ratio) and self.energy_conserved:
            rows.append(
                (
                    "energy / bound",
                    f"max {self.energy_bound_ratio:.4f} (t={self.t_energy_bound_ratio:g})",
                )
            )
        seen = []
        for label, summary in (("estimated error", self.estimated), ("true error", self.error)):
            if summary is None or any(summary is other for other in seen):
                continue
            seen.append(summary)
            if label == "true error" and not self.error_measured:
                rows.append((label, self.error_note))
                continue
            parts = ", ".join(
                f"{n} {v:.3e}" for n, v in zip(summary.names, summary.max_abs, strict=True)
            )
            rows.append((label, f"{parts}; trajectory {summary.max_trajectory:.3e}"))
            rows.append(
                (
                    "  reference",
                    f"{summary.description} (accurate to ~{summary.reference_accuracy:.1e})",
                )
            )
            rows.append(
                (
                    "  trajectory / bound",
                    f"max {summary.bound_ratio:.4f} (t={summary.t_bound_ratio:g})",
                )
            )
        if np.isfinite(self.gamma_max):
            rows.append(("RK8 track |Gamma|", f"max {self.gamma_max:.3e}"))
        rows += [("note", note) for note in self.notes]
        width = max(len(label) for label, _ in rows)
        return "\n".join(f"{label:<{width}}  {text}" for label, text in rows)


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


def _system(problem: Any, params: Any):
    """(hamiltonian, params array) from a Problem, a Hamiltonian or nothing."""
    if problem is None:
        return None, params
    ham = getattr(problem, "hamiltonian", problem)
    if params is None:
        params = (
            problem.parameter_array
            if hasattr(problem, "parameter_array")
            else ham.parameter_values()
        )
    elif isinstance(params, Mapping):
        params = ham.parameter_values(params)
    return ham, params


def _reference_states(sol, kind, ham, params, exact, periodic):
    """(states, source, description, accuracy) for a reference kind or object."""
    if isinstance(kind, Reference):
        if kind.y.shape != sol.y.shape or not np.array_equal(kind.t, sol.t):
            raise InputError("reference must be computed at the solution's node times")
        return kind.y, "independent", kind.method, kind.estimated_error
    if kind == "rk8":
        if sol.z is None:
            raise InputError(f"reference='rk8' needs an RK8 track; method {sol.method!r} has none")
        gamma = float(np.max(np.abs(sol.gamma))) if sol.gamma is not None else float("nan")
        return sol.z, "rk8", "the run's own RK8 track (the paper's yardstick)", gamma
    if kind == "exact":
        if exact is None:
            raise InputError("reference='exact' needs an exact solution (exact= or a problem)")
        states = np.asarray(exact(sol.t), dtype=float).reshape(sol.y.shape)
        scale = float(np.max(np.abs(states)))
        if np.max(np.abs(states[0] - sol.y[0])) > 1e-9 * (1.0 + scale):
            raise InputError(
                f"the exact solution starts at {states[0].tolist()}, not at the run's "
                f"initial state {sol.y[0].tolist()}; use reference='independent'"
            )
        return states, "exact", "exact solution", 4 * _EPS * scale
    if kind == "independent":
        if ham is None:
            raise InputError("reference='independent' needs a problem or a Hamiltonian")
        ref = hamiltonian_reference(ham, sol.y[0], sol.t, params=params, periodic=periodic)
        return ref.y, "independent", ref.method, ref.estimated_error
    raise OptionError(f"reference must be one of {REFERENCE_KINDS} or a Reference, got {kind!r}")


def _gamma_max(sol: Any, series: dict, notes: list[str]) -> float:
    """Largest ``|Gamma|`` (nan without one), with a note when it is rounding."""
    if sol.gamma is None:
        return float("nan")
    series["gamma"] = sol.gamma
    gamma_max = float(np.max(np.abs(sol.gamma)))
    track = sol.z if sol.z is not None else sol.y
    roundoff = GAMMA_ROUNDOFF_ULPS * _EPS * float(np.max(np.abs(track)))
    if gamma_max < roundoff:
        notes.append(
            f"max |Gamma| = {gamma_max:.1e} is at the roundoff level of the RK8 "
            "track: the Richardson estimate measures rounding, not truncation"
        )
    return gamma_max


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
    reference : {"auto", "exact", "independent", "rk8", "none"} or Reference
        What the true error is measured against.  ``"auto"``: the exact
        solution if there is one, else the run's RK8 track, else nothing (an
        independent reference costs a tight integration, so it is never
        chosen silently).  A :class:`~hamrkq.analysis.reference.Reference` computed at
        ``solution.t`` can be passed directly (to share it between runs).
    params : array_like or mapping, optional
        Parameter values; default the problem's (or the Hamiltonian's defaults).
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
        number or other names of state components).
    """
    _check_arguments(solution, problem)
    sol = solution
    ham, params = _system(problem, params)
    if ham is not None:
        if gradient is None:
            gradient = lambda t, Y: numeric_of(ham).gradient(t, Y, params)  # noqa: E731
        if invariants is None and hasattr(problem, "invariant_functions"):
            invariants = problem.invariant_functions()
        if exact is None and getattr(problem, "exact", None) is not None:
            exact = problem.exact
    kind = reference
    if isinstance(kind, str) and kind == "auto":
        kind = "exact" if exact is not None else ("rk8" if sol.z is not None else "none")
    notes: list[str] = []
    t, y = sol.t, sol.y
    rule = str(sol.options.get("tolerance_rule", "componentwise"))
    delta = tolerance(y, sol.atol, sol.rtol, rule)
    series: dict[str, np.ndarray] = {
        "t": t,
        "delta": delta,
        "trajectory_bound": trajectory_bound(delta),
        "energy_error": sol.energy - sol.energy[0],
    }
    energy = drift_summary("energy", t, sol.energy)
    ratio = t_ratio = float("nan")
    if gradient is not None:
        series["energy_bound"] = energy_bound(gradient(t, y), delta)
        ratio, t_ratio = bound_ratio(series["energy_error"], series["energy_bound"], t)
    if ham is not None and ham.time_dependent:
        notes.append(
            "H depends on t explicitly: the energy is not conserved, its error is no "
            "measure of accuracy"
        )
    drifts = tuple(
        drift_summary(name, t, np.asarray(f(t, y), dtype=float).reshape(t.shape))
        for name, f in (invariants or {}).items()
    )
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
            description="the run's own RK8 track (the paper's yardstick)",
        )
    error = None
    if not (isinstance(kind, str) and kind == "none"):
        states, source, description, accuracy = _reference_states(
            sol, kind, ham, params, exact, periodic
        )
        series["reference"] = states
        series["error"] = y - states
        if source == "rk8" and estimated is not None:
            error = estimated
        else:
            error = error_summary(
                t,
                series["error"],
                delta,
                source=source,
                description=description,
                reference_accuracy=accuracy,
                names=names,
            )
        if accuracy > 0.01 * float(np.min(delta)):
            notes.append(
                f"the reference ({source}) is accurate only to ~{accuracy:.1e}, not "
                "far below the tolerance: the true error is uncertain by that much"
            )
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
    )
