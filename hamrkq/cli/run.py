"""``hamrkq run NAME|FILE``: integrate one problem and write a report.

What it writes into ``--out`` (default ``./hamrkq-run/NAME``), every file
atomically:

- ``solution.npz``: the nodes, states and error estimates
  (:meth:`hamrkq.Solution.save`; read back with ``Solution.load``);
- ``summary.json``: the settings, every number of
  :func:`hamrkq.analysis.diagnostics.diagnose`, the counters, wall times, the status
  (``"partial": true`` when the run stopped early) and package versions;
- the figures (PNG) of :mod:`hamrkq.plotting.figures`, unless ``--no-plots``.

The summary table goes to stdout, a progress bar to stderr on a terminal.
Exit status: 0 success, 1 the integration failed or was interrupted (Ctrl-C
or SIGTERM; the partial results are still written), 2 bad input, 3 the
results could not be written (the table is still printed).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq.analysis.diagnostics import REFERENCE_KINDS
from hamrkq.analysis.report_reference import diagnose_for_report
from hamrkq.catalogue.problems import load_problem
from hamrkq.cli import EXIT_WRITE_FAILED
from hamrkq.cli.interrupts import (
    QUICK_REPORT,
    interrupted,
    interrupts_held,
    quick_report,
    signals_received,
)
from hamrkq.errors import InputError, OptionError
from hamrkq.io.report import (
    OutputDir,
    ProgressBar,
    check_dpi,
    format_table,
    jsonable,
    summary_dict,
    summary_rows,
)
from hamrkq.options import GAMMA_MODES, METHOD_NAMES, QUENCHER_PRECISIONS
from hamrkq.solve import BACKENDS, METHODS, solve

__all__ = ["check_keep_every", "check_step", "register", "run_command"]

DEFAULT_ROOT = Path("hamrkq-run")

#: File names of the figures; the ``_true`` variants are against the
#: independent or exact reference, the others against the run's RK8 track
#: (the paper's way) or, for a run without one, against the reference.
FIGURES = {
    "figure1": "figure1_solution.png",
    "figure2": "figure2_global_error.png",
    "figure3": "figure3_trajectory_error.png",
    "figure2_true": "figure2_global_error_true.png",
    "figure3_true": "figure3_trajectory_error_true.png",
    "figure4": "figure4_rk8_error.png",
}


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand."""
    p = subparsers.add_parser(
        "run",
        help="integrate a problem; write summary.json, solution.npz and figures",
        description=(
            "Integrate a catalogue problem (or a .toml problem file) and report: a "
            "summary table on stdout; summary.json, solution.npz and the paper's "
            "figures in --out. Settings not given come from the problem file. "
            "Exit status: 0 success, 1 the integration failed (partial results are "
            "written), 2 bad input."
        ),
    )
    p.add_argument("problem", metavar="NAME|FILE", help="catalogue name or .toml file")
    p.add_argument(
        "--method", metavar="M", help=f"integration method ({', '.join(METHOD_NAMES)}); "
        "default: the problem's, else auto"
    )  # fmt: skip
    p.add_argument(
        "--atol", action="append", default=[], metavar="A|NAME=A",
        help="absolute tolerance: a number for every component, or NAME=A for the "
        "component of that coordinate or momentum (repeatable; the others keep the "
        "plain --atol, else the problem's)",
    )  # fmt: skip
    p.add_argument("--rtol", type=float, metavar="R", help="relative tolerance")
    p.add_argument("--t-start", type=float, metavar="T0", help="start of the interval")
    p.add_argument("--t-end", type=float, metavar="T", help="end of the interval")
    p.add_argument("--max-step", type=float, metavar="H", help="largest step size")
    p.add_argument("--first-step", type=float, metavar="H", help="initial step size")
    p.add_argument(
        "--keep-every", type=int, metavar="K", help="keep every K-th accepted node "
        "(and the first and last)"
    )  # fmt: skip
    p.add_argument(
        "--step", type=float, metavar="H", help="step size of a fixed-step method "
        "(midpoint, gauss4, verlet, ...)"
    )  # fmt: skip
    p.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE",
        help="override a parameter of the problem (a number; repeatable)",
    )  # fmt: skip
    p.add_argument("--max-steps", type=int, metavar="N", help="limit on step attempts")
    p.add_argument(
        "--z-substeps", type=int, metavar="M", help="quencher steps per step of the pair "
        "(family members); default: the member's, or learned by auto"
    )  # fmt: skip
    p.add_argument(
        "--global-error-estimate", choices=tuple(GAMMA_MODES), metavar="E",
        help=f"how the quencher's global error Gamma is estimated ({', '.join(GAMMA_MODES)}); "
        "default: the method's",
    )  # fmt: skip
    p.add_argument(
        "--quencher-precision", choices=QUENCHER_PRECISIONS, metavar="P",
        help=f"the quencher's arithmetic ({', '.join(QUENCHER_PRECISIONS)}); default: "
        "double, which auto may raise",
    )  # fmt: skip
    p.add_argument(
        "--backend", metavar="B", help=f"where the step loop runs ({', '.join(BACKENDS)}); "
        "default: solve's default"
    )  # fmt: skip
    p.add_argument(
        "--reference", choices=REFERENCE_KINDS, default="auto",
        help="what the true error is measured against; auto: the exact solution if "
        "the problem has one, else an independent high-accuracy integration; "
        "extended: heyoka in extended precision (pip install 'hamrkq[bench]'), for "
        "tolerances below what the independent one reaches",
    )  # fmt: skip
    p.add_argument("--out", metavar="DIR", help="output directory (default: hamrkq-run/NAME)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--no-plots", action="store_true", help="do not draw the figures")
    p.add_argument(
        "--dpi", type=int, default=120, help="resolution of the PNGs (10 to 600, default 120)"
    )
    p.add_argument(
        "--csv", action="store_true", help="also write solution.csv (t, the coordinates and "
        "momenta by name, H) beside solution.npz"
    )  # fmt: skip
    output = p.add_mutually_exclusive_group()
    output.add_argument(
        "--json", action="store_true", help="print summary.json on stdout instead of the "
        "table (for scripts); no progress bar"
    )  # fmt: skip
    output.add_argument(
        "--quiet", action="store_true", help="print nothing but errors (the files are "
        "still written); no progress bar"
    )  # fmt: skip
    p.set_defaults(func=run_command)


