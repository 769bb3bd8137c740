"""The generated right-hand side of an N-body problem against a hand-written one.

    python benchmarks/nbody_rhs.py                    # writes benchmarks/nbody_rhs.json
    PYTHONPATH=/other/checkout python benchmarks/nbody_rhs.py --out before.json

outer_solar_system (the Sun and five outer planets, 36 state variables, 15
pairs): the rhs, the Jacobian and the fused ``rhs_jvp`` that
:mod:`hamrkq.backends.codegen` generates, compiled by numba exactly as the
compiled backend compiles them (explicit signatures, ``error_model="numpy"``),
against a hand-written loop over pairs with one square root per pair.

Time per call: a compiled loop calls the function ``--calls`` times, nudging
the state by a rounding-level amount each time so that the compiler cannot
hoist the call out of the loop; the median of ``--repeat`` such loops,
divided by the number of calls (the loop's own cost, a few ns, is included
for both).  Also reported: the compile time of each generated function (no
disk cache), the generated source's length, and the largest difference
between the generated and the hand-written rhs (relative to the largest
component).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import time
import types
from pathlib import Path

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np

HERE = Path(__file__).resolve().parent


def hand_written(t, y, params, out):
    """dy/dt of n bodies: q (3n), then p (3n); params = (G, m_1, ..., m_n)."""
    n = (y.shape[0] // 2) // 3
    G = params[0]
    for i in range(n):
        m = params[1 + i]
        for k in range(3):
            out[3 * i + k] = y[3 * n + 3 * i + k] / m
            out[3 * n + 3 * i + k] = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            dx = y[3 * i] - y[3 * j]
            dy = y[3 * i + 1] - y[3 * j + 1]
            dz = y[3 * i + 2] - y[3 * j + 2]
            r2 = dx * dx + dy * dy + dz * dz
            s = G * params[1 + i] * params[1 + j] / (r2 * math.sqrt(r2))
            out[3 * n + 3 * i] -= s * dx
            out[3 * n + 3 * i + 1] -= s * dy
            out[3 * n + 3 * i + 2] -= s * dz
            out[3 * n + 3 * j] += s * dx
            out[3 * n + 3 * j + 1] += s * dy
            out[3 * n + 3 * j + 2] += s * dz


def _timers(numba):
    """Compiled loops that call f (or jac, or rhs_jvp) many times."""

    def make(python_call):
        call = numba.njit(python_call)

        @numba.njit(error_model="numpy")
        def loop(y, params, v, out, dout, JM, calls):
            for _ in range(calls):
                call(0.0, y, params, v, out, dout, JM)
                y[0] += out[0] * 1e-300  # keeps the call inside the loop
            return out[0]

        return loop

    return make


def ns_per_call(loop, args, calls: int, repeat: int) -> float:
    loop(*args, 10)  # compile the timing loop itself
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        loop(*args, calls)
        times.append(time.perf_counter() - started)
    return statistics.median(times) / calls * 1e9


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "nbody_rhs.json")
    parser.add_argument("--calls", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args(argv)

    import numba

    import hamrkq
    from hamrkq.backends import codegen, numba_compile

    problem = hamrkq.load_problem("outer_solar_system")
    ham = problem.hamiltonian
    params = np.array(ham.parameter_values(), dtype=float)
    y = np.array(problem.y0, dtype=float)  # a writable copy
    dim = y.size
    source = codegen.generate_source(ham)
    with tempfile.TemporaryDirectory() as tmp:  # never the user's cache
        module = codegen.load_module(ham, Path(tmp))
    namespace = {"math": math, "__name__": module.__name__}
    sig = numba_compile.signatures()
    jitted, compile_s = {}, {}
    for name in ("rhs", "jac", "rhs_jvp"):
        function = types.FunctionType(getattr(module, name).__code__, namespace, name)
        started = time.perf_counter()
        jitted[name] = namespace[name] = numba.njit(
            sig[name], nogil=True, error_model="numpy", cache=False
        )(function)
        compile_s[name] = time.perf_counter() - started
    started = time.perf_counter()
    hand = numba.njit(sig["rhs"], nogil=True, error_model="numpy", cache=False)(hand_written)
    compile_s["hand_written_rhs"] = time.perf_counter() - started

    out_g, out_h = np.empty(dim), np.empty(dim)
    jitted["rhs"](0.0, y, params, out_g)
    hand(0.0, y, params, out_h)
    difference = float(np.max(np.abs(out_g - out_h)) / np.max(np.abs(out_h)))

    make = _timers(numba)
    g_rhs, g_jac, g_jvp = jitted["rhs"], jitted["jac"], jitted["rhs_jvp"]
    loops = {
        "generated rhs": make(lambda t, y, p, v, o, d, J: g_rhs(t, y, p, o)),
        "hand-written rhs": make(lambda t, y, p, v, o, d, J: hand(t, y, p, o)),
        "generated jac": make(lambda t, y, p, v, o, d, J: g_jac(t, y, p, J)),
        "generated rhs + jac": make(
            lambda t, y, p, v, o, d, J: (g_rhs(t, y, p, o), g_jac(t, y, p, J))
        ),
        "generated rhs_jvp": make(lambda t, y, p, v, o, d, J: g_jvp(t, y, p, v, o, d, J)),
    }
    v = np.linspace(-1.0, 1.0, dim)
    results = {}
    for label, loop in loops.items():
        work = (y.copy(), params, v, np.empty(dim), np.empty(dim), np.empty((dim, dim)))
        calls = args.calls if "jac" not in label else args.calls // 10
        results[label] = ns_per_call(loop, work, calls, args.repeat)
        print(f"{label:24s} {results[label]:8.0f} ns/call", flush=True)
    report = {
        "hamrkq": hamrkq.__file__,
        "codegen_version": codegen.CODEGEN_VERSION,
        "problem": "outer_solar_system",
        "dim": dim,
        "ns_per_call": results,
        "compile_seconds": compile_s,
        "source_lines": len(source.splitlines()),
        "pow_calls_in_source": source.count("**"),
        "sqrt_calls_in_source": source.count("math.sqrt"),
        "max_relative_difference_generated_vs_hand": difference,
        "numba": numba.__version__,
        "load_average": list(np.round(np.array(__import__("os").getloadavg()), 2)),
    }
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps({k: v for k, v in report.items() if k != "ns_per_call"}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
