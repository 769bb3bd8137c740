"""Work and accuracy of every RKQ family member, side by side, in one run.

For each problem and tolerance: status, steps, rejected steps, evaluations
(f plus Jacobian products), wall time of the integration (compile time
excluded), the maximum true error over the tolerance (against the exact
solution, or a reference far more accurate than the tolerance), the
quencher's true error, and how Gamma compares with it (median ratio).

The truth is the extended-precision Taylor reference of
``extended_reference.py`` (heyoka, the ``bench`` extra) where it is
installed: the periodic DOP853 reference of prentice2011 is 7e-11 off
over [0, 4000], too coarse for 1e-10 and 1e-12 (the exact formula for
Kepler was 1.7e-13 off after ten orbits when this script was written; it is
accurate to a few ulps since, ``tests/test_exact.py``).
Without heyoka the script falls back to them and says so in the table.
outer_solar_system is checked on 201 returned nodes (``t_eval``), the others
at every node.

Run: ``python benchmarks/family.py [--quick]``; writes ``family.json`` and
``family.md`` beside this file (docs/algorithm.md quotes the table).
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import extended_reference
import numpy as np

import hamrkq
from hamrkq.analysis.reference import periodic_reference
from hamrkq.backends.numeric import numeric_of
from hamrkq.rkq.family import MEMBERS

HERE = Path(__file__).resolve().parent


def cases(quick: bool):
    kepler = hamrkq.load_problem("kepler", e=0.6)
    prentice = hamrkq.load_problem("prentice2011")
    t_p = 400.0 if quick else 4000.0
    yield "kepler e=0.6, 10 orbits", kepler, (0.0, 20 * np.pi), [1e-6, 1e-9, 1e-12], None
    yield (f"prentice2011, t <= {t_p:g}", prentice, (0.0, t_p),
           [1e-6, 1e-9, 1e-10, 1e-12], None)  # fmt: skip
    if not quick:
        solar = hamrkq.load_problem("outer_solar_system")
        grid = np.linspace(*solar.t_span, 201)
        yield "outer_solar_system, 500 000 days", solar, solar.t_span, [1e-6, 1e-9], grid


def truth(problem, t):
    """The true states at ``t`` and a bound on their own error."""
    if extended_reference.available():
        return extended_reference.reference(problem, t), 0.0
    if problem.exact is not None:
        return problem.exact(t), 0.0
    ref = periodic_reference(
        numeric_of(problem.hamiltonian).rhs, problem.y0, t, problem.parameter_array
    )
    return ref.y, float(ref.estimated_error)


def measure(problem, span, tol, method, grid=None, known=None):
    sol = hamrkq.solve(problem, method=method, atol=tol, rtol=0.0, t_span=span, t_eval=grid)
    if known is not None:
        exact, ref_error = known[0][: sol.t.size], known[1]
    else:
        exact, ref_error = truth(problem, sol.t)
    row = {
        "method": sol.method,
        "requested": method,
        "status": sol.status.name,
        "t_last": float(sol.t[-1]),
        "steps": sol.stats["steps"],
        "rejected": sol.stats["rejected"],
        # auto's discarded first run, if it ran again with more quencher steps
        "work": sol.stats["nfev"] + sol.stats["njev"] + sol.stats.get("discarded_evaluations", 0),
        "integrate_s": sol.stats["integrate_s"],
        "error_over_tol": float(np.abs(sol.y - exact).max() / tol),
        "reference_error": ref_error,
    }
    if sol.z is not None:
        z_error = np.abs(sol.z - exact)
        row["z_error"] = float(z_error.max())
        if sol.gamma is not None:
            where = z_error > max(10 * ref_error, 1e-13)
            ratio = np.abs(sol.gamma)[where] / z_error[where]
            row["gamma_ratio_median"] = float(np.median(ratio)) if ratio.size else None
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="prentice2011 to t = 400 only")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    methods = ["auto", *[m for m in MEMBERS if m != "rk34"]]
    results = []
    for label, problem, span, tols, grid in cases(args.quick):
        hamrkq.solve(problem, t_span=(span[0], span[0] + 1e-3))  # compile outside the timings
        known = None if grid is None else truth(problem, grid)
        for tol in tols:
            for method in methods:
                if method.startswith("rk34") and tol < (1e-9 if method == "rk34q8" else 1e-8):
                    continue  # tens of millions of evaluations
                row = measure(problem, span, tol, method, grid, known)
                row.update(problem=label, tol=tol)
                results.append(row)
                print(json.dumps(row), flush=True)
    (HERE / "family.json").write_text(json.dumps(results, indent=1) + "\n")
    lines = [
        "| problem | tol | method | status | steps | rejected | work (f + Jv) | "
        "x fewer than rk34q8 | time (s) | max true error / tol | quencher error | "
        "Gamma / quencher error (median) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in results:
        base = next(
            (
                r["work"]
                for r in results
                if r["problem"] == row["problem"]
                and r["tol"] == row["tol"]
                and r["requested"] == "rk34q8"
            ),
            None,
        )
        ratio = f"{base / row['work']:.1f}" if base else "-"
        gamma = row.get("gamma_ratio_median")
        name = row["requested"] if row["requested"] != "auto" else f"auto ({row['method']})"
        lines.append(
            f"| {row['problem']} | {row['tol']:.0e} | {name} | {row['status']} | {row['steps']} | "
            f"{row['rejected']} | {row['work']} | {ratio} | {row['integrate_s']:.3f} | "
            f"{row['error_over_tol']:.3f} | {row.get('z_error', float('nan')):.1e} | "
            f"{'-' if gamma is None else f'{gamma:.2f}'} |"
        )
    source = (
        "extended-precision Taylor reference (heyoka, longdouble, tol 1e-19)"
        if extended_reference.available()
        else "exact solution / periodic DOP853 reference (heyoka not installed)"
    )
    lines.append("")
    lines.append(f"True errors against: {source}.")
    (HERE / "family.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