def parse_parameters(items: list[str]) -> dict[str, float]:
    """``["a=6", "b=0.5"]`` -> ``{"a": 6.0, "b": 0.5}``; values are plain numbers
    (``float``), never expressions."""
    values: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not sep or not name.isidentifier() or not math.isfinite(value):
            raise InputError(f"--param {item!r}: expected NAME=NUMBER with a finite number")
        values[name] = value
    return values


def parse_atol(items: list[str], problem: Any) -> float | list[float] | None:
    """``--atol`` values -> what :func:`hamrkq.solve` takes as ``atol``.

    ``["1e-8"]`` -> ``1e-8``; ``["1e-8", "x=1e-10"]`` -> a list of 2n values, the
    named components set and the others ``1e-8``; with names only, the others
    keep the problem's atol (or solve's default 1e-6).  None when not given.
    """
    if not items:
        return None
    names = list(problem.hamiltonian.names)
    plain: float | None = None
    named: dict[str, float] = {}
    for item in items:
        name, sep, text = item.rpartition("=")
        name = name.strip()
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value <= 0:
            raise InputError(f"--atol {item!r}: expected a positive finite number or NAME=NUMBER")
        if not sep:
            if plain is not None:
                raise InputError(f"--atol {item!r}: a plain --atol was already given ({plain:g})")
            plain = value
            continue
        if name not in names:
            raise InputError(
                f"--atol {item!r}: {name!r} is not a coordinate or momentum of "
                f"{problem.name!r} (names: {', '.join(names)})"
            )
        if name in named:
            raise InputError(f"--atol {item!r}: {name} was already given ({named[name]:g})")
        named[name] = value
    if not named:
        return plain
    base = plain if plain is not None else problem.integration.get("atol", 1e-6)
    values = np.broadcast_to(np.asarray(base, dtype=float), (len(names),)).tolist()
    for name, value in named.items():
        values[names.index(name)] = value
    return values


