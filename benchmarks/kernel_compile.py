"""The step kernel's compile on an empty cache: callees optimised once, or the plain way.

    python benchmarks/kernel_compile.py [--rounds N] [--before CHECKOUT [--before-label TEXT]]

Each round runs two fresh interpreters with empty caches, the modes
alternating: one compiles the kernel with its ``register_jitable`` callees
optimised once, inside the entry point
(:mod:`hamrkq.backends.numba_linking`, what hamrkq does), the other the plain
way (``HAMRKQ_PLAIN_NUMBA_LINKING=1``).  Each then runs prentice2011
(``rk34q8``; ``auto`` at atol 1e-10) and outer_solar_system (``auto``) and
saves the states; the script checks that the two kernels' states agree bit
for bit, and records the kernel's compile time (``build_kernel``, apart from
the systems' own compile) and the warm run time of ``auto`` on prentice2011
at 1e-10 (median of 5) with each kernel.  One more process per mode compiles
the kernel under cProfile and records the time spent in LLVM's pass
managers and its machine-code generation (``finalize_object``), with their
counts (the profiler slows the rest of the compile, not these).  With
``--before``, a third mode compiles the kernel of the checkout at CHECKOUT
(hamrkq's way) in the same rounds, and its states join the comparison.

Writes ``benchmarks/kernel_compile.json`` and ``benchmarks/kernel_compile.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402
import startup  # noqa: E402

MODES = {"once": {}, "plain": {"HAMRKQ_PLAIN_NUMBA_LINKING": "1"}}
LABELS = {"once": "callees optimised once (hamrkq)", "plain": "plain numba"}

CODE = """
import json, os, statistics, sys, time
import numpy as np
started = time.perf_counter()
from hamrkq.backends import kernel
kernel.build_kernel()
kernel_s = time.perf_counter() - started
import hamrkq
prentice = hamrkq.load_problem("prentice2011")
oss = hamrkq.load_problem("outer_solar_system")
runs = [hamrkq.solve(prentice), hamrkq.solve(prentice, method="auto", atol=1e-10),
        hamrkq.solve(oss, method="auto")]
np.save(os.path.join(os.getcwd(), "states.npy"), np.concatenate([s.y.ravel() for s in runs]))
times = []
for _ in range(5):
    t = time.perf_counter()
    hamrkq.solve(prentice, method="auto", atol=1e-10)
    times.append(time.perf_counter() - t)
print(json.dumps({"kernel_s": kernel_s, "warm_auto_s": statistics.median(times),
                  "hamrkq": os.path.dirname(hamrkq.__file__)}))
"""

PROFILED = """
import cProfile, json, os, pstats
import hamrkq
from hamrkq.backends import kernel
profile = cProfile.Profile()
profile.runcall(kernel.build_kernel)
stats = pstats.Stats(profile).stats
llvm = {"passes_s": 0.0, "passes_n": 0, "codegen_s": 0.0, "codegen_n": 0}
for (path, _, name), (_, calls, own, total, _) in stats.items():
    if path.endswith("newpassmanagers.py") and name == "run":
        llvm["passes_s"] += total
        llvm["passes_n"] += calls
    elif path.endswith("executionengine.py") and name == "finalize_object":
        llvm["codegen_s"] += total
        llvm["codegen_n"] += calls
print(json.dumps({**llvm, "hamrkq": os.path.dirname(hamrkq.__file__)}))
"""


def run(rounds: int, before: Path | None = None, before_label: str = "before") -> dict:
    root = HERE.parent
    modes = {mode: (root, extra) for mode, extra in MODES.items()}
    labels = dict(LABELS)
    if before is not None:
        modes["before"] = (before, {})
        labels["before"] = f"{before_label}, callees optimised once"
    for checkout in {r for r, _ in modes.values()}:
        startup.compile_bytecode(checkout)
    runs = {mode: [] for mode in modes}
    results = measure.begin_record(rounds, runs=runs, llvm={}, bit_identical=True, labels=labels)
    with tempfile.TemporaryDirectory(prefix="hamrkq-kernel-compile-") as tmp:
        for mode, (checkout, extra) in modes.items():
            code = "import os\nos.environ.update(" + repr(extra) + ")\n" + PROFILED
            _, info = startup._python(code, checkout, Path(tmp) / f"profiled-{mode}", "wait")
            results["llvm"][mode] = info
            print(f"profiled {mode}: {info}", flush=True)
        for k in range(rounds):
            states = {}
            for mode, (checkout, extra) in modes.items():
                cache = Path(tmp) / f"{mode}-{k}"
                code = "import os\nos.environ.update(" + repr(extra) + ")\n" + CODE
                wall, info = startup._python(code, checkout, cache, compile_mode="wait")
                info["wall"] = wall
                results["runs"][mode].append(info)
                states[mode] = np.load(cache / "states.npy")
                print(f"round {k} {mode}: kernel {info['kernel_s']:.2f} s, "
                      f"warm auto {info['warm_auto_s']:.3f} s", flush=True)  # fmt: skip
            first = states["once"]
            same = all(
                other.shape == first.shape and bool(np.array_equal(other, first))
                for other in states.values()
            )
            results["bit_identical"] = results["bit_identical"] and same
    return measure.end_record(results)


def table(results: dict) -> str:
    def median(mode: str, key: str) -> float:
        return statistics.median(r[key] for r in results["runs"][mode])

    lines = [
        "| kernel compiled | kernel compile, empty cache (median) | each round | "
        "LLVM pass managers (profiled) | LLVM machine code (profiled) | "
        "warm `auto`, prentice2011 atol 1e-10 (median) |",
        "|---|---|---|---|---|---|",
    ]
    for mode, label in results.get("labels", LABELS).items():
        each = ", ".join(f"{r['kernel_s']:.1f}" for r in results["runs"][mode])
        llvm = results["llvm"][mode]
        lines.append(
            f"| {label} | {median(mode, 'kernel_s'):.1f} s | {each} s | "
            f"{llvm['passes_s']:.1f} s in {llvm['passes_n']} runs | "
            f"{llvm['codegen_s']:.1f} s in {llvm['codegen_n']} | "
            f"{median(mode, 'warm_auto_s'):.3f} s |"
        )
    m = results["machine"]
    same = "bit for bit equal" if results["bit_identical"] else "NOT bit for bit equal"
    head = (
        f"`benchmarks/kernel_compile.py`, {results['rounds']} round(s) of fresh processes "
        f"with empty caches, the modes alternating, run {results['started']} to "
        f"{results['finished']}: {m['cpu']}, {m['cores']} cores, numba {m.get('numba')}, "
        f"load average {m['load_average']} at the start and {results['load_average_end']} "
        f"at the end. The states of prentice2011 (rk34q8; auto at 1e-10) and "
        f"outer_solar_system (auto) from the kernels: {same}."
    )
    return head + "\n\n" + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--name", default="kernel_compile", help="the record's file name (another numba release)"
    )
    parser.add_argument("--before", type=Path, help="a checkout from before a change")
    parser.add_argument("--before-label", default="before", help="what the table calls it")
    args = parser.parse_args(argv)
    before = None if args.before is None else args.before.resolve()
    results = run(args.rounds, before, args.before_label)
    measure.save_record(HERE, args.name, results, table)
    return 0 if results["bit_identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
