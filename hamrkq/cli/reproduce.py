"""``hamrkq reproduce prentice2011``: the paper's experiment, and its numbers side by side.

J.S.C. Prentice, arXiv:1111.6996, Section 4, integrates the non-separable
pendulum ``H = p**2/2 - (1 - p/6) cos q`` from ``q = arccos(-0.8), p = 0``
over ``[0, 4000]`` with RK34Q8 and with RK34 (local extrapolation only), at
the absolute tolerance ``delta = 1e-6`` (no relative part).  This command
does the same and writes, into ``--out`` (default
``./hamrkq-reproduce/prentice2011``):

- the paper's Figures 1-4 (``figure*.png``; Figures 2 and 3 twice: against
  the RK8 track as the paper measured, and ``*_true`` against an independent
  reference; Figure 4 shows the RK8 track's true error beside its estimate);
- ``comparison.md``: every number the paper reports (read from the
  problem's ``[expected]`` table), this run's value measured the paper's way
  (against its own RK8 track) and the true value (against an independent
  reference, :mod:`hamrkq.analysis.reference`), side by side;
- ``summary.json`` (both runs: settings, diagnostics, versions) and the two
  solutions (``solution_rk34q8.npz``, ``solution_rk34.npz``).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq.analysis.diagnostics import diagnose, error_summary, tolerance
from hamrkq.analysis.reference import hamiltonian_reference
from hamrkq.analysis.summaries import component_ratio_text
from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import InputError
from hamrkq.io.report import OutputDir, ProgressBar, check_dpi, format_table, summary_dict
from hamrkq.result import Status

__all__ = ["EXPERIMENTS", "register", "reproduce_command"]

DEFAULT_ROOT = Path("hamrkq-reproduce")
#: The paper's settings (Prentice 2011, Section 4): absolute tolerance 1e-6 on
#: local and global error, no relative tolerance, t in [0, 4000].
PAPER_ATOL = 1e-6
PAPER_RTOL = 0.0
PAPER_T_SPAN = (0.0, 4000.0)
LABELS = {"rk34q8": "RK34Q8", "rk34": "RK34"}


def register(subparsers: Any) -> None:
    """Add the ``reproduce`` subcommand."""
    p = subparsers.add_parser(
        "reproduce",
        help="rerun a published experiment: its figures and its numbers side by side",
        description=(
            "Rerun the experiment of a paper as it was done and write its figures and "
            "comparison.md (the paper's numbers, this run's, and the true values "
            "against an independent reference). Exit status: 0 success, 1 a run "
            "failed (partial results are written), 2 bad input."
        ),
    )
    p.add_argument("experiment", choices=sorted(EXPERIMENTS), help="which paper")
    p.add_argument(
        "--out", metavar="DIR", help="output directory (default: hamrkq-reproduce/EXPERIMENT)"
    )
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--backend", metavar="B", help="where the step loop runs (solve's default)")
    p.add_argument(
        "--t-end", type=float, metavar="T",
        help="stop at T instead of the paper's end (a quick look; the numbers then "
        "do not compare with the paper's)",
    )  # fmt: skip
    p.add_argument(
        "--dpi", type=int, default=120, help="resolution of the PNGs (10 to 600, default 120)"
    )
    p.set_defaults(func=reproduce_command)


def reproduce_command(args: argparse.Namespace) -> int:
    """The ``reproduce`` subcommand; returns the exit status."""
    check_dpi(args.dpi)
    _check_t_end(args.t_end)
    out = OutputDir(args.out or DEFAULT_ROOT / args.experiment, force=args.force)
    return EXPERIMENTS[args.experiment](args, out)


def _check_t_end(t_end: float | None) -> None:
    """Refuse a ``--t-end`` at or before the paper's start, t = 0, or not finite.

    The paper's run goes forward from t = 0: ``--t-end -5`` integrated
    backwards and ``--t-end 0`` integrated nothing, both labelled a
    "shortened run".

    Raises
    ------
    InputError
        ``t_end`` is not a finite number above 0.
    """
    if t_end is not None and not (PAPER_T_SPAN[0] < t_end < math.inf):
        raise InputError(
            f"--t-end must be a finite number above {PAPER_T_SPAN[0]:g} (the paper's run goes "
            f"forward from t = {PAPER_T_SPAN[0]:g}), got {t_end:g}"
        )


def _interval_note(t_end: float) -> str:
    """The caveat of a run over another interval than the paper's."""
    how = "shortened" if t_end < PAPER_T_SPAN[1] else "longer"
    than = "" if t_end < PAPER_T_SPAN[1] else " than the paper's"
    return (
        f"**This is a {how} run{than} (the paper's interval is [0, {PAPER_T_SPAN[1]:g}], "
        f"this run's [0, {t_end:g}]): its numbers do not compare with the paper's.**"
    )


