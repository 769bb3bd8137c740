"""hamrkq beside heyoka and SciPy's DOP853 at matched true error, in one run.

    python benchmarks/peers.py                        # rk34q8, every case (~15 min)
    python benchmarks/peers.py --methods rk34q8 rk45q12
    python benchmarks/peers.py --quick                # short spans: checks the script
    python benchmarks/peers.py --cases prentice2011_1e-6 kepler_e0.9

Needs the ``bench`` extra (``pip install hamrkq[bench]``: heyoka).  Writes
``benchmarks/peers.json`` (every number, every tolerance tried),
``benchmarks/peers.md`` (the table) and ``benchmarks/peers.png`` (the
work-precision figure: time against max true error); ``docs/performance.md``
copies the table from ``peers.md``.

For every case:

1. **Reference.**  The catalogue's exact solution where it has one (kepler);
   otherwise heyoka's Taylor integrator at tolerance 1e-15, evaluated (dense
   output) at exactly the times each integrator reports.  Its own error is
   estimated by the same run in extended precision (``long double``, tol
   1e-18) on a grid of 2001 times, and reported.
2. **hamrkq**, every method given with ``--methods``, compiled backend: the
   first call (which may compile) is timed apart; the time reported is the
   median of ``--repeat`` warm calls.  Max true error: largest absolute error
   of any component at any node (at the 2001 output times ``t_eval`` on the
   grid cases).  The first method given is the one the others are matched to;
   each method is also run at 10 times and 1/10 of the case's tolerance for
   the figure.
3. **heyoka** (``taylor_adaptive``, LLVM-compiled Taylor series): the
   tolerance is searched (:func:`measure.match_tolerance`) so that its max
   true error matches hamrkq's; each tolerance needs a new integrator, whose
   construction (code generation and LLVM compilation) is timed apart.  The
   time reported is ``propagate_grid`` over the comparison grid (2001 times,
   or 20 001 on the cases compared at hamrkq's nodes), median of repeats.
4. **SciPy DOP853**: matched the same way; once with hamrkq's compiled rhs as
   ``f`` (its own step loop is then what is timed) and once with
   ``numeric_of(ham).rhs``, interpreted Python (how a SciPy user calls it).

Ratios, not absolute times, are the claim: the machine is shared.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402

import hamrkq  # noqa: E402
from hamrkq.backends import compiled  # noqa: E402
from hamrkq.backends.numeric import numeric_of  # noqa: E402

SCIPY_MIN_RTOL = 100 * np.finfo(float).eps


@dataclass
class Case:
    key: str
    problem: str
    t_end: float
    quick_t_end: float
    params: dict[str, float] = field(default_factory=dict)
    tol: float | None = None  # replaces the catalogue's atol (rtol 0)
    tol_scale: float = 1.0  # else: times the catalogue's atol and rtol
    grid: bool = False  # compare on 2001 equally spaced times (t_eval)
    repeat: int = 5


CASES = [
    Case("prentice2011_1e-6", "prentice2011", 4000.0, 400.0, tol=1e-6),
    Case("prentice2011_1e-9", "prentice2011", 4000.0, 400.0, tol=1e-9),
    Case("kepler_e0.9", "kepler", 20 * math.pi, 4 * math.pi, params={"e": 0.9}),
    Case("outer_solar_system", "outer_solar_system", 500_000.0, 50_000.0, tol_scale=100.0),
    # The same run asked for 2001 output times: hamrkq's steps are clipped to
    # land on them (about twice the steps), heyoka's dense output is nearly free.
    Case(
        "outer_solar_system_grid",
        "outer_solar_system",
        500_000.0,
        50_000.0,
        tol_scale=100.0,
        grid=True,
        repeat=3,
    ),
    Case("fpu", "fpu", 200.0, 20.0, repeat=3),
]


def log(text: str) -> None:
    print(text, flush=True)


# -- heyoka ------------------------------------------------------------------------


def heyoka_system(ham, params: np.ndarray):
    """Hamilton's equations of ``ham`` as heyoka expressions, parameter values
    substituted (see :func:`to_heyoka`)."""
    import heyoka as hy

    variables = hy.make_vars(*[f"y{k}" for k in range(ham.dim)])
    mapping = {s: x for s, x in zip(ham.state, variables, strict=True)}
    mapping[ham.t] = hy.time
    mapping.update(
        {s: hy.expression(float(v)) for s, v in zip(ham.parameters, params, strict=True)}
    )
    return [(x, to_heyoka(f, mapping)) for x, f in zip(variables, ham.rhs, strict=True)]


def to_heyoka(expr, mapping):
    """A SymPy expression as a heyoka expression.

    Not :func:`heyoka.from_sympy`: it turns ``x**3`` into ``pow(x, 3.0)``, whose
    Taylor recursion divides by ``x`` and gives NaN where ``x = 0`` (the FPU
    chain at t = 0), and it refuses rationals such as 1/6.  Here integer
    powers are products (or their reciprocals), other powers ``pow``.
    """
    import heyoka as hy
    import sympy as sp

    def convert(e):
        if e in mapping:
            return mapping[e]
        if e.is_Number or e in (sp.pi, sp.E):
            return hy.expression(float(e))
        if e.is_Add:
            return hy.sum([convert(a) for a in e.args])
        if e.is_Mul:
            return hy.prod([convert(a) for a in e.args])
        if e.is_Pow:
            base = convert(e.base)
            if e.exp.is_Integer and 0 < abs(int(e.exp)) <= 8:
                product = hy.prod([base] * abs(int(e.exp))) if abs(int(e.exp)) > 1 else base
                return product if e.exp > 0 else 1.0 / product
            if e.exp == sp.S.Half:
                return hy.sqrt(base)
            exponent = float(e.exp) if e.exp.is_Number else convert(e.exp)
            return base**exponent
        functions = {sp.sin: hy.sin, sp.cos: hy.cos, sp.tan: hy.tan, sp.exp: hy.exp,
                     sp.log: hy.log, sp.sinh: hy.sinh, sp.cosh: hy.cosh, sp.tanh: hy.tanh,
                     sp.asin: hy.asin, sp.acos: hy.acos, sp.atan: hy.atan}  # fmt: skip
        if e.func in functions:
            return functions[e.func](convert(e.args[0]))
        raise ValueError(f"no heyoka counterpart for {e.func.__name__}")

    return convert(expr)  # a SymPy expression already: nothing is parsed


class Heyoka:
    """Integrators of one system at several tolerances; the construction
    (LLVM compilation) is timed apart from the propagation."""

    def __init__(self, ham, params, t0: float, y0: np.ndarray):
        self.system = heyoka_system(ham, params)
        self.t0, self.y0 = t0, np.asarray(y0, dtype=float)
        self.built: dict[tuple, Any] = {}
        self.compile_seconds: dict[float, float] = {}

    def integrator(self, tol: float, fp_type=float):
        import heyoka as hy

        key = (tol, fp_type)
        if key not in self.built:
            started = time.perf_counter()
            ta = hy.taylor_adaptive(
                self.system, np.asarray(self.y0, dtype=fp_type), tol=fp_type(tol),
                time=fp_type(self.t0), fp_type=fp_type, compact_mode=len(self.y0) > 24,
            )  # fmt: skip
            self.compile_seconds[tol] = time.perf_counter() - started
            self.built[key] = ta
        return self.built[key]

    def grid(self, tol: float, t: np.ndarray, fp_type=float) -> np.ndarray:
        """States at the increasing times ``t`` (the first may equal t0)."""
        ta = self.integrator(tol, fp_type)
        ta.time = fp_type(self.t0)
        ta.state[:] = np.asarray(self.y0, dtype=fp_type)
        times = np.asarray(t, dtype=fp_type)
        prepend = times[0] != self.t0
        if prepend:
            times = np.concatenate([[fp_type(self.t0)], times])
        result = ta.propagate_grid(times)
        states = np.asarray(result[-1], dtype=float)
        if not str(result[0]).endswith(("time_limit", "success")):
            raise RuntimeError(f"heyoka stopped: {result[0]}")
        return states[1:] if prepend else states


# -- one case ----------------------------------------------------------------------


class Bench:
    def __init__(self, case: Case, quick: bool, repeat: int | None):
        self.case = case
        self.problem = hamrkq.load_problem(case.problem, **case.params)
        self.ham = self.problem.hamiltonian
        self.params = np.array(self.problem.parameter_array, dtype=float)
        self.y0 = np.array(self.problem.y0, dtype=float)
        self.t0 = float(self.problem.t_span[0])
        self.t_end = case.quick_t_end if quick else case.t_end
        self.repeat = repeat or (2 if quick else case.repeat)
        dim, integration = self.ham.dim, self.problem.integration
        if case.tol is not None:
            self.atol, self.rtol = np.full(dim, case.tol), np.zeros(dim)
        else:
            self.atol, self.rtol = (
                case.tol_scale * np.broadcast_to(np.asarray(integration.get(k, v), float), (dim,))
                for k, v in (("atol", 1e-6), ("rtol", 0.0))
            )
        self.grid = np.linspace(self.t0, self.t_end, 2001) if case.grid else None
        # heyoka's output grid when hamrkq is compared at its own nodes.
        self.heyoka_grid = self.grid if case.grid else np.linspace(self.t0, self.t_end, 20001)
        self.heyoka = Heyoka(self.ham, self.params, self.t0, self.y0)
        self.exact = self.problem.exact
        self.reference_note = ""

    # the yardstick
    def reference(self, t: np.ndarray) -> np.ndarray:
        if self.exact is not None:
            return self.exact(t)
        return self.heyoka.grid(1e-15, t)

    def check_reference(self) -> dict:
        if self.exact is not None:
            self.reference_note = "the exact solution (Kepler's equation)"
            return {"kind": "exact", "estimated_error": 0.0}
        t = np.linspace(self.t0, self.t_end, 2001)
        double = self.heyoka.grid(1e-15, t)
        started = time.perf_counter()
        extended = self.heyoka.grid(1e-18, t, np.longdouble)
        seconds = time.perf_counter() - started
        estimate = measure.max_error(double, extended)
        self.reference_note = (
            f"heyoka taylor_adaptive at tol 1e-15 (double); it differs from the same "
            f"integration in extended precision (long double, tol 1e-18) by at most "
            f"{estimate:.1e} on 2001 times"
        )
        return {"kind": "heyoka tol 1e-15", "estimated_error": estimate,
                "extended_seconds": seconds}  # fmt: skip

    def true_error(self, t: np.ndarray, y: np.ndarray) -> float:
        return measure.max_error(y, self.reference(t))

    # hamrkq
    def solve(self, method: str, scale: float = 1.0):
        options: dict[str, Any] = {"atol": self.atol * scale, "rtol": self.rtol * scale}
        if self.grid is not None:
            options["t_eval"] = self.grid
        return hamrkq.solve(self.problem, t_span=(self.t0, self.t_end), method=method,
                            backend="numba", **options)  # fmt: skip

    def hamrkq_row(self, method: str, scale: float = 1.0) -> dict:
        started = time.perf_counter()
        first = self.solve(method, scale)
        first_call = time.perf_counter() - started
        timing, sol = measure.timed(lambda: self.solve(method, scale), self.repeat)
        row = {
            "integrator": f"hamrkq {method}",
            "method": method,
            "tolerance": float(np.max(sol.atol)) if np.any(sol.atol) else float(np.max(sol.rtol)),
            "tolerance_scale": scale,
            "max_true_error": self.true_error(sol.t, sol.y),
            "nodes": len(sol),
            "steps": int(sol.stats["steps"]),
            "nfev": int(sol.stats["nfev"]),
            "seconds": timing.median,
            "spread": timing.spread,
            "runs": len(timing.seconds),
            "first_call_seconds": first_call,
            "status": sol.status.name,
            "t_last": float(sol.t[-1]),
        }
        for key in ("compile_s", "integrate_s"):  # when solve reports them
            if key in first.stats:
                row[f"first_call_{key}"] = float(first.stats[key])
        if sol.global_error is not None:
            row["max_estimated_error"] = float(np.max(np.abs(sol.global_error)))
        return row

    # heyoka
    def heyoka_row(self, target: float) -> dict:
        grid = self.heyoka_grid
        timings: dict[float, float] = {}

        def error_at(tol: float) -> float:
            self.heyoka.integrator(tol)  # build (compile) outside the clock
            started = time.perf_counter()
            states = self.heyoka.grid(tol, grid)
            timings[tol] = time.perf_counter() - started
            err = self.true_error(grid, states)
            log(f"    heyoka tol {tol:.3g}: error {err:.3g} "
                f"(compiled in {self.heyoka.compile_seconds[tol]:.2f} s)")  # fmt: skip
            return err

        # heyoka's tolerance only sets the Taylor order, p = ceil(-ln(tol)/2) + 1
        # (the step size follows from the Taylor coefficients): its error is a
        # staircase in tol, and a secant search stalls on a step.  So: one
        # tolerance per order, from loose to tight, until the error is at or
        # below hamrkq's (never crediting heyoka with less accuracy).
        tries = []
        order = max(2, math.ceil(-math.log(target) / 2) - 2)
        while True:
            tol = math.exp(-2.0 * (order - 1)) * 0.99  # the loosest tol of this order
            err = error_at(tol)
            tries.append((tol, err))
            if err <= target or tol < 1e-15:
                break
            order += 1
        tol, error = tries[-1]
        # Matched when within 15 % of hamrkq's error; otherwise this is the
        # first order at or below it (heyoka is credited with more accuracy).
        matched = abs(math.log(error / target)) <= math.log1p(0.15)
        timing, _ = measure.timed(lambda: self.heyoka.grid(tol, grid), self.repeat)
        return {
            "integrator": "heyoka taylor_adaptive",
            "tolerance": tol,
            "max_true_error": error,
            "matched": matched,
            "nodes": int(grid.size),
            "seconds": timing.median,
            "spread": timing.spread,
            "runs": len(timing.seconds),
            "compile_seconds": self.heyoka.compile_seconds[tol],
            "search": [(s, e, timings.get(s)) for s, e in tries],
        }

    # SciPy
    def scipy_rhs(self, kind: str):
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

    def scipy(self, s: float, kind: str = "compiled"):
        from scipy.integrate import solve_ivp

        shape = self.atol / np.max(self.atol) if np.any(self.atol) else np.ones_like(self.atol)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rtol below 100 eps is raised, and said
            return solve_ivp(self.scipy_rhs(kind), (self.t0, self.t_end), self.y0,
                             method="DOP853", rtol=max(s, SCIPY_MIN_RTOL), atol=s * shape,
                             t_eval=self.grid)  # fmt: skip

    def scipy_rows(self, target: float) -> list[dict]:
        timings: dict[float, float] = {}

        def error_at(s: float) -> float:
            started = time.perf_counter()
            sol = self.scipy(s)
            timings[s] = time.perf_counter() - started
            err = self.true_error(sol.t, sol.y.T) if sol.success else math.inf
            log(f"    DOP853 tol {s:.3g}: error {err:.3g} ({sol.t.size} nodes)")
            return err

        match = measure.match_tolerance(error_at, target, start=target * 1e-3)
        rows = []
        for kind, label in (("compiled", "SciPy DOP853, compiled f"),
                            ("python", "SciPy DOP853, f in Python")):  # fmt: skip
            repeat = min(self.repeat, 3)
            timing, sol = measure.timed(lambda k=kind: self.scipy(match.tolerance, k), repeat)
            rows.append({
                "integrator": label,
                "tolerance": match.tolerance,
                "max_true_error": match.error,
                "matched": match.converged,
                "nodes": int(sol.t.size),
                "nfev": int(sol.nfev),
                "seconds": timing.median,
                "spread": timing.spread,
                "runs": len(timing.seconds),
                "search": [(s, e, timings.get(s)) for s, e in match.tries],
            })  # fmt: skip
        return rows

    def run(self, methods: list[str], sweep: bool) -> dict:
        log(f"== {self.case.key}: t in [{self.t0:g}, {self.t_end:g}]")
        reference = self.check_reference()
        log(f"    reference: {self.reference_note}")
        rows = []
        for method in methods:
            row = self.hamrkq_row(method)
            rows.append(row)
            log(f"    hamrkq {method}: {row['seconds']:.3g} s, error {row['max_true_error']:.3g}, "
                f"first call {row['first_call_seconds']:.2f} s")  # fmt: skip
        target = rows[0]["max_true_error"]
        rows.append(self.heyoka_row(target))
        log(f"    heyoka: {rows[-1]['seconds']:.3g} s at error {rows[-1]['max_true_error']:.3g}")
        rows += self.scipy_rows(target)
        log(f"    DOP853: {rows[-2]['seconds']:.3g} s / python f {rows[-1]['seconds']:.3g} s")
        curves = []
        if sweep:
            for method in methods:
                for scale in (10.0, 0.1):
                    curves.append(self.hamrkq_row(method, scale))
        return {
            "case": self.case.key,
            "problem": self.case.problem,
            "params": self.case.params,
            "t_span": [self.t0, self.t_end],
            "compared_on": "2001 equally spaced times" if self.grid is not None else "nodes",
            "reference": {**reference, "note": self.reference_note},
            "rows": rows,
            "sweep": curves,
        }


# -- output ------------------------------------------------------------------------


def _g(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def table(results: dict) -> str:
    lines = [
        "| case | integrator | tolerance | max true error | time (s) | ratio to "
        f"hamrkq {results['methods'][0]} | compile (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for case in results["cases"]:
        base = case["rows"][0]["seconds"]
        for row in case["rows"]:
            if row["integrator"].startswith("hamrkq"):
                compile_s = row.get("first_call_compile_s")
                compile_text = (
                    _g(compile_s) if compile_s is not None
                    else f"first call {row['first_call_seconds']:.2f}"
                )  # fmt: skip
            else:
                compile_text = _g(row.get("compile_seconds"))
            matched = "" if row.get("matched", True) else " (*)"
            lines.append(
                f"| {case['case']} | {measure.integrator_label(row)} | "
                f"{_g(row['tolerance'])}{matched} | "
                f"{_g(row['max_true_error'])} | {_g(row['seconds'])} | "
                f"{row['seconds'] / base:.3g} | {compile_text} |"
            )
    return "\n".join(lines)


def figure(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = results["cases"]
    cols = min(len(cases), 3)
    rows = math.ceil(len(cases) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False)
    styles = {
        "hamrkq": ("o", "C0"),
        "heyoka": ("s", "C1"),
        "SciPy DOP853, compiled f": ("^", "C2"),
        "SciPy DOP853, f in Python": ("v", "C3"),
    }

    method_styles = {
        f"hamrkq {m}": (marker, colour)
        for m, marker, colour in zip(
            results["methods"], "oDph*", ("C0", "C4", "C5", "C6", "C7"), strict=False
        )
    }

    def style(name: str):
        if name in method_styles:
            return method_styles[name]
        for key, value in styles.items():
            if name.startswith(key):
                return value
        return ("x", "k")

    for ax, case in zip(axes.flat, cases, strict=False):
        for row in case["rows"]:
            marker, colour = style(row["integrator"])
            ax.loglog(row["max_true_error"], row["seconds"], marker, color=colour, ms=8,
                      label=row["integrator"])  # fmt: skip
            if row.get("search") and "python" not in row["integrator"]:
                pts = sorted((e, s) for _, e, s in row["search"] if s and math.isfinite(e))
                if pts:
                    ax.loglog(*zip(*pts, strict=True), "-", marker, color=colour, alpha=0.35, ms=4)
        for method in results["methods"]:
            pts = sorted(
                (r["max_true_error"], r["seconds"])
                for r in [*case["rows"], *case["sweep"]]
                if r.get("method") == method
            )
            if len(pts) > 1:
                colour = style(f"hamrkq {method}")[1]
                ax.loglog(*zip(*pts, strict=True), "-", color=colour, alpha=0.5)
        ax.set_title(case["case"], fontsize=10)
        ax.set_xlabel("max true error")
        ax.set_ylabel("time (s)")
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(cases) :]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle(
        "Work-precision: large markers at matched error (medians); faint: "
        "tolerance search (single runs) and hamrkq at 10x and 0.1x",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0.06, 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)


FOOTNOTE = (
    "(*) no tolerance gave an error within 15 % of hamrkq's: heyoka's row is the "
    "loosest tolerance (Taylor order) whose error is at or below it, SciPy's the "
    "closest found.  heyoka's compile time is its integrator's construction "
    "(LLVM); a later construction of the same system may reuse heyoka's in-memory "
    "cache.  hamrkq's first call includes loading (or compiling) its code."
)


def markdown(results: dict) -> str:
    m = results["machine"]
    lines = [
        "# hamrkq beside heyoka and SciPy DOP853 (generated by `benchmarks/peers.py`)",
        "",
        f"Run {results['started']} to {results['finished']}"
        f"{' (--quick)' if results['quick'] else ''}; "
        f"{m['cpu']}, {m['cores']} cores; Python {m['python']}, NumPy {m['numpy']}, "
        f"SciPy {m['scipy']}, numba {m['numba']}, heyoka {results['heyoka']}.  Load average "
        f"at the start {m['load_average']}, at the end {results['load_average_end']} "
        "(a shared machine: ratios, not times).",
        "",
        table(results),
        "",
        FOOTNOTE,
        "",
        "References:",
        "",
    ]
    for case in results["cases"]:
        lines.append(f"- {case['case']} (t in {case['t_span']}, compared on "
                     f"{case['compared_on']}): {case['reference']['note']}.")  # fmt: skip
    lines += ["", "![work-precision](peers.png)", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--methods",
        nargs="+",
        default=["rk34q8"],
        help="hamrkq methods; the first is the one the peers are matched to",
    )
    parser.add_argument(
        "--cases", nargs="+", default=[c.key for c in CASES], choices=[c.key for c in CASES]
    )
    parser.add_argument("--quick", action="store_true", help="short spans, two repeats")
    parser.add_argument("--repeat", type=int, default=None)
    parser.add_argument(
        "--no-sweep", action="store_true", help="skip hamrkq at 10x and 0.1x the tolerance"
    )
    parser.add_argument("--out", type=Path, default=HERE, help="directory for the outputs")
    parser.add_argument(
        "--replot",
        action="store_true",
        help="measure nothing: redraw peers.md and peers.png from peers.json",
    )
    args = parser.parse_args(argv)  # fmt: skip
    if args.replot:
        results = json.loads((args.out / "peers.json").read_text())
        (args.out / "peers.md").write_text(markdown(results))
        figure(results, args.out / "peers.png")
        return 0
    try:
        import heyoka
    except ImportError:
        parser.error("heyoka is needed: pip install 'hamrkq[bench]'")
    results: dict[str, Any] = {
        "started": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "machine": measure.machine(),
        "heyoka": heyoka.__version__,
        "hamrkq": hamrkq.__version__,
        "methods": args.methods,
        "quick": args.quick,
        "cases": [],
    }
    for case in CASES:
        if case.key in args.cases:
            bench = Bench(case, args.quick, args.repeat)
            results["cases"].append(bench.run(args.methods, sweep=not args.no_sweep))
            _write(results, args.out)  # after every case: nothing is lost
    _write(results, args.out, final=True)
    log(table(results))
    return 0


def _write(results: dict, out: Path, final: bool = False) -> None:
    results["finished"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    results["load_average_end"] = measure.machine()["load_average"]
    out.mkdir(parents=True, exist_ok=True)
    (out / "peers.json").write_text(json.dumps(results, indent=1, default=float) + "\n")
    if final:
        (out / "peers.md").write_text(markdown(results))
        figure(results, out / "peers.png")


if __name__ == "__main__":
    sys.exit(main())
