"""What :func:`~hamrkq.analysis.diagnostics.diagnose` returns, as frozen records.

:class:`DriftSummary` says how a quantity that should be conserved changed,
:class:`ErrorSummary` how large a global error was against its bound, and
:class:`Diagnostics` holds them all for one run, with
:meth:`~Diagnostics.to_dict` (plain numbers for ``summary.json``) and
:meth:`~Diagnostics.table` (a text report).  Whether a reference is
accurate enough to measure a true error is decided in
:mod:`hamrkq.analysis.adequacy`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hamrkq.analysis.adequacy import (
    accuracy_ratios,
    largest_tolerances,
    reference_is_close,
    tolerance_scale,
    unmeasured_error,
)
from hamrkq.analysis.bounds import (
    bound_ratio,
    component_ratio,
    trajectory_bound,
    trajectory_error,
)
from hamrkq.rkq.family import track_name

__all__ = [
    "COMPONENT_RATIO_LABEL",
    "NOT_CONSERVED",
    "PAPER_RATIO_LABEL",
    "Diagnostics",
    "DriftSummary",
    "ErrorSummary",
    "component_ratio_text",
    "drift_summary",
    "error_summary",
    "ratio_rows",
    "reference_accuracy",
]


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
        ``"rk8"`` (the run's own RK8 track, the paper's yardstick), ``"exact"``,
        ``"independent"`` or ``"extended"`` (heyoka in extended precision).
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
        The paper's ratio: the largest Euclidean trajectory error over the
        paper's bound ``sqrt(sum delta_k**2)``, and where
        (:func:`~hamrkq.analysis.bounds.bound_ratio`).  Not hamrkq's promise:
        it can stay below 1 while a component is many tolerances off.
    component_accuracy : tuple of float or None
        The reference's estimated error per component, where it states one
        (:class:`~hamrkq.analysis.reference.Accuracy`); None where only
        ``reference_accuracy`` (the max-norm) is known.
    component_ratio, t_component_ratio : float
        hamrkq's promise measured: the largest ``|y_k - ref_k| / delta_k``
        over nodes and components, and where
        (:func:`~hamrkq.analysis.bounds.component_ratio`; nan without a
        tolerance).  At most 1.05 where the promise was kept.
    component_ratio_name : str
        The component of ``component_ratio`` ("" without one).
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
    component_accuracy: tuple[float, ...] | None = None
    component_ratio: float = float("nan")
    t_component_ratio: float = float("nan")
    component_ratio_name: str = ""

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
            "component_ratio",
            "t_component_ratio",
        ):
            out[key] = float(getattr(self, key))
        out["component_ratio_name"] = self.component_ratio_name
        out["max_abs"] = {n: float(v) for n, v in zip(self.names, self.max_abs, strict=True)}
        out["component_accuracy"] = (
            None
            if self.component_accuracy is None
            else {n: float(v) for n, v in zip(self.names, self.component_accuracy, strict=True)}
        )
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
    """Summarise a global error array (N, 2n) against its tolerance ``delta``
    (N, 2n): per component (hamrkq's promise, ``component_ratio``) and as
    the paper's Euclidean trajectory error (``bound_ratio``).
    ``reference_accuracy`` may carry per-component ``components``
    (:class:`~hamrkq.analysis.reference.Accuracy`), kept as
    ``component_accuracy``."""
    t, error = np.asarray(t, dtype=float), np.asarray(error, dtype=float)
    components = getattr(reference_accuracy, "components", None)
    if components is not None and len(components) != error.shape[-1]:
        components = None
    distance = trajectory_error(error)
    i = int(np.argmax(distance))
    ratio, t_ratio = bound_ratio(distance, trajectory_bound(delta), t)
    worst, t_worst, component = component_ratio(error, delta, t)
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
        component_accuracy=None if components is None else tuple(float(v) for v in components),
        component_ratio=worst,
        t_component_ratio=t_worst,
        component_ratio_name=names[component] if component >= 0 else "",
    )


#: What the reports say instead of an energy error when H depends on t.
NOT_CONSERVED = "not conserved: H depends on t (its change is no measure of accuracy)"


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
    """Everything :func:`~hamrkq.analysis.diagnostics.diagnose` found out about one run.

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
        Largest ``|Gamma|``, the estimated global error of the quencher's
        track (the paper's RK8 track).
    notes : tuple of str
        Caveats a reader should see.
    series : mapping of str to ndarray
        Per-node arrays for plots: ``t``, ``energy_error``, ``energy_bound``,
        ``delta``, ``trajectory_bound`` and, where available,
        ``estimated_error``, ``error``, ``reference``, ``gamma``.
    time_dependent : bool
        H depends on t explicitly: the energy is not conserved, and reports
        say so instead of showing its error (:attr:`energy_note`).
    track_error : float
        Largest ``|z_k - ref_k|``, the quencher track's true error against
        :attr:`error`'s reference (nan against its own track or none): what
        ``gamma_max`` estimates, shown beside it where the true error is
        measured (:attr:`error_measured`).
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
    track_error: float = float("nan")

    def __repr__(self) -> str:
        # The generated repr printed every per-node array of ``series``
        # (pages for a long run); the report is ``str(d)`` (:meth:`table`).
        parts = [f"method={self.method!r}", f"status={self.status!r}", f"nodes={self.nodes}"]
        if self.energy is not None and self.energy_conserved:
            parts.append(f"energy_max_abs={self.energy.max_abs:.3e}")
        if self.estimated is not None:
            parts.append(f"estimated_max={max(self.estimated.max_abs, default=0.0):.3e}")
        if self.error_measured:
            parts.append(f"true_error_max={max(self.error.max_abs, default=0.0):.3e}")
        elif self.error is not None and self.error is not self.estimated:
            parts.append("true_error='not measured'")
        if np.isfinite(self.gamma_max):
            parts.append(f"gamma_max={self.gamma_max:.3e}")
        return f"Diagnostics({', '.join(parts)})"

    def __str__(self) -> str:
        return self.table()

    @property
    def energy_conserved(self) -> bool:
        """False when H depends on t: its change along the run measures nothing."""
        return not self.time_dependent

    @property
    def error_measured(self) -> bool:
        """True when :attr:`error` is a true error worth showing: measured against a
        reference (not the run's own RK8 track) whose own accuracy is finite and,
        in each component, below that component's tolerance
        (:func:`~hamrkq.analysis.adequacy.accuracy_ratios`).  Otherwise the
        "true error" would be mostly the reference's error."""
        if self.error is None or self.error is self.estimated:
            return False
        return self._shortfall() is None

    def _shortfall(self) -> tuple[float, str, int | None] | None:
        """None when the reference measures the true error; else the scale it
        misses, its name, and the component (None for a run without a
        tolerance, judged on :meth:`_error_scale`)."""
        accuracy = self.error.reference_accuracy
        if not np.isfinite(accuracy):
            return (*self._error_scale(), None)
        scales = largest_tolerances(self.series["delta"])
        if not np.all(np.isfinite(scales)):
            scale, what = self._error_scale()
            return None if accuracy < scale else (scale, what, None)
        ratios = accuracy_ratios(accuracy, self.series["delta"], self.error.component_accuracy)
        worst = int(np.argmax(ratios))
        return None if ratios[worst] < 1 else (float(scales[worst]), "the tolerance", worst)

    @property
    def reference_close(self) -> bool:
        """Whether the true error's reference, though good enough to measure
        it, is within :data:`~hamrkq.analysis.adequacy.CLOSE_REFERENCE` of the
        tolerance (the true error is then uncertain by that much; the reports
        say so)."""
        if self.error is None or self.error is self.estimated:
            return False
        error = self.error
        return reference_is_close(
            error.reference_accuracy, self.series["delta"], error.component_accuracy
        )

    def _error_scale(self) -> tuple[float, str]:
        """What the reference must be more accurate than, and its name: the
        smallest tolerance, or for a run without one (a fixed-step method) a
        tenth of the largest error it measures (before, no fixed-step run
        ever reported a true error: every comparison with a nan tolerance is
        false)."""
        scale = tolerance_scale(self.series["delta"])
        if np.isfinite(scale):
            return scale, "the tolerance"
        return 0.1 * max(self.error.max_abs, default=0.0), "a tenth of the error it measures,"

    @property
    def measured_track_error(self) -> float:
        """:attr:`track_error` where the true error is measured
        (:attr:`error_measured`), else nan: against a reference no more
        accurate than the tolerance it would be mostly the reference's."""
        return self.track_error if self.error_measured else float("nan")

    @property
    def energy_note(self) -> str | None:
        """What reports show instead of the energy error, or None to show it."""
        return None if self.energy_conserved else NOT_CONSERVED

    @property
    def error_note(self) -> str | None:
        """Why the true error is not shown (its reference is too inaccurate), or None."""
        if self.error is None or self.error is self.estimated or self.error_measured:
            return None
        scale, what, component = self._shortfall()
        if component is None:
            return unmeasured_error(self.error, scale, what)
        reference = self.series.get("reference")
        magnitude = (
            float(np.max(np.abs(reference[:, component]))) if reference is not None else np.nan
        )
        return unmeasured_error(self.error, scale, component=component, magnitude=magnitude)

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
                "rk8_true_global_error_max": self.measured_track_error,
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
        if np.isfinite(delta).any():
            span = f"{np.nanmin(delta):.3e} .. {np.nanmax(delta):.3e} ({self.tolerance_rule})"
        else:  # read "nan .. nan" (found by QA)
            span = "none (a fixed-step run has no tolerance)"
        rows.append(("tolerance delta", span))
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
            rows.append(("  reference", f"{summary.description} ({reference_accuracy(summary)})"))
            rows += ratio_rows(summary)
        if np.isfinite(self.gamma_max):
            rows.append(
                (
                    f"{track_name(self.method)} |Gamma|",
                    f"max {self.gamma_max:.3e}{self.track_error_text()}",
                )
            )
        rows += [("note", note) for note in self.notes]
        width = max(len(label) for label, _ in rows)
        return "\n".join(f"{label:<{width}}  {text}" for label, text in rows)

    def track_error_text(self) -> str:
        """What follows max |Gamma| in the table and in the ``run`` command's
        summary (:func:`hamrkq.io.report.summary_rows`): that it is an
        estimate, and the quencher track's true error where it is measured
        (Kepler e = 0.85 over 100 periods: |Gamma| 4.7e-09 read as the track's
        accuracy, its true error 5.8e-07; found by QA)."""
        true = self.measured_track_error
        if not np.isfinite(true):
            return " (an estimate)"
        return f" (an estimate; true error {true:.3e} against the {self.error.source} reference)"


def reference_accuracy(summary: ErrorSummary) -> str:
    """How accurate the reference of ``summary`` is, worded as what it is:
    the run's own quencher track states only an estimate, max |Gamma|."""
    if summary.source == "rk8":
        return f"its error estimated by max |Gamma| as ~{summary.reference_accuracy:.1e}"
    return f"accurate to ~{summary.reference_accuracy:.1e}"


#: The report's label of :attr:`ErrorSummary.component_ratio`, hamrkq's promise.
COMPONENT_RATIO_LABEL = "error / tolerance (worst component)"
#: The report's label of :attr:`ErrorSummary.bound_ratio`, the paper's yardstick.
PAPER_RATIO_LABEL = "trajectory / paper's bound"


def ratio_rows(summary: ErrorSummary, indent: str = "  ") -> list[tuple[str, str]]:
    """The rows of a report for the two ratios of ``summary``: hamrkq's
    per-component promise first, then the paper's Euclidean ratio; a ratio
    without a tolerance (a fixed-step run) has no row (its row read
    "max inf", found by QA)."""
    rows = []
    promise = component_ratio_text(summary)
    if promise is not None:
        rows.append((indent + COMPONENT_RATIO_LABEL, promise))
    ratio = summary.bound_ratio
    if np.isfinite(ratio) or ratio == np.inf:
        rows.append((indent + PAPER_RATIO_LABEL, f"max {ratio:.4f} (t={summary.t_bound_ratio:g})"))
    return rows


def component_ratio_text(summary: ErrorSummary) -> str | None:
    """:attr:`ErrorSummary.component_ratio`, hamrkq's promise, as the reports
    show it ("max 0.9996 (q, t=143.2)"); None without a tolerance (a
    fixed-step run).  An infinite ratio, an error where the tolerance is
    zero, is a broken promise and is shown ("max inf")."""
    ratio = summary.component_ratio
    if not (np.isfinite(ratio) or ratio == np.inf):
        return None
    return f"max {ratio:.4f} ({summary.component_ratio_name}, t={summary.t_component_ratio:g})"
