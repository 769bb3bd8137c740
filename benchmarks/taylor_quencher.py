"""What a Taylor-series quencher would buy: a measurement, not product code.

The RKQ family's quenchers are Runge-Kutta methods of order 8 to 12, run in
``z_substeps`` steps per step of the pair, with a shadow track one step a
step for Gamma (docs/algorithm.md).  On prentice2011 a third of the run is
``sincos``: every stage evaluates ``f``.  A Taylor method evaluates the
transcendental functions once a step and gets its order from recurrences
(:mod:`hamrkq.rkq.taylor`, the tape of :mod:`hamrkq.symbolic.taylor`).

This script takes the steps of ``method="auto"`` on each case and runs
along them, side by side in one process, (1) the member's own RK quencher
in its ``z_substeps`` steps a step with its shadow (one quencher step a
step of the pair, from the initial value, never quenched), by the kernel's
own step function, and (2) a Taylor quencher of order N in m substeps a
step with its shadow, on the same compensated state (TwoSum), and reports
for each

- the quencher track's true error against the extended-precision reference
  (``extended_reference.py``);
- Gamma = (shadow - z) / (m^order - 1) against that true error (median
  ratio over the nodes where the error is above 1e-14);
- the time of the track and its shadow (compiled, median of 5), per
  quencher step, and the Taylor track's over the RK track's.

Neither track is quenched (quenching moves the pair, not the quencher), so
the comparison is like for like; the pair's own cost is left out of both.

Run: ``python benchmarks/taylor_quencher.py`` (a few minutes; heyoka, the
``bench`` extra, makes the reference).  Output: ``taylor_quencher.txt``.
"""

from __future__ import annotations

import argparse
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from extended_reference import reference
from measure import machine

import hamrkq
from hamrkq.backends.first_use import kernel_functions
from hamrkq.rkq.arith import two_sum
from hamrkq.rkq.family import get_member
from hamrkq.rkq.layout import allocate_work
from hamrkq.rkq.steps import explicit_increment
from hamrkq.rkq.taylor import taylor_coefficients, taylor_increment
from hamrkq.symbolic.taylor import taylor_tape

HERE = Path(__file__).resolve().parent


def _compile():
    import numba

    @numba.njit(error_model="numpy", cache=False)
    def taylor_step(data, t, hi, lo, h, params, inc):
        # lo is left out of the coefficients (their first is f(hi)), as the
        # kernel's quenchers evaluate their first stage at hi
        code, consts, setup, outputs, order, U = data
        taylor_coefficients(code, consts, setup, outputs, t, hi, params, order, U)
        taylor_increment(U, order, h, inc)

    @numba.njit(error_model="numpy", cache=False)
    def rk_step(data, t, hi, lo, h, params, inc):
        # the member's quencher step, by the kernel's own function
        rhs, tab, work = data
        explicit_increment(rhs, t, hi, lo, h, tab, params, work, inc, False)

    @numba.njit(error_model="numpy", cache=False)
    def track(step, data, params, t_nodes, y0, m):
        # the quencher in m substeps a step and its shadow (one step a step
        # from y0, never quenched), compensated, along the nodes
        n = y0.shape[0]
        count = t_nodes.shape[0]
        Z = np.empty((count, n))
        S = np.empty((count, n))
        hi = y0.copy()
        lo = np.zeros(n)
        shi = y0.copy()
        slo = np.zeros(n)
        inc = np.zeros(n)
        Z[0] = y0
        S[0] = y0
        for node in range(count - 1):
            t = t_nodes[node]
            h = t_nodes[node + 1] - t
            hs = h / m
            for k in range(m):
                step(data, t + k * hs, hi, lo, hs, params, inc)
                two_sum(hi, lo, inc, hi, lo)
            step(data, t, shi, slo, h, params, inc)
            two_sum(shi, slo, inc, shi, slo)
            for i in range(n):
                Z[node + 1, i] = hi[i] + lo[i]
                S[node + 1, i] = shi[i] + slo[i]
        return Z, S

    return track, taylor_step, rk_step


def timed_alternating(calls, rounds=7):
    """Median wall times of ``calls`` timed in alternating rounds (each call
    once a round, after one untimed call each), so that a change of the
    machine's load falls on all alike; and each call's last result."""
    results = [call() for call in calls]
    times = [[] for _ in calls]
    for _ in range(rounds):
        for k, call in enumerate(calls):
            start = time.perf_counter()
            results[k] = call()
            times[k].append(time.perf_counter() - start)
    return [float(np.median(t)) for t in times], results


