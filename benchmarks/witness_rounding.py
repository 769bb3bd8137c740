"""The rounding witness's stage values, rounded stochastically for every quencher.

    python benchmarks/witness_rounding.py [--before CHECKOUT [--before-label TEXT]]

The rounding witness runs the quencher again on the same mesh with its sums in
the opposite order; the divergence of the two is read as the quencher's
rounding error.  Rounded to nearest, two tracks whose exact stage values
differ by less than an ulp get the same double, so the witness shares the
quencher's rounding of every stage value and cannot see it; where ``h J`` is
large that rounding dominates.  Until this change only a quencher whose
weights' absolute values sum to more than 4 (DOP853's, 12.9) had the witness
round its stage values stochastically.  QA found named members whose
quenchers' weights sum to 1.3 to 1.8 stopping at Kepler's pericentre at
``e`` = 0.98 to 0.995 with kept nodes up to 1.9 times the tolerance off: the
quencher's rounding there was 30 times what the witness read.

This script measures, with the ``hamrkq`` on the path:

1. every named member with a 9th- to 12th-order quencher and ``auto`` on
   Kepler orbits (``e`` = 0.9 to 0.995, three periods from the pericentre,
   ``atol`` 1e-9 to 3e-11, ``rtol`` 0) against the exact solution: the
   status, how far each run reached, and its worst node and quencher value
   over the tolerance;
2. with ``--before CHECKOUT``: the same runs with that checkout, and warm
   runs where the witness runs (``auto``) in fresh processes, both checkouts
   in turn, medians of 5 rounds: what the stochastic rounding costs.

Writes ``benchmarks/witness_rounding.json`` and ``benchmarks/witness_rounding.md``
(``--name NAME``: ``NAME.json`` and ``NAME.md``; ``witness_increment`` is the
run that measured the witness's exactly summed increment, 0699e33, against
e59c34a).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import measure
import numpy as np

HERE = Path(__file__).resolve().parent
METHODS = (
    "rk34q12",
    "rk45q12",
    "rk56q9",
    "rk67q9",
    "rk67q12",
    "rk78q10",
    "rk78q12",
    "rk89q12",
    "auto",
)
ECCENTRICITIES = (0.9, 0.95, 0.98, 0.99, 0.995)
TOLERANCES = (1e-9, 3e-10, 1e-10, 3e-11)
PERIODS = 3
PROMISE = 1.05
ROUNDS = 5

#: Warm runs in which ``auto`` runs the witness (its members' quenchers are
#: Verner 9's and Feagin 12's): the cost of rounding its stage values
#: stochastically, for 2 and 36 components.
TIMED = (
    ("outer_solar_system", {"rtol": 1e-8}),
    ("prentice2011", {"atol": 1e-11}),
    ("kepler", {"atol": 1e-12}),
    ("fpu", {"atol": 1e-6}),
)

TIMING_CODE = """
import json, time, warnings
warnings.simplefilter("ignore")
import hamrkq
cases = {cases!r}
out = {{"file": hamrkq.__file__}}
for name, kw in cases:
    problem = hamrkq.load_problem(name)
    sol = hamrkq.solve(problem, method="auto", **kw)
    out[name] = {{"s": sol.stats["integrate_s"], "nfev": int(sol.stats["nfev"]),
                 "status": sol.status.name, "t_last": float(sol.t[-1])}}
