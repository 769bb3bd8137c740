"""``hamrkq compare NAME|FILE``: every method on one problem, side by side.

The numerics are :func:`hamrkq.analysis.comparison.compare`; this module turns the
result into files.  What it writes into ``--out`` (default
``./hamrkq-compare/NAME``), every file atomically:

- ``comparison.md``: the headline table (one run per method, at matched error
  or matched cost, and the page says which), the whole sweep, the reference
  and the notes;
- ``comparison.csv`` and ``comparison.json``: every run of the sweep (method,
  settings, steps, nfev, wall time, max true global error, max |energy error|,
  drift slope, status, whether it is a headline run, whether its error is at
  the reference's floor);
- ``work_precision.png``: max true error against f evaluations and against
  wall time, one curve per method over its sweep;
- ``energy_error.png``: |H - H(0)| against t for the headline run of each
  method.

Exit status: 0 when the anchor run (``rk34q8`` at the problem's default
tolerance) succeeded, 1 when it did not (everything is still written; failed
runs elsewhere in a sweep, a Verlet step beyond its stability limit say, are
data and show as their status), 2 bad input.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.analysis.comparison import (
    MATCH_MODES,
    Comparison,
    Run,
    at_reference_floor,
    compare,
    default_methods,
)
from hamrkq.catalogue.problems import load_problem
from hamrkq.cli.interrupts import raise_if_interrupted
from hamrkq.io.report import OutputDir, check_dpi, package_versions

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FILES", "energy_figure", "markdown", "register", "work_precision_figure"]

DEFAULT_ROOT = Path("hamrkq-compare")
FILES = {
    "markdown": "comparison.md",
    "csv": "comparison.csv",
    "json": "comparison.json",
    "work_precision": "work_precision.png",
    "energy": "energy_error.png",
}
#: Columns of the tables, (key of Run.row(), header, format).
COLUMNS = (
    ("method", "method", "s"),
    ("settings", "settings", "s"),
    ("steps", "steps", "d"),
    ("nfev", "nfev", "d"),
    ("wall_time_s", "wall time (s)", ".3g"),
    ("max_true_error", "max true error", ".2e"),
    ("max_abs_energy_error", "max abs(H - H0)", ".2e"),
    ("drift_slope", "drift slope (per unit t)", "+.1e"),
    ("drift_stderr", "slope std. error", ".1e"),
    ("status", "status", "s"),
)
#: Marks a max true error at the reference's floor (at or below its accuracy:
#: :func:`~hamrkq.analysis.comparison.at_reference_floor`); the line under the
#: table says so.
FLOOR_MARK = "*"


def register(subparsers: Any) -> None:
    """Add the ``compare`` subcommand."""
    p = subparsers.add_parser(
        "compare",
        help="run several methods on a problem; table, work-precision and energy figures",
        description=(
            "Run each method over a sweep of tolerances (adaptive methods) or step sizes "
            "(fixed-step methods), measure every run against one independent reference, "
            "and write comparison.md/.csv/.json, work_precision.png and energy_error.png. "
            "The headline table shows one run per method at matched error (default) or "
            "matched cost with RKQ at the problem's default tolerance."
        ),
    )
    p.add_argument("problem", metavar="NAME|FILE", help="catalogue name or .toml file")
    p.add_argument(
        "--methods", nargs="+", metavar="M",
        help="methods to compare, auto and the RKQ family's members too (default: rk34q8 "
        "auto rk34 scipy:DOP853 gauss4 gauss6, and yoshida4 for a separable H); rk34q8 is "
        "always run as the anchor",
    )  # fmt: skip
    p.add_argument("--t-end", type=float, metavar="T", help="end of the interval")
    p.add_argument("--quick", action="store_true", help="three settings per method, not 5-6")
    p.add_argument(
        "--match", choices=MATCH_MODES, default="error",
        help="headline run of each method: the cheapest reaching rk34q8's error (error), "
        "or the one nearest (in ratio) to rk34q8's cost in f evaluations (cost)",
    )  # fmt: skip
    p.add_argument("--tol-factors", type=float, nargs="+", metavar="F",
                   help="tolerance sweep, as multiples of the problem's default")  # fmt: skip
    p.add_argument("--step-factors", type=float, nargs="+", metavar="F",
                   help="step sweep, as multiples of h_ref (matched cost)")  # fmt: skip
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter of the problem (a number; repeatable)",
    )
    p.add_argument(
        "--backend", default="auto", help="backend for RKQ (default auto: compiled when possible)"
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default: hamrkq-compare/NAME)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--no-plots", action="store_true", help="do not draw the figures")
    p.add_argument(
        "--dpi", type=int, default=120, help="resolution of the PNGs (10 to 600, default 120)"
    )
    p.set_defaults(func=compare_command)


# -- tables ------------------------------------------------------------------------------
def _cell(value: Any, spec: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return format(value, spec)


def _table(runs: list[Run], accuracy: float) -> list[str]:
    """The table of ``runs``, errors at the reference's floor marked
    :data:`FLOOR_MARK`, and then, if any is, a blank line and the line that
    says what the mark means."""
    lines = ["| " + " | ".join(header for _, header, _ in COLUMNS) + " |",
             "|" + "---|" * len(COLUMNS)]  # fmt: skip
    error = [key for key, _, _ in COLUMNS].index("max_true_error")
    marked = False
    for run in runs:
        row = run.row()
        cells = [_cell(row[k], f) for k, _, f in COLUMNS]
        if row["ran"] != row["method"]:  # auto says which member it ran
            cells[0] += f" ({row['ran']})"
        if row["status"] != "SUCCESS":  # where it stopped
            cells[-1] += f" at t = {_cell(row['t_final'], '.6g')}"
        if at_reference_floor(run, accuracy):
            cells[error] += FLOOR_MARK
            marked = True
        lines.append("| " + " | ".join(cells) + " |")
    if marked:
        lines += [
            "",
            f"Max true errors marked {FLOOR_MARK} are at or below the reference's accuracy "
            f"(~{accuracy:.1e}): at the reference's floor, mostly its own error; the run's "
            "is at most about that.",
        ]
    return lines


def _wall_times(backend: str) -> str:
    """What the wall times compare: the RKQ loop's methods (rk34q8, auto, the
    family's members, rk34) run on ``backend``, every other method in Python."""
    counted = "nfev counts right-hand-side evaluations (Jacobians not included)."
    if backend == "python":
        return (
            "- Wall times: every method runs in Python (NumPy), the RKQ loop's too "
            f"(backend `python`). {counted}"
        )
    return (
        f"- Wall times: the RKQ loop's methods (rk34q8, auto, the family's members, rk34) "
        f"run on backend `{backend}` (compiled); the others (SciPy's solvers, the "
        "fixed-step methods) in Python (NumPy), so times compare implementations as much "
        f"as methods. {counted}"
    )


