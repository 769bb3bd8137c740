"""The rounding witness on arenstorf at 1e-12: a larger nudge of the parameters.

    python benchmarks/witness_constants.py

On arenstorf at ``atol`` 1e-12 the witness (the quencher again, its sums
reversed and the parameters moved by an ulp,
``hamrkq.rkq.steps.witness_step``) lets nodes of 1.86 delta through before
the run stops (``benchmarks/promise.md``; docs/algorithm.md, "Limit", for
what is known about that systematic error).  This script measures

1. how far the quencher track moves when the constant ``1 - mu`` moves by
   one ulp (``mu`` moved by the 24 ulps that takes): the size of the error
   a systematic change in one constant of ``f`` makes on this orbit;
2. the promise check of ``benchmarks/promise.py`` on every run that uses the
   witness, with the witness's parameters moved by 1 ulp (hamrkq's rule) and
   by 32 ulps (enough to move ``1 - mu``): the violations, and the runs that
   then stop early.

Writes ``benchmarks/witness_constants.txt``.
"""

from __future__ import annotations

import sys
import types
import warnings
from pathlib import Path

import extended_reference
import numpy as np
import promise

import hamrkq
from hamrkq.rkq import arith, driver

HERE = Path(__file__).resolve().parent
EPS = float(np.finfo(float).eps)


def sensitivity(lines: list[str]) -> None:
    arenstorf = hamrkq.load_problem("arenstorf")
    mu = float(arenstorf.parameters["mu"])
    moved = mu
    while 1.0 - moved == 1.0 - mu:
        moved = float(np.nextafter(moved, 1.0))
    grid = np.linspace(0.0, 16.0, 161)
    options = dict(method="rk78q12", z_substeps=3, atol=1e-12, rtol=0.0, t_eval=grid,
                   gamma_limit=np.inf)  # fmt: skip
    a = hamrkq.solve(arenstorf, **options)
    b = hamrkq.solve(arenstorf, parameters={"mu": moved}, **options)
    shift = np.abs(a.z - b.z).max(axis=1) / 1e-12
    lines.append(
        f"1. mu moved by {round((moved - mu) / np.spacing(mu))} ulps moves 1 - mu by "
        f"{(1.0 - moved) - (1.0 - mu):.3g}; the quencher track (rk78q12, 3 steps a step, "
        "atol 1e-12) moves by, in units of 1e-12:"
    )
    for t in (0.5, 1.0, 1.3, 2.0, 5.0, 10.0, 10.9, 12.0, 15.5):
        i = int(np.searchsorted(grid, t))
        lines.append(f"   t = {grid[i]:5.1f}: {shift[i]:.3f}")


def with_nudge(ulps: int):
    """driver's arith with a witness nudge of ``ulps`` ulps."""
    patched = types.ModuleType("arith_nudged")
    patched.__dict__.update(arith.__dict__)

    def nudge(values, out):
        out[:] = values + values * (ulps * EPS)

    patched.nudge = nudge
    return patched


def promise_rows(lines: list[str]) -> None:
    problems = {}
    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        grid = np.linspace(*problem.t_span, promise.NODES)
        try:
            truth = extended_reference.reference(problem, grid)
        except RuntimeError:  # fpu: no long-double reference
            continue
        problems[name] = (problem, grid, truth, extended_reference.error_bound(problem, grid))
    results = {}
    for ulps in (1, 32):
        driver.arith = with_nudge(ulps)
        rows = []
        for problem, grid, truth, bound in problems.values():
            for label, atol, rtol in promise.tolerances():
                r = promise.row(problem, grid, truth, bound, label, atol, rtol)
                if r["witness"] and not r["reference_limits"]:
                    rows.append(r)
        results[ulps] = {(r["problem"], r["tolerance"]): r for r in rows}
        broken = [
            f"{r['problem']} {r['tolerance']} ({r['max_error_over_tol']:.3f})"
            for r in rows
            if r["max_error_over_tol"] > 1.05
        ]
        success = sum(r["status"] == "SUCCESS" for r in rows)
        lines.append(
            f"2. witness nudge {ulps} ulp(s): {len(rows)} runs with the witness, {success} "
            f"SUCCESS, nodes above 1.05 delta: {', '.join(broken) or 'none'}"
        )
    driver.arith = arith
    for key, r in results[32].items():
        before = results[1][key]
        if before["max_error_over_tol"] > 1.05:
            lines.append(
                f"   with 32 ulps {key[0]} {key[1]} stops at t = {r['t_last']:.3g} "
                f"({r['status']}), its largest error {r['max_error_over_tol']:.3f} delta"
            )
        if before["status"] == "SUCCESS" and r["status"] != "SUCCESS":
            lines.append(
                f"   stops with 32 ulps, not with 1: {key[0]} {key[1]} at "
                f"{r['t_last'] / r['t_end']:.2f} of the interval (its largest error with 1 ulp: "
                f"{before['max_error_over_tol']:.3f} delta)"
            )


def main() -> int:
    warnings.simplefilter("ignore")
    lines: list[str] = []
    sensitivity(lines)
    promise_rows(lines)
    text = "\n".join(lines) + "\n"
    (HERE / "witness_constants.txt").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
