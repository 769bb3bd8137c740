"""The quencher's stage sums, several components side by side, measured.

    python benchmarks/stage_sums.py [--before CHECKOUT]

A stage of an explicit Runge-Kutta step is ``y + h sum_l a_jl K_l``; for
Feagin's 12th-order quencher (25 stages) that is 300 coefficient products a
component, twice with the coefficients' low words, against 25 evaluations of
``f``.  ``hamrkq.rkq.arith.stage_value_compensated`` used to add one
component's sum at a time: each addition waits for the one before (about four
cycles), so a step of a 2-variable system was bound by that chain.  It now
runs four (or two) components' sums side by side and skips zero
coefficients (Feagin 12 has 170 nonzero of 300); each component's sum is the
same sequence of roundings, so results keep every bit.

This script measures, in one run:

1. that the kernel's stage sums equal the previous formulation's (kept
   below as ``one_component_at_a_time``) to the bit on random stages; a
   timing of the stage function alone was left out: numba inlines a
   function differently by where it is called from, and such a harness
   gave anything from 0.9 to 1.5 times for the same code;
2. with ``--before CHECKOUT`` (a checkout of the code before the change),
   ``method="auto"`` on prentice2011 (2 variables, atol 1e-6) and the outer
   solar system (36, rtol 1e-6), and ``rk34q8`` on prentice2011, each in
   fresh processes, one checkout after the other, warm (the compiled
   code loaded from each checkout's own cache), median of 7 runs
   each; the end states must agree to the bit.

The checkouts' code is loaded with ``sys.path``: run it from a virtual
environment where hamrkq's dependencies are installed.

Writes ``benchmarks/stage_sums.txt``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import measure
import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
REPEATS = 7
CASES = (
    ("prentice2011", 1e-6, "auto"),
    ("outer_solar_system", 1e-6, "auto"),
    ("prentice2011", 1e-6, "rk34q8"),
)

RUN_ONE = """
import json, sys, time, warnings
sys.path.insert(0, {root!r})
warnings.simplefilter("ignore")
import hamrkq
assert hamrkq.__file__.startswith({root!r}), hamrkq.__file__
problem = hamrkq.load_problem({name!r})
kw = {{"rtol": {tol!r}}} if {name!r} == "outer_solar_system" else {{"atol": {tol!r}}}
sol = hamrkq.solve(problem, method={method!r}, **kw)
times = []
for _ in range({repeats}):
    t0 = time.perf_counter()
    sol = hamrkq.solve(problem, method={method!r}, **kw)
    times.append(time.perf_counter() - t0)
print(json.dumps({{"times": times, "nfev": int(sol.stats["nfev"]),
                  "end": [float(x).hex() for x in sol.y[-1]]}}))
"""


def one_component_at_a_time(base, lo, h, A, A_low, j, K, out):
    """The previous formulation of ``stage_value_compensated`` (forward,
    rounded to nearest): one component's sum at a time, every coefficient."""
    for i in range(out.shape[0]):
        small = lo[i]
        if j:
            acc = 0.0
            low = 0.0
            for m in range(j):
                acc += A[j, m] * K[m, i]
                low += A_low[j, m] * K[m, i]
            small = lo[i] + (acc + low) * h
        out[i] = base[i] + small


def check_same_bits() -> int:
    """Part 1: the kernel's stage sums equal the previous formulation's to the
    bit, on random stages of Feagin 12 for 1 to 9 and 36 components (every
    path: four, two and one component at a time).  Returns the stages checked."""
    import numba

    from hamrkq.rkq import arith, family

    tab = family.get_member("rk78q12").tableaus
    old_stage = numba.njit(one_component_at_a_time)
    new_stage = arith.stage_value_compensated

    @numba.njit
    def check_new(base, lo, h, A, A_low, j, K, out):
        new_stage(base, lo, h, A, A_low, j, K, out)

    rng = np.random.default_rng(1)
    checked = 0
    for d in (*range(1, 10), 36):
        for _ in range(20):
            K = rng.standard_normal((25, d)) * 10.0 ** rng.integers(-8, 8, (25, d))
            base, lo = rng.standard_normal(d), rng.standard_normal(d) * 1e-17
            h = rng.uniform(1e-3, 1.0)
            for j in range(25):
                a, b = np.empty(d), np.empty(d)
                old_stage(base, lo, h, tab.Az, tab.Az_low, j, K, a)
                check_new(base, lo, h, tab.Az, tab.Az_low, j, K, b)
                assert a.tobytes() == b.tobytes(), (d, j)
                checked += 1
    return checked


def whole_runs(before: Path) -> list[dict]:
    """Part 2: warm runs of both checkouts in fresh processes, alternating."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, tol, method in CASES:
            row: dict = {"case": f"{name} {method} {tol:g}"}
            for label, root in (("before", before), ("now", ROOT)):
                env = {"HAMRKQ_COMPILE": "wait", "NUMBA_CACHE_DIR": str(Path(tmp) / label)}
                code = RUN_ONE.format(
                    root=str(root), name=name, tol=tol, method=method, repeats=REPEATS
                )
                # Twice each: the first process fills its fresh cache (compiles).
                for _ in range(2):
                    _, result = measure.python(code, cache=Path(tmp) / label / "hamrkq", env=env)
                row[label] = float(np.median(result["times"]))
                row[label + "_end"] = result["end"]
                row["nfev"] = result["nfev"]
            row["same_bits"] = row["before_end"] == row["now_end"]
            rows.append(row)
    return rows


def _commit(root: Path) -> str:
    """The short commit hash of a checkout (with ``+`` if it has changes)."""
    git = ["git", "-C", str(root)]
    head = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run([*git, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True)  # fmt: skip
    return head.stdout.strip() + ("+" if dirty.stdout.strip() else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a checkout of the code before the change")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    start = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load = [round(x, 2) for x in os.getloadavg()]
    lines = [
        "# The quencher's stage sums (generated by `benchmarks/stage_sums.py`)",
        "",
        f"Run {start}; {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
        f"load average at the start {load}.  Medians of {REPEATS} runs.",
        "",
        f"Stage sums equal to the bit to one component at a time: {check_same_bits()} random",
        "stages of Feagin 12 checked (1 to 9 and 36 components).",
    ]
    if args.before is not None:
        lines += [
            "",
            f"Whole runs, warm (each checkout's code loaded from its own cache), fresh "
            f"processes; before = checkout {_commit(args.before)}, now = {_commit(ROOT)}:",
            "",
            "| case | f evaluations | before (ms) | now (ms) | ratio | end state, same bits |",
            "|---|---|---|---|---|---|",
        ]
        for row in whole_runs(args.before.resolve()):
            lines.append(
                f"| {row['case']} | {row['nfev']} | {row['before'] * 1e3:.1f} "
                f"| {row['now'] * 1e3:.1f} | {row['before'] / row['now']:.2f} "
                f"| {'yes' if row['same_bits'] else 'NO'} |"
            )
    lines += ["", f"Load average at the end {[round(x, 2) for x in os.getloadavg()]}."]
    text = "\n".join(lines) + "\n"
    (HERE / "stage_sums.txt").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