def markdown(result: Comparison, *, command: str = "") -> str:
    """The text of ``comparison.md``."""
    t0, t1 = result.t_span
    anchor = result.anchor
    out = [
        f"# Comparison on `{result.problem}`, t in [{t0:g}, {t1:g}]",
        "",
        f"Headline rows are at **{result.matched_by()}**.",
        "",
        f"- Anchor: rk34q8 {anchor.describe()}: {anchor.nfev} f evaluations, max true "
        f"error {_cell(anchor.max_error, '.3e')}.",
        f"- True errors against: {result.reference} (accurate to "
        f"~{result.reference_accuracy:.1e}); max over the kept nodes and all components.",
        "- Energy error: max abs(H(y_i) - H(y_0)); drift slope: least-squares slope of "
        "H(y_i) - H(y_0) against t, with its standard error (which understates the "
        "uncertainty of a slowly oscillating error).",
        _wall_times(result.backend),
        "",
        "## Headline",
        "",
        *_table(result.selected(), result.reference_accuracy),
        "",
        "## Every run of the sweep",
        "",
        *_table(list(result.runs), result.reference_accuracy),
        "",
    ]
    if result.notes:
        out += ["## Notes", "", *[f"- {note}" for note in result.notes], ""]
    versions = package_versions()
    out += [
        "## Reproduce",
        "",
        f"`{command}`" if command else "",
        "",
        f"Python {versions['python']}, NumPy {versions['numpy']}, SciPy {versions['scipy']}, "
        f"hamrkq {versions['hamrkq']}.",
        "",
    ]
    return "\n".join(out)


def _csv(result: Comparison) -> str:
    rows = result.rows()
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if isinstance(v, float) and not math.isfinite(v) else v)
                         for k, v in row.items()})  # fmt: skip
    return buffer.getvalue()


# -- figures -------------------------------------------------------------------------------
def _figure(ncols: int, figsize: tuple[float, float]):
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    return fig, list(np.ravel(fig.subplots(1, ncols, squeeze=False)))


