"""Close approaches amplify the quencher's rounding: the step range rule.

The rounding witness runs again after a run where the quencher's rounding,
which Gamma does not see, could reach the tolerance
(``hamrkq.rkq.witness_rules.needs_witness_after_run``).  Its law in the run's
length was measured on prentice2011, whose steps range less than twofold.
On an eccentric Kepler orbit the short steps at pericentre round the energy
far more, and the orbit turns that into a phase drift: this script measures
how much more, against the ratio of the run's largest free step to its
smallest (``hamrkq.rkq.loop.step_range``), and checks the rule built on it
(``close_approach_factor``).

1. Kepler orbits, e = 0.3 .. 0.99, atol 1e-8 and 1e-9, 100 and 300 periods
   (and QA's four runs of 1000 and 2000 periods near e = 0.6),
   ``method="auto"`` with the witness off and the quencher in double: the
   quencher's largest true error (against the exact solution), over what
   the length's law allows (1.5e-11 x length_factor x each component's
   size, ``WITNESS_BELOW`` x 0.05 of it), and the worst returned node; the
   step range is the kernel's own, read where the rules read it.
2. The same runs with every rule on (what a user gets): status, the
   quencher's precision, the worst node.
   The integration times (``stats["integrate_s"]`` with the discarded
   runs', compiling apart) are single runs on a shared machine: their
   ratios, not their digits, are the point.
3. The catalogue at its own tolerances with ``method="auto"``: the step
   range, and whether the run was made again with the witness.

Run: ``python benchmarks/close_approach.py`` (about five minutes).
Output: ``close_approach.txt``.
"""

from __future__ import annotations

import importlib
import time
import warnings
from pathlib import Path

import numpy as np
from measure import head_commit

import hamrkq
from hamrkq.catalogue.exact import kepler
from hamrkq.rkq.witness_rules import (
    WITNESS_BELOW,
    close_approach_factor,
    component_scales,
    length_factor,
)

HERE = Path(__file__).resolve().parent
dispatch = importlib.import_module("hamrkq.solve.dispatch")
auto = importlib.import_module("hamrkq.solve.auto")

ECCENTRICITIES = (0.3, 0.6, 0.8, 0.9, 0.93, 0.95, 0.97, 0.99)
TOLERANCES = (1e-8, 1e-9)
PERIODS = (100, 300)
#: Found by QA (2026-11-27) with the factor's range at 16: moderate
#: eccentricities over long runs, (e, atol, periods).
LONG_RUNS = ((0.59, 4.2e-9, 1000), (0.61, 4.2e-9, 1000), (0.62, 4e-9, 1000),
             (0.64, 1.2e-8, 2000))  # fmt: skip
#: What the length's law allows the quencher's rounding: WITNESS_BELOW times
#: gamma_limit's default (0.05) of the state's size, times length_factor.
ALLOWED = WITNESS_BELOW * 0.05


class Rules:
    """Switch the witness's rules off (``off()``) and back, recording the step
    range each finished run handed to them."""

    def __init__(self):
        self.needs = dispatch.needs_witness
        self.rerun = auto.witness_rerun_needed
        self.ranges: list[float] = []

    def _record(self, *args, **kwargs):
        self.ranges.append(args[5] if len(args) > 5 else kwargs.get("step_range", 1.0))
        return False

    def off(self):
        dispatch.needs_witness = lambda *a, **k: False
        auto.witness_rerun_needed = self._record

    def on(self):
        dispatch.needs_witness = self.needs
        auto.witness_rerun_needed = self.rerun


def seconds(sol):
    """The run's integration time with its discarded runs' (compiling apart)."""
    return sol.stats["integrate_s"] + sol.stats.get("discarded_s", 0.0)


def worst_node(sol, truth, atol):
    return float((np.abs(sol.y - truth) / atol).max())


def kepler_cases():
    """(e, atol, periods, problem) for every Kepler run of the tables."""
    for e in ECCENTRICITIES:
        problem = hamrkq.load_problem("kepler", e=e)
        for atol in TOLERANCES:
            for periods in PERIODS:
                yield e, atol, periods, problem
    for e, atol, periods in LONG_RUNS:
        yield e, atol, periods, hamrkq.load_problem("kepler", e=e)


def kepler_without_witness(rules: Rules):
    yield (
        "| e | atol | periods | member, quencher steps | steps | step range | quencher's "
        "error | over the length's law | close_approach_factor | worst node / delta | "
        "integration s |"
    )
    yield "|---|---|---|---|---|---|---|---|---|---|---|"
    for e, atol, periods, problem in kepler_cases():
        rules.ranges.clear()
        rules.off()
        try:
            sol = hamrkq.solve(problem, t_span=(0, 2 * np.pi * periods), atol=atol,
                               quencher_precision="double")  # fmt: skip
        finally:
            rules.on()
        step_range = rules.ranges[-1]
        truth = kepler(sol.t, problem.y0)
        error = np.abs(sol.z - truth).max(axis=0)
        scale = component_scales(np.full(error.shape, atol), np.abs(truth).max(axis=0))
        law = ALLOWED * length_factor(sol.stats["steps"]) * scale
        yield (
            f"| {e:g} | {atol:g} | {periods} | {sol.method}, {sol.options['z_substeps']} "
            f"| {sol.stats['steps']} | {step_range:.3g} | {error.max():.2g} | "
            f"{(error / law).max():.3g} | {close_approach_factor(step_range):.3g} | "
            f"{worst_node(sol, truth, atol):.3g} | {seconds(sol):.3f} |"
        )


def kepler_with_rules():
    yield (
        "| e | atol | periods | status | member, quencher steps, precision | worst node / delta "
        "| integration s |"
    )
    yield "|---|---|---|---|---|---|---|"
    for e, atol, periods, problem in kepler_cases():
        sol = hamrkq.solve(problem, t_span=(0, 2 * np.pi * periods), atol=atol)
        truth = kepler(sol.t, problem.y0)
        yield (
            f"| {e:g} | {atol:g} | {periods} | {sol.status.name} | {sol.method}, "
            f"{sol.options['z_substeps']}, {sol.options['quencher_precision']} | "
            f"{worst_node(sol, truth, atol):.3g} | {seconds(sol):.3f} |"
        )


def catalogue(rules: Rules):
    yield "| problem | step range | the message names the witness |"
    yield "|---|---|---|"

    def recording(*args, **kwargs):
        rules.ranges.append(args[5] if len(args) > 5 else kwargs.get("step_range", 1.0))
        return rules.rerun(*args, **kwargs)

    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        rules.ranges.clear()
        auto.witness_rerun_needed = recording
        try:
            sol = hamrkq.solve(problem, method="auto")
        finally:
            rules.on()
        first = f"{rules.ranges[0]:.3g}" if rules.ranges else "(not asked)"
        again = "yes" if "witness" in sol.message else "no"
        yield f"| {name} | {first} | {again} |"


def main() -> None:
    warnings.simplefilter("ignore")
    started = time.perf_counter()
    rules = Rules()
    lines = [
        "# Close approaches and the quencher's rounding "
        "(generated by benchmarks/close_approach.py)",
        "",
        f"Run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on commit {head_commit()}.",
        "",
        "## Kepler, the witness off, the quencher in double",
        "",
        *kepler_without_witness(rules),
        "",
        "## The same runs with every rule on",
        "",
        *kepler_with_rules(),
        "",
        "## The catalogue at its tolerances, method='auto'",
        "",
        *catalogue(rules),
        "",
        f"({time.perf_counter() - started:.0f} s)",
    ]
    text = "\n".join(lines) + "\n"
    (HERE / "close_approach.txt").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
