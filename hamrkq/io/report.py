"""Shared pieces of the ``run`` and ``reproduce`` commands: output files and reports.

- :class:`OutputDir`, :func:`check_dpi`, :func:`close_all`: the output
  directory, claimed under a lock and written atomically (defined in
  :mod:`hamrkq.io.output_dir`, importable from here).
- :func:`summary_dict`: the content of ``summary.json`` for one run: the
  settings, every number :func:`hamrkq.analysis.diagnostics.diagnose` found, the
  counters, wall times, the status and the package versions.
- :func:`summary_rows` and :func:`format_table`: the text table printed on
  stdout.
- :class:`ProgressBar`: a progress bar (tqdm) on a terminal that appears only
  once a run has lasted about a second, and never when stderr is not a
  terminal (defined in :mod:`hamrkq._progress`, importable from here).
"""

from __future__ import annotations

import datetime as _dt
import math
import platform
from collections.abc import Iterable, Mapping
from importlib import metadata
from typing import Any

from hamrkq._files import jsonable, write_atomic
from hamrkq._progress import ProgressBar
from hamrkq.analysis.summaries import ratio_rows
from hamrkq.io.output_dir import (
    LOCK_NAME,
    MAX_DPI,
    MAX_FIGURE_PIXELS,
    MIN_DPI,
    OutputDir,
    check_dpi,
    close_all,
)
from hamrkq.rkq.family import track_name

__all__ = [
    "LOCK_NAME",
    "MAX_DPI",
    "MAX_FIGURE_PIXELS",
    "MIN_DPI",
    "SUMMARY_FORMAT_VERSION",
    "OutputDir",
    "ProgressBar",
    "check_dpi",
    "close_all",
    "format_table",
    "jsonable",
    "package_versions",
    "summary_dict",
    "summary_rows",
    "write_atomic",
]

#: Version of the layout of ``summary.json``; bumped when keys change meaning.
SUMMARY_FORMAT_VERSION = 1
#: Distributions whose versions go into ``summary.json`` (what a rerun needs).
VERSIONED = ("hamrkq", "numpy", "scipy", "sympy", "matplotlib", "numba")


