"""Small helpers shared by the test modules."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def counters(stats: Mapping[str, Any]) -> dict[str, Any]:
    """A solution's stats without its timings (``compile_s``, ``integrate_s``),
    which differ from run to run."""
    return {key: value for key, value in stats.items() if not key.endswith("_s")}


def without_timings(report: Mapping[str, Any]) -> dict[str, Any]:
    """A diagnostics or summary mapping whose ``stats`` lost their timings."""
    report = dict(report)
    if "stats" in report:
        report["stats"] = counters(report["stats"])
    return report