def work_precision_figure(result: Comparison, *, axes: Any = None) -> Figure:
    """Max true error against f evaluations and against wall time, per method."""
    if axes is None:
        fig, axes = _figure(2, (11.0, 4.5))
    else:
        axes = list(np.ravel(axes))
        fig = axes[0].figure
    methods = list(dict.fromkeys(run.method for run in result.runs))
    for k, method in enumerate(methods):
        runs = [r for r in result.runs if r.method == method and r.success
                and math.isfinite(r.max_error) and r.max_error > 0]  # fmt: skip
        runs.sort(key=lambda r: r.nfev)
        style = {"color": f"C{k % 10}", "marker": "o", "ms": 4, "lw": 1.2}
        for ax, cost in zip(axes, ("nfev", "wall_time"), strict=True):
            x = [getattr(r, cost) for r in runs]
            ax.plot(x, [r.max_error for r in runs], label=method, **style)
            chosen = [(getattr(r, cost), r.max_error) for r in runs if r.selected]
            if chosen:
                ax.plot(*zip(*chosen, strict=True), ls="none", marker="o", ms=11,
                        mfc="none", mec=style["color"], mew=1.5)  # fmt: skip
    for ax, label in zip(axes, ("f evaluations", "wall time (s)"), strict=True):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("max true global error")
        ax.grid(True, which="major", alpha=0.3)
        if result.match == "error" and math.isfinite(result.target) and result.target > 0:
            ax.axhline(result.target, color="0.4", ls=":", lw=1)
    axes[0].legend(fontsize=8)
    fig.suptitle(
        f"{result.problem}: work-precision (circled: headline runs, {result.match} matched)"
    )
    return fig


def energy_figure(result: Comparison, *, ax: Any = None) -> Figure:
    """abs(H - H(0)) against t for the headline run of each method."""
    from hamrkq.plotting.figures import upper_envelope

    if ax is None:
        fig, (ax,) = _figure(1, (9.0, 4.5))
    else:
        fig = ax.figure
    methods = list(dict.fromkeys(run.method for run in result.runs))
    for run in result.selected():
        sol = run.solution
        error = np.abs(sol.energy - sol.energy[0])
        error[error == 0] = np.nan  # no place on a log axis
        color = f"C{methods.index(run.method) % 10}"
        ax.plot(*upper_envelope(sol.t, error), color=color, lw=1.0,
                label=f"{run.method} ({run.describe()})")  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel("t")
    ax.set_ylabel("abs(H - H(0)), max per bin")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{result.problem}: energy error of the headline runs ({result.match} matched)")
    return fig


# -- the command ------------------------------------------------------------------------------
def _command_line(args: argparse.Namespace, methods: list[str]) -> str:
    """The command that reproduces this comparison (the settings it used)."""
    parts = ["hamrkq", "compare", args.problem, "--methods", *methods]
    for flag, value in (("--t-end", args.t_end), ("--match", args.match),
                        ("--backend", args.backend)):  # fmt: skip
        if value is not None:
            parts += [flag, repr(value) if isinstance(value, float) else str(value)]
    for flag, values in (("--tol-factors", args.tol_factors),
                         ("--step-factors", args.step_factors)):  # fmt: skip
        if values:
            parts += [flag, *map(repr, values)]
    parts += [f"--param={item}" for item in args.param]
    if args.quick:
        parts.append("--quick")
    return " ".join(parts)


def compare_command(args: argparse.Namespace) -> int:
    """The ``compare`` subcommand; returns the exit status."""
    from hamrkq.cli.run import parse_parameters

    check_dpi(args.dpi)
    problem = load_problem(args.problem)
    if args.param:
        problem = problem.with_parameters(**parse_parameters(args.param))
    out = OutputDir(args.out or DEFAULT_ROOT / problem.name, force=args.force)
    methods = args.methods or default_methods(problem)

    def log(text: str) -> None:
        print(f"  {text}", flush=True)
        # After each run: a run stopped by Ctrl-C or SIGTERM returns its
        # status, and compare() would go on with the rest of the sweep.  A
        # comparison keeps no partial results (its headline matches every
        # method to the anchor's error or cost over the whole sweep): stop.
        raise_if_interrupted()

    result = compare(
        problem, methods, t_end=args.t_end, quick=args.quick, match=args.match,
        tol_factors=args.tol_factors, step_factors=args.step_factors, backend=args.backend,
        log=log,
    )  # fmt: skip
    command = _command_line(args, methods)
    out.text(FILES["markdown"], markdown(result, command=command))
    out.text(FILES["csv"], _csv(result))
    if not args.no_plots:
        out.figure(FILES["work_precision"], work_precision_figure(result), dpi=args.dpi)
        out.figure(FILES["energy"], energy_figure(result), dpi=args.dpi)
    # last, listing what was written (it listed the figures after --no-plots too; QA)
    out.json(FILES["json"], {**result.to_dict(), "files": [*out.written, FILES["json"]]})
    print(f"{problem.name}: headline at {result.matched_by()}")
    print("\n".join(_table(result.selected(), result.reference_accuracy)))
    for note in result.notes:
        print(f"note: {note}")
    print(f"wrote {out.path}/: {', '.join(out.written)}")
    return 0 if result.anchor.success else 1
