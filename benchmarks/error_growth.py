"""How fast the shadow estimate grows on regular and unstable orbits, and what is certified there.

    python benchmarks/error_growth.py [--before CHECKOUT [--before-label TEXT]] [--from-json]

Part 1: every run ``method="auto"`` abandons or stops, on the catalogue's
periodic orbits and on three unstable ones, with the factor by which its
estimate of the quencher's error (the running largest ``|Gamma| / delta``)
grew over the second half of the interval it covered
(:func:`hamrkq.rkq.auto_rules.error_growth`).  Above
:data:`hamrkq.rkq.auto_rules.EXPONENTIAL_GROWTH` auto measures the rounding
(the witness), and adds quencher steps only where the growth, projected to
``t_end``, leaves the end within reach
(:func:`hamrkq.rkq.auto_rules.auto_retry_substeps`).

Part 2: on the unstable orbits, what auto (and two members run as given)
returns (status, last node) and
its largest true error over the tolerance at the nodes it returns, against
heyoka's Taylor integrator in extended precision from the initial value
(``hamrkq.analysis.extended_reference``; the ``bench`` extra).  With
``--before``, a checkout from before the rule runs part 2 too, side by side.

Writes ``benchmarks/error_growth.json`` and ``benchmarks/error_growth.txt``,
and part 2's table into ``docs/algorithm.md`` between the ``error_growth``
markers (``--from-json``: only that, from the last run's record).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402


def _duffing():
    """A Duffing oscillator on its separatrix (H = 0: the orbit tends to the saddle)."""
    import sympy as sp

    import hamrkq

    x, v, a, b = sp.symbols("x v a b", real=True)
    H = v**2 / 2 + a * x**2 / 2 + b * x**4 / 4
    return hamrkq.Hamiltonian(H, q=[x], p=[v], parameters={a: -1.0, b: 0.5})


def _henon_heiles_chaotic() -> tuple[list[float], list[float]]:
    q2 = -0.25
    return [0.0, q2], [math.sqrt(2 * (1 / 6 - q2**2 / 2 + q2**3 / 3)), 0.0]


def _duffing_separatrix(t: np.ndarray) -> np.ndarray:
    """The Duffing separatrix through (2, 0) at t = 0, exactly: x = 2 sech t,
    v = -2 sech t tanh t (H = v^2/2 - x^2/2 + x^4/8 = 0; the initial state
    and the parameters are exact doubles)."""
    sech = 1.0 / np.cosh(t)
    return np.column_stack([2.0 * sech, -2.0 * sech * np.tanh(t)])


def unstable_cases():
    """(label, system, solve keywords, tolerance, exact solution or None) of
    the unstable orbits; the others are measured against heyoka in extended
    precision (whose error on the Duffing separatrix reached 2.7e-6 by
    t = 34, where the orbit is 4e-15 from the saddle)."""
    import hamrkq

    arenstorf = hamrkq.load_problem("arenstorf")
    period = arenstorf.t_span[1]
    henon = hamrkq.load_problem("henon_heiles")
    q0, p0 = _henon_heiles_chaotic()
    cases = [
        (f"arenstorf, {n} periods, atol 1e-8", arenstorf, {"t_span": (0, n * period)}, 1e-8, None)
        for n in (3, 10)
    ]
    for member in ("rk45q12", "rk56q12"):  # run as given: no reruns but the witness's
        options = {"t_span": (0, 3 * period), "method": member}
        label = f"arenstorf, 3 periods, atol 1e-8, {member}"
        cases.append((label, arenstorf, options, 1e-8, None))
    chaotic = {"q0": q0, "p0": p0, "t_span": (0, 1000)}
    cases += [
        (f"Henon-Heiles chaotic (E = 1/6), t <= 1000, atol {tol:g}", henon, chaotic, tol, None)
        for tol in (1e-6, 1e-8)
    ]
    separatrix = {"q0": [2.0], "p0": [0.0], "t_span": (0, 100)}
    label = "Duffing separatrix, t <= 100, atol 1e-9"
    cases.append((label, _duffing(), separatrix, 1e-9, _duffing_separatrix))
    return cases


def regular_cases():
    import hamrkq

    cases = [("prentice2011", {}, tol) for tol in (1e-6, 1e-8, 1e-10)]
    cases += [
        ("prentice2011", {"t_span": (0, 40000)}, 1e-6),
        ("kepler", {"t_span": (0, 2000)}, 1e-8),
        ("toda", {"t_span": (0, 2000)}, 1e-9),
    ]
    rows = [(f"{n} {kw.get('t_span', '')} atol {tol:g}".replace("  ", " "),
             hamrkq.load_problem(n), kw, tol) for n, kw, tol in cases]  # fmt: skip
    oss = hamrkq.load_problem("outer_solar_system")
    rows.append(("outer_solar_system rtol 1e-8", oss, {"rtol": 1e-8}, None))
    return rows


def growth_rows() -> list[dict]:
    """Part 1: the growth factor of every run auto abandons or stops."""
    import hamrkq
    from hamrkq.solve import auto
    from hamrkq.solve.growth import growth

    seen: list[dict] = []
    plain = auto.rerun

    def spy(requested, task, out):
        if not isinstance(out, hamrkq.Solution) and out.gamma is not None:
            seen.append({"z_substeps": task.options.z_substeps, "t_last": float(out.t_last),
                         "status": int(out.status), "growth": growth(out, task),
                         "witness": auto.uses_witness(task),
                         "double_double": task.options.double_double})  # fmt: skip
        return plain(requested, task, out)

    rows = []
    auto.rerun = spy
    try:
        for kind, cases in (("regular", regular_cases()), ("unstable", unstable_cases())):
            for label, system, options, tol, *_ in cases:
                seen.clear()
                extra = {} if tol is None else {"atol": tol}
                sol = hamrkq.solve(system, **{"method": "auto", **options, **extra})
                rows.append({"kind": kind, "case": label, "runs": list(seen),
                             "final": sol.status.name, "t_last": float(sol.t[-1])})  # fmt: skip
                print(label, [round(r["growth"], 3) for r in seen], sol.status.name, flush=True)
    finally:
        auto.rerun = plain
    return rows


def truth_rows() -> list[dict]:
    """Part 2: auto's status and largest true error on the unstable orbits."""
    import hamrkq
    from hamrkq.analysis.extended_reference import extended_reference

    rows = []
    for label, system, options, tol, exact in unstable_cases():
        sol = hamrkq.solve(system, **{"method": "auto", "atol": tol, **options})
        ham = getattr(system, "hamiltonian", system)
        if "q0" in options:
            y0 = np.array([*options["q0"], *options["p0"]], dtype=float)
        else:
            y0 = system.y0
        later = sol.t > 0
        if exact is not None:
            states, reference_error = exact(sol.t[later]), 4 * np.finfo(float).eps
        else:
            ref = extended_reference(ham, ham.parameter_values(), y0, sol.t[later], t0=0.0)
            states, reference_error = ref.y, ref.estimated_error
        error = np.abs(sol.y[later] - states).max(axis=1) / tol
        worst = int(np.argmax(error))
        rows.append({"case": label, "status": sol.status.name, "t_last": float(sol.t[-1]),
                     "z_substeps": sol.options.get("z_substeps"),
                     "error_over_tol": float(error[worst]),
                     "at": float(sol.t[later][worst]),
                     "reference_error": float(reference_error),
                     "hamrkq": os.path.dirname(hamrkq.__file__)})  # fmt: skip
        print(label, sol.status.name, f"{error[worst]:.3g}", flush=True)
    return rows


