"""``hamrkq compare`` marks the errors at the reference's floor in its tables
(found by QA: the note named the runs whose max true error is at or below the
reference's accuracy, ``compare henon_heiles --quick``: gauss6 at h = 0.0315,
0.00786 and 0.00197 with 1.8e-13 to 2.1e-13 against a reference accurate to
2.1e-12, but their cells in comparison.md and on stdout looked like any
other measured error)."""

from __future__ import annotations

import csv
import io
import re
from types import SimpleNamespace

import numpy as np
from helpers import run_cli

import hamrkq.cli.compare as compare_cli
from hamrkq.analysis.comparison import Comparison, Run, _closing_notes
from hamrkq.result import Solution, Status

ACCURACY = 2.1e-12


def _run(method: str, step: float | None, error: float, *, selected: bool = False) -> Run:
    t = np.linspace(0.0, 20.0, 5)
    sol = Solution(
        t=t, y=np.zeros((5, 2)), energy=np.zeros(5), status=Status.SUCCESS, message="ok",
        method=method, n=1, names=("q", "p"), atol=1e-8, rtol=0.0,
        stats={"steps": 4, "rejected": 0, "quenches": 0, "nfev": 100},
    )  # fmt: skip
    settings = {"atol": 1e-8, "rtol": 0.0} if step is None else {"step": step}
    return Run(method, 1.0, settings, sol, 0.01, max_error=error, selected=selected)


def _comparison() -> Comparison:
    runs = [
        _run("rk34q8", None, 9.97e-9, selected=True),
        _run("gauss6", 0.189, 8.0e-9, selected=True),
        _run("gauss6", 0.0315, 1.8e-13),
        _run("gauss6", 0.00786, 2.1e-13),
        _run("gauss6", 0.00197, ACCURACY),  # at it: on the floor too
    ]
    problem = SimpleNamespace(hamiltonian=SimpleNamespace(time_dependent=False))
    notes = _closing_notes(runs, "error", 9.97e-9, ACCURACY, problem)
    return Comparison(
        problem="henon_heiles", t_span=(0.0, 20.0), runs=tuple(runs), match="error",
        target=9.97e-9, anchor=runs[0], reference="DOP853", reference_accuracy=ACCURACY,
        backend="python", notes=tuple(notes),
    )  # fmt: skip


def _error_cells(table_lines: list[str]) -> dict[str, str]:
    """settings -> the max-true-error cell of each row of a table."""
    column = [key for key, _, _ in compare_cli.COLUMNS].index("max_true_error")
    cells = {}
    for line in table_lines:
        if line.startswith("| ") and not line.startswith("| method"):
            parts = [part.strip() for part in line.strip("|").split("|")]
            cells[parts[1]] = parts[column]
    return cells


def test_errors_at_the_floor_are_marked_as_the_note_names_them():
    result = _comparison()
    (note,) = [n for n in result.notes if "at the reference's floor" in n]
    named = set(re.findall(r"gauss6 (h=[0-9.]+) \(", note))
    assert named == {"h=0.0315", "h=0.00786", "h=0.00197"}
    text = compare_cli.markdown(result)
    sweep = text.split("## Every run of the sweep")[1].split("## Notes")[0].splitlines()
    cells = _error_cells(sweep)
    assert {s for s, cell in cells.items() if cell.endswith("*")} == named
    assert cells["h=0.0315"] == "1.80e-13*" and cells["h=0.189"] == "8.00e-09"
    legend = (
        "Max true errors marked * are at or below the reference's accuracy (~2.1e-12): at the "
        "reference's floor, mostly its own error; the run's is at most about that."
    )
    assert legend in sweep
    # the headline runs are above the floor: no mark, and no legend under that table
    headline = text.split("## Headline")[1].split("## Every run")[0]
    assert "*" not in headline.replace("**", "")


def test_the_printed_headline_marks_a_run_at_the_floor_and_says_what_the_mark_means(
    tmp_path, monkeypatch
):
    result = _comparison()
    runs = [Run(**{**r.__dict__, "selected": r.max_error < 2e-13}) for r in result.runs]
    result = Comparison(**{**result.__dict__, "runs": tuple(runs)})
    monkeypatch.setattr(compare_cli, "compare", lambda *args, **kwargs: result)
    status, stdout, _ = run_cli("compare", "henon_heiles", "--methods", "rk34q8", "gauss6",
                                "--no-plots", "--out", tmp_path / "cmp")  # fmt: skip
    assert status == 0
    cells = _error_cells(stdout.splitlines())
    assert cells == {"h=0.0315": "1.80e-13*"}
    assert "Max true errors marked * are at or below the reference's accuracy" in stdout
    markdown = (tmp_path / "cmp" / "comparison.md").read_text()
    assert markdown.count("Max true errors marked *") == 2  # under both tables


def test_the_csv_and_json_rows_say_which_errors_are_at_the_floor():
    # Found in review: only the tables carried the mark; a reader of
    # comparison.csv or comparison.json could not tell those errors apart.
    result = _comparison()
    rows = result.rows()
    floor = {row["settings"] for row in rows if row["at_reference_floor"]}
    assert floor == {"h=0.0315", "h=0.00786", "h=0.00197"}
    csv_rows = list(csv.DictReader(io.StringIO(compare_cli._csv(result))))
    assert [row["at_reference_floor"] for row in csv_rows] == [
        "False", "False", "True", "True", "True"
    ]  # fmt: skip
    assert [row["at_reference_floor"] for row in result.to_dict()["runs"]] == [
        False, False, True, True, True
    ]  # fmt: skip
