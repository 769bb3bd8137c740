"""Which method ``hamrkq.solve`` runs by default: ``rk34q8`` (the paper's) against ``auto``.

    python benchmarks/default_method.py [--rounds N] [--from-json]

Part 1, warm: every catalogue problem at its own tolerance and interval (its
file's ``[integration]``), each method after a first call that compiled it:
status, the time reached, the evaluations (f, Jacobian products and those of
runs ``auto`` discarded), the integration's wall time (median of three calls)
and the largest true error over the tolerance on 201 output times, against
the long-double reference of ``promise.py`` (``extended_reference.py``).

Part 2, a first use: a user's Hamiltonian (two degrees of freedom, quartic
terms) solved once in fresh processes with empty caches, each method,
``HAMRKQ_COMPILE=wait``: the wall time of ``solve`` (compiling included) and
of a second call, ``--rounds`` rounds with the methods alternating; medians.

Writes ``default_method.json`` and ``default_method.md`` beside this file and
the tables into ``docs/algorithm.md`` between the ``default-method`` markers
(``--from-json``: only that, from the last run's record).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import textwrap
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np  # noqa: E402
import promise  # noqa: E402

METHODS = ("rk34q8", "auto")
DOCS = HERE.parent / "docs" / "algorithm.md"
BEGIN, END = "<!-- default-method:begin -->", "<!-- default-method:end -->"

FIRST_USE = textwrap.dedent(
    """
    import json, time
    import sympy as sp
    import hamrkq

    q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")
    H = (p1**2 + p2**2) / 2 + (q1**2 + q2**2) / 2 + q1**2 * q2 - q2**3 / 3 + q1**4 / 7
    ham = hamrkq.Hamiltonian(H, q=[q1, q2], p=[p1, p2])
    times = []
    for _ in range(2):
        started = time.perf_counter()
        sol = hamrkq.solve(ham, q0=[0.1, 0.2], p0=[0.3, 0.1], t_span=(0, 100), atol=1e-8,
                           method=METHOD)
        times.append(time.perf_counter() - started)
    print(json.dumps({"first": times[0], "second": times[1], "status": sol.status.name,
                      "evaluations": sol.stats["nfev"] + sol.stats["njev"]}))
    """
)


def warm_rows() -> list[dict]:
    """Part 1: one row per problem and method."""
    problems, _ = promise.references()
    rows = []
    for problem, grid, truth, bound in problems.values():
        atol = problem.integration.get("atol", 1e-6)
        rtol = problem.integration.get("rtol", 0.0)
        for method in METHODS:
            promise.row(problem, grid, truth, bound, "warm-up", atol, rtol, method)
            runs = [
                promise.row(problem, grid, truth, bound, "", atol, rtol, method) for _ in range(3)
            ]
            row = runs[-1]
            row["seconds"] = statistics.median(r["seconds"] for r in runs)
            row["tolerance"] = (
                f"atol {atol:g}"
                if np.ndim(atol) == 0
                else f"atol per component (from {np.min(atol):g})"
            ) + (f", rtol {rtol:g}" if rtol else "")
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def first_use_rows(rounds: int) -> list[dict]:
    """Part 2: fresh processes, empty caches, the methods alternating."""
    rows = []
    for _ in range(rounds):
        for method in METHODS:
            with tempfile.TemporaryDirectory() as cache:
                env = {"HAMRKQ_COMPILE": "wait", "NUMBA_CACHE_DIR": cache}
                code = FIRST_USE.replace("METHOD", repr(method))
                _, out = measure.python(code, cache=Path(cache), env=env)
            rows.append({"method": method, **out})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def tables(results: dict) -> str:
    warm = results["warm"]
    lines = [
        f"`benchmarks/default_method.py`, run {results['started']} to {results['finished']} "
        f"({results['machine']['cpu']}, {results['machine']['cores']} cores). Part 1: each "
        "catalogue problem at its own tolerance and interval, warm; the time is the "
        "integration's wall time, median of three calls; the true error is checked on "
        "201 output times against the long-double reference (marked where that reference's "
        "own error exceeds a twentieth of the tolerance).",
        "",
        "| problem | tolerance | method | status | t reached | evaluations | time (s) | "
        "max true error / tol |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in warm:
        mark = " (reference limits)" if r["reference_limits"] else ""
        lines.append(
            f"| {r['problem']} | {r['tolerance']} | {r['method']} | {r['status']} | "
            f"{r['t_last']:.6g} / {r['t_end']:.6g} | {r['evaluations']} | "
            f"{r['seconds']:.3f} | {r['max_error_over_tol']:.3f}{mark} |"
        )
    pairs = {}
    for r in warm:
        pairs.setdefault(r["problem"], {})[r["method"]] = r
    ratios = [
        p["rk34q8"]["evaluations"] / p["auto"]["evaluations"]
        for p in pairs.values()
        if p["rk34q8"]["status"] == p["auto"]["status"] == "SUCCESS"
    ]
    times = [
        p["rk34q8"]["seconds"] / p["auto"]["seconds"]
        for p in pairs.values()
        if p["rk34q8"]["status"] == p["auto"]["status"] == "SUCCESS"
    ]
    lines += [
        "",
        f"Where both reach t_end ({len(ratios)} of {len(pairs)} problems), rk34q8 needs "
        f"{min(ratios):.2g} to {max(ratios):.3g} times auto's evaluations (median "
        f"{statistics.median(ratios):.3g}) and {min(times):.2g} to {max(times):.3g} times "
        f"its time (median {statistics.median(times):.3g}).",
        "",
        "Part 2: a user's Hamiltonian (two degrees of freedom) to t = 100 at atol 1e-8, in a "
        "fresh process with empty caches (`HAMRKQ_COMPILE=wait`), "
        f"{results['rounds']} round(s) with the methods alternating; medians.",
        "",
        "| method | first `solve` (compiling included) | second `solve` | evaluations |",
        "|---|---|---|---|",
    ]
    for method in METHODS:
        runs = [r for r in results["first_use"] if r["method"] == method]
        first = statistics.median(r["first"] for r in runs)
        second = statistics.median(r["second"] for r in runs)
        lines.append(f"| {method} | {first:.2f} s | {second:.4f} s | {runs[-1]['evaluations']} |")
    return "\n".join(lines)


def write_docs(text: str) -> None:
    page = DOCS.read_text()
    head, rest = page.split(BEGIN)
    _, tail = rest.split(END)
    DOCS.write_text(f"{head}{BEGIN}\n{text}\n{END}{tail}")


def main() -> None:
    warnings.simplefilter("ignore")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2, help="rounds of part 2")
    parser.add_argument("--from-json", action="store_true", help="only rewrite the tables")
    args = parser.parse_args()
    if args.from_json:
        results = json.loads((HERE / "default_method.json").read_text())
    else:
        results = measure.begin_record(args.rounds)
        results["warm"] = warm_rows()
        results["first_use"] = first_use_rows(args.rounds)
        measure.end_record(results)
        (HERE / "default_method.json").write_text(json.dumps(results, indent=1) + "\n")
    text = tables(results)
    (HERE / "default_method.md").write_text(text + "\n")
    write_docs(text)
    print(text)


if __name__ == "__main__":
    main()