def _elsewhere(root: Path) -> list[dict]:
    """:func:`truth_rows` with the checkout at ``root``."""
    return measure.rows_at_checkout(__file__, root, "--truth-only")


def table(results: dict) -> str:
    from hamrkq.rkq.auto_rules import EXPONENTIAL_GROWTH

    m = results["machine"]
    lines = [
        "# How fast auto's estimate grows, and what auto certifies on unstable orbits",
        "",
        f"(generated by `benchmarks/error_growth.py`, run {results['started']} to "
        f"{results['finished']}; {m['cpu']}, {m['cores']} cores)",
        "",
        "## 1. The growth of the estimate over the second half of each run auto abandons or stops",
        "",
        f"Above {EXPONENTIAL_GROWTH:g}, auto runs again once with the rounding witness, "
        "and with more quencher steps only where the growth, projected to t_end, leaves "
        "the end within reach.",
        "",
        "| orbit | case | runs: quencher steps, growth (w: with the witness, dd: in "
        "double-double) | auto's result |",
        "|---|---|---|---|",
    ]
    for row in results["growth"]:
        runs = ", ".join(
            f"m={r['z_substeps']}{' w' if r['witness'] else ''}"
            f"{' dd' if r['double_double'] else ''}: {r['growth']:.3g}"
            for r in row["runs"]
        )
        lines.append(f"| {row['kind']} | {row['case']} | {runs or '-'} | "
                     f"{row['final']} at t = {row['t_last']:.6g} |")  # fmt: skip
    lines += [
        "",
        "## 2. What auto returns on the unstable orbits: the largest true error over the "
        "tolerance at its nodes",
        "",
        truth_table(results),
    ]
    return "\n".join(lines)


def truth_table(results: dict) -> str:
    """Part 2 as a table (also in docs/algorithm.md)."""
    lines = [
        f"`benchmarks/error_growth.py`, run {results['started']}: against heyoka in extended "
        "precision from the initial value (its own error, estimated, in the last column), "
        "or, on the Duffing separatrix, the exact solution x = 2 sech t.",
        "",
        "| case | checkout | status | last node | quencher steps | max true error / tol "
        "(at t) | reference's error |",
        "|---|---|---|---|---|---|---|",
    ]
    before = (results.get("before"), results.get("truth_before") or [])
    for checkout, rows in (("now", results["truth"]), before):
        for row in rows:
            lines.append(
                f"| {row['case']} | {checkout} | {row['status']} | {row['t_last']:.6g} | "
                f"{row['z_substeps']} | {row['error_over_tol']:.3g} ({row['at']:.4g}) | "
                f"{row['reference_error']:.1e} |"
            )
    return "\n".join(lines)


DOCS = HERE.parent / "docs" / "algorithm.md"
BEGIN, END = "<!-- error_growth:begin -->", "<!-- error_growth:end -->"


def write(results: dict) -> None:
    """The record, the text, and part 2's table into docs/algorithm.md."""
    (HERE / "error_growth.json").write_text(json.dumps(results, indent=1) + "\n")
    text = table(results)
    (HERE / "error_growth.txt").write_text(text + "\n")
    doc = DOCS.read_text()
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOCS.write_text(head + BEGIN + "\n" + truth_table(results) + "\n" + END + tail)
    print(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="a checkout from before the rule")
    parser.add_argument("--before-label", help="what the table calls it (its commit)")
    parser.add_argument("--from-json", action="store_true", help="only rewrite the tables")
    parser.add_argument("--truth-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.truth_only:
        print(json.dumps(truth_rows()))
        return 0
    if args.from_json:
        write(json.loads((HERE / "error_growth.json").read_text()))
        return 0
    results = measure.begin_record(1)
    results["growth"] = growth_rows()
    results["truth"] = truth_rows()
    if args.before is not None:
        results["before"] = args.before_label or str(args.before)
        results["truth_before"] = _elsewhere(args.before.resolve())
    write(measure.end_record(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
