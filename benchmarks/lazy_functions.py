"""What compiling ``jac`` and ``rhs_jvp`` only for the runs that call them saves.

    python benchmarks/lazy_functions.py [--rounds N]

A system's ``jac`` is called only by the paper's estimate of Gamma (and by
``rhs_jvp`` above 12 state variables), its ``rhs_jvp`` only by the tangent
estimate (``rk34q8``'s); ``auto``'s shadow estimate calls neither.  Each
case runs in a fresh interpreter with empty caches, the estimates
alternating: generating and compiling a catalogue system
(:func:`hamrkq.backends.compiled.compile_system`) and what a run with the
estimate calls (``CompiledSystem.prepare``).  ``"tangent"`` compiles what
every run compiled before (all five functions, above 12 state variables);
``"shadow"`` is what ``method="auto"`` compiles now.  The kernel is not
included (it is the same for every system: ``benchmarks/kernel_compile.py``).

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
ESTIMATES = ("tangent", "shadow")

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


def run(rounds: int) -> dict:
    root = HERE.parent
    startup.compile_bytecode(root)
    cases = {name: {gamma: [] for gamma in ESTIMATES} for name in PROBLEMS}
    results = measure.begin_record(rounds, cases=cases)
    with tempfile.TemporaryDirectory(prefix="hamrkq-lazy-") as tmp:
        for name in PROBLEMS:
            for k in range(rounds):
                for gamma in ESTIMATES:
                    cache = Path(tmp) / f"{name}-{gamma}-{k}"
                    code = f"import sys\nsys.argv[1:] = [{name!r}, {gamma!r}]\n" + CODE
                    _, info = startup._python(code, root, cache, compile_mode="wait")
                    results["cases"][name][gamma].append(info)
                    print(f"{name} {gamma}: {info['seconds']:.2f} s, "
                          f"{info['compiled']} compiled", flush=True)  # fmt: skip
    return measure.end_record(results)


def table(results: dict) -> str:
    lines = [
        "| problem (state variables) | tangent estimate (`rk34q8`) | "
        "shadow estimate (`auto`) | saved |",
        "|---|---|---|---|",
    ]
    dims = {"prentice2011": 2, "outer_solar_system": 36, "pleiades": 28}
    for name, runs in results["cases"].items():
        tangent = statistics.median(r["seconds"] for r in runs["tangent"])
        shadow = statistics.median(r["seconds"] for r in runs["shadow"])
        counts = {g: runs[g][0]["compiled"] for g in runs}
        lines.append(
            f"| {name} ({dims.get(name, '?')}) | {tangent:.2f} s ({counts['tangent']} compiled) | "
            f"{shadow:.2f} s ({counts['shadow']} compiled) | {1 - shadow / tangent:.0%} |"
        )
    m = results["machine"]
    head = (
        f"`benchmarks/lazy_functions.py`, {results['rounds']} round(s) of fresh processes with "
        f"empty caches, the estimates alternating, run {results['started']} to "
        f"{results['finished']}: {m['cpu']}, {m['cores']} cores, load average "
        f"{m['load_average']} at the start and {results['load_average_end']} at the end; "
        "medians of generating and compiling the system (SymPy and numba; the kernel apart). "
        "Before, every run compiled all five functions: the tangent column above 12 state "
        "variables."
    )
    return head + "\n\n" + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    measure.save_record(HERE, "lazy_functions", run(args.rounds), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
