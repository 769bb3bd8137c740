"""A first use, compiled first (``HAMRKQ_COMPILE=wait``) or in the background.

    python benchmarks/first_use.py [--rounds N]

Each case runs in a fresh interpreter with empty caches (temporary
directories), once per mode and round, the modes alternating: ``solve`` of a
catalogue problem over a short span (what an exploratory first call looks
like) and over its whole default span.  Recorded: the time of ``solve``, the
steps run interpreted before the switch to compiled code, and the time from
the start of the process until the compiled code is in the cache (the
helpers waited for: the next run's start).

Writes ``benchmarks/first_use.json`` and ``benchmarks/first_use.md`` (the
table in docs/performance.md, block ``first_use``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402
import startup  # noqa: E402

CASES = [
    ("prentice2011", 10.0),
    ("prentice2011", None),
    ("outer_solar_system", 1000.0),
    ("outer_solar_system", None),
]
MODES = ("wait", "background")


def run(rounds: int) -> dict:
    root = HERE.parent
    startup.compile_bytecode(root)
    results = {
        "machine": measure.machine(),
        "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        "rounds": rounds,
        "cases": [],
    }
    with tempfile.TemporaryDirectory(prefix="hamrkq-first-use-") as tmp:
        for name, span in CASES:
            case = {"problem": name, "span": span, "runs": {m: [] for m in MODES}}
            for k in range(rounds):
                for mode in MODES:
                    cache = Path(tmp) / f"{name}-{span}-{mode}-{k}"
                    code = startup.FIRST_CALL.format(name=name, span=span)
                    wall, info = startup._python(code, root, cache, compile_mode=mode)
                    info["wall"] = wall
                    case["runs"][mode].append(info)
                    print(f"{name} span={span} {mode}: solve {info['solve']:.2f} s, "
                          f"cached after {info['cached_after']:.2f} s, interpreted "
                          f"{info['interpreted_steps']}/{info['steps']}", flush=True)  # fmt: skip
            results["cases"].append(case)
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    results["load_average_end"] = measure.machine()["load_average"]
    return results


def _median(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def table(results: dict) -> str:
    """Markdown: medians over the rounds, wait beside background."""
    lines = [
        "| problem, span | `solve`, compiled first | `solve`, background | "
        "steps interpreted | code cached after (wait / background) |",
        "|---|---|---|---|---|",
    ]
    for case in results["cases"]:
        wait, back = case["runs"]["wait"], case["runs"]["background"]
        span = "whole default span" if case["span"] is None else f"t0 + {case['span']:g}"
        steps = f"{_median(back, 'interpreted_steps'):.0f} of {_median(back, 'steps'):.0f}"
        lines.append(
            f"| {case['problem']}, {span} | {_median(wait, 'solve'):.2f} s | "
            f"{_median(back, 'solve'):.2f} s | {steps} | "
            f"{_median(wait, 'cached_after'):.2f} s / {_median(back, 'cached_after'):.2f} s |"
        )
    m = results["machine"]
    head = (
        f"`benchmarks/first_use.py`, {results['rounds']} round(s) of fresh processes with "
        f"empty caches, the modes alternating, run {results['started']} to "
        f"{results['finished']}: {m['cpu']}, {m['cores']} cores, load average "
        f"{m['load_average']} at the start and {results['load_average_end']} at the end; "
        "medians. `solve` excludes `import hamrkq` and parsing the problem (about 0.5 s); "
        '"code cached after" counts from the process\'s start.'
    )
    return head + "\n\n" + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    results = run(args.rounds)
    (HERE / "first_use.json").write_text(json.dumps(results, indent=1) + "\n")
    text = table(results)
    (HERE / "first_use.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
