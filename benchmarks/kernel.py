"""The compiled step kernel's own speed, side by side across checkouts.

    python benchmarks/kernel.py                                  # this checkout
    python benchmarks/kernel.py --root /old/tree --root .        # before/after
    python benchmarks/kernel.py --out benchmarks/kernel.json     # and kernel.md

For each ``--root`` (a checkout of hamrkq), a fresh interpreter with that
checkout first on ``PYTHONPATH`` and empty temporary caches solves each case
once (the first call: code generation and compilation, CPU seconds) and then
``--repeats`` more times with everything compiled; the table gives the median
warm CPU time (``time.process_time``: the machine is shared, CPU time is
steadier than wall time) and the counters, which must agree across
checkouts whose numbers are meant to be unchanged.  Cases run through
``hamrkq.solve`` with the catalogue's settings; a method a checkout does not
have is reported as missing.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (the machine's description)

#: (problem, method, atol): the paper's problem with the paper's method, and
#: a high-order member at a tight tolerance.
CASES = (
    ("prentice2011", "rk34q8", 1e-6),
    ("prentice2011", "rk78q12", 1e-9),
    ("kepler", "rk34q8", 1e-8),
)

SCRIPT = """
import json, statistics, time
import hamrkq
from hamrkq.catalogue.problems import load_problem
out = {{"hamrkq": hamrkq.__file__}}
for name, method, atol in {cases!r}:
    problem = load_problem(name)
    key = f"{{name}} {{method}} {{atol:g}}"
    try:
        c0 = time.process_time()
        sol = hamrkq.solve(problem, method=method, atol=atol)
        first = time.process_time() - c0
    except Exception as exc:  # a method this checkout does not have
        out[key] = {{"missing": f"{{type(exc).__name__}}: {{exc}}"}}
        continue
    warm = []
    for _ in range({repeats}):
        c0 = time.process_time()
        sol = hamrkq.solve(problem, method=method, atol=atol)
        warm.append(time.process_time() - c0)
    stats = {{k: int(v) for k, v in sol.stats.items() if isinstance(v, int)}}
    out[key] = {{"first_cpu": first, "warm_cpu": warm, "median_cpu": statistics.median(warm),
                "status": str(sol.status), "stats": stats}}
print(json.dumps(out))
"""


def run_root(root: Path, repeats: int) -> dict:
    """The cases in a fresh process on ``root`` with empty caches."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ)
        env.update(
            PYTHONPATH=str(root),
            HAMRKQ_CACHE_DIR=str(Path(cache) / "hamrkq"),
            NUMBA_CACHE_DIR=str(Path(cache) / "numba"),
        )
        code = SCRIPT.format(cases=CASES, repeats=repeats)
        done = subprocess.run(
            [sys.executable, "-c", code],
            env=env,
            cwd=root,  # python -c puts the working directory first on sys.path
            capture_output=True,
            text=True,
            check=True,
        )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if not Path(result["hamrkq"]).is_relative_to(root):
        raise RuntimeError(f"{root}: the process imported {result['hamrkq']}")
    return result


def table(results: dict[str, dict]) -> str:
    """Markdown: one row per case and checkout."""
    lines = [
        "| case | checkout | first call (CPU s) | warm median (CPU s) | steps | nfev |",
        "|---|---|---|---|---|---|",
    ]
    for name, method, atol in CASES:
        key = f"{name} {method} {atol:g}"
        for root, result in results.items():
            row = result.get(key, {})
            if "missing" in row or not row:
                lines.append(f"| {key} | {root} | – | – | – | – |")
                continue
            stats = row["stats"]
            lines.append(
                f"| {key} | {root} | {row['first_cpu']:.2f} | {row['median_cpu']:.3f} "
                f"| {stats.get('steps', '')} | {stats.get('nfev', '')} |"
            )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", action="append", type=Path, help="a checkout (repeatable)")
    parser.add_argument(
        "--label", action="append", help="a name for each --root in the table (in order)"
    )
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, help="write the results as JSON here")
    args = parser.parse_args()
    roots = args.root or [HERE.parent]
    labels = args.label or [str(root) for root in roots]
    if len(labels) != len(roots):
        parser.error("give one --label per --root")
    results = {
        label: run_root(root.resolve(), args.repeats)
        for label, root in zip(labels, roots, strict=True)
    }
    print(table(results))
    if args.out:
        record = {"machine": measure.machine(), "cases": CASES, "results": results}
        args.out.write_text(json.dumps(record, indent=1) + "\n")
        machine = record["machine"]
        args.out.with_suffix(".md").write_text(
            "# The compiled kernel, side by side\n\n"
            f"`python benchmarks/kernel.py {' '.join(sys.argv[1:])}`; "
            f"{machine['cpu']}, {machine['cores']} cores, load average "
            f"{machine['load_average']} (a shared machine: compare rows of one run).\n\n"
            + table(results)
            + "\n"
        )


if __name__ == "__main__":
    main()
