"""What :func:`~hamrkq.analysis.comparison.compare` records: its runs and how they were chosen.

:class:`Run` is one integration of a sweep with the errors measured on it
(one row of the comparison table); :class:`Comparison` is every run, the
matching rule and the reference they were measured against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hamrkq.result import Solution

__all__ = ["Comparison", "Run", "at_reference_floor"]


@dataclass(frozen=True, eq=False)
class Run:
    """One integration of the sweep and what was measured on it.

    ``settings`` are the keywords given to :func:`hamrkq.solve` (tolerances or
    ``step``); ``factor`` their multiple of the base setting.  The errors are
    nan until :func:`~hamrkq.analysis.comparison.compare` has the reference.
    """

    method: str
    factor: float
    settings: dict[str, Any]
    solution: Solution
    wall_time: float
    max_error: float = math.nan
    max_energy_error: float = math.nan
    relative_energy_error: float = math.nan
    drift: float = math.nan
    drift_stderr: float = math.nan
    selected: bool = False

    @property
    def success(self) -> bool:
        return self.solution.success

    @property
    def nfev(self) -> int:
        """f evaluations, and the evaluations of the runs ``auto`` discarded
        before running again (its cost; ``stats["discarded_evaluations"]``)."""
        return self.solution.nfev + int(self.solution.stats.get("discarded_evaluations", 0))

    def describe(self) -> str:
        """The settings in a few characters: ``"atol=1e-08 rtol=0"`` or ``"h=0.0125"``."""
        parts = []
        for key, value in self.settings.items():
            array = np.ravel(value)
            shown = f"{array[0]:.3g}" if np.all(array == array[0]) else f"{array.max():.3g}(max)"
            parts.append(f"{'h' if key == 'step' else key}={shown}")
        return " ".join(parts)

    def row(self) -> dict[str, Any]:
        """One table row, plain values."""
        sol = self.solution
        return {
            "method": self.method,
            "ran": sol.method,  # auto's member
            "settings": self.describe(),
            "factor": self.factor,
            "selected": self.selected,
            "steps": int(sol.stats.get("steps", 0)),
            "nfev": self.nfev,
            "wall_time_s": self.wall_time,
            "max_true_error": self.max_error,
            "max_abs_energy_error": self.max_energy_error,
            "max_rel_energy_error": self.relative_energy_error,
            "drift_slope": self.drift,
            "drift_stderr": self.drift_stderr,
            "status": sol.status.name,
            "t_final": float(sol.t[-1]) if len(sol) else math.nan,
        }


def at_reference_floor(run: Run, accuracy: float) -> bool:
    """Whether ``run``'s max true error is at or below the reference's
    ``accuracy``: then it is mostly the reference's own error, and the run's
    is at most about ``accuracy``.  The note on uncertain errors names these
    runs, ``hamrkq compare``'s tables mark their errors, and its CSV and JSON
    rows say so (``at_reference_floor``)."""
    return run.max_error <= accuracy


@dataclass(frozen=True, eq=False)
class Comparison:
    """Every run of :func:`~hamrkq.analysis.comparison.compare` and how they were chosen
    and measured."""

    problem: str
    t_span: tuple[float, float]
    runs: tuple[Run, ...]
    match: str
    target: float  # the anchor's max true error (match="error") or nfev ("cost")
    anchor: Run
    reference: str
    reference_accuracy: float
    backend: str
    notes: tuple[str, ...] = field(default_factory=tuple)

    def selected(self) -> list[Run]:
        """The headline run of each method, in the order the methods were given."""
        return [run for run in self.runs if run.selected]

    def rows(self) -> list[dict[str, Any]]:
        """Every run's :meth:`Run.row`, with whether its max true error is at
        the reference's floor (:func:`at_reference_floor`)."""
        return [
            {**run.row(), "at_reference_floor": at_reference_floor(run, self.reference_accuracy)}
            for run in self.runs
        ]

    def matched_by(self) -> str:
        """One sentence: what the headline rows have in common."""
        if self.match == "error":
            return (
                f"matched error: for each method the cheapest run (fewest f evaluations) "
                f"whose max true error is at most {self.target:.3g}, that of rk34q8 at the "
                "problem's default tolerance"
            )
        return (
            f"matched cost: for each method the run whose f evaluations are nearest (in ratio) to "
            f"{self.target:.0f}, those of rk34q8 at the problem's default tolerance"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "problem": self.problem,
            "t_span": list(self.t_span),
            "match": self.match,
            "matched_by": self.matched_by(),
            "target": self.target,
            "reference": self.reference,
            "reference_accuracy": self.reference_accuracy,
            "backend": self.backend,
            "notes": list(self.notes),
            "runs": self.rows(),
        }
