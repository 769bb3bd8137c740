"""The dense output's true error between the nodes, for rk34q8 and the family.

    python benchmarks/dense_error.py [--before CHECKOUT [--before-label TEXT]]

For Kepler e = 0.6 over ten orbits (against its exact solution) and
prentice2011 over [0, 4000] (against the periodic-orbit reference of
``hamrkq.analysis.reference``, 4.5e-12 off a long-double Taylor run), at
``atol`` 1e-6 and 1e-9, each method is run with ``dense_output=True`` and
``sol(t)`` evaluated at 10 000 uniformly random times: the largest true
error over the tolerance there, beside the largest at the nodes, and the
largest jump of ``sol(t)`` at the middle of an interval (where it switches
from one node's step to the other's).  And the FPU chain at ``rtol`` 1e-6
over [0, 60] (:func:`relative_rows`), where a component's tolerance between
two nodes can be below the nodes'.  RKQ promises at most 1.05 at the
nodes; the dense output should keep it.

``--before``: the same runs with the checkout at CHECKOUT, side by side.
Writes ``benchmarks/dense_error.json`` and ``benchmarks/dense_error.md``
(docs/events.md quotes the table), or ``--out NAME``'s: the run beside
297e777, before the rule for rtol between nodes, is ``dense_error_rtol``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import measure
import numpy as np

HERE = Path(__file__).resolve().parent
SEED = 20261123
METHODS = ("rk34q8", "auto", "rk45q12")
TOLERANCES = (1e-6, 1e-9)


def rows() -> list[dict]:
    """Every case, measured with the ``hamrkq`` on the path."""
    import hamrkq
    from hamrkq.analysis.reference import periodic_reference
    from hamrkq.backends.numeric import numeric_of

    kepler = hamrkq.load_problem("kepler", e=0.6)
    prentice = hamrkq.load_problem("prentice2011")
    rhs = numeric_of(prentice.hamiltonian).rhs

    def truth(problem, times):
        if problem is kepler:
            return np.asarray(problem.exact(times))
        return periodic_reference(rhs, problem.y0, times, problem.parameter_array).y

    out = []
    for method in METHODS:
        for name, problem in (("kepler e=0.6, 10 orbits", kepler), ("prentice2011", prentice)):
            for atol in TOLERANCES:
                sol = hamrkq.solve(problem, atol=atol, method=method, dense_output=True)
                times = np.random.default_rng(SEED).uniform(sol.t[0], sol.t[-1], 10_000)
                between = np.abs(sol.sol.values(times) - truth(problem, times)).max() / atol
                at_nodes = np.abs(sol.y - truth(problem, sol.t)).max() / atol
                out.append({
                    "problem": name, "atol": atol, "method": method, "member": sol.method,
                    "nodes": int(sol.t.size), "between": float(between),
                    "at_nodes": float(at_nodes), "jump": _jump(sol) / atol,
                })  # fmt: skip
                print(json.dumps(out[-1]), file=sys.stderr, flush=True)
    return out + relative_rows()


def relative_rows() -> list[dict]:
    """The FPU chain at rtol 1e-6 (atol 1e-9) over [0, 60], against the
    quencher in double-double at atol 1e-11 (its dense output): the error
    over each component's tolerance ``max(atol, rtol |y|)`` at the time,
    which falls towards atol where a component passes near zero."""
    import hamrkq

    fpu = hamrkq.load_problem("fpu")
    span = (0.0, 60.0)
    reference = hamrkq.solve(fpu, t_span=span, method="rk78q12", atol=1e-11,
                             quencher_precision="double-double", dense_output=True)  # fmt: skip

    def ratio(y, t):
        truth = reference.sol.values(t)
        return float(np.max(np.abs(y - truth) / np.maximum(1e-9, 1e-6 * np.abs(truth))))

    out = []
    for method in METHODS:
        sol = hamrkq.solve(fpu, t_span=span, method=method, atol=1e-9, rtol=1e-6,
                           dense_output=True)  # fmt: skip
        times = np.random.default_rng(SEED).uniform(*span, 10_000)
        out.append({
            "problem": "fpu, t <= 60", "atol": "rtol 1e-6", "method": method,
            "member": sol.method, "nodes": int(sol.t.size),
            "between": ratio(sol.sol.values(times), times), "at_nodes": ratio(sol.y, sol.t),
            "jump": float("nan"),
        })  # fmt: skip
        print(json.dumps(out[-1]), file=sys.stderr, flush=True)
    return out


def _jump(sol) -> float:
    """The largest jump of ``sol.sol`` at the middle of an interval, where
    the value switches from one node's step to the other's (an ulp before
    and after the middle)."""
    from hamrkq.rkq.dense import node_index

    t = sol.t
    middle = 0.5 * (t[:-1] + t[1:])
    before, after = np.nextafter(middle, -np.inf), np.nextafter(middle, np.inf)
    switches = (node_index(t, before) == np.arange(t.size - 1)) & (
        node_index(t, after) == np.arange(1, t.size)
    )
    values = sol.sol.values(before[switches]) - sol.sol.values(after[switches])
    return float(np.abs(values).max())


def table(results: dict) -> str:
    lines = [
        f"`benchmarks/dense_error.py`, run {results['started']}: the largest true error over "
        "the tolerance at 10 000 random times between the nodes and at the nodes, and the "
        "largest jump of sol(t) at the middle of an interval.",
        "",
        "| problem | atol | method | checkout | nodes | between nodes / delta "
        "| at nodes / delta | largest jump at a middle / delta |",
        "|---|---|---|---|---|---|---|---|",
    ]
    before = {(r["problem"], r["atol"], r["method"]): r for r in results.get("rows_before", [])}
    for row in results["rows"]:
        method = row["method"] if row["method"] == row["member"] else (
            f"{row['method']} ({row['member']})"
        )  # fmt: skip
        cases = [("now", row)]
        old = before.get((row["problem"], row["atol"], row["method"]))
        if old is not None:
            cases.append((results["before"], old))
        for checkout, r in cases:
            lines.append(
                f"| {row['problem']} | {_tolerance(row['atol'])} | {method} | {checkout} | "
                f"{r['nodes']} | "
                f"{r['between']:.4f} | {r['at_nodes']:.4f} | "
                f"{'-' if r['jump'] != r['jump'] else format(r['jump'], '.1e')} |"
            )
    return "\n".join(lines) + "\n"


def _tolerance(value) -> str:
    return value if isinstance(value, str) else f"{value:g}"


def _elsewhere(root: Path) -> list[dict]:
    """:func:`rows` with the checkout at ``root``."""
    return measure.rows_at_checkout(__file__, root, "--rows-only")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a checkout from before the change")
    parser.add_argument("--before-label", help="what the table calls it (its commit)")
    parser.add_argument("--out", default="dense_error", help="name of the .json and .md")
    parser.add_argument("--rows-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.rows_only:
        print(json.dumps(rows()))
        return 0
    results = measure.begin_record(1)
    results["rows"] = rows()
    if args.before is not None:
        results["before"] = args.before_label or str(args.before)
        results["rows_before"] = _elsewhere(args.before.resolve())
    results = measure.end_record(results)
    (HERE / f"{args.out}.json").write_text(json.dumps(results, indent=1) + "\n")
    text = table(results)
    (HERE / f"{args.out}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
