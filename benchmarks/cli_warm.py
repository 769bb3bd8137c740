"""``hamrkq run prentice2011 --no-plots`` with a warm cache, checkouts side by side.

    python benchmarks/cli_warm.py --root /before/tree --root /work/main --rounds 7

Each checkout's bytecode is written first (as an installation would), and
each gets its own temporary caches, warmed by one run (which compiles); then
the rounds alternate between checkouts, so that a change in the machine's
load touches all of them alike.  Every run is a fresh
``python -m hamrkq`` process (the checkout's own ``__main__``, so its own way
of exiting).  Writes ``benchmarks/cli_warm.json`` (or ``--out``) and
``cli_warm.md`` beside it: the median, lowest and highest wall time and the
median CPU time of each checkout.  The issue's target is 1.2 s.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (the machine's description)
from startup import _cli, compile_bytecode  # noqa: E402  (timed as startup.py times it)


def _commit(root: Path) -> str:
    done = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h %s"],
                          capture_output=True, text=True)  # fmt: skip
    return done.stdout.strip()[:60] if done.returncode == 0 else "?"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, action="append", help="a checkout (repeatable)")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--out", type=Path, default=HERE / "cli_warm.json")
    args = parser.parse_args(argv)
    roots = [r.resolve() for r in (args.root or [HERE.parent])]
    for root in roots:
        compile_bytecode(root)
    results = {"machine": measure.machine(), "rounds": args.rounds,
               "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
               "checkouts": [{"root": str(r), "commit": _commit(r)} for r in roots]}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="hamrkq-cli-") as tmp:
        caches = [Path(tmp) / f"cache-{k}" for k in range(len(roots))]
        for root, cache in zip(roots, caches, strict=True):
            cache.mkdir()
            _cli(root, cache, Path(tmp) / f"warm-{cache.name}")
        runs: list[list[tuple[float, float]]] = [[] for _ in roots]
        for round_ in range(args.rounds):
            for k, (root, cache) in enumerate(zip(roots, caches, strict=True)):
                runs[k].append(_cli(root, cache, Path(tmp) / f"run-{k}-{round_}"))
    for entry, timings in zip(results["checkouts"], runs, strict=True):
        walls, cpus = [w for w, _ in timings], [c for _, c in timings]
        entry.update(walls=walls, median=statistics.median(walls), lowest=min(walls),
                     highest=max(walls), median_cpu=statistics.median(cpus))  # fmt: skip
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    results["load_average_end"] = measure.machine()["load_average"]
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    text = table(results)
    args.out.with_suffix(".md").write_text(text + "\n")
    print(text)
    return 0


def table(results: dict) -> str:
    """Markdown: one row per checkout."""
    lines = [
        "| checkout | median wall | lowest | highest | median CPU | target |",
        "|---|---|---|---|---|---|",
    ]
    for e in results["checkouts"]:
        lines.append(f"| {e['commit']} | {e['median']:.2f} s | {e['lowest']:.2f} s | "
                     f"{e['highest']:.2f} s | {e['median_cpu']:.2f} s | <= 1.2 s |")  # fmt: skip
    lines.append("")
    lines.append(f"{results['rounds']} alternating rounds, {results['started']}, load average "
                 f"{results['machine']['load_average']} at the start and "
                 f"{results['load_average_end']} at the end.")  # fmt: skip
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