print(json.dumps(out))
"""


def rows() -> list[dict]:
    """Part 1: every case, measured with the ``hamrkq`` on the path."""
    import warnings

    import hamrkq

    warnings.simplefilter("ignore")
    out = []
    for e in ECCENTRICITIES:
        problem = hamrkq.load_problem("kepler", e=e)
        t_end = PERIODS * 2.0 * math.pi
        for atol in TOLERANCES:
            for method in METHODS:
                sol = hamrkq.solve(
                    problem, t_span=(0.0, t_end), method=method, atol=atol, rtol=0.0
                )
                exact = np.asarray(problem.exact(sol.t))
                node = float(np.abs(sol.y - exact).max() / atol) if len(sol.t) else 0.0
                track = float(np.abs(sol.z - exact).max() / atol) if len(sol.t) else 0.0
                out.append({
                    "e": e, "atol": atol, "method": method, "status": sol.status.name,
                    "reached": float((sol.t[-1] if len(sol.t) else 0.0) / t_end),
                    "node": node, "quencher": track,
                })  # fmt: skip
    return out


def timings(before: Path) -> dict[str, list[dict]]:
    """Part 2: warm runs of both checkouts in fresh processes, in turn."""
    roots = [before, HERE.parent]
    code = TIMING_CODE.format(cases=list(TIMED))
    measured = measure.rounds_at_checkouts(code, roots, ROUNDS, "witness-rounding-")
    return {"before": measured[0], "now": measured[1]}


def _summary(table: list[dict]) -> str:
    above = [r for r in table if r["node"] > PROMISE]
    worst = max(table, key=lambda r: r["node"])
    return (
        f"{len(table)} runs, {sum(r['status'] == 'SUCCESS' for r in table)} SUCCESS, "
        f"{len(above)} with a node above {PROMISE} delta; worst node {worst['node']:.3f} delta "
        f"({worst['method']}, e = {worst['e']}, atol {worst['atol']:g}, {worst['status']} at "
        f"{worst['reached']:.3f} of the span)"
    )


def markdown(record: dict) -> str:
    now, m = record["now"], record["machine"]
    lines = [
        "# The rounding witness's stage values (generated by `benchmarks/witness_rounding.py`)",
        "",
        f"{m['cpu']}, {m['cores']} cores, numba {m['numba']}; run {record['started']} to "
        f"{record['finished']}, load average {m['load_average']} at the start and "
        f"{record['load_average_end']} at the end.",
        "",
        f"Kepler, three periods from the pericentre, e = {', '.join(map(str, ECCENTRICITIES))}, "
        f"atol {', '.join(f'{t:g}' for t in TOLERANCES)} (rtol 0), against the exact solution; "
        f"methods {', '.join(METHODS)}.",
        "",
        f"- now ({record['now_label']}): {_summary(now)}",
    ]
    if "before" in record:
        lines.append(f"- before ({record['before_label']}): {_summary(record['before'])}")
        lines += ["", "Runs with a node above the promise in either:", "",
                  "| method | e | atol | before: status, reached, worst node, quencher | now |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for b, n in zip(record["before"], now, strict=True):
            if max(b["node"], n["node"]) > PROMISE:
                cells = [
                    f"{r['status']}, {r['reached']:.4f}, {r['node']:.3f}, {r['quencher']:.3g}"
                    for r in (b, n)
                ]
                lines.append(
                    f"| {n['method']} | {n['e']} | {n['atol']:g} | {cells[0]} | {cells[1]} |"
                )
        lines += ["", f"Warm `auto` runs with the witness, fresh processes, both checkouts in "
                  f"turn, medians of {ROUNDS} rounds (`integrate_s`):", "",
                  "| case | before (s) | now (s) | now / before | f evaluations | status |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for name, kw in TIMED:
            b = [r[name] for r in record["timing"]["before"]]
            n = [r[name] for r in record["timing"]["now"]]
            tb, tn = (float(np.median([r["s"] for r in x])) for x in (b, n))
            lines.append(
                f"| {name} {kw} | {tb:.4f} | {tn:.4f} | {tn / tb:.2f} | "
                f"{b[0]['nfev']} / {n[0]['nfev']} | {b[0]['status']} / {n[0]['status']} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a checkout from before the change")
    parser.add_argument("--before-label", help="what the table calls it (its commit)")
    parser.add_argument("--rows-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--name", default="witness_rounding", help="the outputs' name (NAME.json, NAME.md)"
    )
    args = parser.parse_args(argv)
    if args.rows_only:
        print(json.dumps(rows()))
        return 0
    sys.path.insert(0, str(HERE.parent))
    record = measure.begin_record(ROUNDS)
    record["now"] = rows()
    record["now_label"] = measure.head_commit()
    if args.before is not None:
        root = args.before.resolve()
        record["before"] = measure.rows_at_checkout(__file__, root, "--rows-only")
        record["before_label"] = args.before_label or str(root)
        record["timing"] = timings(root)
    measure.save_record(HERE, args.name, measure.end_record(record), markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
