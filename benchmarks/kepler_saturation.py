"""``method="auto"`` on eccentric Kepler orbits at loose tolerances, against
the exact solution: where the shadow saturates and auto runs again.

The sweep of QA (2026-11-27): eccentricity 0.3 to 0.95, ``rtol`` 1e-3 to
1e-6 with ``atol`` = ``rtol``/100 and ``rtol``/1000, 10 to 300 periods from
the pericentre; every node ``auto`` returns is compared with Kepler's exact
solution (``hamrkq.catalogue.exact``), ``max_k |y_k - y_k(t)| /
max(atol, rtol |y_k(t)|)``.  Until 2026-11-27 auto ran a saturated shadow
again with a shorter ``max_step``, which kept the shadow within its limit
without making Gamma honest: 8 of 182 SUCCESS runs returned nodes up to
23.5 tolerances off.  It now runs the tangent estimate instead.

Run: ``python benchmarks/kepler_saturation.py --label after`` writes
``kepler_saturation_after.json``; ``kepler_saturation.md`` compares every
label's JSON beside this file (``--label before`` on the checkout before,
e.g. with ``PYTHONPATH`` pointing at a ``git archive`` of it).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

import hamrkq

HERE = Path(__file__).resolve().parent
ECCENTRICITIES = (0.3, 0.6, 0.75, 0.85, 0.9, 0.95)
RELATIVE = (1e-3, 1e-4, 1e-5, 1e-6)
ABSOLUTE_SHARE = (1e-3, 1e-2)
PERIODS = (10, 30, 100, 300)
LIMIT = 1.05


def run_one(e: float, rtol: float, atol: float, periods: int) -> dict:
    """One run of auto and its largest true error over the tolerance."""
    problem = hamrkq.load_problem("kepler", e=e)
    started = time.perf_counter()
    sol = hamrkq.solve(problem, t_span=(0.0, 2 * np.pi * periods), atol=atol, rtol=rtol)
    seconds = time.perf_counter() - started
    truth = problem.exact(sol.t)
    ratio = np.abs(sol.y - truth) / np.maximum(atol, rtol * np.abs(truth))
    return {
        "e": e,
        "rtol": rtol,
        "atol": atol,
        "periods": periods,
        "status": sol.status.name,
        "periods_reached": float(sol.t[-1] / (2 * np.pi)),
        "method": sol.options["method"],
        "z_substeps": sol.options.get("z_substeps"),
        "estimate": sol.options.get("global_error_estimate") or "shadow",
        "max_step": sol.options.get("max_step"),
        "evaluations": int(
            sol.stats["nfev"] + sol.stats["njev"] + sol.stats.get("discarded_evaluations", 0)
        ),
        "seconds": seconds,
        "max_error_over_tol": float(ratio.max()),
    }


def sweep() -> list[dict]:
    rows = []
    for e in ECCENTRICITIES:
        for rtol in RELATIVE:
            for share in ABSOLUTE_SHARE:
                for periods in PERIODS:
                    row = run_one(e, rtol, rtol * share, periods)
                    print(json.dumps(row), flush=True)
                    rows.append(row)
    return rows


def summary(label: str, rows: list[dict]) -> str:
    success = [r for r in rows if r["status"] == "SUCCESS"]
    above = [r for r in rows if r["max_error_over_tol"] > LIMIT]
    evaluations = sum(r["evaluations"] for r in rows)
    worst = max(r["max_error_over_tol"] for r in rows)
    return (
        f"| {label} | {len(rows)} | {len(success)} | {len(above)} | {worst:.3f} | "
        f"{evaluations / 1e6:.1f} M |"
    )


def markdown(results: dict[str, list[dict]]) -> str:
    lines = [
        "| label | runs | SUCCESS | any node above 1.05 tol | largest error / tol | "
        "evaluations (all runs, discarded too) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [summary(label, rows) for label, rows in results.items()]
    labels = list(results)
    if len(labels) >= 2:
        first, last = results[labels[0]], results[labels[-1]]
        lines += [
            "",
            f"Rows whose status or largest error changed ({labels[0]} -> {labels[-1]}):",
            "",
            "| e | rtol | atol | periods | status | periods reached | estimate, max_step | "
            "error / tol | evaluations |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for a, b in zip(first, last, strict=True):
            changed = a["status"] != b["status"] or (
                max(a["max_error_over_tol"], b["max_error_over_tol"]) > LIMIT
            )
            if not changed:
                continue

            def setting(r):
                step = "-" if r["max_step"] is None else f"{r['max_step']:.3g}"
                return f"{r['estimate']} m={r['z_substeps']}, {step}"

            lines.append(
                f"| {a['e']} | {a['rtol']:g} | {a['atol']:g} | {a['periods']} | "
                f"{a['status']} -> {b['status']} | {a['periods_reached']:.4f} -> "
                f"{b['periods_reached']:.4f} | {setting(a)} -> {setting(b)} | "
                f"{a['max_error_over_tol']:.3f} -> {b['max_error_over_tol']:.3f} | "
                f"{a['evaluations']} -> {b['evaluations']} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", required=True, help="the checkout's name in the table")
    parser.add_argument("--checkout", default="", help="its commit, for the record")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    rows = sweep()
    path = HERE / f"kepler_saturation_{args.label}.json"
    source = {"hamrkq": str(Path(hamrkq.__file__).parent), "checkout": args.checkout}
    path.write_text(json.dumps({**source, "rows": rows}, indent=1) + "\n")
    results = {}
    for label in ("before", "after"):
        found = HERE / f"kepler_saturation_{label}.json"
        if found.exists():
            results[label] = json.loads(found.read_text())["rows"]
    (HERE / "kepler_saturation.md").write_text(markdown(results))


if __name__ == "__main__":
    main()
