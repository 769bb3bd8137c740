"""Work-precision of every RKQ family member beside SciPy's DOP853, in one run.

The paper's problem, prentice2011 over [0, 4000], compared on 401 equally
spaced times (``t_eval``).  For each member (and ``auto``) at absolute
tolerances 1e-5 to 1e-9, and for SciPy's DOP853 at tolerances 1e-7 to 1e-13
(``rtol = atol``, the right-hand side hamrkq's compiled one, so that SciPy's
own step loop is what is timed): the max true error over the 401 times, the
evaluations (``f`` plus Jacobian products, and ``auto``'s discarded first
run), and the integration time, median of three warm runs (compilation
excluded).  Runs that stop early (``TOLERANCE_UNATTAINABLE``) are left out of
the lines and counted in the table.

The truth is the long-double Taylor reference of ``extended_reference.py``
(heyoka, the ``bench`` extra): 2.2e-14 from quad precision over this interval
(``extended_reference_accuracy.txt``).

Run: ``python benchmarks/work_precision.py`` (``--from-json`` redraws the
table and figure from the last run); writes ``work_precision.json``,
``work_precision.md`` and ``work_precision.png`` beside this file, and the
summary table (``auto`` beside SciPy) into docs/algorithm.md between its
``work-precision`` markers.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
import warnings
from pathlib import Path

import extended_reference
import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np

import hamrkq
from hamrkq.backends import compiled
from hamrkq.rkq.family import MEMBERS

HERE = Path(__file__).resolve().parent
SPAN = (0.0, 4000.0)
MEMBER_TOLS = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
SCIPY_TOLS = (1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)
REPEAT = 3


def hamrkq_point(problem, method: str, tol: float, grid, truth) -> dict:
    runs = [
        hamrkq.solve(problem, method=method, atol=tol, rtol=0.0, t_span=SPAN, t_eval=grid)
        for _ in range(REPEAT)
    ]
    sol = runs[-1]
    n = sol.t.size
    return {
        "integrator": f"hamrkq {method}",
        "method": sol.method,
        "tol": tol,
        "status": sol.status.name,
        "error": float(np.abs(sol.y - truth[:n]).max()),
        "evaluations": sol.stats["nfev"]
        + sol.stats["njev"]
        + sol.stats.get("discarded_evaluations", 0),
        "seconds": statistics.median(r.stats["integrate_s"] for r in runs),
    }


def scipy_point(problem, tol: float, grid, truth) -> dict:
    from scipy.integrate import solve_ivp

    system = compiled.compile_system(problem.hamiltonian)
    params, dim = problem.parameter_array, problem.hamiltonian.dim

    def fun(t, y):
        out = np.empty(dim)
        system.rhs(t, np.require(y, np.float64, "CW"), params, out)
        return out

    times, sol = [], None
    for _ in range(REPEAT):
        start = time.perf_counter()
        sol = solve_ivp(fun, SPAN, problem.y0, method="DOP853", rtol=tol, atol=tol, t_eval=grid)
        times.append(time.perf_counter() - start)
    return {
        "integrator": "SciPy DOP853",
        "method": "scipy:DOP853",
        "tol": tol,
        "status": "SUCCESS" if sol.success else "FAILED",
        "error": float(np.abs(sol.y.T - truth).max()),
        "evaluations": int(sol.nfev),
        "seconds": statistics.median(times),
    }


def figure(points: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), sharex=True)
    names = list(dict.fromkeys(p["integrator"] for p in points))
    cmap = plt.get_cmap("tab20")
    for k, name in enumerate(names):
        pts = sorted(
            (p["error"], p["seconds"], p["evaluations"])
            for p in points
            if p["integrator"] == name and p["status"] == "SUCCESS"
        )
        if not pts:
            continue
        err, sec, ev = zip(*pts, strict=True)
        if name == "SciPy DOP853":
            style = {"color": "k", "lw": 2.5, "marker": "s"}
        elif name == "hamrkq auto":
            style = {"color": "crimson", "lw": 2.5, "marker": "*", "ms": 10}
        elif name == "hamrkq rk34q8":
            style = {"color": "0.4", "lw": 2, "marker": "o", "ls": "--"}
        else:
            style = {"color": cmap(k % 20), "lw": 1, "marker": ".", "alpha": 0.8}
        axes[0].loglog(err, sec, label=name, **style)
        axes[1].loglog(err, ev, label=name, **style)
    axes[0].set_ylabel("integration time (s, median of 3; compile excluded)")
    axes[1].set_ylabel("evaluations (f + Jacobian products)")
    for ax in axes:
        ax.set_xlabel("max true error over 401 times (long-double reference)")
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2, loc="upper right")
    fig.suptitle(
        "prentice2011, t in [0, 4000]: every RKQ member (atol 1e-5..1e-9) "
        "beside SciPy DOP853 (tol 1e-7..1e-13); runs that stopped early are left out",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summary(points: list[dict]) -> list[str]:
    """``auto`` at each tolerance beside the cheapest SciPy run at least as accurate."""
    lines = [
        "| auto atol | auto max error | auto time (s) | auto evaluations | "
        "SciPy DOP853 tol reaching it | its time (s) | its evaluations | time ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    scipy = [p for p in points if p["integrator"] == "SciPy DOP853"]
    for p in points:
        if p["integrator"] != "hamrkq auto" or p["status"] != "SUCCESS":
            continue
        good = [q for q in scipy if q["error"] <= p["error"]]
        if good:
            q = min(good, key=lambda q: q["seconds"])
            peer = f"{q['tol']:g} | {q['seconds']:.3f} | {q['evaluations']} | "
            peer += f"{q['seconds'] / p['seconds']:.0f}"
        else:
            best = min(scipy, key=lambda q: q["error"])
            peer = f"none (tightest, {best['tol']:g}, reaches {best['error']:.2e}) | - | - | -"
        lines.append(
            f"| {p['tol']:g} | {p['error']:.2e} | {p['seconds']:.3f} | {p['evaluations']} | "
            + peer
            + " |"
        )
    return lines


def markdown(points: list[dict]) -> str:
    lines = [
        *summary(points),
        "",
        "Every run:",
        "",
        *[
            "| integrator | member | tol | status | max true error | evaluations | time (s) |",
            "|---|---|---|---|---|---|---|",
        ],
    ]
    for p in points:
        lines.append(
            f"| {p['integrator']} | {p['method']} | {p['tol']:g} | {p['status']} | "
            f"{p['error']:.2e} | {p['evaluations']} | {p['seconds']:.3f} |"
        )
    return "\n".join(lines) + "\n"


DOCS = HERE.parent / "docs" / "algorithm.md"
BEGIN, END = "<!-- work-precision:begin -->", "<!-- work-precision:end -->"


def write(points: list[dict]) -> None:
    """The table, the figure, and the summary into docs/algorithm.md."""
    (HERE / "work_precision.md").write_text(markdown(points))
    figure(points, HERE / "work_precision.png")
    text = DOCS.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOCS.write_text(head + BEGIN + "\n" + "\n".join(summary(points)) + "\n" + END + tail)


def main() -> None:
    if "--from-json" in sys.argv:  # only rewrite the tables and the figure
        write(json.loads((HERE / "work_precision.json").read_text()))
        return
    warnings.simplefilter("ignore")
    problem = hamrkq.load_problem("prentice2011")
    grid = np.linspace(*SPAN, 401)
    truth = extended_reference.reference(problem, grid)
    hamrkq.solve(problem, t_span=(0.0, 1e-3))  # compile outside the timings
    points = []
    for method in ["auto", *[m for m in MEMBERS if m != "rk34"]]:
        for tol in MEMBER_TOLS:
            points.append(hamrkq_point(problem, method, tol, grid, truth))
            print(json.dumps(points[-1]), flush=True)
    for tol in SCIPY_TOLS:
        points.append(scipy_point(problem, tol, grid, truth))
        print(json.dumps(points[-1]), flush=True)
    (HERE / "work_precision.json").write_text(json.dumps(points, indent=1) + "\n")
    write(points)


if __name__ == "__main__":
    main()
