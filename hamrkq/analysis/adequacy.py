"""When a reference is accurate enough to measure a run's true error.

A run's true error is its difference from a reference, and that difference
is the run's error only where the reference's own error is smaller: a
reference *accurate enough to measure an error of delta* is one whose
accuracy, in each component, is below that component's tolerance
(:func:`accuracy_ratios` below 1).  A component's tolerance here is its
largest along the run (:func:`largest_tolerances`; the smallest of those is
:func:`tolerance_scale`), not its smallest at any node: with ``rtol`` a
component crossing zero has only ``atol`` there, which no reference beats.
The reference's accuracy is per component where it states one
(:class:`~hamrkq.analysis.reference.Accuracy`, :func:`component_accuracy`),
else its max-norm accuracy for every component.  A reference within
:data:`CLOSE_REFERENCE` of a tolerance still measures the error, uncertain
by that much (:func:`reference_is_close`: the reports add a note); one that
does not measure it is explained by :func:`unmeasured_error`, which knows
that no reference rounded to double beats :data:`DOUBLE_ROUNDING` of the
values.  The records these rules judge are in :mod:`hamrkq.analysis.summaries`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from hamrkq.analysis.summaries import ErrorSummary

__all__ = [
    "CLOSE_REFERENCE",
    "DOUBLE_ROUNDING",
    "accuracy_ratios",
    "component_accuracy",
    "largest_tolerances",
    "reference_is_close",
    "tolerance_scale",
    "unmeasured_error",
]


#: A reference less accurate than this fraction of the tolerance leaves the
#: true error uncertain by a visible amount: the reports add a note.
CLOSE_REFERENCE = 0.01

#: No reference rounded to double is more accurate than half an ulp of its
#: values, ``DOUBLE_ROUNDING * max |y_k|``: a component whose tolerance is below
#: that has no reference in hamrkq that measures its error.
DOUBLE_ROUNDING = float(np.finfo(np.float64).eps) / 2


def largest_tolerances(delta: Any) -> np.ndarray:
    """Each component's largest tolerance over the run (nan for a component,
    or a run, without one): the scale its reference must beat
    (:func:`tolerance_scale` is the smallest of them)."""
    delta = np.asarray(delta, dtype=float)
    delta = delta.reshape(-1, delta.shape[-1]) if delta.ndim else delta.reshape(1, 1)
    finite = np.isfinite(delta)
    widest = np.where(finite, delta, -np.inf).max(axis=0, initial=-np.inf)
    return np.where(finite.any(axis=0), widest, np.nan)


def component_accuracy(accuracy: Any, width: int, components: Any = None) -> np.ndarray:
    """A reference's accuracy per component: ``components``, or the
    ``components`` ``accuracy`` carries
    (:class:`~hamrkq.analysis.reference.Accuracy`), else the max-norm
    ``accuracy`` for every component."""
    if components is None:
        components = getattr(accuracy, "components", None)
    if components is None or len(components) != width:
        return np.full(width, float(accuracy))
    return np.asarray(components, dtype=float)


def accuracy_ratios(accuracy: Any, delta: Any, components: Any = None) -> np.ndarray:
    """Each component's reference accuracy over that component's tolerance
    (:func:`largest_tolerances`): below 1 the reference measures the
    component's true error.  nan for a component without a tolerance.

    Per component, not the max-norm accuracy over the smallest tolerance:
    the outer solar system's independent reference is accurate to 2.4e-10
    in the positions (30 AU) and its momentum tolerance is 1.1e-19 (Pluto's,
    atol 8e-20), so its true error was never measured, though each
    component's reference error is below 5e-4 of that component's tolerance
    (found by QA)."""
    scales = largest_tolerances(delta)
    with np.errstate(divide="ignore", invalid="ignore"):
        return component_accuracy(accuracy, scales.size, components) / scales


def tolerance_scale(delta: Any) -> float:
    """The tolerance a reference must beat to measure a run's true error:
    each component's largest tolerance over the run, and the smallest of those
    (nan for a run without a tolerance).

    Not the smallest tolerance of any component at any node: with ``rtol`` a
    component passing through zero has a tolerance down to ``atol`` (1e-20,
    say) there, which no reference beats, so a relative-tolerance run never
    had its true error measured.  A component's error is measured on the
    scale of its tolerance along the run; with ``rtol = 0`` this is the
    smallest ``atol_k``, as before.
    """
    delta = np.asarray(delta, dtype=float)
    if not np.any(np.isfinite(delta)):
        return float("nan")
    return float(np.nanmin(np.nanmax(delta, axis=0)))


def reference_is_close(accuracy: float, delta: Any, components: Any = None) -> bool:
    """Whether a reference's ``accuracy``, in some component, is above
    :data:`CLOSE_REFERENCE` times that component's tolerance
    (:func:`accuracy_ratios`; never, for a run without one)."""
    ratios = accuracy_ratios(accuracy, delta, components)
    return bool(np.any(ratios[np.isfinite(largest_tolerances(delta))] > CLOSE_REFERENCE))


def unmeasured_error(
    summary: ErrorSummary,
    scale: float,
    what: str = "the tolerance",
    *,
    component: int | None = None,
    magnitude: float = float("nan"),
) -> str:
    """Why a true error is not shown: its reference is no more accurate than
    ``scale``, ``what`` it must beat (the tolerance, or a tenth of the error
    for a run without one), so the difference would be mostly the
    reference's own error.

    With ``component`` (an index into ``summary.names``) the reference's
    accuracy and the tolerance are that component's.  The extended reference
    is suggested for an independent one unless ``scale`` is below the
    rounding of the component's values to double (``magnitude``, the largest
    ``|y_k|``, times :data:`DOUBLE_ROUNDING`), which no reference beats.
    """
    accuracy = float(summary.reference_accuracy)
    where = ""
    if component is not None:
        width = len(summary.names)
        accuracy = float(
            component_accuracy(accuracy, width, summary.component_accuracy)[component]
        )
        name = summary.names[component]
        where, what = f" in {name}", f"{name}'s tolerance"
    text = (
        f"not measured: the reference ({summary.description}) is accurate only to "
        f"~{accuracy:.1e}{where}, not below {what} {scale:.1e}"
    )
    if summary.source == "independent":
        rounding = DOUBLE_ROUNDING * magnitude
        if rounding >= scale:
            text += (
                f"; no reference rounded to double reaches it (half an ulp of the values "
                f"is ~{rounding:.1e})"
            )
        else:
            text += "; reference='extended' (--reference extended, with heyoka) reaches further"
    return text