CASES = [
    ("prentice2011, t <= 4000", "prentice2011", {}, 4000.0, 1e-6),
    ("kepler e=0.6, 10 orbits", "kepler", {"e": 0.6}, 20 * np.pi, 1e-6),
    ("kepler e=0.6, 10 orbits", "kepler", {"e": 0.6}, 20 * np.pi, 1e-9),
]


def measure_case(tracks, label, name, params, t_end, tol, orders, substeps, lines):
    track, taylor_step, rk_step = tracks
    problem = hamrkq.load_problem(name, **params)
    runs = [
        hamrkq.solve(problem, t_span=(0.0, t_end), method="auto", atol=tol, rtol=0.0)
        for _ in range(5)
    ]
    sol = runs[-1]
    integrate_s = float(np.median([run.stats["integrate_s"] for run in runs]))
    ref = reference(problem, sol.t)
    member, m_rk = sol.method, int(sol.options["z_substeps"])
    lines.append(
        f"\n## {label}, atol {tol:g}: auto ran {member} in {m_rk} quencher steps a step "
        f"({len(sol.t) - 1} steps), integrate_s {integrate_s:.3f} s (median of 5)\n"
    )
    lines.append(
        "| quencher | m | z true error | / tol | Gamma / true error (median) "
        "| z + shadow time (s) | us a quencher step | / RK quencher's time |"
    )
    lines.append("|---|---|---|---|---|---|---|---|")
    tab = get_member(member, None, m_rk).tableaus
    work = allocate_work(problem.y0, tab.b.shape[0], tab.bz.shape[0])
    rhs = kernel_functions(problem.hamiltonian, "shadow").rhs
    tape = taylor_tape(problem.hamiltonian)
    common = (problem.parameter_array, sol.t, problem.y0)
    rows = [(f"{member}'s RK (order {tab_order(member)})", m_rk, tab_order(member),
             (rk_step, (rhs, tab, work), *common, m_rk))]  # fmt: skip
    for order in orders:
        data = (tape.code, tape.consts, tape.setup, tape.outputs, order,
                np.zeros((tape.slots, order + 1)))  # fmt: skip
        rows += [(f"Taylor, order {order}", m, order, (taylor_step, data, *common, m))
                 for m in substeps]  # fmt: skip
    calls = [lambda a=args: track(*a) for *_, args in rows]
    seconds, results = timed_alternating(calls)
    for (quencher, m, order, _), elapsed, (Z, S) in zip(rows, seconds, results, strict=True):
        _row(lines, quencher, m, Z, S, ref, tol, order, elapsed, len(sol.t), seconds[0])


def tab_order(member: str) -> int:
    """The order of a member's quencher."""
    return get_member(member).z_order


def _row(lines, quencher, m, Z, S, ref, tol, order, elapsed, nodes, rk_s):
    error = np.abs(Z - ref).max()
    gamma = (S - Z) / (float(m) ** order - 1.0)
    per_step = elapsed / ((nodes - 1) * (m + 1)) * 1e6
    lines.append(
        f"| {quencher} | {m} | {error:.1e} | {error / tol:.2g} "
        f"| {_median_ratio(gamma, Z - ref):.2f} | {elapsed:.4f} | {per_step:.2f} "
        f"| {elapsed / rk_s:.2f} |"
    )
    print(lines[-1], flush=True)


def _median_ratio(gamma, error, floor=1e-14):
    """Median over the nodes of max|gamma| / max|error| where the error is
    above ``floor`` (below it the error is rounding, which Gamma does not
    estimate); nan where no node is."""
    g = np.abs(np.asarray(gamma)).max(axis=1)
    e = np.abs(np.asarray(error)).max(axis=1)
    keep = e > floor
    return float(np.median(g[keep] / e[keep])) if keep.any() else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", type=int, nargs="+", default=[12, 16, 20, 24])
    parser.add_argument("--substeps", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--out", default="taylor_quencher.txt")
    args = parser.parse_args()
    start = time.perf_counter()
    tracks = _compile()
    info = machine()
    lines = [
        "# A Taylor quencher along auto's steps (generated with benchmarks/taylor_quencher.py)",
        "",
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {info['cpu']}, {info['cores']} cores, "
        f"load {info['load_average']}.  True errors against the extended-precision reference "
        "(extended_reference.py) at auto's nodes; times compiled, medians of 7 alternating "
        "rounds.",
    ]
    for case in CASES:
        measure_case(tracks, *case, args.orders, args.substeps, lines)
    lines.append(f"\n(total {time.perf_counter() - start:.0f} s)")
    (HERE / args.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
