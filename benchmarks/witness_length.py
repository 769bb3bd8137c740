"""How the quencher's rounding error grows with the length of a regular run.

    python benchmarks/witness_length.py [--before CHECKOUT [--before-label TEXT]]

(about 4 minutes, and as long again with ``--before``; writes
``witness_length.txt``.)

``hamrkq.rkq.witness_rules.needs_witness`` runs the rounding witness where
some component's tolerance is below ``WITNESS_BELOW`` (3e-10) of its size,
a threshold measured on prentice2011 over [0, 4000] (about 10 000 steps
with ``auto``).  The quencher's rounding grows with the interval: this
script measures how, on two regular orbits, with the quencher in double and
in double-double (whose rounding is far below), ``gamma_limit=inf`` so that
nothing stops the run:

- prentice2011 to t = 160 000 (about 15 000 periods), ``rk78q12`` with
  four quencher steps a step at atol 1e-8 (what ``auto`` runs there);
- Kepler e = 0.6 to 3 000 periods, ``rk67q9`` in two steps at atol 1e-10.

For each length T: the accepted steps up to T (the run's steps times the
share of the interval), the largest true error of the quencher's track z up
to T (against heyoka in extended precision, or the exact solution), over the
state's size, and the same for the double-double quencher.  The ratio of
successive errors gives the growth law the witness rule scales by.

Then ``method="auto"`` on prentice2011 over three lengths and tolerances,
and three members whose pairs take short steps, as a user calls them (2001
output times): status, largest true error over the
tolerance, the quencher's precision, evaluations (and those of runs made
again, discarded), time; with ``--before``, the same calls with the checkout
at CHECKOUT, side by side.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402

import hamrkq  # noqa: E402
from hamrkq.analysis.extended_reference import extended_reference  # noqa: E402

CASES = (
    ("prentice2011", {}, 160_000.0, "rk78q12", 4, 1e-8),
    ("kepler", {"e": 0.6}, 3000 * 2 * np.pi, "rk67q9", 2, 1e-10),
)


def truth(problem, t):
    if problem.exact is not None:
        return np.asarray(problem.exact(t))
    ham = problem.hamiltonian
    return extended_reference(ham, problem.parameter_array, problem.y0, t, t0=0.0).y


def growth_rows(name, params, t_end, method, substeps, atol) -> list[str]:
    problem = hamrkq.load_problem(name, **params)
    grid = np.linspace(0.0, t_end, 4001)
    ref = truth(problem, grid)
    size = float(np.max(np.abs(ref)))
    errors = {}
    steps = 0
    for precision in ("double", "double-double"):
        started = time.perf_counter()
        sol = hamrkq.solve(
            problem, t_span=(0.0, t_end), method=method, z_substeps=substeps, atol=atol,
            rtol=0.0, gamma_limit=np.inf, quencher_precision=precision, t_eval=grid,
        )  # fmt: skip
        elapsed = time.perf_counter() - started
        errors[precision] = np.maximum.accumulate(np.max(np.abs(sol.z - ref), axis=1)) / size
        steps = sol.stats["steps"] if precision == "double" else steps
        print(f"  {name} {precision}: {sol.stats['steps']} steps, {elapsed:.1f} s", flush=True)
    lines = [
        f"{name} {params or ''} {method}, z_substeps={substeps}, atol {atol:g}, "
        f"gamma_limit=inf, t to {t_end:g}; state size {size:.3g}",
        "",
        "| T | steps to T | z error / size, double | growth from T/2 | double-double |",
        "|---|---|---|---|---|",
    ]
    lengths = t_end / 2.0 ** np.arange(7)[::-1]
    previous = None
    for length in lengths:
        k = int(np.searchsorted(grid, length, side="right")) - 1
        err = errors["double"][k]
        growth = "-" if previous is None else f"{err / previous:.2f}"
        lines.append(
            f"| {length:.6g} | {int(steps * length / t_end)} | {err:.3e} | {growth} | "
            f"{errors['double-double'][k]:.3e} |"
        )
        previous = err
    return [*lines, ""]


#: (method, t_end, atol) of the runs on prentice2011: ``auto``, and members
#: whose pairs take short steps.
AUTO_RUNS = (
    ("auto", 4000.0, 1e-9),
    ("auto", 20_000.0, 1e-9),
    ("auto", 170_000.0, 1e-8),
    ("rk45q9", 4000.0, 1e-9),
    ("rk45q12", 4000.0, 1e-9),
    ("rk56q10", 4000.0, 1e-9),
)


def auto_rows() -> list[dict]:
    problem = hamrkq.load_problem("prentice2011")
    # the first call of a checkout may compile its kernel: not timed
    hamrkq.solve(problem, t_span=(0.0, 10.0), method="auto", atol=1e-9, t_eval=[5.0, 10.0])
    rows = []
    for method, t_end, atol in AUTO_RUNS:
        grid = np.linspace(0.0, t_end, 2001)
        ref = truth(problem, grid)
        started = time.perf_counter()
        sol = hamrkq.solve(
            problem, t_span=(0.0, t_end), method=method, atol=atol, rtol=0.0, t_eval=grid
        )
        elapsed = time.perf_counter() - started
        n = sol.t.size
        rows.append(
            {
                "method": method,
                "t_end": t_end,
                "atol": atol,
                "status": sol.status.name,
                "t_last": float(sol.t[-1]),
                "max_error_over_tol": float(np.abs(sol.y - ref[:n]).max() / atol),
                "member": sol.options["method"],
                "z_substeps": sol.options["z_substeps"],
                "quencher": sol.options["quencher_precision"],
                "evaluations": int(sol.stats["nfev"]),
                "discarded": int(sol.stats.get("discarded_evaluations", 0)),
                "seconds": elapsed,
            }
        )
        print(f"  {method} to {t_end:g} at {atol:g}: {elapsed:.1f} s", file=sys.stderr, flush=True)
    return rows


def _elsewhere(root: Path) -> list[dict]:
    """:func:`auto_rows` with the checkout at ``root``."""
    return measure.rows_at_checkout(__file__, root, "--auto-only")


def auto_table(rows: list[dict], label: str, before: list[dict], before_label: str) -> list[str]:
    lines = [
        "prentice2011 (2001 output times; true error against heyoka in extended precision):",
        "",
        "| method | t_end | atol | checkout | status | max true error / tol | member | "
        "quencher | evaluations | discarded | time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    pairs = [(label, rows)] + ([(before_label, before)] if before else [])
    for i in range(len(rows)):
        for name, group in pairs:
            r = group[i]
            lines.append(
                f"| {r.get('method', 'auto')} | {r['t_end']:g} | {r['atol']:g} | {name} | "
                f"{r['status']} | "
                f"{r['max_error_over_tol']:.3f} | {r['member']}, m = {r['z_substeps']} | "
                f"{r['quencher']} | {r['evaluations']} | {r['discarded']} | "
                f"{r['seconds']:.2f} |"
            )
    return [*lines, ""]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a checkout from before the change")
    parser.add_argument("--before-label", help="what the table calls it (its commit)")
    parser.add_argument("--auto-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.auto_only:
        print(json.dumps(auto_rows()))
        return 0
    lines = [
        "`benchmarks/witness_length.py`: the quencher's true error over the state's size "
        "on regular orbits, by length (largest up to T).",
        "",
    ]
    for case in CASES:
        lines += growth_rows(*case)
    before = []
    if args.before is not None:
        before = _elsewhere(args.before.resolve())
    label = args.before_label or (str(args.before) if args.before else "")
    lines += auto_table(auto_rows(), "now", before, label)
    text = "\n".join(lines)
    (HERE / "witness_length.txt").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
