"""Resident memory of long runs: flat with ``keep_every`` or ``t_eval``.

    python benchmarks/memory.py            # 1e5, 1e6 and 1e7 steps
    python benchmarks/memory.py --quick    # 1e4, 1e5 and 1e6 steps

Each run is prentice2011 with its own method (the paper's rk34q8, atol 1e-6)
in a fresh interpreter whose caches already hold the compiled code, over a
span that takes about the given number of steps (62 197 steps per 4000 time
units).  ``gamma_limit=inf`` lets the run go on past t ~ 30 000, where the
RK8 track's estimated error passes 5 % of atol and a normal run stops
(docs/algorithm.md): the point here is memory, not accuracy.  The peak
resident set size (``ru_maxrss``) is reported above that of an interpreter
that loaded the same code and ran one short solve.

Three ways to keep nodes are measured: every node (the positive control: its
memory must grow with the steps, or the measurement sees nothing), every
1000th node (``keep_every``), and 2001 times (``t_eval``).  Issue 13 asks
that a 1e7-step run with ``keep_every`` or ``t_eval`` keep resident memory
flat.  Writes ``benchmarks/memory.json`` and ``benchmarks/memory.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (the machine, fresh interpreters)

#: Accepted steps of prentice2011's rk34q8 run per unit of time (62 197 steps
#: over [0, 4000]).
STEPS_PER_TIME = 62197 / 4000.0

SCRIPT = """
import time
import numpy as np
import hamrkq
problem = hamrkq.load_problem("prentice2011")
hamrkq.solve(problem, t_span=(0.0, 1.0))  # load the compiled code
t_end, keep, thin = {t_end!r}, {keep!r}, {thin!r}
if t_end:
    options = {{"t_eval": np.linspace(0.0, t_end, thin)}} if thin else {{"keep_every": keep}}
    started = time.perf_counter()
    sol = hamrkq.solve(problem, t_span=(0.0, t_end), gamma_limit=float("inf"),
                       max_steps=10**8, **options)
    EXTRA = {{"nodes": len(sol), "steps": sol.stats["steps"], "t_last": float(sol.t[-1]),
             "status": sol.status.name, "seconds": time.perf_counter() - started}}
"""

KEEPING = {
    "every node": {"keep": 1, "thin": 0},
    "keep_every=1000": {"keep": 1000, "thin": 0},
    "t_eval of 2001 times": {"keep": 1, "thin": 2001},
}


def rss(cache: Path, t_end: float = 0.0, keep: int = 1, thin: int = 0) -> dict[str, Any]:
    code = SCRIPT.format(t_end=t_end, keep=keep, thin=thin) + measure.RSS_TAIL
    return measure.python(code, cache=cache, timeout=3600)[1]


def table(results: dict[str, Any]) -> str:
    lines = [
        "| nodes kept | steps | kept nodes | peak RSS above the interpreter (MB) | run (s) |",
        "|---|---|---|---|---|",
    ]
    for row in results["runs"]:
        lines.append(
            f"| {row['keeping']} | {row['steps']:,} | {row['nodes']:,} | "
            f"{row['above_interpreter_mb']:.1f} | {row['seconds']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="ten times fewer steps")
    args = parser.parse_args(argv)
    sizes = [10**4, 10**5, 10**6] if args.quick else [10**5, 10**6, 10**7]
    results: dict[str, Any] = {
        "machine": measure.machine(),
        "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        "runs": [],
    }
    with tempfile.TemporaryDirectory(prefix="hamrkq-memory-") as tmp:
        cache = Path(tmp)
        rss(cache)  # compile into the cache, so the runs below only load
        base = rss(cache)["peak_rss_mb"]
        results["interpreter_mb"] = base
        for steps in sizes:
            for keeping, how in KEEPING.items():
                if keeping == "every node" and steps > sizes[1]:
                    continue  # the control grows as expected; 1e7 nodes would take GBs
                info = rss(cache, t_end=steps / STEPS_PER_TIME, **how)
                row = {"keeping": keeping, "target_steps": steps, **info}
                row["above_interpreter_mb"] = info["peak_rss_mb"] - base
                results["runs"].append(row)
                print(
                    f"{keeping:>22}: {info['steps']:>10,} steps, {info['nodes']:>9,} nodes, "
                    f"{row['above_interpreter_mb']:7.1f} MB above the interpreter, "
                    f"{info['seconds']:.1f} s ({info['status']})",
                    flush=True,
                )
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    name = "memory_quick" if args.quick else "memory"
    (HERE / f"{name}.json").write_text(json.dumps(results, indent=2) + "\n")
    (HERE / f"{name}.md").write_text(
        f"Interpreter with the code loaded: {base:.1f} MB peak RSS.\n\n" + table(results) + "\n"
    )
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
