"""Output times (``t_eval``): landing a step on each, or passing it with dense output.

    python benchmarks/dense_t_eval.py [--shares 0 0.25 0.5 0.75 0.9] [--repeat 3]

A run asked for ``t_eval`` times used to land a step on every one of them:
as many steps as times where the times are denser than the steps.  Now a
time closer to the step's start than ``dense_share`` of the free step is
passed, and its value is dense output (one quencher step from the nearer
node, ``hamrkq.rkq.loop.write_dense``); a time further into the step is
still landed on (a shortened step costs less than a dense value there).
This script runs each case at each share (0: every time landed on, as
before) through ``solve``, and records the steps, the evaluations
(``nfev + njev``, and auto's discarded runs'), the median time of
``--repeat`` warm runs and, on Kepler
(its exact solution), the largest true error over the tolerance at the
output times.  Writes ``benchmarks/dense_t_eval.json`` and ``.md``, and
the summary in ``docs/algorithm.md`` (``--docs-only``: from the JSON).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (timing, the record)

import hamrkq  # noqa: E402
from hamrkq.rkq.config import DENSE_SHARE, Settings  # noqa: E402
from hamrkq.solve import dispatch  # noqa: E402

#: (label, problem, its parameters, t_end, tolerances, output times, method)
CASES = [
    *(("kepler e=0.6, 10 orbits", "kepler", {"e": 0.6}, 20 * math.pi, {"atol": 1e-9}, n, m)
      for m in ("auto", "rk34q8") for n in (51, 501, 5001, 50001)),
    ("prentice2011", "prentice2011", {}, 4000.0, {"atol": 1e-6}, 2001, "auto"),
    ("prentice2011", "prentice2011", {}, 4000.0, {"atol": 1e-6}, 40001, "auto"),
    ("outer_solar_system, file tolerances x 100", "outer_solar_system", {}, 500_000.0,
     {"scale": 100.0}, 2001, "auto"),
]  # fmt: skip


def tolerances(problem, given: dict) -> dict:
    if "scale" not in given:
        return {"atol": given["atol"], "rtol": 0.0}
    dim, integration = problem.hamiltonian.dim, problem.integration
    return {k: given["scale"] * np.broadcast_to(np.asarray(integration.get(k, d), float), (dim,))
            for k, d in (("atol", 1e-6), ("rtol", 0.0))}  # fmt: skip


def one_run(case, share: float, repeat: int) -> dict:
    label, name, params, t_end, given, n, method = case
    problem = hamrkq.load_problem(name, **params)
    t0 = float(problem.t_span[0])
    t_eval = np.linspace(t0, t_end, n)
    options = tolerances(problem, given)
    dispatch.Settings = functools.partial(Settings, dense_share=share)
    try:

        def run():
            return hamrkq.solve(problem, t_span=(t0, t_end), t_eval=t_eval, method=method,
                                backend="numba", **options)  # fmt: skip

        run()  # compile or load outside the clock
        timing, sol = measure.timed(run, repeat)
    finally:
        dispatch.Settings = Settings
    row = {"case": label, "method": sol.method if method != "auto" else f"auto ({sol.method})",
           "times": n, "share": share, "status": sol.status.name,
           "steps": int(sol.stats["steps"]),
           "evaluations": int(sol.stats["nfev"] + sol.stats["njev"]
                              + sol.stats.get("discarded_evaluations", 0)),
           "seconds": timing.median, "spread": timing.spread}  # fmt: skip
    if problem.exact is not None and sol.t.size:
        tol = float(np.max(options["atol"]))
        row["max_error_over_tol"] = float(np.abs(sol.y - problem.exact(sol.t)).max() / tol)
    measure_log = f"{label} {method} n={n} share={share}: {row['steps']} steps, "
    print(measure_log + f"{row['evaluations']} evaluations, {timing.median:.3g} s", flush=True)
    return row


def table(results: dict) -> str:
    lines = [
        "| case | method | output times | share | status | steps | evaluations "
        "| time (s) | max true error / tol |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results["rows"]:
        err = r.get("max_error_over_tol")
        lines.append(
            f"| {r['case']} | {r['method']} | {r['times']} | {r['share']:g} | {r['status']} | "
            f"{r['steps']} | {r['evaluations']} | {r['seconds']:.3g} | "
            f"{'-' if err is None else f'{err:.3f}'} |"
        )
    lines += ["", f"Run {results['started']} to {results['finished']}, {results['rounds']} warm "
              f"runs a row (median); load average {results['machine']['load_average']} at the "
              f"start and {results['load_average_end']} at the end.  Share 0: every output "
              "time landed on (before)."]  # fmt: skip
    return "\n".join(lines)


#: docs/algorithm.md's summary of the run: the chosen share beside landing on every time.
DOC = HERE.parent / "docs" / "algorithm.md"
MARKERS = ("<!-- dense-t-eval:begin -->", "<!-- dense-t-eval:end -->")


def summary(results: dict, chosen: float) -> str:
    """Markdown: each case landing on every time (share 0) and at ``chosen``,
    and the sum over the cases of the evaluations relative to share 0."""
    rows = {(r["case"], r["method"], r["times"], r["share"]): r for r in results["rows"]}
    lines = [
        f"| case | method | output times | steps: every time landed on, share {chosen:g} "
        f"| evaluations: landed on, share {chosen:g} | max true error / tol at share {chosen:g} |",
        "|---|---|---|---|---|---|",
    ]
    for case, method, times, share in rows:
        if share != 0.0 or (case, method, times, chosen) not in rows:
            continue
        before, now = rows[(case, method, times, 0.0)], rows[(case, method, times, chosen)]
        err = now.get("max_error_over_tol")
        lines.append(
            f"| {case} | {method} | {times} | {before['steps']}, {now['steps']} | "
            f"{before['evaluations']}, {now['evaluations']} | "
            f"{'-' if err is None else f'{err:.3f}'} |"
        )
    relative: dict[float, float] = {}
    for (case, method, times, share), r in rows.items():
        base = rows[(case, method, times, 0.0)]["evaluations"]
        relative[share] = relative.get(share, 0.0) + r["evaluations"] / base
    cases = sum(1 for key in rows if key[3] == 0.0)
    totals = ", ".join(f"{share:g}: {total / cases:.2f}" for share, total in relative.items())
    lines += ["", f"Evaluations relative to landing on every time, averaged over the {cases} "
              f"cases, by share: {totals} (`benchmarks/dense_t_eval.py`, run "
              f"{results['started']})."]  # fmt: skip
    return "\n".join(lines)


def fill_doc(results: dict, chosen: float) -> None:
    text = DOC.read_text()
    begin, end = MARKERS
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    DOC.write_text(f"{head}{begin}\n{summary(results, chosen)}\n{end}{tail}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shares", type=float, nargs="*", default=[0.0, 0.25, 0.5, 0.75, 0.9])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, default=HERE / "dense_t_eval.json")
    parser.add_argument("--docs-only", action="store_true",
                        help="fill docs/algorithm.md from the last run's JSON")  # fmt: skip
    args = parser.parse_args(argv)
    if not args.docs_only:
        results = measure.begin_record(args.repeat)
        results["rows"] = [
            one_run(case, share, args.repeat) for case in CASES for share in args.shares
        ]
        measure.save_record(args.out.parent, args.out.stem, measure.end_record(results), table)
    fill_doc(json.loads(args.out.read_text()), DENSE_SHARE)
    return 0


if __name__ == "__main__":
    sys.exit(main())
