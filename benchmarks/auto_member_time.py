"""``method="auto"`` at loose tolerances: rk67q9 (the rule) against rk78q12, in time.

    python benchmarks/auto_member_time.py

``auto_member.py`` counts evaluations; this times the two members as auto
runs them (reruns included, compiled, warm), alternating in one process, on
every catalogue problem below 12 state variables at ``atol`` 1e-6 (rtol 0,
no output times), and reports medians of seven integration times
(``stats["integrate_s"]``) with the evaluations.  Writes
``benchmarks/auto_member_time.txt``.
"""

from __future__ import annotations

import math
import statistics
import sys
import warnings
from pathlib import Path

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)

import hamrkq
from hamrkq.rkq import auto_rules

HERE = Path(__file__).resolve().parent
REPEATS = 7
TOL = 1e-6


def timed(problem, loose: float) -> tuple[str, float, int]:
    """auto's member, median integration time and evaluations with the
    loose-tolerance threshold set to ``loose``."""
    saved = auto_rules.AUTO_LOOSE_TOLERANCE
    auto_rules.AUTO_LOOSE_TOLERANCE = loose
    try:
        sol = hamrkq.solve(problem, method="auto", atol=TOL, rtol=0.0)
        return sol.method, sol.stats["integrate_s"], _work(sol)
    finally:
        auto_rules.AUTO_LOOSE_TOLERANCE = saved


def _work(sol) -> int:
    stats = sol.stats
    return int(stats["nfev"] + stats["njev"] + stats.get("discarded_evaluations", 0))


def main() -> int:
    warnings.simplefilter("ignore")
    lines = [
        f"auto at atol {TOL:g}, rtol 0, no output times: the rule's member against "
        f"rk78q12, median of {REPEATS} integration times each, alternating in one process",
        "",
        f"{'problem':16s} {'rule':8s} {'time (s)':>10s} {'work':>9s}   {'rk78q12':8s} "
        f"{'time (s)':>10s} {'work':>9s}   time ratio",
    ]
    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        if problem.hamiltonian.dim >= auto_rules.AUTO_LARGE_DIM:
            continue  # rk67q9 by dimension, with or without the rule
        runs: dict[str, list] = {"rule": [], "old": []}
        for _ in range(REPEATS):
            runs["rule"].append(timed(problem, auto_rules.AUTO_LOOSE_TOLERANCE))
            runs["old"].append(timed(problem, math.inf))
        (member, _, work), (old, _, old_work) = runs["rule"][0], runs["old"][0]
        now = statistics.median(r[1] for r in runs["rule"])
        before = statistics.median(r[1] for r in runs["old"])
        lines.append(
            f"{name:16s} {member:8s} {now:10.5f} {work:9d}   {old:8s} {before:10.5f} "
            f"{old_work:9d}   {now / before:.2f}"
        )
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    (HERE / "auto_member_time.txt").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