# -- summary.json --------------------------------------------------------------
def package_versions() -> dict[str, str | None]:
    """Python, the platform and the versions of hamrkq and its dependencies."""
    from hamrkq._version import __version__

    versions: dict[str, str | None] = {
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    for name in VERSIONED:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = __version__ if name == "hamrkq" else None
    return versions


def summary_dict(
    solution: Any,
    diagnostics: Any,
    *,
    problem: Any = None,
    settings: Mapping[str, Any] | None = None,
    wall_time: Mapping[str, float] | None = None,
    notes: Iterable[str] = (),
) -> dict[str, Any]:
    """Everything about one run, for ``summary.json``.

    Parameters
    ----------
    solution : Solution
    diagnostics : Diagnostics or None
        From :func:`hamrkq.analysis.diagnostics.diagnose`; its :meth:`to_dict` is stored
        unchanged under ``"diagnostics"``, so the file and a library call with
        the same settings agree number for number.
    problem : Problem, optional
    settings : mapping, optional
        The command's own settings (reference kind, output options, ...);
        the solution's ``options`` (what :func:`hamrkq.solve` actually used)
        are stored beside them.
    wall_time : mapping, optional
        Seconds, by phase.
    notes : iterable of str
        Caveats the command found (besides the diagnostics' own notes).
    """
    out: dict[str, Any] = {
        "format_version": SUMMARY_FORMAT_VERSION,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }
    if problem is not None:
        out["problem"] = {
            "name": problem.name,
            "title": problem.title,
            "file": None if problem.path is None else str(problem.path),
            "degrees_of_freedom": problem.hamiltonian.n,
            "hamiltonian": str(problem.hamiltonian.H),
            "parameters": dict(problem.parameters),
            "q0": problem.q0,
            "p0": problem.p0,
        }
    out["settings"] = {**dict(settings or {}), "solve": dict(solution.options)}
    out.update(
        status=solution.status.name,
        success=solution.success,
        partial=solution.partial,
        message=solution.message,
        nodes=len(solution),
        t_final=float(solution.t[-1]) if len(solution) else None,
        stats=dict(solution.stats),
        wall_time_s=dict(wall_time or {}),
        diagnostics=None if diagnostics is None else diagnostics.to_dict(),
        notes=list(notes),
        versions=package_versions(),
    )
    if getattr(solution, "t_events", None) is not None:
        # Per event function: its roots, the states there and RKQ's bound
        # max(atol, rtol |y|) on each state's error (hamrkq.events).
        out["events"] = [
            {"label": label, "t": t, "y": y, "error_bound": bound}
            for label, t, y, bound in zip(
                solution.event_labels,
                solution.t_events,
                solution.y_events,
                solution.event_bound,
                strict=True,
            )
        ]
    return jsonable(out)


# -- the table on stdout ----------------------------------------------------------
def _num(value: Any, spec: str = ".3e") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return format(value, spec)


def _wall_time(wall_time: float, stats: Any) -> str:
    """The wall time of a solve and where it went (``stats``' seconds)."""
    text = f"{wall_time:.2f} s"
    if "integrate_s" not in stats:
        return text
    text += f" (integration {float(stats['integrate_s']):.3f} s"
    if stats.get("interpreted_steps"):  # a first use compiling in the background
        text += f", {stats['interpreted_steps']} steps interpreted"
    if stats.get("discarded_s"):  # method="auto"'s runs made again (sol.message)
        text += f"; discarded runs {float(stats['discarded_s']):.3f} s"
    if "compile_s" in stats:
        text += f"; compiling or loading code {float(stats['compile_s']):.3f} s"
    return text + ")"


def summary_rows(
    solution: Any, diagnostics: Any, wall_time: float | None = None
) -> list[tuple[str, str]]:
    """The rows of the run summary: (label, text)."""
    sol, diag = solution, diagnostics
    stats = sol.stats
    method = _method_line(sol)
    evaluations = str(stats.get("nfev", 0))
    if stats.get("njev"):
        evaluations += f" and {stats['njev']} Jacobian products"
    if stats.get("discarded_evaluations"):
        # method="auto" ran again with more quencher steps (sol.message says why)
        evaluations += f", and {stats['discarded_evaluations']} in discarded runs"
    rows = [
        ("method", method),
        ("status", f"{sol.status.name}" + ("" if sol.success else " (partial results)")),
        ("nodes", f"{len(sol)} (t = {_num(sol.t[0], 'g')} .. {_num(sol.t[-1], 'g')})"),
        ("steps", f"{stats.get('steps', 0)} accepted, {stats.get('rejected', 0)} rejected"),
        ("quenches", str(stats.get("quenches", 0)) if sol.z is not None else "n/a (no quencher)"),
        ("f evaluations", evaluations),
    ]
    if wall_time is not None:
        rows.append(("wall time (solve)", _wall_time(wall_time, stats)))
    rows += _event_rows(sol)
    if diag is None:
        return rows
    if diag.estimated is not None:
        rows.append(("max est. global error", _components(diag.estimated)))
        rows += ratio_rows(diag.estimated)
    if diag.error is not None and diag.error is not diag.estimated:
        label = f"max true error ({diag.error.source})"
        if diag.error_measured:
            # never a true error without the accuracy of what it is measured against
            accuracy = f"reference accurate to ~{_num(diag.error.reference_accuracy, '.1e')}"
            rows.append((label, f"{_components(diag.error)} ({accuracy})"))
            rows += ratio_rows(diag.error)
        else:
            rows.append((label, diag.error_note))
    if diag.energy is not None and not diag.energy_conserved:
        rows.append(("energy", diag.energy_note))
    elif diag.energy is not None:
        rows.append(
            (
                "max |H - H(0)|",
                f"{_num(diag.energy.max_abs)} "
                f"(drift {_num(diag.energy.drift, '+.2e')} per unit t)",
            )
        )
        rows.append(("  energy / bound", _num(diag.energy_bound_ratio, ".4f")))
    for inv in diag.invariants:
        rows.append((f"max |{inv.name} - {inv.name}(0)|", _num(inv.max_abs)))
    if math.isfinite(diag.gamma_max):
        gamma = f"{_num(diag.gamma_max)}{diag.track_error_text()}"
        rows.append((f"max |Gamma| ({track_name(sol.method)})", gamma))
    return rows


#: How many event times the summary shows per event function (all are in
#: summary.json and solution.npz).
EVENT_TIMES_SHOWN = 4


def _event_rows(sol: Any) -> list[tuple[str, str]]:
    """One row per event function: how many roots, and the first few times."""
    if getattr(sol, "t_events", None) is None:
        return []
    rows = []
    for label, times in zip(sol.event_labels, sol.t_events, strict=True):
        shown = ", ".join(_num(float(t), ".6g") for t in times[:EVENT_TIMES_SHOWN])
        more = ", ..." if len(times) > EVENT_TIMES_SHOWN else ""
        text = f"{len(times)}" + (f" at t = {shown}{more}" if len(times) else "")
        rows.append((f"event {label}", text))
    return rows


def _method_line(sol: Any) -> str:
    """The method, and how its quencher ran where that is not the default."""
    options = sol.options or {}
    details = []
    if (options.get("z_substeps") or 1) > 1:
        details.append(f"{options['z_substeps']} quencher steps a step")
    if options.get("quencher_precision") == "double-double":
        details.append("the quencher in double-double")
    return sol.method + (f" ({', '.join(details)})" if details else "")


def _components(summary: Any) -> str:
    parts = ", ".join(
        f"{n} {_num(v)}" for n, v in zip(summary.names, summary.max_abs, strict=True)
    )
    return f"{parts}; trajectory {_num(summary.max_trajectory)}"


def format_table(rows: Iterable[tuple[str, str]]) -> str:
    """Two aligned columns."""
    rows = list(rows)
    width = max((len(label) for label, _ in rows), default=0)
    return "\n".join(f"{label:<{width}}  {text}" for label, text in rows)
