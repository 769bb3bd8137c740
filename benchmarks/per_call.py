"""Per-call overhead of ``solve`` on a cached tiny problem, checkouts side by side.

    python benchmarks/per_call.py --root /before/tree --root /work/main --rounds 5

A checkout made with ``git archive`` has no commit to name it by: give each
a ``--label`` (in ``--root``'s order).

The issue's row "per call, cached tiny problem" (``benchmarks/startup.py``
measures it once per checkout, among its fresh-process rows): here each
round runs every checkout in turn, each in a fresh interpreter with its own
warm caches (warmed by a first round that is not counted), and each round
takes the median of 300 calls of ``solve`` on the harmonic oscillator over a
span of five nodes, with the paper's method and with ``method="auto"``: of
their wall time, and of the CPU time of the calling thread (which time taken
by other processes on a shared machine does not count).  The
rounds alternate, so that a change in the machine's load touches every
checkout alike.  Writes ``benchmarks/per_call.json`` (or ``--out``) and the
table beside it (``per_call.md``): the median over the rounds, and the
lowest and highest round.  The target is 0.3 ms, measured on the machine of
``docs/performance.md``'s start-up table; compare checkouts measured here.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (the machine, the record, fresh interpreters)
from cli_warm import _commit  # noqa: E402  (a checkout's commit line)

#: One round in a fresh interpreter: the median milliseconds of CALLS calls.
ROUND = """
import json, statistics, time
import hamrkq
from hamrkq.catalogue.problems import load_problem
problem = load_problem("harmonic")
span = (0.0, 0.05)
result = {{}}
for method in ("rk34q8", "auto"):
    hamrkq.solve(problem, t_span=span, method=method)  # load the compiled code
    times, cpu = [], []
    for _ in range({calls}):
        started, started_cpu = time.perf_counter(), time.thread_time()
        hamrkq.solve(problem, t_span=span, method=method)
        cpu.append(time.thread_time() - started_cpu)
        times.append(time.perf_counter() - started)
    result[method] = statistics.median(times) * 1e3
    result[method + ":cpu"] = statistics.median(cpu) * 1e3
result["file"] = hamrkq.__file__
print(json.dumps(result))
"""

METHODS = ("rk34q8", "auto")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, action="append", help="a checkout (repeatable)")
    parser.add_argument("--label", action="append",
                        help="each checkout's name in the table, in --root's order (default: "
                             "its commit; a `git archive` copy has none)")  # fmt: skip
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--out", type=Path, default=HERE / "per_call.json")
    args = parser.parse_args(argv)
    roots = [r.resolve() for r in (args.root or [HERE.parent])]
    labels = args.label or [_commit(r) for r in roots]
    if len(labels) != len(roots):
        parser.error("give one --label per --root")
    code = ROUND.format(calls=args.calls)
    checkouts = [{"root": str(r), "commit": label} for r, label in zip(roots, labels, strict=True)]
    results = measure.begin_record(args.rounds, calls=args.calls, checkouts=checkouts)
    rounds = measure.rounds_at_checkouts(code, roots, args.rounds, "hamrkq-per-call-")
    for entry, measured in zip(results["checkouts"], rounds, strict=True):
        for method in METHODS:
            values = [r[method] for r in measured]
            cpu = [r[method + ":cpu"] for r in measured]
            entry[method] = {"rounds": values, "median": statistics.median(values),
                             "lowest": min(values), "highest": max(values),
                             "cpu_rounds": cpu, "cpu_median": statistics.median(cpu),
                             "cpu_lowest": min(cpu)}  # fmt: skip
    measure.save_record(args.out.parent, args.out.stem, measure.end_record(results), table)
    return 0


def table(results: dict) -> str:
    """Markdown: one row per checkout and method."""
    lines = [
        "| checkout | method | median ms a call | lowest round | highest round "
        "| median CPU ms a call | lowest round (CPU) |",
        "|---|---|---|---|---|---|---|",
    ]
    for e in results["checkouts"]:
        for method in METHODS:
            m = e[method]
            lines.append(f"| {e['commit']} | {method} | {m['median']:.3f} | "
                         f"{m['lowest']:.3f} | {m['highest']:.3f} | "
                         f"{m['cpu_median']:.3f} | {m['cpu_lowest']:.3f} |")  # fmt: skip
    lines.append("")
    lines.append(f"{results['rounds']} alternating rounds of {results['calls']} calls each, "
                 f"{results['started']}, load average {results['machine']['load_average']} at "
                 f"the start and {results['load_average_end']} at the end.")  # fmt: skip
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