# -- prentice2011 ----------------------------------------------------------------
def _prentice2011(args: argparse.Namespace, out: OutputDir) -> int:
    problem = load_problem("prentice2011")
    t_span = PAPER_T_SPAN if args.t_end is None else (PAPER_T_SPAN[0], args.t_end)
    settings = {"atol": PAPER_ATOL, "rtol": PAPER_RTOL, "t_span": t_span}
    if args.backend is not None:
        settings["backend"] = args.backend
    started = time.perf_counter()
    runs, refs, diags, times = {}, {}, {}, {}
    for number, method in enumerate(LABELS, start=1):
        label = LABELS[method]
        clock = time.perf_counter()
        with ProgressBar(f"{label} ({number}/{len(LABELS)})") as bar:
            sol = runs[label] = _solve(problem, method, settings, bar)
        times[f"solve_{method}"] = time.perf_counter() - clock
        out.solution(f"solution_{method}.npz", sol)
        if sol.status is Status.INTERRUPTED:
            # Ctrl-C: keep what was computed, run nothing more.
            out.json("summary.json", {
                "experiment": "prentice2011",
                "settings": {**settings, "out": str(out.path)},
                "interrupted": label,
                "runs": {k: summary_dict(v, None, problem=problem) for k, v in runs.items()},
                "files": [*out.written, "summary.json"],
            })  # fmt: skip
            print(f"{label}: {sol.message}\nwrote {out.path}/: {', '.join(out.written)}")
            return 1
        clock = time.perf_counter()
        # One independent reference per run, at its own nodes; diagnose() with
        # reference="independent" computes exactly this, so the numbers agree
        # with a library call.
        refs[label] = hamiltonian_reference(problem, sol.y[0], sol.t)
        diags[label] = diagnose(sol, problem, reference=refs[label])
        times[f"diagnose_{method}"] = time.perf_counter() - clock
    q8 = runs["RK34Q8"]
    rk8_error = q8.z - refs["RK34Q8"].y
    rk8_true = _rk8_true_error(q8, rk8_error, refs["RK34Q8"])
    clock = time.perf_counter()
    _figures(out, runs, diags, rk8_error, dpi=args.dpi)
    times["figures"] = time.perf_counter() - clock
    times["total"] = time.perf_counter() - started

    rows = comparison_rows(problem.expected, runs, diags, rk8_true)
    out.text("comparison.md", comparison_markdown(rows, runs, diags, refs, t_span, times))
    summary = {
        "experiment": "prentice2011",
        "settings": {**settings, "out": str(out.path), "dpi": args.dpi},
        "wall_time_s": times,
        "runs": {
            label: summary_dict(sol, diags[label], problem=problem, settings=settings)
            for label, sol in runs.items()
        },
        "rk8_track_true_error": rk8_true.to_dict(),
        "comparison": rows,
        "files": [*out.written, "summary.json"],
    }
    out.json("summary.json", summary)

    print(f"prentice2011 (Prentice 2011, Section 4) over [{t_span[0]:g}, {t_span[1]:g}]")
    if t_span != PAPER_T_SPAN:  # as comparison.md says it (stdout did not; QA)
        print(_interval_note(t_span[1]).replace("**", ""))
    print(format_table((r["quantity"], f"paper {r['paper']} | this run {r['run']} | "
                        f"true {r['true']}") for r in rows))  # fmt: skip
    print(promise_line(diags["RK34Q8"]))
    for label, sol in runs.items():
        if not sol.success:
            print(f"{label}: {sol.message}")
    print(f"wall time {times['total']:.1f} s; wrote {out.path}/: {', '.join(out.written)}")
    return 0 if all(sol.success for sol in runs.values()) else 1


def _solve(problem: Any, method: str, settings: Mapping[str, Any], bar: ProgressBar) -> Any:
    from hamrkq.solve import solve

    return solve(problem, method=method, progress=bar, **settings)


def _rk8_true_error(sol: Any, error: np.ndarray, ref: Any) -> Any:
    """Summary of the RK8 track's error against the independent reference
    (``error = z - reference``: what Gamma estimates)."""
    rule = str(sol.options.get("tolerance_rule", "componentwise"))
    return error_summary(
        sol.t,
        error,
        tolerance(sol.z, sol.atol, sol.rtol, rule),
        source="independent",
        description=ref.method,
        reference_accuracy=ref.estimated_error,
        names=sol.names,
    )


