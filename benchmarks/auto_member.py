"""Which family member ``method="auto"`` should run: every candidate, as auto runs it.

    python benchmarks/auto_member.py [--tolerances 1e-4 1e-5 ...] [--out NAME]

For every catalogue problem with a long-double reference
(``extended_reference.py``; fpu has none, so only its work is recorded) and
``atol`` 1e-6, 1e-8, 1e-9 and 1e-10, each candidate member is run the way
``method="auto"`` runs its member (two quencher steps a step first, the
projection and the reruns of docs/algorithm.md), on 201 output times: its
status, quencher steps, evaluations (f plus Jacobian products, discarded runs
included) and largest true error over the tolerance.  The rule in
``hamrkq.rkq.auto_rules.auto_member`` is read from this table.

Writes ``benchmarks/auto_member.json`` and ``benchmarks/auto_member.md``
(``--out NAME``: ``NAME.json`` and ``NAME.md``; ``--tolerances``: others
than those four).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import extended_reference
import numpy as np

import hamrkq
from hamrkq.rkq import auto_rules

HERE = Path(__file__).resolve().parent
CANDIDATES = ("rk78q12", "rk67q9", "rk67q12")
TOLERANCES = (1e-6, 1e-8, 1e-9, 1e-10)


def run(problem, grid, truth, member: str, tol: float) -> dict:
    chosen = auto_rules.AUTO_MEMBER, auto_rules.AUTO_LARGE_MEMBER
    auto_rules.AUTO_MEMBER = auto_rules.AUTO_LARGE_MEMBER = member  # what auto_member reads
    try:
        sol = hamrkq.solve(problem, method="auto", atol=tol, rtol=0.0, t_eval=grid)
    finally:
        auto_rules.AUTO_MEMBER, auto_rules.AUTO_LARGE_MEMBER = chosen
    stats = sol.stats
    n = sol.t.size
    error = float(np.abs(sol.y - truth[:n]).max() / tol) if truth is not None and n else None
    return {
        "problem": problem.name,
        "dim": problem.hamiltonian.dim,
        "tol": tol,
        "member": member,
        "status": sol.status.name,
        "z_substeps": int(sol.options["z_substeps"]),
        "work": int(stats["nfev"] + stats["njev"] + stats.get("discarded_evaluations", 0)),
        "error_over_tol": error,
    }


def table(rows: list[dict]) -> str:
    lines = [
        "| problem (dim) | atol | "
        + " | ".join(f"{m}: status, m, work, error/tol" for m in CANDIDATES)
        + " | fewest (SUCCESS) |",
        "|---|---|" + "---|" * (len(CANDIDATES) + 1),
    ]
    keys = sorted(
        {(r["problem"], r["dim"], r["tol"]) for r in rows}, key=lambda k: (k[1], k[0], -k[2])
    )
    for name, dim, tol in keys:
        group = {r["member"]: r for r in rows if (r["problem"], r["tol"]) == (name, tol)}
        cells = []
        for m in CANDIDATES:
            r = group[m]
            err = "-" if r["error_over_tol"] is None else f"{r['error_over_tol']:.3f}"
            cells.append(f"{r['status'][:7]}, {r['z_substeps']}, {r['work']}, {err}")
        done = [r for r in group.values() if r["status"] == "SUCCESS"]
        best = min(done, key=lambda r: r["work"])["member"] if done else "-"
        lines.append(f"| {name} ({dim}) | {tol:g} | " + " | ".join(cells) + f" | {best} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerances", type=float, nargs="+", default=TOLERANCES)
    parser.add_argument("--out", default="auto_member", help="file name, without suffix")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    rows = []
    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        grid = np.linspace(*problem.t_span, 201)
        try:
            truth = extended_reference.reference(problem, grid)
        except RuntimeError:  # fpu: heyoka reports a non-finite state at t = 0
            truth = None
        for tol in args.tolerances:
            for member in CANDIDATES:
                rows.append(run(problem, grid, truth, member, tol))
                print(json.dumps(rows[-1]), flush=True)
    (HERE / f"{args.out}.json").write_text(json.dumps(rows, indent=1) + "\n")
    text = table(rows)
    (HERE / f"{args.out}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
