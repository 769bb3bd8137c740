"""Each note of a comparison is made once (found by QA: ``hamrkq compare
harmonic --methods rk34q8 auto scipy:DOP853 verlet --t-end 20 --quick``
printed "verlet: reaching the target error would take about ... f
evaluations ...; not run" twice, on stdout and in comparison.md: the
extension rounds asked verlet again though its runs had not changed)."""

from __future__ import annotations

from collections import Counter

from helpers import run_cli

import hamrkq
from hamrkq.analysis.comparison import compare

METHODS = ["rk34q8", "auto", "scipy:DOP853", "verlet"]


def test_a_declined_extension_is_noted_once(tmp_path):
    result = compare(hamrkq.load_problem("harmonic"), METHODS, t_end=20, quick=True)
    counts = Counter(result.notes)
    assert counts and max(counts.values()) == 1, counts
    assert sum("verlet: reaching the target error" in n for n in result.notes) == 1


def test_cli_prints_and_writes_each_note_once(tmp_path):
    out = tmp_path / "cmp"
    status, stdout, _ = run_cli("compare", "harmonic", "--methods", *METHODS,
                                "--t-end", "20", "--quick", "--out", out)  # fmt: skip
    assert status == 0
    notes = [line for line in stdout.splitlines() if line.startswith("note: ")]
    assert notes and len(notes) == len(set(notes))
    assert sum("verlet: reaching the target error" in line for line in notes) == 1
    markdown = (out / "comparison.md").read_text()
    assert markdown.count("verlet: reaching the target error") == 1