def _figures(out: OutputDir, runs: dict, diags: dict, rk8_error: np.ndarray, *, dpi: int) -> None:
    from matplotlib.figure import Figure

    from hamrkq.plotting import figures as plotting

    title = "prentice2011"
    out.figure("figure1_solution.png", plotting.figure1(runs, title=title), dpi=dpi)
    for error, suffix in (("estimated", ""), ("true", "_true")):
        for name, draw in (
            ("figure2_global_error", plotting.figure2),
            ("figure3_trajectory_error", plotting.figure3),
        ):
            fig = draw(runs, diagnostics=diags, error=error, title=title)
            out.figure(f"{name}{suffix}.png", fig, dpi=dpi)
    # Figure 4 with the true error of the RK8 track drawn over its estimate: the
    # paper could not show this, and it is where this run and the paper differ most.
    q8 = runs["RK34Q8"]
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    plotting.figure4(q8, ax=ax, title=title)
    error = np.max(np.abs(rk8_error), axis=1)
    error = np.where(error > 0, error, np.nan)  # a log axis cannot show the exact zero at t0
    label = "true error of RK8, max(|q|, |p|), vs independent reference (upper envelope)"
    ax.plot(*plotting.upper_envelope(q8.t, error), color="k", lw=1.0, label=label)
    ax.legend(fontsize="small")
    out.figure("figure4_rk8_error.png", fig, dpi=dpi)


# -- the comparison ------------------------------------------------------------------
def _g(value: Any, spec: str = ".3e") -> str:
    if value is None or not np.isfinite(value):
        return "n/a"
    return format(value, spec)


def _paper(expected: Mapping[str, Any], key: str, prefix: str = "") -> str:
    if key not in expected:
        return "—"
    value = expected[key]
    return f"{prefix}{value}" if isinstance(value, int) else f"{prefix}{value:.4g}"


def promise_line(diag: Any) -> str:
    """RK34Q8's largest error over its tolerance, component by component
    (hamrkq's promise, which the paper's Euclidean trajectory bound does not
    measure), against its RK8 track and against the reference, as the run
    reports show it (:func:`~hamrkq.analysis.summaries.component_ratio_text`:
    an infinite ratio, a broken promise, is shown, not "n/a")."""

    def ratio(summary: Any) -> str:
        text = None if summary is None else component_ratio_text(summary)
        return "n/a" if text is None else text

    return (
        "RK34Q8 error / tolerance (worst component, hamrkq's promise; not in the "
        f"paper): {ratio(diag.estimated)} against its RK8 track, {ratio(diag.error)} true"
    )


def comparison_rows(
    expected: Mapping[str, Any], runs: Mapping[str, Any], diags: Mapping[str, Any], rk8_true: Any
) -> list[dict[str, str]]:
    """One row per number the paper reports: quantity, paper, run, true, source."""
    q8, rk34 = runs["RK34Q8"], runs["RK34"]
    d8, d34 = diags["RK34Q8"], diags["RK34"]
    est, true = d8.estimated, d8.error
    h_exact = expected.get("energy")
    rows: list[dict[str, str]] = []

    def row(key: str, quantity: str, paper: str, run: str, truth: str) -> None:
        rows.append(
            {
                "key": key,
                "quantity": quantity,
                "paper": paper,
                "run": run,
                "true": truth,
                "source": str(expected.get(f"{key}_source", "")),
            }
        )

    steps = q8.stats.get("steps", 0)
    mean_step = float(q8.t[-1] - q8.t[0]) / max(steps, 1)
    row("nodes", "RK34Q8 nodes", _paper(expected, "nodes", "about "),
        f"{len(q8)} (mean step {mean_step:.4f})", "—")  # fmt: skip
    for k, name in enumerate(q8.names):
        key = f"max_global_error_{name}"
        row(key, f"RK34Q8 max abs. global error in {name}", _paper(expected, key),
            _g(est.max_abs[k]), _g(true.max_abs[k]))  # fmt: skip
    row("trajectory_error_bound", "RK34Q8 max trajectory error (/ paper's bound)",
        _paper(expected, "trajectory_error_bound", "bound "),
        f"{_g(est.max_trajectory)} ({_g(est.bound_ratio, '.4f')})",
        f"{_g(true.max_trajectory)} ({_g(true.bound_ratio, '.4f')})")  # fmt: skip
    energy_run = (
        f"max abs(H - H(0)) = {_g(d8.energy.max_abs)} (/ bound {_g(d8.energy_bound_ratio, '.3f')})"
    )
    energy_true = "—"
    if h_exact is not None:
        energy_true = f"max abs(H - {h_exact:g}) = {_g(np.max(np.abs(q8.energy - h_exact)))}"
    row("energy", "RK34Q8 energy H", _paper(expected, "energy", "constant at "),
        energy_run, energy_true)  # fmt: skip
    rk34_true = ", ".join(
        f"{n} {_g(v)}" for n, v in zip(rk34.names, d34.error.max_abs, strict=True)
    )
    row("rk34_max_global_error", "RK34 max abs. global error",
        _paper(expected, "rk34_max_global_error", "about "),
        "— (RK34 has no RK8 track)", rk34_true)  # fmt: skip
    drift_run = f"H(end) - H(0) = {d34.energy.final:+.3e} (max {_g(d34.energy.max_abs)})"
    drift_true = "—"
    if h_exact is not None:
        drift_true = f"H(end) - {h_exact:g} = {rk34.energy[-1] - h_exact:+.3e}"
    row("rk34_energy_drift", "RK34 drift of H over the run",
        _paper(expected, "rk34_energy_drift", "about "), drift_run, drift_true)  # fmt: skip
    row("rk8_estimated_global_error", "RK8 track: max global error (Gamma est. / true)",
        _paper(expected, "rk8_estimated_global_error"), _g(d8.gamma_max),
        _g(max(rk8_true.max_abs)))  # fmt: skip
    return rows


