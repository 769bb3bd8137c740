"""Memory of an ensemble that keeps only end states: bounded by its outputs.

Runs Hénon-Heiles ensembles of increasing size (end states only) under
``tracemalloc`` and prints the peak of traced memory (NumPy's arrays
included) against the size of the result's arrays.  If per-member solutions
were kept, the peak would grow by kilobytes per member (every node of every
member); chunking keeps it at the result's own few hundred bytes per member,
twice over at the end (the collected arrays and the frozen result's copies).

Run: ``SIZES=1000,10000,100000,1000000 WORKERS=2 python benchmarks/ensemble_memory.py
> benchmarks/ensemble_memory.txt`` (defaults: those sizes, 1 worker).
"""

from __future__ import annotations

import os
import time
import tracemalloc

import numpy as np

import hamrkq


def result_bytes(ens: hamrkq.EnsembleSolution) -> int:
    names = ("t", "y", "y0", "t_last", "status", "max_global_error", "energy0", "energy_drift")
    arrays = [getattr(ens, name) for name in names]
    arrays += [*ens.stats.values(), *ens.parameters.values()]
    return sum(a.nbytes for a in arrays)


def main() -> None:
    problem = hamrkq.load_problem("henon_heiles")
    sizes = [int(s) for s in os.environ.get("SIZES", "1000,10000,100000,1000000").split(",")]
    workers = int(os.environ.get("WORKERS", "1"))
    rng = np.random.default_rng(5)
    hamrkq.ensemble(problem, q0=[0.1, 0.1], t_span=(0, 5), workers=1)  # compile first
    print(f"# Henon-Heiles, t in [0, 5], atol 1e-8, end states only, {workers} worker(s); "
          f"load average {os.getloadavg()[0]:.2f}")  # fmt: skip
    print(f"{'members':>8} {'result MB':>10} {'peak MB':>9} {'peak B/member':>14} "
          f"{'nodes/member':>12} {'wall s':>8}")  # fmt: skip
    for m in sizes:
        y0 = rng.uniform(-0.25, 0.25, (m, 4))
        tracemalloc.start()
        start = time.perf_counter()
        ens = hamrkq.ensemble(
            problem, q0=y0[:, :2], p0=y0[:, 2:], t_span=(0, 5), workers=workers, progress=False
        )
        wall = time.perf_counter() - start
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        nodes = float(np.mean(ens.stats["steps"])) + 1
        print(f"{m:>8} {result_bytes(ens) / 1e6:10.2f} {peak / 1e6:9.2f} {peak / m:14.0f} "
              f"{nodes:12.0f} {wall:8.1f}")  # fmt: skip


if __name__ == "__main__":
    main()
