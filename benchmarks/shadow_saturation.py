"""Runs that ``method="auto"`` cut where its shadow track saturated, with and
without the tangent estimate as the last resort (``hamrkq.solve.auto._with_tangent``).

The shadow behind Gamma is the quencher in one step where the quencher takes
``m``: its error is ``m^z`` times the quencher's, so on a long run at a loose
tolerance, where auto takes many quencher steps, it leaves the linear regime
(half the orbit's size from the quencher) while the quencher is still far
within the tolerance.  auto runs again with Gamma from the tangent flow,
which has no shadow (whose stop stands: the quencher in double-double has
the shadow's Gamma only); until 2026-11-27 it first ran again with shorter
steps (two runs), as in ``shadow_saturation.txt`` at 701e72c, which kept
the shadow within its limit without making it honest
(``kepler_saturation.py``).  Each case is run twice in one process, the
fallback off (the saturated run's stop) and on, and checked against
Kepler's exact solution on 2001 output times, or at every node
(``nodes``).

Run: ``python benchmarks/shadow_saturation.py > benchmarks/shadow_saturation.txt``
(a few minutes).
"""

from __future__ import annotations

import os
import time
import warnings

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np

import hamrkq
from hamrkq.solve import auto

CASES = [
    # (eccentricity, periods, atol, rtol, every node)
    (0.5, 10_000, 1e-3, 1e-3, False),
    (0.3, 10_000, 1e-3, 1e-3, False),
    (0.95, 100, 1e-8, 1e-5, False),
    (0.95, 100, 1e-8, 1e-5, True),
]


def run(e: float, periods: float, atol: float, rtol: float, nodes: bool) -> str:
    """One case as auto runs it: status, reach, worst node, time, how."""
    problem = hamrkq.load_problem("kepler", e=e)
    span = (0.0, 2 * np.pi * periods)
    times = None if nodes else np.linspace(*span, 2001)
    started = time.perf_counter()
    sol = hamrkq.solve(problem, t_span=span, atol=atol, rtol=rtol, t_eval=times)
    seconds = time.perf_counter() - started
    truth = problem.exact(sol.t)
    worst = np.max(np.abs(sol.y - truth) / np.maximum(atol, rtol * np.abs(truth)))
    return (
        f"{sol.status.name:23s} t = {sol.t[-1]:9.6g} of {span[1]:9.6g}  worst node "
        f"{worst:.3f} delta  {seconds:6.1f} s  Gamma {sol.options['global_error_estimate']}, "
        f"z_substeps {sol.options['z_substeps']}, "
        f"{sol.stats['nfev'] + sol.stats['njev'] + sol.stats.get('discarded_evaluations', 0)} "
        "evaluations"
    )


def main() -> None:
    warnings.simplefilter("ignore")
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
          f"{os.getloadavg()[0]:.2f} at the start; Kepler, auto")  # fmt: skip
    with_tangent = auto._with_tangent
    for case in CASES:
        e, periods, atol, rtol, nodes = case
        where = "every node" if nodes else "2001 output times"
        print(f"\ne = {e}, {periods} periods, atol {atol:g}, rtol {rtol:g}, {where}")
        auto._with_tangent = lambda requested, task: None
        print(f"  without the tangent fallback: {run(*case)}", flush=True)
        auto._with_tangent = with_tangent
        print(f"  with it:                      {run(*case)}", flush=True)
    print(f"\n# load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
