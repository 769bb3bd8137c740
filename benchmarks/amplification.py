"""The orbit's amplification as the witness's rules read it, and what runs keep.

For every run a solve makes without the rounding witness, the readings of
the rule after a run (``hamrkq.rkq.witness_rules.needs_witness_after_run``):
the estimate's growth from the first sixteenth of the interval to its end
(``hamrkq.solve.growth.early_growth``) over a regular orbit's ``t^2``
(256), the factor beyond the length's law that would run the witness again
("needed": the tolerance over ``WITNESS_BELOW`` times the length factor
times the scale), the close approaches' factor, and the growth over ``t^2``
divided by "needed" (above ``REGULAR_GROWTH / T_SQUARED_GROWTH`` the run is
made again).  Then what the solve returned: its status, whether the witness
ran, and where a truth is at hand its largest node error over the
tolerance: the pendulum near its separatrix against a 40-digit Taylor
integration (mpmath), Kepler and the harmonic oscillator against their
exact solutions; the Pleiades, the double pendulum and the outer solar
system are in ``benchmarks/promise.md``.

Run: ``python benchmarks/amplification.py`` (about three minutes); writes
``amplification.txt`` beside this file.
"""

from __future__ import annotations

import importlib
import math
import time
import warnings
from pathlib import Path

import numpy as np
from measure import head_commit
from promise_outside import pendulum_truth

import hamrkq
from hamrkq._tolerance import component_tolerance
from hamrkq.catalogue.exact import kepler
from hamrkq.rkq import witness_rules
from hamrkq.rkq.scales import component_scales
from hamrkq.solve.shadow import largest_state

HERE = Path(__file__).resolve().parent
auto = importlib.import_module("hamrkq.solve.auto")
growth = importlib.import_module("hamrkq.solve.growth")
Solution = importlib.import_module("hamrkq.result").Solution


class Readings:
    """Record the readings of every run without the witness (wraps
    ``hamrkq.solve.auto._next_run``, the decision after each run)."""

    def __init__(self) -> None:
        self.runs: list[str] = []
        self.real = auto._next_run

    def __enter__(self):
        auto._next_run = self._record
        return self

    def __exit__(self, *exc) -> None:
        auto._next_run = self.real

    def _record(self, requested, task, out):
        if not isinstance(out, Solution) and out.gamma is not None and not auto.uses_witness(task):
            steps = out.stats.get("steps", 0)
            tolerance = component_tolerance(task.atol, task.rtol, task.y0)
            largest = np.maximum(np.abs(task.y0), largest_state(out))
            threshold = (
                witness_rules.WITNESS_BELOW
                * witness_rules.length_factor(steps)
                * component_scales(task.atol, largest)
            )
            needed = float(np.min(tolerance / threshold))
            over = growth.early_growth(out, task) / witness_rules.T_SQUARED_GROWTH
            close = witness_rules.close_approach_factor(out.step_range)
            self.runs.append(
                f"{steps} steps: growth over t^2 {over:.3g}, needed {needed:.3g}, "
                f"close approaches {close:.3g}, over needed {over / needed:.3g}"
            )
        return self.real(requested, task, out)


def worst(sol, truth, atol, rtol) -> str:
    if truth is None:
        return "-"
    delta = np.maximum(atol, rtol * np.abs(truth))
    return f"{float((np.abs(sol.y - truth) / delta).max()):.3g}"


def cases():
    pendulum = hamrkq.load_problem("pendulum")
    below9 = {"q0": [0.0], "p0": [math.sqrt(4 - 2e-9)]}
    below6 = {"q0": [math.pi - math.sqrt(2e-6)], "p0": [0.0]}
    separatrix = [
        ("E = 1 - 1e-9, [0, 60]", below9, "rk45q12", 1e-9, 0.0, 60.0),
        ("E = 1 - 1e-6, [0, 150]", below6, "rk67q12", 1e-9, 0.0, 150.0),
        ("E = 1 - 1e-6, [0, 150]", below6, "rk45q12", 1e-8, 1e-8, 150.0),
        ("E = 1 - 1e-6, [0, 150]", below6, "auto", 1e-9, 0.0, 150.0),
    ]
    for label, start, method, atol, rtol, t_end in separatrix:
        options = {"t_span": (0.0, t_end), "method": method, "atol": atol, "rtol": rtol}

        def truth(sol, start=start):
            return pendulum_truth(start["q0"][0], sol.t, start["p0"][0])

        yield f"pendulum {label}", pendulum, {**start, **options}, truth
    ten = hamrkq.load_problem("kepler", e=0.6)
    for atol in (1e-6, 1e-9):
        for method in ("auto", "rk67q12"):
            options = {"t_span": (0.0, 20 * np.pi), "method": method, "atol": atol}
            yield "kepler e = 0.6, ten periods", ten, options, lambda s, p=ten: kepler(s.t, p.y0)
    tolerances = [(1e-4, 0.0), (1e-6, 0.0), (1e-8, 0.0), (1e-9, 1e-6)]
    for name in ("kepler", "harmonic", "pleiades", "double_pendulum", "outer_solar_system"):
        problem = hamrkq.load_problem(name)
        exact = getattr(problem, "exact", None)
        for atol, rtol in tolerances:
            for method in ("auto", "rk67q12"):
                grid = np.linspace(*problem.t_span, 201)
                options = {"t_eval": grid, "method": method, "atol": atol, "rtol": rtol}

                def truth(sol, exact=exact):
                    return None if exact is None else exact(sol.t)

                yield f"{name} (catalogue, 201 times)", problem, options, truth


def main() -> None:
    warnings.simplefilter("ignore")
    lines = [
        "# The orbit's amplification (generated by benchmarks/amplification.py)",
        "",
        f"Run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on commit {head_commit()}; "
        f"REGULAR_GROWTH / T_SQUARED_GROWTH = "
        f"{witness_rules.REGULAR_GROWTH / witness_rules.T_SQUARED_GROWTH:g}.",
        "",
    ]
    for label, problem, options, truth in cases():
        with Readings() as readings:
            sol = hamrkq.solve(problem, **options)
        atol, rtol = options["atol"], options.get("rtol", 0.0)
        witness = "yes" if sol.options.get("rounding_witness") else "no"
        line = (
            f"- {label}, {options['method']}, atol {atol:g}, rtol {rtol:g}: {sol.status.name} "
            f"to t = {sol.t[-1]:.6g}, witness {witness}, "
            f"worst node / tol {worst(sol, truth(sol), atol, rtol)}; runs without the witness: "
            + ("; ".join(readings.runs) or "none")
        )
        print(line, flush=True)
        lines.append(line)
    (HERE / "amplification.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
