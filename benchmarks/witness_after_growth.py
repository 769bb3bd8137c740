"""What the witness-after-growth rule changed in ``benchmarks/promise.py``'s runs.

    python benchmarks/witness_after_growth.py BEFORE.json [AFTER.json]

Compares two records of ``promise.py`` (``method="auto"`` on every catalogue
problem at eight tolerances, against heyoka's extended-precision
reference): BEFORE made with every exponentially grown run made again with
the rounding witness, AFTER (default ``benchmarks/promise.json``) with the
witness run again only where the rounding so amplified could reach the
tolerance (``hamrkq.rkq.witness_rules.needs_witness_after_run``).  For
each run whose evaluations or result changed: both counts, both largest
true errors over the tolerance, both statuses.  Writes
``benchmarks/witness_after_growth.md``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def table(before: list[dict], after: list[dict]) -> str:
    old = {(r["problem"], r["tolerance"]): r for r in before}
    lines = [
        "| problem | tolerance | evaluations before | after | ratio | status before / after "
        "| max true error / tol before / after |",
        "|---|---|---|---|---|---|---|",
    ]
    total_before = total_after = 0
    worst = 0.0
    for row in after:
        was = old[(row["problem"], row["tolerance"])]
        total_before += was["evaluations"]
        total_after += row["evaluations"]
        if not row["reference_limits"]:
            worst = max(worst, row["max_error_over_tol"])
        if was["evaluations"] == row["evaluations"] and was["status"] == row["status"]:
            continue
        lines.append(
            f"| {row['problem']} | {row['tolerance']} | {was['evaluations']} | "
            f"{row['evaluations']} | {row['evaluations'] / was['evaluations']:.2f} | "
            f"{was['status']} / {row['status']} | {was['max_error_over_tol']:.3f} / "
            f"{row['max_error_over_tol']:.3f} |"
        )
    lines += [
        "",
        f"All {len(after)} runs: {total_before} evaluations before, {total_after} after "
        f"({total_after / total_before:.2f}); the largest true error over the tolerance "
        f"of the runs the reference can judge, after: {worst:.3f}.",
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    before = json.loads(Path(argv[0]).read_text())
    after_path = Path(argv[1]) if len(argv) > 1 else HERE / "promise.json"
    after = json.loads(after_path.read_text())
    text = table(before, after)
    (HERE / "witness_after_growth.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
