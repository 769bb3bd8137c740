"""What a user pays before any physics: first calls, per-call overhead, the CLI.

    python benchmarks/startup.py                      # this checkout
    python benchmarks/startup.py --root /other/tree   # another checkout (before/after)
    python benchmarks/startup.py --quick              # fewer repeats

Every measurement runs in a fresh interpreter (``subprocess``) whose
``PYTHONPATH`` is ``--root`` and whose caches (``HAMRKQ_CACHE_DIR`` and
``NUMBA_CACHE_DIR``) are temporary directories made here, never the user's:

- **first call, empty cache**: ``hamrkq.solve`` of a catalogue problem over a
  short span in a process whose caches are empty (code generation and the
  compilation of the loop and of the system).  ``import hamrkq`` is timed
  apart; ``wall`` includes the interpreter's start.
- **new system, loop cached**: the same for outer_solar_system when the
  compiled loop is already in the cache (what a user meets with a second
  system).
- **per-call overhead**: in a process with a warm cache, the median wall time
  of ``solve`` on a tiny problem (the harmonic oscillator over a span of a few
  steps), and of the parts that do not integrate.
- **CLI**: ``hamrkq run prentice2011 --no-plots`` in fresh processes with a
  warm cache (median).

The checkout's bytecode is written first (:func:`compile_bytecode`), as an
installation would.

Writes ``benchmarks/startup.json`` (or ``--out``) and prints a Markdown table.
Targets (issue 13) are printed beside the numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (the machine's description)

FIRST_CALL = """
import json, time
t0, c0 = time.perf_counter(), time.process_time()
import hamrkq
from hamrkq.backends import compiled
from hamrkq.catalogue.problems import load_problem
t1, c1 = time.perf_counter(), time.process_time()
problem = load_problem({name!r})
t2, c2 = time.perf_counter(), time.process_time()
span = {span!r}
t_span = problem.t_span if span is None else (problem.t_span[0], problem.t_span[0] + span)
sol = hamrkq.solve(problem, t_span=t_span)
t3, c3 = time.perf_counter(), time.process_time()
# A first use compiles in the background (hamrkq.backends.background): wait
# for the helpers, so that the compiled code is in the cache when this ends.
try:
    from hamrkq.backends import background
    helpers = list(background._HELPERS.values())
except ImportError:  # a checkout before the background compile
    helpers = []
for helper in helpers:
    helper.wait()
t4 = time.perf_counter()
print(json.dumps({{"hamrkq": hamrkq.__file__, "import": t1 - t0, "load_problem": t2 - t1,
                  "solve": t3 - t2, "import_cpu": c1 - c0, "solve_cpu": c3 - c2,
                  "status": str(sol.status), "nodes": len(sol.t), "steps": sol.stats["steps"],
                  "backend": sol.options["backend"],
                  "interpreted_steps": sol.stats.get("interpreted_steps", 0),
                  "helpers": len(helpers), "cached_after": t4 - t0,
                  "numba": compiled.stats()}}))
"""

BREAKDOWN = """
import json, math, time, types
import numba
import hamrkq
from hamrkq.backends import codegen, numba_compile
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problems import load_problem
clock = time.process_time
out = {{"hamrkq": hamrkq.__file__}}
t = clock(); ham = load_problem({name!r}).hamiltonian; out["load_problem"] = clock() - t
t = clock(); ham.rhs; out["derive_rhs"] = clock() - t
t = clock(); ham.jacobian; out["derive_jacobian"] = clock() - t
t = clock(); source = codegen.generate_source(ham); out["generate_source"] = clock() - t
out["source_lines"] = len(source.splitlines())
module = codegen.load_module(ham)
namespace = {{"math": math, "__name__": module.__name__}}
sig = numba_compile.signatures()
for name in ("rhs", "jac", "rhs_jvp", "energy", "energy_rows"):
    plain = types.FunctionType(getattr(module, name).__code__, namespace, name)
    t = clock()
    namespace[name] = numba.njit(sig[name], cache=False, nogil=True, error_model="numpy")(plain)
    out["compile_" + name] = clock() - t
