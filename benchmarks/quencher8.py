"""The order-8 quencher of the new members: DOP853's formula or Cooper & Verner's.

    python benchmarks/quencher8.py

``rk45q8`` and ``rk56q8`` (two quencher steps a step, shadow Gamma, no
rerun) with ``z_method="dop853"`` and ``z_method="cooper_verner"`` on the
runs of ``benchmarks/promise.py`` (every catalogue problem over its own
interval at ``atol`` 1e-4 ... 1e-12 and ``rtol`` 1e-6 ... 1e-10, checked on
201 times against the long-double reference): how the runs end, the nodes
above 1.05 tolerances and the evaluations.  Also the absolute sums of each
formula's weights and largest row of coefficients, which set how much the
rounding of the stage values (shared by the rounding witness) is
magnified, and, on the Arenstorf orbit at ``atol`` 1e-10, the quencher's
error and Gamma at the end of the orbit with the default steps and with
``max_step=1e-3`` (16 to 20 times more steps): an error that does not fall
with the steps is not truncation.  Writes ``benchmarks/quencher8.md`` and
``quencher8.json``.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import promise

import hamrkq
from hamrkq.methods.registry import QUENCHERS

HERE = Path(__file__).resolve().parent
MEMBERS = ("rk45q8", "rk56q8")
FORMULAS = ("dop853", "cooper_verner")


def coefficient_sizes() -> list[str]:
    lines = [
        "| formula | stages | sum of abs(b) | largest row sum of abs(A) |",
        "|---|---|---|---|",
    ]
    for name in FORMULAS:
        q = QUENCHERS[name]
        rows = np.abs(q.A).sum(axis=1)
        lines.append(f"| {name} | {q.stages} | {np.abs(q.b).sum():.2f} | {rows.max():.1f} |")
    return lines


def arenstorf_end(problems) -> list[str]:
    """The quencher's error and Gamma at the end of the Arenstorf orbit."""
    problem, grid, truth, _ = problems["arenstorf"]
    lines = [
        "Arenstorf orbit, atol 1e-10, two quencher steps, gamma_limit 1e30 (never stops):",
        "",
        "| member | quencher | max_step | steps | quencher error at t_end | Gamma at t_end |",
        "|---|---|---|---|---|---|",
    ]
    for member in MEMBERS:
        for formula in FORMULAS:
            for max_step in (None, 1e-3):
                options = {} if max_step is None else {"max_step": max_step}
                sol = hamrkq.solve(
                    problem, method=member, atol=1e-10, rtol=0.0, t_eval=grid,
                    z_method=formula, gamma_limit=1e30, **options,
                )  # fmt: skip
                error = np.abs(sol.y[-1] - sol.global_error[-1] - truth[sol.t.size - 1]).max()
                lines.append(
                    f"| {member} | {formula} | {max_step or 'default'} | {sol.stats['steps']} | "
                    f"{error:.2e} | {np.abs(sol.gamma[-1]).max():.2e} |"
                )
    return lines


def main() -> None:
    warnings.simplefilter("ignore")
    problems, skipped = promise.references()
    for problem, _, _, _ in problems.values():
        hamrkq.solve(problem, t_span=(problem.t_span[0], problem.t_span[0] + 1e-3))  # compile
    rows = []
    for member in MEMBERS:
        for formula in FORMULAS:
            for problem, grid, truth, bound in problems.values():
                for label, atol, rtol in promise.tolerances():
                    r = promise.row(
                        problem, grid, truth, bound, label, atol, rtol, member, z_method=formula
                    )
                    r["z_method"] = formula
                    rows.append(r)
                    print(json.dumps(r), flush=True)
    lines = [*coefficient_sizes(), ""]
    lines += [
        "| member | quencher | runs counted | SUCCESS | stopped, naming the floor | "
        "stopped otherwise | nodes above 1.05 delta | evaluations (sum) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for member in MEMBERS:
        for formula in FORMULAS:
            kept = [
                r for r in rows
                if r["method"] == member and r["z_method"] == formula
                and not r["reference_limits"]
            ]  # fmt: skip
            work = sum(r["evaluations"] for r in kept)
            lines.append(f"| {member} | {formula} | {promise.outcome_cells(kept)} | {work} |")
    lines += ["", *arenstorf_end(problems)]
    notes = "".join(f"\nNot checked: {text}.\n" for text in skipped)
    (HERE / "quencher8.json").write_text(json.dumps(rows, indent=1) + "\n")
    (HERE / "quencher8.md").write_text("\n".join(lines) + "\n" + notes)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
