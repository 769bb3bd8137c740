"""What a run report (``hamrkq run``) measures the true error against:
:func:`diagnose_for_report` runs :func:`hamrkq.analysis.diagnostics.diagnose`
against the reference asked for, falling back, or moving to a more accurate
one, with a note for the reader each time.
"""

from __future__ import annotations

from typing import Any

from hamrkq.analysis.diagnostics import Diagnostics, diagnose
from hamrkq.errors import HamrkqError

__all__ = ["diagnose_for_report"]


def diagnose_for_report(
    sol: Any, problem: Any, reference: str, *, extend: bool = False
) -> tuple[Diagnostics | None, str, list[str]]:
    """What a report (``hamrkq run``) shows: :func:`diagnose` against
    ``reference``, and notes for the reader.

    Where the reference cannot be had (a diverging partial run, say) the
    run's own numbers are still reported, against no reference.  With
    ``extend`` (``--reference auto``), where the independent reference is not
    accurate enough to measure the true error (the Pleiades at 1e-8: 2.1e-8)
    or not far below the tolerance (within
    :data:`~hamrkq.analysis.adequacy.CLOSE_REFERENCE` of it: fpu, arenstorf),
    and the extended one can be had (heyoka) and is more accurate, the run is
    measured against that instead, and a note says so; and where the exact
    solution cannot be had (a run from another initial time), the independent
    reference is used, with a note.

    Returns
    -------
    (diagnostics or None, the reference used, notes)
        None for a run of fewer than two nodes.
    """
    if len(sol) < 2:
        return None, reference, ["fewer than two nodes: no diagnostics"]
    notes: list[str] = []
    # --reference auto promises the independent reference where the exact
    # solution cannot be had (a run from --t-start, whose initial state is
    # not the exact solution's there); a reference asked for by name is not
    # replaced.
    kinds = [reference, "independent"] if extend and reference == "exact" else [reference]
    for kind in kinds:
        try:
            diag = diagnose(sol, problem, reference=kind)
        except HamrkqError as exc:
            notes.append(f"reference {kind!r} unavailable ({exc})")
            continue
        if kind != reference:
            notes[-1] += f"; measured against {kind!r}"
        if extend and kind == "independent":
            diag, kind = _extended_if_unmeasured(sol, problem, diag, notes)
        return diag, kind, notes
    notes[-1] += "; true error not reported"
    return diagnose(sol, problem, reference="none"), reference, notes


def _extended_if_unmeasured(
    sol: Any, problem: Any, diag: Diagnostics, notes: list[str]
) -> tuple[Diagnostics, str]:
    """``diag`` against the extended reference where the independent one
    does not measure the true error well (see :func:`diagnose_for_report`)."""
    from hamrkq.analysis.extended_reference import available

    unchanged = diag, "independent"
    if diag.error is None or (diag.error_measured and not diag.reference_close):
        return unchanged
    if not available():  # last: it imports heyoka (30 ms)
        return unchanged
    accuracy = diag.error.reference_accuracy
    try:
        extended = diagnose(sol, problem, reference="extended")
    except HamrkqError as exc:
        notes.append(f"reference 'extended' unavailable ({exc})")
        return unchanged
    better = extended.error.reference_accuracy
    if not better < accuracy:
        return unchanged
    outcome = (
        "the true error is measured against the extended one (heyoka in extended "
        f"precision, accurate to ~{better:.1e})"
        if extended.error_measured
        else f"the extended one (heyoka, accurate to ~{better:.1e}) is reported; it is "
        "not accurate enough either"
    )
    notes.append(
        f"the independent reference is accurate only to ~{accuracy:.1e}, "
        f"{'not far below' if diag.error_measured else 'not below'} the tolerance: {outcome}"
    )
    return extended, "extended"