t = clock(); numeric_of(ham).rhs; out["numeric_construct"] = clock() - t
print(json.dumps(out))
"""

OVERHEAD = """
import json, statistics, time
import numpy as np
import hamrkq
from hamrkq.backends import codegen, compiled
from hamrkq.catalogue.problems import load_problem
from hamrkq.backends.numeric import numeric_of
problem = load_problem("harmonic")
ham = problem.hamiltonian
span = (0.0, {span!r})
sol = hamrkq.solve(problem, t_span=span)  # warm: load the compiled code

def median_ms(call, n, clock=time.perf_counter):
    times = []
    for _ in range(n):
        t = clock()
        call()
        times.append(clock() - t)
    return statistics.median(times) * 1e3

n = {repeat}
result = {{
    "hamrkq": hamrkq.__file__, "nodes": len(sol.t), "steps": int(sol.stats.get("steps", -1)),
    "solve_problem_ms": median_ms(lambda: hamrkq.solve(problem, t_span=span), n),
    "solve_problem_cpu_ms": median_ms(lambda: hamrkq.solve(problem, t_span=span), n,
                                      time.process_time),
    "solve_hamiltonian_ms": median_ms(
        lambda: hamrkq.solve(ham, [1.0], [0.0], span, atol=1e-6, rtol=0.0), n),
    "cache_key_ms": median_ms(lambda: codegen.cache_key(ham), n),
    "compile_system_ms": median_ms(lambda: compiled.compile_system(ham), n),
}}
# A fresh Hamiltonian object per call (the key is computed once per object).
fresh = []
for _ in range(max(n // 10, 20)):
    h = load_problem("harmonic").hamiltonian
    t = time.perf_counter()
    codegen.cache_key(h)
    fresh.append(time.perf_counter() - t)
result["cache_key_new_object_ms"] = statistics.median(fresh) * 1e3
print(json.dumps(result))
"""


def _env(root: Path, cache: Path, compile_mode: str | None = None) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": str(root)}
    env["HAMRKQ_CACHE_DIR"] = str(cache / "hamrkq")
    env["NUMBA_CACHE_DIR"] = str(cache / "numba")
    env.pop("HAMRKQ_DISABLE_NUMBA", None)
    env.pop("HAMRKQ_COMPILE", None)
    if compile_mode is not None:
        env["HAMRKQ_COMPILE"] = compile_mode
    return env


def _python(
    code: str, root: Path, cache: Path, compile_mode: str | None = None
) -> tuple[float, dict]:
    """Run ``code`` in a fresh interpreter: (wall seconds, the JSON it printed last).

    The working directory is ``cache``: ``python -c`` puts the working
    directory first on ``sys.path``, and a checkout there would shadow ``root``.
    """
    cache.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], env=_env(root, cache, compile_mode),
                          cwd=cache,
                          capture_output=True, text=True, timeout=1800)  # fmt: skip
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"subprocess failed ({done.returncode}):\n{done.stderr[-3000:]}")
    info = json.loads([line for line in done.stdout.splitlines() if line.startswith("{")][-1])
    if not info.get("hamrkq", "").startswith(str(root)):
        raise RuntimeError(f"measured {info.get('hamrkq')}, not the checkout {root}")
    return wall, info


def compile_bytecode(root: Path) -> None:
    """Write the checkout's ``.pyc`` files, as ``pip install`` does: with
    ``PYTHONDONTWRITEBYTECODE`` set (as on these machines) a checkout's edited
    or never-imported modules would otherwise be compiled from source in
    every measured process."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(root / "hamrkq")],
                   check=True, capture_output=True)  # fmt: skip


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _cli(root: Path, cache: Path, out: Path) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one ``hamrkq run prentice2011 --no-plots``."""
    env = _env(root, cache)
    args = [sys.executable, "-m", "hamrkq", "run", "prentice2011", "--no-plots"]
    cpu = _children_cpu()
    started = time.perf_counter()
    done = subprocess.run(
        [*args, "--out", str(out)],
        env=env,
        cwd=cache,
        capture_output=True,
        text=True,
        timeout=600,
    )
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"hamrkq run failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return wall, _children_cpu() - cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=HERE.parent, help="checkout to measure")
    parser.add_argument("--out", type=Path, default=HERE / "startup.json")
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--label", default="", help="a note stored with the results")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    compile_bytecode(root)
    results: dict[str, Any] = {
        "root": str(root),
        "label": args.label,
        "machine": measure.machine(),
        "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
    }
    with tempfile.TemporaryDirectory(prefix="hamrkq-startup-") as tmp:
        tmp = Path(tmp)
        spans = {"prentice2011": 10.0, "outer_solar_system": 1000.0}
        for name, span in spans.items():
            cache = tmp / f"cold-{name}"
            wall, info = _python(FIRST_CALL.format(name=name, span=span), root, cache)
            results[f"first_call_{name}"] = {"wall": wall, "span": span, **info}
            print(f"first call, empty cache, {name}: solve {info['solve']:.2f} s "
                  f"(CPU {info['solve_cpu']:.2f} s), wall {wall:.2f} s", flush=True)  # fmt: skip
        # outer_solar_system with the loop already compiled: the cache of the
        # prentice2011 run, used in place (numba's index records the path of
        # each source file, so a copied cache would not be found).
        wall, info = _python(
            FIRST_CALL.format(name="outer_solar_system", span=1000.0),
            root,
            tmp / "cold-prentice2011",
        )
        results["new_system_outer_solar_system"] = {"wall": wall, **info}
        print(f"outer_solar_system, loop cached: solve {info['solve']:.2f} s "
              f"(CPU {info['solve_cpu']:.2f} s)", flush=True)  # fmt: skip

        wall, info = _python(BREAKDOWN.format(name="outer_solar_system"), root, tmp / "breakdown")
        results["breakdown_outer_solar_system"] = info
        print(f"outer_solar_system, CPU seconds: {json.dumps(info)}", flush=True)

        warm = tmp / "cold-prentice2011"
        _cli(root, warm, tmp / "cli-warmup")  # the CLI's own first run warms its extras
        runs = [_cli(root, warm, tmp / f"cli-{k}") for k in range(2 if args.quick else 5)]
        walls, cpus = [w for w, _ in runs], [c for _, c in runs]
        results["cli_warm"] = {"walls": walls, "median": statistics.median(walls),
                               "cpus": cpus, "median_cpu": statistics.median(cpus)}  # fmt: skip
        print(f"hamrkq run prentice2011 --no-plots, warm: {statistics.median(walls):.2f} s wall, "
              f"{statistics.median(cpus):.2f} s CPU")  # fmt: skip

        wall, info = _python(
            OVERHEAD.format(span=0.05, repeat=200 if args.quick else 2000), root, warm
        )
        results["overhead"] = info
        print(f"per-call overhead: {json.dumps(info)}", flush=True)
    results["finished"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    results["load_average_end"] = measure.machine()["load_average"]
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(table(results))
    return 0


def table(results: dict[str, Any]) -> str:
    """The Markdown table of one run: wall time, and CPU time of the process
    (what an idle machine would take, roughly: the machine is shared)."""
    fp, fo = results["first_call_prentice2011"], results["first_call_outer_solar_system"]
    ns = results["new_system_outer_solar_system"]
    ov, cli = results["overhead"], results["cli_warm"]
    rows = [
        ("first call, empty cache, prentice2011 (solve)",
         f"{fp['solve']:.2f} s", f"{fp['solve_cpu']:.2f} s", "<= 3 s"),
        ("first call, empty cache, outer_solar_system (solve)",
         f"{fo['solve']:.2f} s", f"{fo['solve_cpu']:.2f} s", "<= 10 s"),
        ("outer_solar_system, loop already cached (solve)",
         f"{ns['solve']:.2f} s", f"{ns['solve_cpu']:.2f} s", ""),
        ("per call, cached tiny problem (solve of harmonic, median)",
         f"{ov['solve_problem_ms']:.3f} ms", f"{ov['solve_problem_cpu_ms']:.3f} ms", "<= 0.3 ms"),
        ("cache key, same Hamiltonian object", f"{ov['cache_key_ms'] * 1e3:.1f} us", "", ""),
        ("`hamrkq run prentice2011 --no-plots`, warm cache (median)",
         f"{cli['median']:.2f} s", f"{cli['median_cpu']:.2f} s", "<= 1.2 s"),
    ]  # fmt: skip
    lines = ["| what | wall | CPU | target |", "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
