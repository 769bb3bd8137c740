"""10 000 periods of the pendulum: the baselines' energy, rk34's drift, RKQ's reach.

    python benchmarks/pendulum_long.py [--skip-fixed] [--skip-rkq]

The pendulum of the catalogue (H = p^2/2 - cos q, q0 = 0, p0 = 1, period
4 K(1/4) = 6.7430...) over t in [0, 10 000 periods] = [0, 67 430]:

1. the fixed-step methods at the steps of ``tests/test_symplectic.py``
   (``DRIFT_STEPS``, every 7th node kept, as the test keeps them), and
   classical RK4 at h = 0.2 as a non-symplectic foil: steps, f evaluations,
   Newton iterations a step, max abs(H - H0) over the kept nodes, the fitted
   change of H over the run (slope times the run's length) and the scatter
   of the residuals about that line (their standard deviation), the largest
   energy error in the last tenth of the run over that in the first tenth,
   and the time; this is ``docs/baselines.md``'s table;
2. ``rk34`` at atol 1e-4 (every 7th node), as ``tests/test_baselines.py``
   runs it: the same drift and scatter;
3. ``rk34q8`` and ``auto`` at atol 1e-3 and 1e-4 over the whole interval,
   every node kept: status, where the run ended, f evaluations of the run
   returned and of the runs ``auto`` made and discarded
   (``stats["discarded_evaluations"]``; ``hamrkq compare`` counts both), the
   member and quencher steps ``auto`` ran, and the max true error against
   the exact solution at the nodes.  Each of these methods runs once over
   one period before, untimed, so that no time includes compiling.

The drift and scatter are those of ``tests/test_symplectic.py``'s
``drift_and_scatter``.  Writes ``benchmarks/pendulum_long.txt``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

import hamrkq
from hamrkq.fixed_step.symplectic import solve_fixed

HERE = Path(__file__).resolve().parent
PERIOD = 6.743001419250385  # 4 K(1/4)
T_END = 10_000 * PERIOD
#: tests/test_symplectic.py's DRIFT_STEPS
STEPS = {"verlet": 0.25, "yoshida4": 0.5, "midpoint": 0.5, "gauss4": 1.0, "gauss6": 1.25}
KEEP = 7


def drift_and_scatter(t: np.ndarray, energy: np.ndarray) -> tuple[float, float]:
    """Fitted change of H over the run (slope * T_END) and the residuals' std."""
    err = energy - energy[0]
    slope, intercept = np.polyfit(t, err, 1)
    return slope * T_END, float(np.std(err - (slope * t + intercept)))


