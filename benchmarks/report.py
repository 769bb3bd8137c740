"""Turn the results of ``benchmarks/run.py`` into ``benchmarks/README.md``."""

from __future__ import annotations

from typing import Any

import measure

# The targets (issue 5), checked against the measurements.
TARGET_WARM_S = 0.15
TARGET_SCIPY_RATIO = 15.0
TARGET_FIRST_CALL_S = 10.0
TARGET_CLI_S = 3.0
TARGET_PYTHON_S = 60.0
TARGET_MEMORY_MB = 100.0

HEADER = """\
# Benchmarks

`python benchmarks/run.py` measures hamrkq against SciPy on this machine, side by
side in one run, and rewrites this file (every number also goes to
`benchmarks/results.json`).  `--quick` runs short spans to check that the script
works; `--skip-rk45` leaves out SciPy's RK45, the slowest row.

How to read it:

- **Ratios, not absolute times, are the claim.**  The times are medians of several
  warm runs (the code already compiled and loaded) on a shared machine; the
  ratio column divides each time by hamrkq's `rk34q8` time on the same problem,
  measured minutes apart in the same process.
- **Matched true error.**  hamrkq runs at the problem's tolerance; its maximum
  true error (any component, any node) is measured against an independent
  reference.  SciPy's DOP853 and RK45 are then run at the tolerance (searched,
  reported) at which each reaches that same maximum true error, so the rows
  compare the cost of the same accuracy.  SciPy is given hamrkq's compiled
  right-hand side (the fastest `f` there is), so its time is its own step
  loop; the row "f in Python" repeats DOP853 at the same tolerance with the
  interpreted `numeric_of(ham).rhs`, the kind of `f` a SciPy user writes.
  `rk34` (local extrapolation only, the paper's comparison) runs at hamrkq's
  tolerance and shows what the global-error control buys.
- **References.**  prentice2011: `hamrkq.analysis.reference.periodic_reference` (one
  period at SciPy's tightest tolerance, Newton on the period); kepler: the exact
  solution (Kepler's equation); outer_solar_system: a DOP853 run at rtol 1e-13
  (`integrate_reference`, with its check run), compared on 2001 equally spaced
  times that every integrator is asked for (`t_eval`).
- **Memory.**  "peak MB" is the peak of memory allocated through Python's
  allocators during one run (NumPy arrays included; `tracemalloc`).  The memory
  table measures resident memory (RSS) of fresh processes above an interpreter
  that imported hamrkq and loaded the same compiled code.
"""


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _case_table(key: str, case: dict[str, Any]) -> list[str]:
    t0, t1 = case["t_span"]
    scale = case.get("tol_scale", 1.0)
    lines = [
        f"### {key}, t in [{t0:g}, {t1:g}]",
        "",
        f"Reference: {case['reference']} (estimated error {case['reference_error']:.1e})."
        + (f"  Tolerances: {scale:g} x the catalogue's." if scale != 1.0 else ""),
        "",
        "| integrator | tolerance | max true error | nodes | steps | f evals | time (s) "
        "| ratio | peak MB |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in case["rows"]:
        tol = _fmt(row["tolerance"], 3)
        if row.get("matched") is False:
            tol += " (closest)"
        lines.append(
            f"| {measure.integrator_label(row)} | {tol} | {_fmt(row['max_true_error'])} "
            f"| {row['nodes']} "
            f"| {_fmt(row.get('steps'))} | {row['nfev']} | {row['seconds']:.3g} "
            f"({row['runs']} runs: {row['spread']}) | {row['ratio']:.3g} "
            f"| {row['memory_mb']:.3g} |"
        )
    lines.append("")
    return lines


def _verdict(ok: bool) -> str:
    return "met" if ok else "**not met**"


def _targets(results: dict[str, Any]) -> list[str]:
    lines = ["## The issue's targets", "", "| target | measured | |", "|---|---|---|"]
    case = results["cases"].get("prentice2011")
    if case:
        rows = {row["integrator"]: row for row in case["rows"]}
        warm = rows["hamrkq rk34q8 (numba)"]["seconds"]
        lines.append(
            f"| prentice2011 warm <= {TARGET_WARM_S} s | {warm:.3g} s "
            f"| {_verdict(warm <= TARGET_WARM_S)} |"
        )
        for label, name in (
            ("", "SciPy DOP853"),
            (" (SciPy given an interpreted f)", "SciPy DOP853, f in Python"),
        ):
            if name in rows:
                ratio = rows[name]["ratio"]
                lines.append(
                    f"| >= {TARGET_SCIPY_RATIO:g}x faster than SciPy DOP853 at matched true "
                    f"error{label} | {ratio:.3g}x | {_verdict(ratio >= TARGET_SCIPY_RATIO)} |"
                )
        py = rows.get("hamrkq rk34q8 (python)")
        if py:
            lines.append(
                f"| interpreted backend <= {TARGET_PYTHON_S:g} s | {py['seconds']:.3g} s "
                f"| {_verdict(py['seconds'] <= TARGET_PYTHON_S)} |"
            )
    start = results["startup"]
    first = start["cold_first_call"]["solve"]
    lines.append(
        f"| first call incl. generation + compilation <= {TARGET_FIRST_CALL_S:g} s "
        f"| {first:.3g} s | {_verdict(first <= TARGET_FIRST_CALL_S)} |"
    )
    cli = start["cli_warm_cache"]["median"]
    lines.append(
        f"| `hamrkq run prentice2011 --no-plots`, fresh process, warm cache <= "
        f"{TARGET_CLI_S:g} s wall | {cli:.3g} s | {_verdict(cli <= TARGET_CLI_S)} |"
    )
    mem = start["memory"]["runs"]["keep every node, t_end = 4000"]["above_interpreter_mb"]
    lines.append(
        f"| every node of prentice2011 kept: <= {TARGET_MEMORY_MB:g} MB above the "
        f"interpreter | {mem:.3g} MB | {_verdict(mem <= TARGET_MEMORY_MB)} |"
    )
    thin = start["memory"]["runs"]
    a = thin["t_eval of 2001 times, t_end = 4000"]["above_interpreter_mb"]
    b = thin["t_eval of 2001 times, t_end = 40000"]["above_interpreter_mb"]
    lines.append(
        f"| with thinning, memory flat up to t_end = 40 000 | {a:.3g} MB -> {b:.3g} MB "
        f"| {_verdict(b <= a + 5.0)} |"
    )
    lines.append("")
    return lines


def _startup(results: dict[str, Any]) -> list[str]:
    start = results["startup"]
    cold = start["cold_first_call"]
    lines = [
        "## Start-up",
        "",
        "| what | seconds |",
        "|---|---|",
        f"| prentice2011, first call in a fresh process with an empty cache (code generation, "
        f"compilation of the loop and the system; `import hamrkq` not included) "
        f"| {cold['solve']:.3g} ({cold['compiled']} signatures compiled) |",
        "| the same process, wall time including interpreter start and imports "
        f"| {cold['wall']:.3g} |",
    ]
    for key, info in start.items():
        if key.startswith("new_system_"):
            lines.append(
                f"| {key[11:]}, first call when the loop is cached but not the system "
                f"(generation + compilation of rhs/jac) | {info['solve']:.3g} |"
            )
    cli = start["cli_warm_cache"]
    lines.append(
        f"| `hamrkq run prentice2011 --no-plots`, fresh process, warm cache (wall, "
        f"interpreter start included; median of {len(cli['walls'])}) "
        f"| {cli['median']:.3g} |"
    )
    d = start["derive_generate_outer_solar_system"]
    lines += [
        "",
        "Deriving and generating the numerical functions of outer_solar_system "
        "(18 degrees of freedom), in a fresh process:",
        "",
        "| step | seconds |",
        "|---|---|",
        f"| parse the problem file | {d['parse']:.3g} |",
        f"| Hamilton's equations and the 36 x 36 Jacobian (SymPy) | {d['derive']:.3g} |",
        f"| NumPy functions (`numeric_of(ham)`, lambdify with CSE) | {d['numeric']:.3g} |",
        f"| scalar source for the compiled backend (`codegen.generate_source`, CSE, "
        f"{d['lines']} lines) | {d['codegen']:.3g} |",
        "",
    ]
    return lines


def _memory(results: dict[str, Any]) -> list[str]:
    mem = results["startup"]["memory"]
    lines = [
        "## Memory (resident, fresh processes)",
        "",
        f"Interpreter with hamrkq imported and the compiled code loaded: "
        f"{mem['interpreter_mb']:.0f} MB.",
        "",
        "| prentice2011 run (`gamma_limit=inf`) | nodes kept | steps | reached t | MB above |",
        "|---|---|---|---|---|",
    ]
    for label, info in mem["runs"].items():
        lines.append(
            f"| {label} | {info.get('nodes', '-')} | {info.get('steps', '-')} "
            f"| {_fmt(info.get('t_last'), 6)} | {info['above_interpreter_mb']:.3g} |"
        )
    lines.append("")
    return lines


def readme(results: dict[str, Any]) -> str:
    m = results["machine"]
    lines = [HEADER]
    if results.get("quick"):
        lines += ["**This file was written by a `--quick` run: short spans, not the claim.**", ""]
    lines += [
        "## Machine",
        "",
        f"{m['cpu']}, {m['cores']} cores, {_fmt(m['memory_gb'])} GB; {m['os']}; Python "
        f"{m['python']}, NumPy {m['numpy']}, SciPy {m['scipy']}, SymPy {m['sympy']}, "
        f"numba {m['numba']}.  Load average at the start {m['load_average']}, at the end "
        f"{m.get('load_average_end')} (other jobs shared the machine: ratios, not times).",
        "",
    ]
    lines += _targets(results)
    lines += ["## Time at matched true error", ""]
    for key, case in results["cases"].items():
        lines += _case_table(key, case)
    lines += _startup(results)
    lines += _memory(results)
    return "\n".join(lines)
