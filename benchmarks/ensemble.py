"""Ensemble throughput: Hénon-Heiles orbits, t in [0, 100], atol 1e-8 (issue 15).

Measures, on this machine (wall times; the machine's load average is printed
because other processes share its cores):

1. the per-member overhead: an ensemble whose members take one tiny step
   (t_span = (0, 1e-9)), so that nearly all of its time is the cost of
   setting up, deciding and packing each member (the best of three;
   ``benchmarks/ensemble_overhead.py`` compares checkouts side by side);
2. the ensemble of MEMBERS orbits on 1 worker and on 2 workers (threads and
   processes), and the speed-up;
3. a plain Python loop over ``hamrkq.solve`` on the same orbits (what a user
   writes without ``ensemble``), and that it gives the same bits;
4. heyoka's ``ensemble_propagate_until`` (Taylor method, threads) at matched
   error, when heyoka is installed: the end-state error of both against a
   heyoka reference at tol 1e-16 on the first 200 members, and heyoka's
   loosest tolerance whose largest error is no larger than hamrkq's.

Run: ``MEMBERS=10000 python benchmarks/ensemble.py > benchmarks/ensemble.txt``.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

import hamrkq

T_END = 100.0
ATOL = 1e-8
CHECK = 200  # members whose end states are checked against the reference
WARM = 40  # members of the run that compiles and warms the caches


def initial_states(members: int) -> np.ndarray:
    """Random states with |q_k|, |p_k| <= 0.25 (H < 0.15 < 1/6: bounded orbits)."""
    return np.random.default_rng(2011).uniform(-0.25, 0.25, (members, 4))


def run(problem, y0, **how) -> tuple[float, hamrkq.EnsembleSolution]:
    start = time.perf_counter()
    ens = hamrkq.ensemble(problem, q0=y0[:, :2], p0=y0[:, 2:], atol=ATOL, progress=False, **how)
    return time.perf_counter() - start, ens


def line(label: str, wall: float, members: int, base: float | None = None) -> str:
    speed = f"{base / wall:8.2f}" if base else f"{'':8}"
    return f"{label:<34} {wall:9.2f} {1e6 * wall / members:10.0f} {speed}"


def heyoka_part(y0: np.ndarray, hamrkq_end: np.ndarray) -> list[str]:
    try:
        import heyoka as hy
    except ImportError:
        return ["heyoka not installed: comparison skipped"]
    x, y, vx, vy = hy.make_vars("x", "y", "vx", "vy")
    system = [(x, vx), (y, vy), (vx, -x - 2.0 * x * y), (vy, -y - x**2 + y**2)]

    def propagate(tol: float, states: np.ndarray) -> tuple[float, float, np.ndarray]:
        start = time.perf_counter()
        ta = hy.taylor_adaptive(system, [0.0] * 4, tol=tol)
        compiled = time.perf_counter()

        def gen(copy, i):
            copy.state[:] = states[i]
            copy.time = 0.0
            return copy

        out = hy.ensemble_propagate_until(ta, T_END, len(states), gen, algorithm="thread")
        end = np.array([r[0].state for r in out])
        return compiled - start, time.perf_counter() - compiled, end

    lines = []
    check = y0[:CHECK]
    _, _, reference = propagate(1e-16, check)
    ours = np.abs(hamrkq_end[:CHECK] - reference).max(axis=1)
    lines.append(
        f"hamrkq atol {ATOL:g}: end-state error vs heyoka tol 1e-16 on {CHECK} members: "
        f"median {np.median(ours):.2e}, max {ours.max():.2e}"
    )
    chosen = None
    for tol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14):
        _, _, end = propagate(tol, check)
        theirs = np.abs(end - reference).max(axis=1)
        lines.append(f"heyoka tol {tol:g}: median {np.median(theirs):.2e}, max {theirs.max():.2e}")
        if theirs.max() <= ours.max():
            chosen = tol
            break
    if chosen is None:
        return [*lines, "no heyoka tolerance matched"]
    jit, wall, _ = propagate(chosen, y0)
    lines.append(
        f"heyoka tol {chosen:g} (matched), {len(y0)} members, threads: {wall:.2f} s "
        f"({1e6 * wall / len(y0):.0f} us/member; JIT compilation {jit:.2f} s apart)"
    )
    return lines


def main() -> None:
    members = int(os.environ.get("MEMBERS", "10000"))
    problem = hamrkq.load_problem("henon_heiles")
    y0 = initial_states(members)
    print(f"# {platform.machine()}, {os.cpu_count()} cores, hamrkq {hamrkq.__version__}, "
          f"numpy {np.__version__}; load average {os.getloadavg()[0]:.2f} at start")  # fmt: skip
    print(f"# Henon-Heiles, {members} members, t in [0, {T_END:g}], atol {ATOL:g}")
    # compile / warm the cache, in chunks of several members: the compiled
    # batch loop is looked up by its arrays' flags, which differ between a
    # chunk of one member (C- and F-contiguous arrays) and one of several;
    # warmed with four members, the row below loaded it once more (0.08 s,
    # 40 us a member)
    run(problem, y0[:WARM], t_span=(0, T_END), workers=1)

    tiny = min(members, 2000)
    wall = min(run(problem, y0[:tiny], t_span=(0, 1e-9), workers=1)[0] for _ in range(3))
    print(f"per-member overhead (one tiny step, {tiny} members, 1 worker, best of 3): "
          f"{1e6 * wall / tiny:.0f} us")  # fmt: skip

    print(f"{'how':<34} {'wall s':>9} {'us/member':>10} {'speed-up':>8}")
    serial, ens = run(problem, y0, t_span=(0, T_END), workers=1)
    print(line("ensemble, 1 worker", serial, members))
    for pool in ("threads", "processes"):
        wall, other = run(problem, y0, t_span=(0, T_END), workers=2, scheduler=pool)
        assert np.array_equal(other.y, ens.y)
        print(line(f"ensemble, 2 workers ({pool})", wall, members, serial))

    start = time.perf_counter()
    ends = [hamrkq.solve(problem, q0=s[:2], p0=s[2:], t_span=(0, T_END), atol=ATOL).y[-1]
            for s in y0]  # fmt: skip
    loop = time.perf_counter() - start
    assert np.array_equal(np.array(ends), ens.y[:, 0])
    print(line("python loop over solve", loop, members, serial))
    steps = ens.stats["steps"]
    drift = ens.energy_drift.max()
    print(f"steps per member: median {np.median(steps):.0f}, max {steps.max()}; "
          f"failed members: {ens.failed.size}; largest energy drift {drift:.2e}")  # fmt: skip
    for text in heyoka_part(y0, ens.y[:, 0]):
        print(text)
    print(f"# load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
