"""What RKQ's structure costs beside heyoka: auto's run, and its reported track alone.

    python benchmarks/track_costs.py [--quick] [--cases prentice2011_1e-6 ...]

An RKQ run is two tracks over the same steps: the reported one, an explicit
Runge-Kutta pair with local extrapolation whose steps keep its local error
below the tolerance (it is quenched, never allowed a longer step), and the
quencher with its estimate of Gamma.  The reported track alone is therefore
a floor under any member's time: this script measures it beside auto's whole
run and heyoka's (``benchmarks/peers.py``'s cases, heyoka at the loosest
Taylor order whose true error is at or below auto's, timed the same way):

- ``auto``: ``solve(..., method="auto")``, warm, median of the case's runs;
- auto's pair alone: the same pair (``Member`` with no quencher, so no
  Gamma, no quenches) over the same interval at the same tolerances, through
  the same compiled kernel (``hamrkq.rkq.driver.Integration``);
- the cheapest pair alone: every pair of the family alone, the fastest.

Writes ``benchmarks/track_costs.json`` and ``track_costs.md`` (or
``--out``).  Times are medians on a shared machine: read the ratios.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import measure  # noqa: E402  (timing, the record)
from peers import CASES, Bench, log  # noqa: E402  (the cases, heyoka's row)

from hamrkq.backends.first_use import kernel_functions  # noqa: E402
from hamrkq.rkq.config import Settings  # noqa: E402
from hamrkq.rkq.driver import Integration  # noqa: E402
from hamrkq.rkq.family import MEMBERS  # noqa: E402
from hamrkq.rkq.layout import GAMMA_OFF, QUENCH_NODE, RULE_COMPONENTWISE  # noqa: E402

DEFAULT_CASES = ("prentice2011_1e-6", "prentice2011_1e-9", "kepler_e0.9",
                 "outer_solar_system", "fpu")  # fmt: skip


def pairs() -> dict[str, str]:
    """Each pair of the family (``"rk67"``) and a member that carries it."""
    found: dict[str, str] = {}
    for name, member in MEMBERS.items():
        if member.use_z and member.gamma == "shadow":
            found.setdefault(name.split("q")[0], name)
    return found


def pair_alone(bench: Bench, member_name: str):
    """A warm run of ``member_name``'s pair without its quencher: (timing, steps)."""
    member = replace(MEMBERS[member_name], name=member_name.split("q")[0], quencher=None)
    functions = kernel_functions(bench.ham, "off")
    settings = Settings(QUENCH_NODE, RULE_COMPONENTWISE, GAMMA_OFF, max_steps=10**9,
                        t_eval=bench.grid)  # fmt: skip

    def run():
        return Integration(functions, member, bench.params, bench.t0, bench.y0, bench.t_end,
                           bench.atol, bench.rtol, settings).run()  # fmt: skip

    run()  # compile or load outside the clock
    timing, out = measure.timed(run, bench.repeat)
    return timing, int(out.stats["steps"]), int(out.stats["nfev"])


def one_case(case, quick: bool) -> dict:
    bench = Bench(case, quick, None)
    log(f"== {case.key}: t in [{bench.t0:g}, {bench.t_end:g}]")
    bench.check_reference()
    auto = bench.hamrkq_row("auto")
    sol = bench.solve("auto")
    member = sol.method  # the member auto ran
    log(f"    auto ({member}): {auto['seconds']:.3g} s, error {auto['max_true_error']:.3g}")
    heyoka = bench.heyoka_row(auto["max_true_error"])
    log(f"    heyoka: {heyoka['seconds']:.3g} s at error {heyoka['max_true_error']:.3g}")
    alone = {}
    for pair, carrier in pairs().items():
        timing, steps, nfev = pair_alone(bench, carrier)
        alone[pair] = {"seconds": timing.median, "spread": timing.spread, "steps": steps,
                       "nfev": nfev}  # fmt: skip
        log(f"    {pair} alone: {timing.median:.3g} s, {steps} steps")
    own = member.split("q")[0]
    cheapest = min(alone, key=lambda p: alone[p]["seconds"])
    return {"case": case.key, "t_span": [bench.t0, bench.t_end], "auto": auto,
            "auto_member": member, "auto_steps": int(sol.stats["steps"]),
            "heyoka": heyoka, "pairs_alone": alone, "own_pair": own,
            "cheapest_pair": cheapest}  # fmt: skip


def table(results: dict) -> str:
    lines = [
        "| case | heyoka (s) | auto (s) | auto / heyoka | auto's pair alone (s) "
        "| / heyoka | cheapest pair alone (s) | / heyoka | steps: auto, its pair alone |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in results["cases"]:
        h, a = c["heyoka"]["seconds"], c["auto"]["seconds"]
        own, cheap = c["pairs_alone"][c["own_pair"]], c["pairs_alone"][c["cheapest_pair"]]
        lines.append(
            f"| {c['case']} | {h:.3g} | {a:.3g} ({c['auto_member']}) | {a / h:.1f} | "
            f"{own['seconds']:.3g} ({c['own_pair']}) | {own['seconds'] / h:.1f} | "
            f"{cheap['seconds']:.3g} ({c['cheapest_pair']}) | {cheap['seconds'] / h:.1f} | "
            f"{c['auto_steps']}, {own['steps']} |"
        )
    lines += ["", f"Run {results['started']} to {results['finished']}; load average "
              f"{results['machine']['load_average']} at the start and "
              f"{results['load_average_end']} at the end.  heyoka at the loosest Taylor "
              "order whose true error is at or below auto's (benchmarks/peers.py's "
              "search).  Every pair alone, steps and seconds:", ""]  # fmt: skip
    for c in results["cases"]:
        cells = ", ".join(f"{p} {v['seconds']:.3g} s ({v['steps']} steps)"
                          for p, v in c["pairs_alone"].items())  # fmt: skip
        lines.append(f"- {c['case']}: {cells}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short spans, to check the script")
    parser.add_argument("--cases", nargs="*", default=list(DEFAULT_CASES))
    parser.add_argument("--out", type=Path, default=HERE / "track_costs.json")
    args = parser.parse_args(argv)
    results = measure.begin_record(0, quick=args.quick)
    chosen = [c for c in CASES if c.key in args.cases]
    results["cases"] = [one_case(case, args.quick) for case in chosen]
    measure.save_record(args.out.parent, args.out.stem, measure.end_record(results), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