def comparison_markdown(
    rows: list[dict[str, str]],
    runs: Mapping[str, Any],
    diags: Mapping[str, Any],
    refs: Mapping[str, Any],
    t_span: tuple[float, float],
    times: Mapping[str, float],
) -> str:
    """``comparison.md``: the table, how each column was measured, and the caveats."""
    q8 = runs["RK34Q8"]
    lines = [
        "# prentice2011: the paper's numbers and this run's",
        "",
        "J.S.C. Prentice, *Global Error Control in the Runge-Kutta Solution of a "
        "Hamiltonian System using the RKQ Algorithm*, arXiv:1111.6996, Section 4.",
        f"H = p**2/2 - (1 - p/6) cos q, q(0) = arccos(-0.8), p(0) = 0, "
        f"t in [{t_span[0]:g}, {t_span[1]:g}], atol = {PAPER_ATOL:g}, rtol = {PAPER_RTOL:g}.",
        "",
    ]
    if tuple(t_span) != PAPER_T_SPAN:
        lines += [_interval_note(t_span[1]), ""]
    lines += [
        "- *paper*: the value the paper reports (from the problem file's `[expected]` table).",
        "- *this run*: measured the paper's way, against the run's own RK8 track.",
        f"- *true*: against an independent reference, {refs['RK34Q8'].describe()}.",
        "",
        "| quantity | paper | this run (vs RK8 track) | true (vs reference) |",
        "|---|---|---|---|",
    ]
    lines += [f"| {r['quantity']} | {r['paper']} | {r['run']} | {r['true']} |" for r in rows]
    lines += ["", promise_line(diags["RK34Q8"])]
    lines += ["", "Runs:", ""]
    for label, sol in runs.items():
        stats = sol.stats
        extra = f", {stats.get('quenches', 0)} quenches" if sol.z is not None else ""
        lines.append(
            f"- {label}: {sol.status.name}, {len(sol)} nodes, {stats.get('steps', 0)} steps, "
            f"{stats.get('rejected', 0)} rejected{extra}, {stats.get('nfev', 0)} f-evaluations, "
            f"{times.get('solve_' + sol.method, float('nan')):.1f} s "
            f"(backend {sol.options.get('backend', '?')})."
        )
    lines.append(
        f"- Wall time of the whole reproduction: {times.get('total', float('nan')):.1f} s."
    )
    notes = [f"{label}: {note}" for label, d in diags.items() for note in d.notes]
    if notes:
        lines += ["", "Notes:", "", *[f"- {note}" for note in notes]]
    sources = [(r["quantity"], r["source"]) for r in rows if r["source"]]
    if sources:
        lines += ["", "Sources of the paper's values:", ""]
        lines += [f"- {quantity}: {source}" for quantity, source in sources]
    lines += [
        "",
        f"Step sizes: RK34Q8 mean step {float(q8.t[-1] - q8.t[0]) / max(len(q8) - 1, 1):.4f} "
        "(the paper's nodes imply about 0.042).",
        "",
    ]
    return "\n".join(lines)


#: Experiments ``reproduce`` knows: name -> function(args, out) -> exit status.
EXPERIMENTS: dict[str, Callable[[argparse.Namespace, OutputDir], int]] = {
    "prentice2011": _prentice2011,
}
