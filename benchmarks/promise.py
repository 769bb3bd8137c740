"""The promise of ``method="auto"`` on every catalogue problem, in one run.

For each problem of the catalogue, over its own time span, at ``atol`` 1e-4,
1e-6, 1e-8, 1e-10 and 1e-12 (``rtol = 0``) and at ``rtol`` 1e-6, 1e-8 and
1e-10 (with ``atol = 1e-3 rtol``, so that a component crossing zero keeps a
floor): the status, where the run ended, whether the rounding witness ran,
the evaluations, and the largest true error over the tolerance,
``max_k |y_k - y_ref,k| / max(atol_k, rtol_k |y_ref,k|)``, over 201 equally
spaced times (``t_eval``).  The promise is that this is at most 1.05 at
every node returned, SUCCESS or not.

The truth is the long-double Taylor reference of ``extended_reference.py``
(heyoka, the ``bench`` extra), whose own error bound (against the same run
at 1e-17) is in the table: a row where it exceeds a twentieth of the smallest
tolerance is marked and not counted, the check being no better than the
reference there.

Run: ``python benchmarks/promise.py``; writes ``promise.json`` and
``promise.md`` beside this file (docs/algorithm.md quotes the summary).
``--members`` runs every RKQ family member the same way, each with its
defaults (two quencher steps a step; run again only with the rounding
witness where its estimate grew exponentially), and writes
``promise_members.json`` and ``promise_members.md``: one line per member;
``--members --only rk45q8 rk56q8`` runs those again and keeps the other
members' rows.  ``--loose``: ``auto`` at the tolerances of a first look
(``atol`` 1e-2 and 1e-3, ``rtol`` 1e-3 and 1e-4), into ``promise_loose.json``
and ``promise_loose.md``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import extended_reference
import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np

import hamrkq
from hamrkq.rkq.family import MEMBERS

HERE = Path(__file__).resolve().parent
ABSOLUTE = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
RELATIVE = (1e-6, 1e-8, 1e-10)
NODES = 201
#: A row is not counted where the reference's own error bound exceeds this
#: share of the smallest tolerance.
LIMITS = 0.05


#: ``--loose``: the tolerances of a first look.
LOOSE_ABSOLUTE = (1e-2, 1e-3)
LOOSE_RELATIVE = (1e-3, 1e-4)


def tolerances(loose: bool = False):
    for atol in LOOSE_ABSOLUTE if loose else ABSOLUTE:
        yield f"atol {atol:g}", atol, 0.0
    for rtol in LOOSE_RELATIVE if loose else RELATIVE:
        yield f"rtol {rtol:g}", 1e-3 * rtol, rtol


def row(problem, grid, truth, bound, label, atol, rtol, method="auto", **options) -> dict:
    """One run checked against the reference; ``options`` go to ``solve``."""
    started = time.perf_counter()
    sol = hamrkq.solve(problem, method=method, atol=atol, rtol=rtol, t_eval=grid, **options)
    elapsed = time.perf_counter() - started
    n = sol.t.size
    ref = truth[:n]
    delta = np.maximum(atol, rtol * np.abs(ref))
    ratio = float((np.abs(sol.y - ref) / delta).max()) if n else 0.0
    return {
        "problem": problem.name,
        "method": method,
        "tolerance": label,
        "status": sol.status.name,
        "t_last": float(sol.t[-1]) if n else float("nan"),
        "t_end": float(grid[-1]),
        "witness": bool(sol.options.get("rounding_witness")),
        "evaluations": sol.stats["nfev"]
        + sol.stats["njev"]
        + sol.stats.get("discarded_evaluations", 0),
        "seconds": elapsed,
        "max_error_over_tol": ratio,
        "reference_bound": bound,
        "smallest_tolerance": float(delta.min()) if n else float("nan"),
        # the reference's own error could be a twentieth of the tolerance
        "reference_limits": bool(n and bound > LIMITS * float(delta.min())),
        "floor_named": "floor" in sol.message,
        "quencher": sol.options.get("quencher_precision", "-"),
    }


def markdown(rows: list[dict]) -> str:
    kept = [r for r in rows if not r["reference_limits"]]
    broken = [r for r in kept if r["max_error_over_tol"] > 1.05]
    success = [r for r in kept if r["status"] == "SUCCESS"]
    unattainable = [r for r in kept if r["status"] == "TOLERANCE_UNATTAINABLE"]
    where = ", ".join(
        f"{r['problem']} {r['tolerance']} ({r['max_error_over_tol']:.3f})" for r in broken
    )
    lines = [
        f"{len(rows)} runs; {len(rows) - len(kept)} where the reference's error exceeds "
        f"{LIMITS:g} of the tolerance (marked, not counted).  "
        f"Of the {len(kept)} counted: {len(success)} SUCCESS, "
        f"{len(unattainable)} TOLERANCE_UNATTAINABLE "
        f"({sum(r['floor_named'] for r in unattainable)} naming double precision's floor), "
        f"{len(broken)} with a node above 1.05 tolerances"
        + (f": {where}." if broken else ".")
        + f"  {sum(r.get('quencher') == 'double-double' for r in kept)} of the counted ran "
        "their quencher in double-double.",
        "",
        "| problem | tolerance | status | t reached / t_end | witness | evaluations | time (s) | "
        "max true error / tol | reference error |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        mark = " (reference limits)" if r["reference_limits"] else ""
        lines.append(
            f"| {r['problem']} | {r['tolerance']} | {r['status']}"
            # a stop that names the floor (a run that reached the end may name
            # it too: auto's message on a run in double it discarded)
            f"{' (floor)' if r['floor_named'] and r['status'] != 'SUCCESS' else ''} | "
            f"{r['t_last']:.6g} / {r['t_end']:.6g} | {'yes' if r['witness'] else 'no'} | "
            f"{r['evaluations']} | {r['seconds']:.2f} | {r['max_error_over_tol']:.3f}{mark} | "
            f"{r['reference_bound']:.1e} |"
        )
    return "\n".join(lines) + "\n"


def references() -> tuple[dict, list[str]]:
    """The catalogue's problems with their long-double references on the grid."""
    problems, skipped = {}, []
    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        grid = np.linspace(*problem.t_span, NODES)
        try:
            truth = extended_reference.reference(problem, grid)
            bound = extended_reference.error_bound(problem, grid)
        except RuntimeError as exc:  # fpu: heyoka reports a non-finite state at t = 0
            skipped.append(f"{name}: no reference ({exc})")
            print(skipped[-1], flush=True)
            continue
        problems[name] = (problem, grid, truth, bound)
    return problems, skipped


