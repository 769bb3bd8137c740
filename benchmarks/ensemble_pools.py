"""Threads or processes for a local ensemble?  Measure, on this machine.

Two workloads, each run serially, on a thread pool and on a process pool of
2 workers (wall time; the process pool's time includes starting its
processes and loading the compiled code from the disk cache):

- ``henon_heiles``: orbits at H ~ 0.04-0.1, t in [0, 100], atol 1e-8
  (~4 000 steps each: integration dominates);
- ``pendulum_short``: pendulum orbits over t in [0, 1] (~30 steps each:
  the per-call overhead of ``hamrkq.solve`` dominates).

Run: ``python benchmarks/ensemble_pools.py > benchmarks/ensemble_pools.txt``.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

import hamrkq


def workloads(members: int):
    rng = np.random.default_rng(1)
    hh = hamrkq.load_problem("henon_heiles")
    q = rng.uniform(-0.25, 0.25, (members, 2))
    p = rng.uniform(-0.25, 0.25, (members, 2))
    yield "henon_heiles", dict(problem_or_hamiltonian=hh, q0=q, p0=p, t_span=(0, 100))
    pend = hamrkq.load_problem("pendulum")
    q = np.linspace(-3, 3, 4 * members)[:, None]
    yield "pendulum_short", dict(problem_or_hamiltonian=pend, q0=q, p0=[0.0], t_span=(0, 1))


def timed(kwargs, **how) -> tuple[float, hamrkq.EnsembleSolution]:
    start = time.perf_counter()
    ens = hamrkq.ensemble(**kwargs, atol=1e-8, progress=False, **how)
    return time.perf_counter() - start, ens


def main() -> None:
    members = int(os.environ.get("MEMBERS", "400"))
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"hamrkq {hamrkq.__version__}, numpy {np.__version__}")  # fmt: skip
    print(f"# load average before: {os.getloadavg()[0]:.2f}")
    print(f"{'workload':<16} {'members':>7} {'how':<12} {'wall s':>8} {'us/member':>10} "
          f"{'speed-up':>8}")  # fmt: skip
    for name, kwargs in workloads(members):
        m = len(kwargs["q0"])
        few = {k: v[:2] if np.ndim(v) == 2 and len(v) == m else v for k, v in kwargs.items()}
        timed(few, workers=1)  # compile, warm the cache
        serial, reference = timed(kwargs, workers=1)
        print(f"{name:<16} {m:>7} {'serial':<12} {serial:8.2f} {1e6 * serial / m:10.0f} {1:8.2f}")
        for pool in ("threads", "processes"):
            wall, ens = timed(kwargs, workers=2, scheduler=pool)
            assert np.array_equal(ens.y, reference.y, equal_nan=True), pool
            print(f"{name:<16} {m:>7} {pool + ' x2':<12} {wall:8.2f} {1e6 * wall / m:10.0f} "
                  f"{serial / wall:8.2f}")  # fmt: skip
    print(f"# load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