def check_keep_every(keep_every: int | None, problem: Any) -> None:
    """Refuse ``--keep-every K`` (K > 1) for a problem whose file has a
    terminal event.

    Events are located between consecutive nodes, so a thinned run leaves a
    file's events out (with a warning): the run would not stop where the
    problem says it ends (``osct.toml``'s terminal event at t = 2.354) but go
    on to ``t_end`` with status SUCCESS.  ``--keep-every`` only makes the
    output smaller; it must not change what is computed, and leaving it out
    honours both.  (A method outside the RKQ family, which cannot locate
    events either, is still allowed, with the warning and a note in
    summary.json: running a problem with another method is what comparing
    methods means.)

    Raises
    ------
    InputError
        ``keep_every`` above 1 and a terminal event in the problem file.
    """
    if keep_every is None or keep_every <= 1:
        return
    terminal = [repr(str(event["expression"])) for event in problem.events if event["terminal"]]
    if terminal:
        raise InputError(
            f"--keep-every {keep_every}: problem {problem.name!r} has a terminal event "
            f"({', '.join(terminal)}) that ends the run where it occurs, and events are "
            "located only with every node kept: the run would go on past it to t_end. "
            "Leave out --keep-every (and thin the nodes afterwards: "
            f"Solution.load(path).t[::{keep_every}])"
        )


def resolve_reference(kind: str, problem: Any, method: str) -> str:
    """The reference kind for :func:`diagnose`, checked before the run starts."""
    if kind == "auto":
        return "exact" if problem.exact_spec is not None else "independent"
    if kind == "exact" and problem.exact_spec is None:
        raise OptionError(
            f"--reference exact: problem {problem.name!r} has no exact solution; "
            "use --reference independent"
        )
    if kind == "extended":
        from hamrkq.analysis.extended_reference import unavailable_reason

        reason = unavailable_reason()
        if reason:
            raise OptionError(f"--reference extended is not available: {reason}")
    spec = METHODS.get(method)
    if kind == "rk8" and spec is not None and not spec.rk8:
        raise OptionError(f"--reference rk8: method {method!r} has no quencher track")
    return kind


def solve_arguments(args: argparse.Namespace, problem: Any) -> dict[str, Any]:
    """Keywords for :func:`hamrkq.solve`: only what the command line set, so that
    everything else keeps the problem's (or solve's) default."""
    kwargs: dict[str, Any] = {}
    names = (
        "method", "rtol", "step", "max_steps", "backend", "max_step", "first_step",
        "z_substeps", "global_error_estimate", "quencher_precision",
    )  # fmt: skip
    for name in (*names, "keep_every"):
        value = getattr(args, name)
        if value is not None:
            kwargs[name] = value
    atol = parse_atol(args.atol, problem)
    if atol is not None:
        kwargs["atol"] = atol
    check_step(kwargs.get("method"), args.step, problem, "--step H")
    if args.t_start is not None or args.t_end is not None:
        t0, t_end = problem.t_span
        kwargs["t_span"] = (
            t0 if args.t_start is None else args.t_start,
            t_end if args.t_end is None else args.t_end,
        )
    return kwargs


def check_step(method: str | None, step: float | None, problem: Any, option: str) -> None:
    """An InputError naming the command's option for the step size (``option``)
    when a fixed-step method has none, from the command line or the problem
    file (solve's own message names its keyword, ``step``)."""
    from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS

    method = method or problem.integration.get("method", "auto")
    if method in FIXED_STEP_METHODS and step is None and "step" not in problem.integration:
        raise InputError(
            f"--method {method} is a fixed-step method: give its step size with {option}"
        )


def write_csv(out: OutputDir, name: str, sol: Any) -> None:
    """``t``, every coordinate and momentum by name, and ``H`` at each node, as
    CSV with a header line; full precision (``repr`` of each float)."""
    header = ",".join(["t", *sol.names, "H"])
    table = np.column_stack([sol.t, sol.y, sol.energy])
    lines = [header, *(",".join(repr(float(v)) for v in row) for row in table)]
    out.text(name, "\n".join(lines) + "\n")