def outcome_cells(runs: list[dict]) -> str:
    """Table cells for ``runs`` (counted ones): their number, SUCCESS, stopped
    naming the floor, stopped otherwise, and the nodes above 1.05 delta."""
    success = sum(r["status"] == "SUCCESS" for r in runs)
    floor = sum(r["status"] != "SUCCESS" and r["floor_named"] for r in runs)
    broken = ", ".join(
        f"{r['problem']} {r['tolerance']} ({r['max_error_over_tol']:.3f})"
        for r in runs
        if r["max_error_over_tol"] > 1.05
    )
    others = len(runs) - success - floor
    return f"{len(runs)} | {success} | {floor} | {others} | {broken or 'none'}"


def members_table(rows: list[dict]) -> str:
    """One line per member: how its runs ended and where a node broke the promise."""
    lines = [
        "| member | runs counted | SUCCESS | stopped, naming the floor | stopped otherwise | "
        "nodes above 1.05 delta |",
        "|---|---|---|---|---|---|",
    ]
    for method in dict.fromkeys(r["method"] for r in rows):
        kept = [r for r in rows if r["method"] == method and not r["reference_limits"]]
        lines.append(f"| {method} | {outcome_cells(kept)} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    warnings.simplefilter("ignore")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--members",
        action="store_true",
        help="every family member with its defaults (no reruns), into promise_members.*",
    )
    parser.add_argument(
        "--only",
        nargs="+",
        metavar="MEMBER",
        help="with --members: run these members again and replace their rows in "
        "promise_members.json (the others are kept as they are)",
    )
    parser.add_argument(
        "--loose",
        action="store_true",
        help="auto at atol 1e-2 and 1e-3 and rtol 1e-3 and 1e-4, into promise_loose.*",
    )
    args = parser.parse_args(argv)
    problems, skipped = references()
    for problem, _, _, _ in problems.values():
        hamrkq.solve(problem, t_span=(problem.t_span[0], problem.t_span[0] + 1e-3))  # compile
    methods = list(MEMBERS) if args.members else ["auto"]
    rows: list[dict] = []
    if args.members and args.only:
        methods = args.only
        kept = json.loads((HERE / "promise_members.json").read_text())
        rows = [r for r in kept if r["method"] not in methods]
    for method in methods:
        if method not in ("auto",) and not MEMBERS[method].use_z:
            continue  # rk34: no quencher track, nothing is promised
        for problem, grid, truth, bound in problems.values():
            for label, atol, rtol in tolerances(args.loose):
                rows.append(row(problem, grid, truth, bound, label, atol, rtol, method))
                print(json.dumps(rows[-1]), flush=True)
    notes = "".join(f"\nNot checked: {text}.\n" for text in skipped)
    if args.members:
        order = {name: i for i, name in enumerate(MEMBERS)}
        rows.sort(key=lambda r: order[r["method"]])  # stable: problems keep their order
        (HERE / "promise_members.json").write_text(json.dumps(rows, indent=1) + "\n")
        (HERE / "promise_members.md").write_text(members_table(rows) + notes)
        return
    name = "promise_loose" if args.loose else "promise"
    (HERE / f"{name}.json").write_text(json.dumps(rows, indent=1) + "\n")
    (HERE / f"{name}.md").write_text(markdown(rows) + notes)


if __name__ == "__main__":
    main()
