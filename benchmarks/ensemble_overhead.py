"""An ensemble's per-member overhead, checkouts side by side (issue 13).

    python benchmarks/ensemble_overhead.py --root /before/tree --root /work/main --rounds 7

``benchmarks/ensemble.py``'s first row, alternating between checkouts: each
round runs every checkout in turn, each in a fresh interpreter with its own
warm caches (warmed by a first round that is not counted), and times an
ensemble of MEMBERS Henon-Heiles orbits (``benchmarks/ensemble.py``'s
states) at atol 1e-8 whose members take one tiny step (t_span = (0, 1e-9)),
on one worker, with ``method="auto"`` and ``"rk34q8"``: nearly all of its
time is the cost of setting up, deciding and packing each member.  Each
round takes the best of three such ensembles; the rounds alternate, so that
a change in the machine's load touches every checkout alike.  Writes
``benchmarks/ensemble_overhead.json`` (or ``--out``) and the table beside
it (``ensemble_overhead.md``): per checkout and method, the median over the
rounds of the microseconds a member, and the lowest and highest round.
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

METHODS = ("auto", "rk34q8")

#: One round in a fresh interpreter: the best of three ensembles a method.
ROUND = """
import json, time
import numpy as np
import hamrkq
problem = hamrkq.load_problem("henon_heiles")
y0 = np.random.default_rng(2011).uniform(-0.25, 0.25, ({members}, 4))

def run(states, method):
    started = time.perf_counter()
    hamrkq.ensemble(problem, q0=states[:, :2], p0=states[:, 2:], atol=1e-8, t_span=(0, 1e-9),
                    method=method, workers=1, progress=False)
    return time.perf_counter() - started

result = {{}}
for method in {methods}:
    run(y0[:40], method)  # load the compiled code (chunks of several: benchmarks/ensemble.py)
    result[method] = min(run(y0, method) for _ in range(3)) / {members} * 1e6
result["file"] = hamrkq.__file__
print(json.dumps(result))
"""


def arguments() -> argparse.ArgumentParser:
    """The command line: the checkouts, the rounds, the members, the record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--root", type=Path, action="append", help="a checkout (repeatable)")
    parser.add_argument("--out", type=Path, default=HERE / "ensemble_overhead.json")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = arguments().parse_args(argv)
    roots = [r.resolve() for r in (args.root or [HERE.parent])]
    checkouts = [{"root": str(r), "commit": _commit(r)} for r in roots]
    results = measure.begin_record(args.rounds, members=args.members, checkouts=checkouts)
    code = ROUND.format(members=args.members, methods=METHODS)
    rounds = measure.rounds_at_checkouts(code, roots, args.rounds, "hamrkq-ensemble-overhead-")
    for entry, measured in zip(results["checkouts"], rounds, strict=True):
        for method in METHODS:
            values = [r[method] for r in measured]
            entry[method] = {"rounds": values, "median": statistics.median(values),
                             "lowest": min(values), "highest": max(values)}  # fmt: skip
    measure.save_record(args.out.parent, args.out.stem, measure.end_record(results), table)
    return 0


def table(results: dict) -> str:
    """Markdown: a row per method and checkout, with the first checkout's
    median over this one's (how many times faster this one is)."""
    rows = [
        "| method | checkout | median us a member | lowest round | highest round | speed-up |",
        "|---|---|---|---|---|---|",
    ]
    for method in METHODS:
        first = results["checkouts"][0][method]["median"]
        for checkout in results["checkouts"]:
            m = checkout[method]
            cells = (method, checkout["commit"], f"{m['median']:.1f}", f"{m['lowest']:.1f}",
                     f"{m['highest']:.1f}", f"{first / m['median']:.2f}")  # fmt: skip
            rows.append("| " + " | ".join(cells) + " |")
    note = (f"{results['members']} Henon-Heiles members of one tiny step (t_span = (0, 1e-9), "
            f"atol 1e-8, 1 worker), best of 3 ensembles a round; {results['rounds']} "
            f"alternating rounds, {results['started']}, load average "
            f"{results['machine']['load_average']} at the start and "
            f"{results['load_average_end']} at the end.")  # fmt: skip
    return "\n".join([*rows, "", note])


if __name__ == "__main__":
    sys.exit(main())