def write_figures(out: OutputDir, sol: Any, diag: Any, *, title: str, dpi: int) -> list[str]:
    """Draw and save the figures this run supports; returns notes on those skipped."""
    from hamrkq.plotting import figures as plotting

    if len(sol) < 2:
        return ["fewer than two nodes: no figures"]
    true_ref = diag is not None and diag.error is not None and diag.error.source != "rk8"
    notes = []
    if true_ref and not diag.error_measured:
        # The summary says the true error was not measured (the reference is
        # not accurate enough); a figure of it would say the opposite.
        true_ref = False
        if sol.global_error is not None:
            names = f"{FIGURES['figure2_true']}, {FIGURES['figure3_true']}"
            notes.append(f"{names} not drawn: the true error is {diag.error_note}")
    jobs: list[tuple[str, Any]] = [("figure1", lambda: plotting.figure1(sol, title=title))]
    for number, draw in (("2", plotting.figure2), ("3", plotting.figure3)):
        jobs.append((f"figure{number}", lambda d=draw: d(sol, diagnostics=diag, title=title)))
        if true_ref and sol.global_error is not None:
            jobs.append(
                (
                    f"figure{number}_true",
                    lambda d=draw: d(sol, diagnostics=diag, error="true", title=title),
                )
            )
    if sol.gamma is not None:
        jobs.append(("figure4", lambda: plotting.figure4(sol, title=title)))
    for key, draw in jobs:
        try:
            fig = draw()
        except InputError as exc:  # e.g. no error to plot: RK34 with --reference none
            notes.append(f"{FIGURES[key]} not drawn: {exc}")
            continue
        out.figure(FIGURES[key], fig, dpi=dpi)
    return notes


def run_command(args: argparse.Namespace) -> int:
    """The ``run`` subcommand; returns the exit status."""
    check_dpi(args.dpi)
    problem = load_problem(args.problem)
    if args.param:
        problem = problem.with_parameters(**parse_parameters(args.param))
    kwargs = solve_arguments(args, problem)
    check_keep_every(args.keep_every, problem)
    method = kwargs.get("method", problem.integration.get("method", "auto"))
    reference = resolve_reference(args.reference, problem, method)
    out = OutputDir(args.out or DEFAULT_ROOT / problem.name, force=args.force)

    started = time.perf_counter()
    quiet = args.quiet or args.json  # stdout and stderr stay clean for scripts
    if not quiet:
        announce_preparation(problem)
    with ProgressBar(f"{problem.name} {method}", enabled=False if quiet else None) as bar:
        sol = solve(problem, progress=bar, **kwargs)
    solve_time = time.perf_counter() - started
    notes = _events_left_out(sol)
    with interrupts_held() as held:
        write_failed = _attempt(lambda: out.solution("solution.npz", sol))
        if args.csv and write_failed is None:
            write_failed = _attempt(lambda: write_csv(out, "solution.csv", sol))
    diag, reference, more, write_failed, cut_short = _report(
        sol, problem, reference, args, out, held, write_failed
    )
    notes += more
    total = time.perf_counter() - started
    settings = {
        "command": "run",
        "problem": args.problem,
        "reference": reference,
        "plots": not args.no_plots,
        "dpi": args.dpi,
        "out": str(out.path),
        "cli_overrides": kwargs,
        "parameters": dict(problem.parameters),
    }
    with interrupts_held():
        summary = summary_dict(
            sol,
            diag,
            problem=problem,
            settings=settings,
            wall_time={"solve": solve_time, "total": total},
            notes=notes,
        )
        if signals_received():  # the status says "KeyboardInterrupt"; say what it was
            summary["notes"].append(
                f"stopped by {', '.join(signals_received())} (handled like Ctrl-C)"
            )
        notes = summary["notes"]
        summary["files"] = [*out.written, "summary.json"]
        if write_failed is None:
            write_failed = _attempt(lambda: out.json("summary.json", summary))

    if args.json:
        print(json.dumps(jsonable(summary), indent=2, allow_nan=False))
    elif not args.quiet:
        print_summary(problem, sol, diag, notes, solve_time)
    if write_failed is not None:
        # The table above is all that is left of the run: say so, distinctly
        # from a failed integration.
        print(f"hamrkq: error: cannot write output: {write_failed}", file=sys.stderr)
        if out.written and not quiet:
            print(f"wrote only {out.path}/: {', '.join(out.written)}")
        return EXIT_WRITE_FAILED
    if not quiet:
        print(f"wrote {out.path}/: {', '.join(out.written)}")
    # Ctrl-C or SIGTERM after the run (in the report, or held back while a
    # file was written): the files are whole, the exit status says it.
    return 0 if sol.success and not cut_short and not interrupted() else 1


