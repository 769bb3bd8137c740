"""What generating and compiling ``jac`` and ``rhs_jvp`` only for the runs that call them saves.

    python benchmarks/lazy_functions.py [--rounds N] [--before CHECKOUT [--before-label TEXT]]

A system's ``jac`` is called only by the paper's estimate of Gamma (and by
``rhs_jvp`` above 12 state variables), its ``rhs_jvp`` only by the tangent
estimate (``rk34q8``'s); ``auto``'s shadow estimate calls neither.  Each
case runs in a fresh interpreter with empty caches, the cases alternating:
generating and compiling a catalogue system
(:func:`hamrkq.backends.compiled.compile_system`) and what a run with the
estimate calls (``CompiledSystem.prepare``).  ``"tangent"`` generates and
compiles every function (what every run did two changes ago, above 12 state
variables); ``"shadow"`` is what ``method="auto"`` does now: the system part
of the code only (:data:`hamrkq.backends.codegen.PARTS`), the Jacobian
neither derived nor printed nor compiled.  With ``--before``, a checkout
from before the code was split (``git archive cffd808``: it generated the
Jacobian for every run, and compiled it only for the runs that call it)
runs the shadow case too, side by side.  The kernel is not included (it is
the same for every system: ``benchmarks/kernel_compile.py``).

Writes ``benchmarks/lazy_functions.json`` and ``benchmarks/lazy_functions.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402
import startup  # noqa: E402

PROBLEMS = ("prentice2011", "outer_solar_system", "pleiades")
#: (case, checkout, estimate of Gamma)
CASES = (("tangent", "now", "tangent"), ("shadow", "now", "shadow"),
         ("shadow_before", "before", "shadow"))  # fmt: skip

CODE = """
import json, os, sys, time
import hamrkq
from hamrkq.backends import compiled
problem = hamrkq.load_problem(sys.argv[1])
started = time.perf_counter()
system = compiled.compile_system(problem.hamiltonian)
system.prepare(sys.argv[2])
seconds = time.perf_counter() - started
print(json.dumps({"seconds": seconds, "compiled": compiled.stats()["compiled"],
                  "hamrkq": os.path.dirname(hamrkq.__file__)}))
"""


def run(rounds: int, before: Path | None, label: str | None = None) -> dict:
    roots = {"now": HERE.parent, "before": before}
    for root in roots.values():
        if root is not None:
            startup.compile_bytecode(root)
    cases = [case for case in CASES if roots[case[1]] is not None]
    record = {name: {case: [] for case, _, _ in cases} for name in PROBLEMS}
    results = measure.begin_record(
        rounds, cases=record, before=(label or str(before)) if before else None
    )
    with tempfile.TemporaryDirectory(prefix="hamrkq-lazy-") as tmp:
        for name in PROBLEMS:
            for k in range(rounds):
                for case, checkout, gamma in cases:
                    cache = Path(tmp) / f"{name}-{case}-{k}"
                    code = f"import sys\nsys.argv[1:] = [{name!r}, {gamma!r}]\n" + CODE
                    _, info = startup._python(code, roots[checkout], cache, compile_mode="wait")
                    results["cases"][name][case].append(info)
                    print(f"{name} {case}: {info['seconds']:.2f} s, "
                          f"{info['compiled']} compiled", flush=True)  # fmt: skip
    return measure.end_record(results)


def table(results: dict) -> str:
    lines = [
        "| problem (state variables) | tangent estimate (`rk34q8`) | "
        "shadow estimate (`auto`) | saved | shadow, before the split | saved by the split |",
        "|---|---|---|---|---|---|",
    ]
    dims = {"prentice2011": 2, "outer_solar_system": 36, "pleiades": 28}
    for name, runs in results["cases"].items():
        seconds = {case: statistics.median(r["seconds"] for r in runs[case]) for case in runs}
        counts = {case: runs[case][0]["compiled"] for case in runs}
        tangent, shadow = seconds["tangent"], seconds["shadow"]
        before = seconds.get("shadow_before")
        row = (
            f"| {name} ({dims.get(name, '?')}) | {tangent:.2f} s ({counts['tangent']} compiled) | "
            f"{shadow:.2f} s ({counts['shadow']} compiled) | {1 - shadow / tangent:.0%} | "
        )
        row += "- | - |" if before is None else f"{before:.2f} s | {1 - shadow / before:.0%} |"
        lines.append(row)
    m = results["machine"]
    head = (
        f"`benchmarks/lazy_functions.py`, {results['rounds']} round(s) of fresh processes with "
        f"empty caches, the cases alternating, run {results['started']} to "
        f"{results['finished']}: {m['cpu']}, {m['cores']} cores, load average "
        f"{m['load_average']} at the start and {results['load_average_end']} at the end; "
        "medians of generating and compiling the system (SymPy and numba; the kernel apart). "
        "The tangent column generates and compiles every function; the shadow column the "
        "system part of the code only; before the split (a checkout from before it: "
        f"{results.get('before') or 'not run'}), the shadow estimate generated every function "
        "and compiled three."
    )
    return head + "\n\n" + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--before", type=Path, help="a checkout from before the split")
    parser.add_argument("--before-label", help="what the table calls it (its commit)")
    args = parser.parse_args(argv)
    before = args.before.resolve() if args.before else None
    results = run(args.rounds, before, args.before_label)
    measure.save_record(HERE, "lazy_functions", results, table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