def rk4_energy(h: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Classical RK4 on the pendulum, every KEEP-th node's t and H; steps."""
    steps = int(T_END / h)
    y = np.array([0.0, 1.0])
    ts, hs = [0.0], [0.5 * y[1] ** 2 - np.cos(y[0])]

    def f(y):
        return np.array([y[1], -np.sin(y[0])])

    for i in range(1, steps + 1):
        k1 = f(y)
        k2 = f(y + 0.5 * h * k1)
        k3 = f(y + 0.5 * h * k2)
        k4 = f(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if i % KEEP == 0:
            ts.append(i * h)
            hs.append(0.5 * y[1] ** 2 - np.cos(y[0]))
    return np.array(ts), np.array(hs), steps


def tenths(energy: np.ndarray) -> float:
    """The largest energy error in the last tenth over that in the first."""
    err = np.abs(energy - energy[0])
    tenth = err.size // 10
    return float(err[-tenth:].max() / err[:tenth].max())


def fixed_rows(problem) -> list[str]:
    rows = [
        "| method | h | steps | nfev | Newton it./step | max abs(H - H0) | fitted drift "
        "| scatter | drift / scatter | last tenth / first tenth | time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method, h in STEPS.items():
        started = time.perf_counter()
        sol = solve_fixed(problem.hamiltonian, problem.y0, (0.0, T_END), method, h,
                          keep_every=KEEP)  # fmt: skip
        seconds = time.perf_counter() - started
        steps = sol.stats["steps"]
        newton = sol.stats.get("newton_iterations")
        per_step = f"{newton / steps:.1f}" if newton else "-"
        drift, scatter = drift_and_scatter(sol.t, sol.energy)
        largest = np.abs(sol.energy - sol.energy[0]).max()
        rows.append(f"| {method} | {h} | {steps} | {sol.nfev} | {per_step} "
                    f"| {largest:.1e} | {drift:.1e} | {scatter:.1e} | {drift / scatter:.1e} "
                    f"| {tenths(sol.energy):.2f} | {seconds:.1f} |")  # fmt: skip
        print(rows[-1], flush=True)
    started = time.perf_counter()
    t, energy, steps = rk4_energy(0.2)
    seconds = time.perf_counter() - started
    drift, scatter = drift_and_scatter(t, energy)
    largest = np.abs(energy - energy[0]).max()
    rows.append(f"| RK4 (foil, not symplectic; NumPy loop) | 0.2 | {steps} | {4 * steps} | - "
                f"| {largest:.1e} | {drift:.1e} | {scatter:.1e} | {drift / scatter:.1e} "
                f"| {tenths(energy):.2f} | {seconds:.1f} |")  # fmt: skip
    print(rows[-1], flush=True)
    return rows


def warm(problem) -> None:
    """Each hamrkq method once over one period, untimed: a first call's
    compile (or cache load) is not in the times below."""
    for method in ("rk34", "rk34q8", "auto"):
        hamrkq.solve(problem, method=method, t_span=(0.0, PERIOD), atol=1e-4)


def rk34_rows(problem) -> list[str]:
    started = time.perf_counter()
    sol = hamrkq.solve(problem, method="rk34", t_span=(0.0, T_END), atol=1e-4, keep_every=KEEP)
    seconds = time.perf_counter() - started
    drift, scatter = drift_and_scatter(sol.t, sol.energy)
    err = np.abs(sol.energy - sol.energy[0])
    return [
        f"rk34, atol 1e-4, every {KEEP}th node: {sol.status.name}, {sol.stats['steps']} steps, "
        f"{sol.nfev} f evaluations, {seconds:.1f} s; fitted change of H {drift:.3g}, "
        f"scatter {scatter:.2g} ({abs(drift) / scatter:.0f} times); max abs(H - H0) "
        f"{err.max():.2g}; largest error in the last tenth / first tenth "
        f"{tenths(sol.energy):.1f}",
    ]


def rkq_rows(problem) -> list[str]:
    rows = [
        "| method | atol | status | reached t | periods | f evaluations (run returned) "
        "| discarded runs' | in all | ran | quencher steps a step | max true error | time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method in ("rk34q8", "auto"):
        for atol in (1e-3, 1e-4):
            started = time.perf_counter()
            sol = hamrkq.solve(problem, method=method, t_span=(0.0, T_END), atol=atol)
            seconds = time.perf_counter() - started
            error = np.abs(sol.y - problem.exact(sol.t)).max()
            discarded = sol.stats.get("discarded_evaluations", 0)
            ran = sol.options["method"]
            substeps = sol.options.get("z_substeps", "-")
            rows.append(f"| {method} | {atol:g} | {sol.status.name} | {sol.t[-1]:.0f} "
                        f"| {sol.t[-1] / PERIOD:.0f} | {sol.nfev} | {discarded} "
                        f"| {sol.nfev + discarded} | {ran} | {substeps} "
                        f"| {error:.3g} | {seconds:.1f} |")  # fmt: skip
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--skip-fixed", action="store_true")
    parser.add_argument("--skip-rkq", action="store_true")
    args = parser.parse_args()
    problem = hamrkq.load_problem("pendulum")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False, cwd=HERE).stdout.strip()  # fmt: skip
    lines = [
        "# The pendulum over 10 000 periods (generated by `benchmarks/pendulum_long.py`)",
        "",
        f"Run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} at commit {commit}; "
        f"{platform.machine()}, {os.cpu_count()} cores; load average at the start "
        f"{[round(x, 2) for x in os.getloadavg()]}.  t in [0, {T_END:.1f}].",
        "",
    ]
    if not args.skip_fixed:
        lines += ["## Fixed steps (every 7th node kept)", "", *fixed_rows(problem), ""]
    if not args.skip_rkq:
        warm(problem)
        lines += ["## rk34 (no global-error control)", "", *rk34_rows(problem), ""]
        lines += ["## RKQ, every node kept", "", *rkq_rows(problem), ""]
    lines.append(f"Load average at the end {[round(x, 2) for x in os.getloadavg()]}.")
    text = "\n".join(lines) + "\n"
    (HERE / "pendulum_long.txt").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
