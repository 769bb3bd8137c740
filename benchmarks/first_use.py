"""A first use, compiled first (``HAMRKQ_COMPILE=wait``) or in the background.

    python benchmarks/first_use.py [--rounds N] [--helpers]

Each case runs in a fresh interpreter with empty caches (temporary
directories), once per mode and round, the modes alternating: ``solve`` of a
catalogue problem over a short span (what an exploratory first call looks
like) and over its whole default span.  Recorded: the time of ``solve``, the
steps run interpreted before the switch to compiled code, and the time from
the start of the process until the compiled code is in the cache (the
helpers waited for: the next run's start).

Writes ``benchmarks/first_use.json`` and ``benchmarks/first_use.md`` (the
table in docs/performance.md, block ``first_use``).

``--helpers`` measures instead the whole default run of outer_solar_system
compiled first, in the background with two helpers (system and kernel side
by side, what hamrkq does at 12 state variables or more) and with one
helper compiling both (the second core left to the run), and writes
``benchmarks/first_use_helpers.json`` and ``.md``.
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
#: Makes every system "small" for hamrkq.backends.background: one helper.
ONE_HELPER = (
    "from hamrkq.backends import kernel_helper as _helper; _helper.HELPER_MIN_DIM = 10**9\n"
)


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


def run_helpers(rounds: int) -> dict:
    """outer_solar_system's whole run: compiled first, two helpers, one helper."""
    root = HERE.parent
    startup.compile_bytecode(root)
    code = startup.FIRST_CALL.format(name="outer_solar_system", span=None)
    one = code.replace("import hamrkq\n", "import hamrkq\n" + ONE_HELPER, 1)
    variants = {"compiled first": (code, "wait"), "two helpers": (code, "background"),
                "one helper": (one, "background")}  # fmt: skip
    results = {
        "machine": measure.machine(),
        "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        "rounds": rounds,
        "runs": {label: [] for label in variants},
    }
    with tempfile.TemporaryDirectory(prefix="hamrkq-first-use-") as tmp:
        for k in range(rounds):
            for label, (text, mode) in variants.items():
                cache = Path(tmp) / f"{label.replace(' ', '-')}-{k}"
                wall, info = startup._python(text, root, cache, compile_mode=mode)
                info["wall"] = wall
                results["runs"][label].append(info)
                print(f"{label}: solve {info['solve']:.2f} s, interpreted "
                      f"{info['interpreted_steps']}/{info['steps']}", flush=True)  # fmt: skip
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    results["load_average_end"] = measure.machine()["load_average"]
    return results


def helpers_table(results: dict) -> str:
    lines = [
        "| outer_solar_system, whole default span | `solve` (median) | each round | "
        "steps interpreted |",
        "|---|---|---|---|",
    ]
    for label, runs in results["runs"].items():
        each = ", ".join(f"{r['solve']:.2f}" for r in runs)
        lines.append(
            f"| {label} | {_median(runs, 'solve'):.2f} s | {each} s | "
            f"{_median(runs, 'interpreted_steps'):.0f} of {_median(runs, 'steps'):.0f} |"
        )
    m = results["machine"]
    head = (
        f"`benchmarks/first_use.py --helpers`, {results['rounds']} round(s), fresh processes "
        f"with empty caches, run {results['started']} to {results['finished']}: {m['cpu']}, "
        f"{m['cores']} cores, load average {m['load_average']} at the start and "
        f"{results['load_average_end']} at the end."
    )
    return head + "\n\n" + "\n".join(lines)


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
    parser.add_argument("--helpers", action="store_true", help=run_helpers.__doc__)
    args = parser.parse_args(argv)
    name, measure_, tabulate = (
        ("first_use_helpers", run_helpers, helpers_table)
        if args.helpers
        else ("first_use", run, table)
    )
    results = measure_(args.rounds)
    (HERE / f"{name}.json").write_text(json.dumps(results, indent=1) + "\n")
    text = tabulate(results)
    (HERE / f"{name}.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
