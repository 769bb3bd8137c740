"""Benchmark hamrkq against SciPy, side by side, on one machine, in one run.

    python benchmarks/run.py            # the full benchmark (~10 minutes)
    python benchmarks/run.py --quick    # short spans, to check the script works

Writes ``benchmarks/README.md`` (tables, ratios, the machine) and
``benchmarks/results.json`` (every number).  Ratios, not absolute times, are
the claim: the absolute times depend on the machine and on its load.

Per problem (prentice2011 over [0, 4000] at atol 1e-6; outer_solar_system
over 500 000 days; kepler with e = 0.9 over 100 periods):

- hamrkq ``rk34q8`` with the compiled backend: warm (median of several runs),
  and its maximum true error against an independent reference;
- SciPy ``solve_ivp`` DOP853 and RK45 at the tolerance (searched) at which
  each reaches the same maximum true error; hamrkq ``rk34`` at hamrkq's tolerance;
- the peak memory of each run (traced allocations, NumPy arrays included).

Start-up: the first call in a fresh process with an empty cache (code
generation and compilation of the loop and the system), the first call of a
new system once the loop is cached, ``hamrkq run prentice2011 --no-plots`` in
a fresh process with a warm cache, and deriving + generating the numerical
functions of outer_solar_system.  Memory: resident memory above the
interpreter when every node of prentice2011 is kept, and with output thinning
up to t_end = 40 000.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq.backends.numeric import numeric_of

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import measure  # noqa: E402
import report  # noqa: E402

import hamrkq  # noqa: E402
from hamrkq.analysis.reference import hamiltonian_reference, integrate_reference  # noqa: E402
from hamrkq.backends import compiled  # noqa: E402


@dataclass
class Case:
    key: str
    problem: str
    t_end: float
    quick_t_end: float
    params: dict[str, float] = field(default_factory=dict)
    reference: str = "periodic"  # "periodic", "exact" or "grid"
    grid: int = 0  # compare on this many equally spaced times (t_eval)
    repeat: int = 5
    tol_scale: float = 1.0  # times the catalogue's atol and rtol


CASES = [
    Case("prentice2011", "prentice2011", 4000.0, 400.0),
    Case(
        "outer_solar_system",
        "outer_solar_system",
        500_000.0,
        50_000.0,
        reference="grid",
        grid=2001,
        repeat=3,
        # The reference (DOP853 at rtol 1e-13 over 500 000 days) is good to a
        # few 1e-8 AU, about hamrkq's error at the catalogue's tolerance: at
        # 100 times that tolerance the errors measured are the integrators'.
        tol_scale=100.0,
    ),
    Case(
        "kepler_e0.9", "kepler", 200 * math.pi, 20 * math.pi, params={"e": 0.9}, reference="exact"
    ),
]
SCIPY_METHODS = ("DOP853", "RK45")
#: SciPy raises any smaller rtol to this (100 eps) and warns; the search
#: shrinks atol further when the error still has to come down.
SCIPY_MIN_RTOL = 100 * float(np.finfo(float).eps)


def log(text: str) -> None:
    print(text, flush=True)


# -- one problem -------------------------------------------------------------------


class Bench:
    """Everything measured in-process on one problem."""

    def __init__(self, case: Case, quick: bool):
        self.case = case
        self.problem = hamrkq.load_problem(case.problem, **case.params)
        self.ham = self.problem.hamiltonian
        self.params = self.problem.parameter_array
        self.t0 = float(self.problem.t_span[0])
        self.t_end = case.quick_t_end if quick else case.t_end
        self.repeat = 2 if quick else case.repeat
        self.grid = np.linspace(self.t0, self.t_end, case.grid) if case.grid else None
        self.grid_reference = None
        dim, integration = self.ham.dim, self.problem.integration
        self.atol, self.rtol = (
            case.tol_scale * np.broadcast_to(np.asarray(integration.get(k, v), float), (dim,))
            for k, v in (("atol", 1e-6), ("rtol", 0.0))
        )
        self.reference_error = 0.0  # the largest estimated error of a reference used
        self.reference_method = "the exact solution" if case.reference == "exact" else ""

    # the yardstick
    def reference(self, t: np.ndarray) -> np.ndarray:
        y0 = self.problem.y0
        if self.case.reference == "exact":
            return self.problem.exact(t)
        if self.case.reference == "periodic":
            ref = hamiltonian_reference(self.problem, y0, t, t0=self.t0)
            self._note_reference(ref)
            return ref.y
        if self.grid_reference is None:
            ref = integrate_reference(
                numeric_of(self.ham).rhs, y0, self.grid, self.params, t0=self.t0
            )
            self.grid_reference = ref
            self._note_reference(ref)
            log(f"    reference: {ref.describe()}")
        assert np.array_equal(t, self.grid), "grid problems are compared on the grid"
        return self.grid_reference.y

    def _note_reference(self, ref) -> None:
        self.reference_error = max(self.reference_error, ref.estimated_error)
        self.reference_method = ref.method

    def true_error(self, t: np.ndarray, y: np.ndarray) -> float:
        return measure.max_error(y, self.reference(t))

    # hamrkq
    def solve(self, method: str = "rk34q8", backend: str = "numba", **options: Any):
        if self.grid is not None:
            options.setdefault("t_eval", self.grid)
        options.setdefault("atol", self.atol)
        options.setdefault("rtol", self.rtol)
        return hamrkq.solve(
            self.problem, t_span=(self.t0, self.t_end), method=method, backend=backend, **options
        )

    def hamrkq_row(self, method: str, backend: str = "numba", repeat: int | None = None):
        if backend == "numba":
            self.solve(method, backend)  # warm: load (or compile) the code first
        timing, sol = measure.timed(lambda: self.solve(method, backend), repeat or self.repeat)
        peak = measure.traced_peak(lambda: self.solve(method, backend))
        row = {
            "integrator": f"hamrkq {method} ({backend})",
            "tolerance": float(np.max(sol.atol)),
            "max_true_error": self.true_error(sol.t, sol.y),
            "nodes": len(sol),
            "steps": sol.stats["steps"],
            "nfev": sol.stats["nfev"],
            "seconds": timing.median,
            "spread": timing.spread,
            "runs": len(timing.seconds),
            "memory_mb": peak,
            "energy_drift": float(np.max(np.abs(sol.energy - sol.energy[0]))),
            "status": sol.status.name,
            "t_last": float(sol.t[-1]),
        }
        if sol.global_error is not None:
            row["max_estimated_error"] = float(np.max(np.abs(sol.global_error)))
            row["quenches"] = sol.stats["quenches"]
        return row

    # SciPy
    def scipy_rhs(self, kind: str = "compiled"):
        """f for SciPy: ``"compiled"``, the compiled generated rhs (the fastest
        f there is, so SciPy's time is its own loop), or ``"python"``,
        ``numeric_of(ham).rhs`` (an interpreted f, as a SciPy user would write)."""
        params, dim = self.params, self.ham.dim
        if kind == "python":
            numeric = numeric_of(self.ham)
            return lambda t, y: numeric.rhs(t, y, params)
        system = compiled.compile_system(self.ham)

        def fun(t, y):
            out = np.empty(dim)
            system.rhs(t, np.require(y, np.float64, "CW"), params, out)
            return out

        return fun

    def scipy(self, method: str, s: float, f: str = "compiled"):
        from scipy.integrate import solve_ivp

        shape = self.atol / np.max(self.atol)  # keep the problem's per-component floors
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rtol below 100 eps is raised, and said
            return solve_ivp(
                self.scipy_rhs(f),
                (self.t0, self.t_end),
                self.problem.y0,
                method=method,
                rtol=max(s, SCIPY_MIN_RTOL),
                atol=s * shape,
                t_eval=self.grid,
            )

    def scipy_row(self, method: str, target: float):
        def error_at(s: float) -> float:
            sol = self.scipy(method, s)
            err = self.true_error(sol.t, sol.y.T) if sol.success else math.inf
            log(f"    {method} tol {s:.3g}: error {err:.3g} ({sol.t.size} nodes)")
            return err

        match = measure.match_tolerance(error_at, target, start=target * 1e-3)
        repeat = min(self.repeat, 3)
        timing, sol = measure.timed(lambda: self.scipy(method, match.tolerance), repeat)
        peak = measure.traced_peak(lambda: self.scipy(method, match.tolerance))
        return {
            "integrator": f"SciPy {method}",
            "tolerance": match.tolerance,
            "max_true_error": match.error,
            "matched": match.converged,
            "nodes": int(sol.t.size),
            "steps": int(sol.t.size - 1) if self.grid is None else None,
            "nfev": int(sol.nfev),
            "seconds": timing.median,
            "spread": timing.spread,
            "runs": len(timing.seconds),
            "memory_mb": peak,
            "search": match.tries,
        }

    def scipy_python_f_row(self, matched: dict) -> dict:
        """The same SciPy run with an interpreted f (same tolerance, same nodes)."""
        method = matched["integrator"].split()[-1]
        s = matched["tolerance"]
        timing, sol = measure.timed(lambda: self.scipy(method, s, "python"), min(self.repeat, 3))
        return {
            **matched,
            "integrator": f"SciPy {method}, f in Python",
            "nodes": int(sol.t.size),
            "nfev": int(sol.nfev),
            "seconds": timing.median,
            "spread": timing.spread,
            "runs": len(timing.seconds),
        }

    def rows(self, skip_rk45: bool, python_backend: bool) -> list[dict]:
        log(f"== {self.case.key}: t in [{self.t0:g}, {self.t_end:g}]")
        rows = [self.hamrkq_row("rk34q8")]
        log(
            f"    hamrkq rk34q8: {rows[0]['seconds']:.3f} s, error {rows[0]['max_true_error']:.3g}"
        )
        target = rows[0]["max_true_error"]
        for method in SCIPY_METHODS:
            if method == "RK45" and skip_rk45:
                continue
            rows.append(self.scipy_row(method, target))
            log(f"    SciPy {method}: {rows[-1]['seconds']:.3f} s")
            if method == "DOP853":
                rows.append(self.scipy_python_f_row(rows[-1]))
                log(f"    SciPy {method}, f in Python: {rows[-1]['seconds']:.3f} s")
        rows.append(self.hamrkq_row("rk34"))
        if python_backend:
            rows.append(self.hamrkq_row("rk34q8", backend="python", repeat=1))
            log(f"    interpreted: {rows[-1]['seconds']:.1f} s")
        for row in rows:
            row["ratio"] = row["seconds"] / rows[0]["seconds"]
        return rows


# -- fresh processes -----------------------------------------------------------------

SOLVE_SCRIPT = """
import json, time
t0 = time.perf_counter()
import hamrkq
from hamrkq.backends import compiled
imported = time.perf_counter() - t0
problem = hamrkq.load_problem({name!r}, **{params!r})
t1 = time.perf_counter()
sol = hamrkq.solve(problem, t_span=(problem.t_span[0], {t_end!r}), backend="numba")
print(json.dumps({{"import": imported, "solve": time.perf_counter() - t1,
                  "compiled": compiled.COMPILE_COUNT, "nodes": len(sol)}}))
"""

DERIVE_SCRIPT = """
import json, time
import hamrkq
from hamrkq.backends import codegen
from hamrkq.backends.numeric import numeric_of
t0 = time.perf_counter()
problem = hamrkq.load_problem("outer_solar_system")
t1 = time.perf_counter()
ham = problem.hamiltonian
ham.rhs, ham.jacobian
t2 = time.perf_counter()
numeric_of(ham)
t3 = time.perf_counter()
source = codegen.generate_source(ham)
t4 = time.perf_counter()
print(json.dumps({"parse": t1 - t0, "derive": t2 - t1, "numeric": t3 - t2,
                  "codegen": t4 - t3, "lines": source.count("\\n")}))
"""

MEMORY_SCRIPT = """
import numpy as np
import hamrkq
problem = hamrkq.load_problem("prentice2011")
hamrkq.solve(problem, t_span=(0.0, 1.0), backend="numba")  # load the compiled code
t_end, thin, keep = {t_end!r}, {thin!r}, {keep!r}
if t_end:
    options = {{"t_eval": np.linspace(0.0, t_end, thin)}} if thin else {{"keep_every": keep}}
    # gamma_limit=inf: past t ~ 30 000 the RK8 track's own estimated error
    # passes 5 % of atol and the run would stop (docs/algorithm.md); here the
    # point is memory over the whole span.
    sol = hamrkq.solve(problem, t_span=(0.0, t_end), backend="numba", gamma_limit=float("inf"),
                       **options)
    EXTRA = {{"nodes": len(sol), "steps": sol.stats["steps"], "t_last": float(sol.t[-1]),
             "status": sol.status.name}}
"""


def startup(cases: list[Bench], quick: bool) -> dict[str, Any]:
    """First calls, a fresh process with a warm cache, derive + generate."""
    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="hamrkq-bench-") as tmp:
        cold = Path(tmp) / "cold"
        for bench in cases:
            code = SOLVE_SCRIPT.format(
                name=bench.case.problem, params=bench.case.params, t_end=bench.t_end
            )
            if bench is cases[0]:
                wall, info = measure.python(code, cache=cold)
                results["cold_first_call"] = {"wall": wall, **info}
                log(f"  first call, empty cache: solve {info['solve']:.2f} s, wall {wall:.2f} s")
                continue
            # A cache holding the compiled loop but not this system.
            loop_only = Path(tmp) / f"loop-{bench.case.key}"
            shutil.copytree(
                cold,
                loop_only,
                ignore=lambda d, names: [
                    n for n in names if n.startswith("hamrkq_gen_") and "kernel" not in n
                ],
            )
            wall, info = measure.python(code, cache=loop_only)
            results[f"new_system_{bench.case.key}"] = {"wall": wall, **info}
            log(f"  first call of {bench.case.key} (loop cached): solve {info['solve']:.2f} s")
        walls = []
        for _ in range(1 if quick else 3):
            out = Path(tmp) / f"run-{len(walls)}"
            walls.append(
                measure.command(
                    [
                        sys.executable,
                        "-m",
                        "hamrkq",
                        "run",
                        "prentice2011",
                        "--no-plots",
                        "--out",
                        str(out),
                    ],
                    cache=cold,
                )
            )
        results["cli_warm_cache"] = {"walls": walls, "median": float(np.median(walls))}
        log(f"  hamrkq run prentice2011 --no-plots, warm cache: {np.median(walls):.2f} s wall")
        _, info = measure.python(DERIVE_SCRIPT)
        results["derive_generate_outer_solar_system"] = info
        log(f"  derive + generate outer_solar_system: {info}")
        results["memory"] = memory(cold, quick)
    return results


def memory(cache: Path, quick: bool) -> dict[str, Any]:
    """Peak resident memory above an interpreter that loaded the same code."""

    def rss(t_end=0.0, thin=0, keep=1):
        code = MEMORY_SCRIPT.format(t_end=t_end, thin=thin, keep=keep) + measure.RSS_TAIL
        return measure.python(code, cache=cache)[1]

    base = rss()["peak_rss_mb"]
    runs = {}
    scale = 0.1 if quick else 1.0
    for label, kwargs in [
        ("keep every node, t_end = 4000", {"t_end": 4000.0 * scale}),
        ("t_eval of 2001 times, t_end = 4000", {"t_end": 4000.0 * scale, "thin": 2001}),
        ("t_eval of 2001 times, t_end = 40000", {"t_end": 40000.0 * scale, "thin": 2001}),
        ("keep_every = 100, t_end = 40000", {"t_end": 40000.0 * scale, "keep": 100}),
    ]:
        info = rss(**kwargs)
        runs[label] = {"above_interpreter_mb": info["peak_rss_mb"] - base, **info}
        log(f"  memory, {label}: {runs[label]['above_interpreter_mb']:.1f} MB")
    return {"interpreter_mb": base, "runs": runs}


# -- main ----------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short spans (checks the script)")
    parser.add_argument("--skip-rk45", action="store_true", help="leave out SciPy RK45 (slow)")
    parser.add_argument(
        "--skip-python",
        action="store_true",
        help="leave out the interpreted backend on prentice2011",
    )
    parser.add_argument("--output", type=Path, default=HERE / "README.md")
    args = parser.parse_args(argv)

    ok, reason = compiled.available()
    if not ok:
        print(f"the compiled backend is not available: {reason}", file=sys.stderr)
        return 2
    results: dict[str, Any] = {"machine": measure.machine(), "quick": args.quick, "cases": {}}
    log(f"machine: {results['machine']}")
    benches = [Bench(case, args.quick) for case in CASES]
    log("== start-up and memory (fresh processes)")
    results["startup"] = startup(benches, args.quick)
    for bench in benches:
        python_backend = bench.case.key == "prentice2011" and not args.skip_python
        results["cases"][bench.case.key] = {
            "t_span": [bench.t0, bench.t_end],
            "rows": bench.rows(args.skip_rk45, python_backend),
            "reference": bench.reference_method,
            "reference_error": bench.reference_error,
            "tol_scale": bench.case.tol_scale,
        }
    results["machine"]["load_average_end"] = measure.machine()["load_average"]
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.with_name("results.json").write_text(json.dumps(results, indent=1, default=str))
    args.output.write_text(report.readme(results))
    log(f"wrote {args.output} and {args.output.with_name('results.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