def _events_left_out(sol: Any) -> list[str]:
    """The note that the problem file's events were left out (a thinned or
    baseline run), in the warning's words, for scripts reading
    summary.json; none where the message says it already (events located
    along part of an interrupted run)."""
    missing = sol.options.get("events_not_located")
    return [missing] if missing and missing not in sol.message else []


def _report(
    sol: Any,
    problem: Any,
    reference: str,
    args: argparse.Namespace,
    out: OutputDir,
    held: list[BaseException],
    write_failed: OSError | None,
) -> tuple[Any, str, list[str], OSError | None, bool]:
    """The diagnostics against ``reference`` and the figures of a run:
    ``(diagnostics or None, the reference used, notes, write_failed,
    interrupted)``.  After SIGTERM the quick report (no reference, no
    figures); Ctrl-C now, or ``held`` while the nodes were written, skips the
    rest of it."""
    notes: list[str] = []
    quick = quick_report()
    if quick:
        reference = "none"
        notes.append(QUICK_REPORT)
    diag = None
    try:
        if held and not quick:
            raise held[0]  # Ctrl-C while the nodes were written: as a second Ctrl-C
        diag, reference, more = diagnose_for_report(
            sol, problem, reference, extend=args.reference == "auto"
        )
        notes += more
        if not args.no_plots and not quick and write_failed is None:
            write_failed = _attempt(
                lambda: notes.extend(
                    write_figures(out, sol, diag, title=problem.name, dpi=args.dpi)
                )
            )
    except KeyboardInterrupt:
        notes.append("interrupted during diagnostics or plotting; report incomplete")
        return diag, reference, notes, write_failed, True
    return diag, reference, notes, write_failed, False


def print_summary(problem: Any, sol: Any, diag: Any, notes: list[str], solve_time: float) -> None:
    """The human-readable report on stdout."""
    print(f"{problem.name}: {problem.title}")
    print(format_table(summary_rows(sol, diag, wall_time=solve_time)))
    if not sol.success and diag is None:  # otherwise the diagnostics' notes carry it
        print(f"message: {sol.message}")
    for note in [*(diag.notes if diag is not None else ()), *notes]:
        print(f"note: {note}")


#: Degrees of freedom from which deriving and compiling takes long enough
#: (tens of seconds and more) to be announced even when stderr is not a terminal.
LARGE_SYSTEM = 50


def announce_preparation(problem: Any, stream: Any = None) -> None:
    """Say on stderr that the equations are being derived and compiled.

    The first step of a large system comes only after SymPy has derived
    Hamilton's equations and the Jacobian and numba has compiled them (issue
    17 measured about five minutes for a 200-degree-of-freedom chain); without
    a word the run would look hung.  Said on a terminal, and for large systems everywhere.
    """
    stream = sys.stderr if stream is None else stream
    n = problem.hamiltonian.n
    isatty = getattr(stream, "isatty", None)
    if n >= LARGE_SYSTEM or (isatty is not None and isatty()):
        stream.write(
            f"{problem.name}: deriving and compiling Hamilton's equations "
            f"({n} degree{'s' if n != 1 else ''} of freedom)"
            f"{'; this can take minutes' if n >= LARGE_SYSTEM else ''} ...\n"
        )
        stream.flush()


def _attempt(write: Any) -> OSError | None:
    """Run ``write``; return the OSError it raised (disk full, ...), or None."""
    try:
        write()
    except OSError as exc:
        return exc
    return None
