"""``--force``: hamrkq's own earlier outputs in ``--out`` are removed, a
user's other files kept (hamrkq.io.output_dir.OWN_FILES).

Before, only the names of ``run``'s figures, ``compare``'s and ``reproduce``'s
files were known: ``run --csv`` then ``run --force`` without ``--csv`` left
the old 147-row ``solution.csv`` beside the new 16-node ``solution.npz``;
``ensemble --force --no-plots`` left ``ensemble_map.png`` and
``ensemble_orbits.png``, and ``poincare --force --no-plots`` ``section.png``.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from hamrkq.cli import main
from hamrkq.io.output_dir import LOCK_NAME, OWN_FILES, is_own


def _cli(args: list[str]) -> tuple[int, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(args)
    assert "Traceback" not in stderr.getvalue()
    return status, stdout.getvalue() + stderr.getvalue()


def _files(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir())


#: Each command twice into one --out: first writing more files, then with
#: --force writing fewer.  (command, first, second, files after the first,
#: files after the second)
CASES = {
    "run": (
        ["run", "harmonic", "--csv", "--backend", "python", "--dpi", "20"],
        ["run", "harmonic", "--t-end", "5", "--no-plots", "--backend", "python"],
        {
            "solution.npz",
            "solution.csv",
            "summary.json",
            "figure1_solution.png",
            "figure2_global_error.png",
            "figure2_global_error_true.png",
            "figure3_trajectory_error.png",
            "figure3_trajectory_error_true.png",
            "figure4_rk8_error.png",
        },
        {"solution.npz", "summary.json"},
    ),
    "ensemble": (
        ["ensemble", "pendulum", "--grid", "q=-1:1:3", "--samples", "3", "--dpi", "20"],
        ["ensemble", "pendulum", "--grid", "q=-1:1:3", "--no-plots"],
        {"ensemble.npz", "ensemble_map.png", "ensemble_orbits.png", "summary.json"},
        {"ensemble.npz", "summary.json"},
    ),
    "poincare": (
        ["poincare", "henon_heiles", "--orbits", "2", "--t-end", "20", "--dpi", "20"],
        ["poincare", "henon_heiles", "--orbits", "3", "--t-end", "20", "--no-plots"],
        {"section.npz", "section.png", "summary.json"},
        {"section.npz", "summary.json"},
    ),
}


@pytest.mark.parametrize("command", sorted(CASES))
def test_force_removes_what_an_earlier_command_wrote_and_keeps_other_files(command, tmp_path):
    first, second, before, after = CASES[command]
    out = tmp_path / "out"
    status, text = _cli([*first, "--out", str(out)])
    assert status == 0, text
    assert set(_files(out)) == before
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["files"]) == before
    # Every name a command writes is hamrkq's own: --force may remove it.
    assert all(is_own(name) for name in before), [n for n in before if not is_own(n)]

    (out / "notes.txt").write_text("mine")
    (out / "solution-mine.csv").write_text("mine too")
    status, text = _cli([*second, "--out", str(out), "--force"])
    assert status == 0, text
    assert set(_files(out)) == after | {"notes.txt", "solution-mine.csv"}
    assert (out / "notes.txt").read_text() == "mine"
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["files"]) == after


def test_the_names_of_hamrkqs_own_files():
    for ours in ("solution.csv", "solution_rk34.npz", "ensemble_orbits.png", "section.npz"):
        assert is_own(ours), ours
    for mine in ("notes.txt", "solution.txt", "section.pdf", "my_summary.json", LOCK_NAME):
        assert not is_own(mine), mine
    # QA: the patterns solution*.npz and figure[0-9]_*.png took a user's copies
    for mine in ("solution_previous.npz", "solution-old.npz", "figure9_x.png",
                 "figure1_solution_v2.png"):  # fmt: skip
        assert not is_own(mine), mine
    assert len(set(OWN_FILES)) == len(OWN_FILES)
