"""`hamrkq reproduce prentice2011`: promised files, parity with the library, the numbers."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import counters

import hamrkq
from hamrkq.analysis.diagnostics import diagnose
from hamrkq.cli import main
from hamrkq.io.report import jsonable
from hamrkq.solve import solve

FILES = {
    "comparison.md",
    "summary.json",
    "solution_rk34q8.npz",
    "solution_rk34.npz",
    "figure1_solution.png",
    "figure2_global_error.png",
    "figure2_global_error_true.png",
    "figure3_trajectory_error.png",
    "figure3_trajectory_error_true.png",
    "figure4_rk8_error.png",
}
#: Every number the paper reports, as keyed in the problem file's [expected] table.
PAPER_KEYS = (
    "nodes",
    "max_global_error_q",
    "max_global_error_p",
    "trajectory_error_bound",
    "energy",
    "rk34_max_global_error",
    "rk34_energy_drift",
    "rk8_estimated_global_error",
)


def assert_png_not_blank(path: Path) -> None:
    from matplotlib.image import imread

    rgb = imread(path)[..., :3]
    assert rgb.shape[0] > 200 and rgb.shape[1] > 200
    ink = np.any(rgb < 0.9, axis=-1).mean()  # share of pixels that are not (near) white
    assert 0.01 < ink < 0.9, f"{path.name}: {ink:.3%} of the pixels are drawn"
    packed = (np.round(rgb * 255).astype(np.uint32) * np.array([1 << 16, 1 << 8, 1])).sum(-1)
    assert np.unique(packed).size > 20  # text, lines and colours, not a flat fill


def _reproduce(out: Path, *extra: str) -> tuple[int, str]:
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        status = main(["reproduce", "prentice2011", "--out", str(out), *extra])
    return status, stdout.getvalue()


def _check_files(out: Path) -> dict:
    assert {p.name for p in out.iterdir()} == FILES
    for name in FILES:
        if name.endswith(".png"):
            assert_png_not_blank(out / name)
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["files"]) == FILES
    return summary


def _table(out: Path) -> dict[str, list[str]]:
    """comparison.md's table: quantity -> [paper, this run, true]."""
    rows = {}
    for line in (out / "comparison.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 4 and cells[0] != "quantity":
            rows[cells[0]] = cells[1:]
    return rows


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce") / "short"
    status, stdout = _reproduce(out, "--t-end", "100")
    return status, out, stdout


def test_short_reproduction_writes_every_promised_file(short_run):
    status, out, stdout = short_run
    assert status == 0
    summary = _check_files(out)
    assert summary["settings"]["t_span"] == [0.0, 100.0]
    text = (out / "comparison.md").read_text()
    assert "shortened run" in text
    # stdout says it too, under its header, before the paper's numbers (QA)
    assert stdout.splitlines()[1].startswith("This is a shortened run"), stdout
    expected = hamrkq.load_problem("prentice2011").expected
    rows = summary["comparison"]
    assert [r["key"] for r in rows] == list(PAPER_KEYS)
    for row in rows:  # the paper's column is the problem file's value, with its source
        value = expected[row["key"]]
        shown = str(value) if isinstance(value, int) else f"{value:.4g}"
        assert shown in row["paper"] and row["source"] == expected[row["key"] + "_source"]
    assert set(_table(out)) == {r["quantity"] for r in rows}
    assert "RK34Q8 max abs. global error in q" in stdout


def test_short_reproduction_matches_the_library(short_run):
    """The numbers in summary.json and comparison.md are those of solve + diagnose."""
    _, out, _ = short_run
    summary = json.loads((out / "summary.json").read_text())
    problem = hamrkq.load_problem("prentice2011")
    table = _table(out)
    for method, label in (("rk34q8", "RK34Q8"), ("rk34", "RK34")):
        sol = solve(problem, method=method, atol=1e-6, rtol=0.0, t_span=(0, 100))
        diag = diagnose(sol, problem, reference="independent")
        run = summary["runs"][label]
        mine, theirs = jsonable(diag.to_dict()), dict(run["diagnostics"])
        mine["stats"], theirs["stats"] = counters(mine["stats"]), counters(theirs["stats"])
        assert theirs == mine
        assert counters(run["stats"]) == counters(sol.stats)
        if method == "rk34q8":
            est, true = diag.estimated, diag.error
            assert table["RK34Q8 max abs. global error in q"][1:] == [
                f"{est.max_abs[0]:.3e}", f"{true.max_abs[0]:.3e}"
            ]  # fmt: skip
            assert table["RK8 track: max global error (Gamma est. / true)"][1] == (
                f"{diag.gamma_max:.3e}"
            )
            # the RK8 track's true error, computed here independently of the command
            z_error = np.max(np.abs(sol.z - diag.series["reference"]))
            assert table["RK8 track: max global error (Gamma est. / true)"][2] == (
                f"{z_error:.3e}"
            )
        else:
            assert f"q {diag.error.max_abs[0]:.3e}" in table["RK34 max abs. global error"][2]
            assert f"{diag.energy.final:+.3e}" in table["RK34 drift of H over the run"][1]


def test_unknown_experiment_exits_2(tmp_path, capsys):
    assert main(["reproduce", "nobody1999", "--out", str(tmp_path / "x")]) == 2
    assert "invalid choice" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_full_reproduction_of_the_paper(tmp_path):
    """The paper's whole experiment (about 45 s with the Python backend)."""
    out = tmp_path / "full"
    status, _ = _reproduce(out)
    assert status == 0
    summary = _check_files(out)
    assert "shortened run" not in (out / "comparison.md").read_text()
    q8 = summary["runs"]["RK34Q8"]["diagnostics"]
    rk34 = summary["runs"]["RK34"]["diagnostics"]
    # RKQ: every node within delta of the RK8 track, and truly within it to 5 %
    assert max(q8["estimated_global_error"]["max_abs"].values()) <= 1e-6
    assert max(q8["global_error"]["max_abs"].values()) <= 1.05e-6
    assert q8["global_error"]["bound_ratio"] <= 1.05
    assert q8["energy_bound_ratio"] <= 1.05
    # RK34 alone: the error grows far beyond the tolerance (the paper: ~0.02)
    assert max(rk34["global_error"]["max_abs"].values()) > 0.01
    assert rk34["energy"]["max_abs"] > 10 * q8["energy"]["max_abs"]
    # the RK8 track: Gamma and the true error agree within a factor 10, both far
    # below the tolerance (and far above the paper's 1.86e-12)
    true_rk8 = max(summary["rk8_track_true_error"]["max_abs"].values())
    gamma = q8["rk8_estimated_global_error_max"]
    assert 1e-11 < true_rk8 < 1e-8 and 0.1 < gamma / true_rk8 < 10
    assert 40_000 < summary["runs"]["RK34Q8"]["nodes"] < 120_000


def test_interrupt_keeps_the_run_so_far_and_exits_1(tmp_path, monkeypatch):
    from hamrkq.cli import reproduce as reproduce_module
    from hamrkq.io.report import ProgressBar

    class Interrupting(ProgressBar):
        def __call__(self, fraction: float, t: float) -> None:
            raise KeyboardInterrupt

    monkeypatch.setattr(reproduce_module, "ProgressBar", Interrupting)
    out = tmp_path / "interrupted"
    status, _ = _reproduce(out)
    assert status == 1
    assert {p.name for p in out.iterdir()} == {"solution_rk34q8.npz", "summary.json"}
    summary = json.loads((out / "summary.json").read_text())
    run = summary["runs"]["RK34Q8"]
    assert summary["interrupted"] == "RK34Q8"
    assert run["status"] == "INTERRUPTED" and run["partial"] is True
    assert 1 < run["nodes"] < 62000 and run["t_final"] < 4000
