"""`hamrkq run`: promised files, CLI/API parity, exit codes, output-directory policy."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import counters, without_timings

import hamrkq
from hamrkq import Solution, Status
from hamrkq.analysis.diagnostics import diagnose
from hamrkq.cli import main
from hamrkq.cli import run as run_module
from hamrkq.io.report import OutputDir, ProgressBar, jsonable
from hamrkq.solve import solve

FIGURES = (
    "figure1_solution.png",
    "figure2_global_error.png",
    "figure2_global_error_true.png",
    "figure3_trajectory_error.png",
    "figure3_trajectory_error_true.png",
    "figure4_rk8_error.png",
)


def _summary(folder: Path) -> dict:
    # strict JSON: a NaN or Infinity in the file would raise here
    def refuse(token):
        raise AssertionError(f"non-standard JSON constant {token}")

    return json.loads((folder / "summary.json").read_text(), parse_constant=refuse)


def assert_png_not_blank(path: Path) -> None:
    from matplotlib.image import imread

    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200
    rgb = image[..., :3]
    ink = np.any(rgb < 0.9, axis=-1).mean()  # share of pixels that are not (near) white
    assert 0.01 < ink < 0.9, f"{path.name}: {ink:.3%} of the pixels are drawn"
    packed = (np.round(rgb * 255).astype(np.uint32) * np.array([1 << 16, 1 << 8, 1])).sum(-1)
    assert np.unique(packed).size > 20  # text, lines and colours, not a flat fill


@pytest.fixture(scope="module")
def prentice_run(tmp_path_factory):
    """One `hamrkq run prentice2011 --t-end 50` with figures, shared by tests."""
    out = tmp_path_factory.mktemp("run") / "prentice"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        status = main(["run", "prentice2011", "--t-end", "50", "--out", str(out)])
    return status, out, stdout.getvalue()


def test_run_writes_every_promised_file(prentice_run):
    status, out, _ = prentice_run
    assert status == 0
    names = {path.name for path in out.iterdir()}
    assert names == {"summary.json", "solution.npz", *FIGURES}
    assert set(_summary(out)["files"]) == names
    for name in FIGURES:
        assert_png_not_blank(out / name)


def test_summary_numbers_equal_the_library_call(prentice_run):
    """CLI/API parity: the same settings through solve + diagnose give the same numbers."""
    _, out, _ = prentice_run
    summary = _summary(out)
    problem = hamrkq.load_problem("prentice2011")
    sol = solve(problem, t_span=(0, 50))
    diag = diagnose(sol, problem, reference="independent")
    assert without_timings(summary["diagnostics"]) == without_timings(jsonable(diag.to_dict()))
    assert counters(summary["stats"]) == counters(sol.stats)
    assert summary["nodes"] == len(sol) and summary["t_final"] == 50.0
    assert summary["status"] == "SUCCESS" and summary["partial"] is False
    assert summary["settings"]["solve"] == jsonable(dict(sol.options))
    assert summary["settings"]["reference"] == "independent"
    saved = Solution.load(out / "solution.npz")
    for name in ("t", "y", "z", "global_error", "gamma", "energy", "quenched"):
        np.testing.assert_array_equal(getattr(saved, name), getattr(sol, name))
    # the numbers themselves: RKQ keeps every node within delta = 1e-6 of the RK8
    # track, and the true error (independent reference) is within it too
    est = summary["diagnostics"]["estimated_global_error"]
    true = summary["diagnostics"]["global_error"]
    assert true["source"] == "independent" and true["reference_accuracy"] < 1e-10
    assert max(est["max_abs"].values()) <= 1e-6
    assert max(true["max_abs"].values()) <= 1.05e-6
    assert 0.5 < true["bound_ratio"] <= 1.05
    assert summary["diagnostics"]["energy_bound_ratio"] <= 1.05
    versions = summary["versions"]
    assert versions["numpy"] == np.__version__ and versions["hamrkq"]


def test_stdout_table_shows_the_summary_numbers(prentice_run):
    _, out, stdout = prentice_run
    summary = _summary(out)
    diag = summary["diagnostics"]
    assert f"{summary['nodes']} (t = 0 .. 50)" in stdout
    assert f"{summary['stats']['quenches']}" in stdout
    assert f"q {diag['global_error']['max_abs']['q']:.3e}" in stdout
    assert f"{diag['energy']['max_abs']:.3e}" in stdout
    assert f"{diag['energy_bound_ratio']:.4f}" in stdout
    assert "wall time" in stdout and str(out) in stdout
    # hamrkq's promise per component beside the paper's Euclidean ratio (QA)
    true = diag["global_error"]
    worst = f"max {true['component_ratio']:.4f} ({true['component_ratio_name']}, t="
    assert "error / tolerance (worst component)" in stdout and worst in stdout
    assert "trajectory / paper's bound" in stdout and 0.5 < true["component_ratio"] <= 1.05


def test_exact_reference_is_the_default_where_the_problem_has_one(tmp_path, capsys):
    out = tmp_path / "harmonic"
    assert main(["run", "harmonic", "--out", str(out), "--no-plots"]) == 0
    summary = _summary(out)
    problem = hamrkq.load_problem("harmonic")
    sol = solve(problem)
    diag = diagnose(sol, problem, reference="exact")
    assert without_timings(summary["diagnostics"]) == without_timings(jsonable(diag.to_dict()))
    true = summary["diagnostics"]["global_error"]
    assert true["source"] == "exact"
    # atol 1e-8 from the problem file: the true error stays within the tolerance
    assert max(true["max_abs"].values()) <= 1.05e-8
    assert {p.name for p in out.iterdir()} == {"summary.json", "solution.npz"}


def test_rk34_without_reference(tmp_path, capsys):
    out = tmp_path / "rk34"
    argv = ["run", "prentice2011", "--method", "rk34", "--t-end", "100",
            "--reference", "none", "--atol", "1e-7", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    summary = _summary(out)
    assert summary["diagnostics"]["global_error"] is None
    assert summary["diagnostics"]["estimated_global_error"] is None
    assert summary["settings"]["solve"]["atol"] == [1e-7, 1e-7]
    # only Figure 1 can be drawn: no RK8 track and no reference
    assert {p.name for p in out.iterdir()} == {"summary.json", "solution.npz", FIGURES[0]}
    assert any("figure2_global_error.png not drawn" in note for note in summary["notes"])
    text = capsys.readouterr().out
    assert "n/a (no quencher)" in text


def test_parameters_override_the_problem(tmp_path, capsys):
    out = tmp_path / "kepler"
    argv = ["run", "kepler", "--param", "e=0.3", "--t-end", "6.3", "--no-plots",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    summary = _summary(out)
    assert summary["settings"]["solve"]["parameters"] == {"e": 0.3}
    assert summary["problem"]["q0"] == [pytest.approx(0.7), 0.0]  # q0 = 1 - e follows
    problem = hamrkq.load_problem("kepler", e=0.3)
    sol = solve(problem, t_span=(problem.t_span[0], 6.3))
    assert counters(summary["stats"]) == counters(sol.stats)
    # Kepler has an exact solution: the true error is measured against it
    true = summary["diagnostics"]["global_error"]
    assert true["source"] == "exact"
    atol = summary["settings"]["solve"]["atol"][0]
    assert max(true["max_abs"].values()) <= 1.05 * atol


def test_failed_integration_exits_1_and_keeps_partial_results(tmp_path, capsys):
    out = tmp_path / "failed"
    argv = ["run", "prentice2011", "--max-steps", "200", "--out", str(out), "--no-plots"]
    assert main(argv) == 1
    summary = _summary(out)
    assert summary["partial"] is True and summary["success"] is False
    assert summary["status"] == "MAX_STEPS"
    saved = Solution.load(out / "solution.npz")
    assert saved.status is Status.MAX_STEPS and saved.partial
    assert len(saved) == summary["nodes"] > 100 and saved.t[-1] < 4000
    # the partial run is still diagnosed against the independent reference
    assert max(summary["diagnostics"]["global_error"]["max_abs"].values()) <= 1.05e-6
    captured = capsys.readouterr()
    assert "MAX_STEPS (partial results)" in captured.out and "max_steps = 200" in captured.out


class _InterruptingBar(ProgressBar):
    def __call__(self, fraction: float, t: float) -> None:
        raise KeyboardInterrupt


def test_interrupt_writes_partial_results_and_exits_1(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(run_module, "ProgressBar", _InterruptingBar)
    out = tmp_path / "interrupted"
    argv = ["run", "prentice2011", "--method", "rk34", "--t-end", "400",
            "--out", str(out), "--no-plots", "--reference", "none"]  # fmt: skip
    assert main(argv) == 1
    summary = _summary(out)
    assert summary["status"] == "INTERRUPTED" and summary["partial"] is True
    saved = Solution.load(out / "solution.npz")
    assert 1 < len(saved) < 6000 and saved.t[-1] < 400


def test_a_closed_standard_output_ends_quietly_with_the_files_written(tmp_path, monkeypatch):
    # `hamrkq run ... | head`: before, "hamrkq: error: cannot write output:
    # [Errno 32] Broken pipe" and status 3, as if the results were lost.
    import io
    import sys

    from hamrkq.cli import EXIT_BROKEN_PIPE, main

    class ClosedPipe(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

    errors = io.StringIO()
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    monkeypatch.setattr(sys, "stderr", errors)
    out = tmp_path / "run"
    code = main(["run", "harmonic", "--t-end", "1", "--no-plots", "--out", str(out)])
    assert code == EXIT_BROKEN_PIPE == 141
    assert errors.getvalue() == ""
    assert (out / "summary.json").is_file() and (out / "solution.npz").is_file()


def test_existing_output_directory_needs_force(tmp_path, capsys):
    out = tmp_path / "busy"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "figure4_rk8_error.png").write_bytes(b"stale")
    argv = ["run", "prentice2011", "--method", "rk34", "--t-end", "20", "--no-plots",
            "--reference", "none", "--out", str(out)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "not empty" in err and "--force" in err and "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == ["figure4_rk8_error.png", "notes.txt"]
    assert main([*argv, "--force"]) == 0
    # the user's file is kept, hamrkq's stale figure is gone
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "solution.npz", "summary.json"]
    assert (out / "notes.txt").read_text() == "mine"


def test_default_output_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["run", "prentice2011", "--method", "rk34", "--t-end", "10", "--no-plots",
            "--reference", "none"]  # fmt: skip
    assert main(argv) == 0
    assert (tmp_path / "hamrkq-run" / "prentice2011" / "summary.json").is_file()
    assert main(argv) == 2  # a second run does not overwrite the first silently


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--atol", "-1"], "--atol '-1': expected a positive finite number"),
        (["--atol", "nan"], "--atol 'nan': expected a positive finite number"),
        (["--method", "nope"], "method='nope' is not valid"),
        (["--reference", "exact"], "has no exact solution"),
        (["--method", "rk34", "--reference", "rk8"], "has no quencher track"),
        (["--param", "a"], "--param 'a'"),
        (["--param", "a=exp(1)"], "NAME=NUMBER"),
        (["--param", "a=2"], "has no parameter"),
        (["--backend", "gpu"], "backend='gpu'"),
        (["--dpi", "1"], "--dpi"),
        (["--atol", "tiny"], "--atol 'tiny': expected a positive finite number"),
        (["--reference", "psychic"], "invalid choice"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, extra, fragment):
    out = tmp_path / "never"
    assert main(["run", "prentice2011", "--out", str(out), "--t-end", "1", *extra]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err
    assert not out.exists()


def test_unknown_problem_exits_2(tmp_path, capsys):
    assert main(["run", "no_such_problem", "--out", str(tmp_path / "x")]) == 2
    assert "no problem named" in capsys.readouterr().err


# -- the shared pieces -------------------------------------------------------------
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal_and_after_the_delay():
    quiet = io.StringIO()
    bar = ProgressBar("x", stream=quiet, delay=0.0)
    bar(0.5, 1.0)
    bar.close()
    assert quiet.getvalue() == ""  # not a terminal
    terminal = _Terminal()
    slow = ProgressBar("x", stream=terminal, delay=3600.0)
    slow(0.5, 1.0)
    slow.close()
    assert terminal.getvalue() == ""  # a short run stays quiet
    bar = ProgressBar("run", stream=terminal, delay=0.0)
    bar(0.25, 12.5)
    bar.close()
    text = terminal.getvalue()
    assert text.startswith("\rrun: [") and "25.0%" in text and "t=12.5" in text
    assert text.endswith("\n")


def test_output_dir_writes_strict_json_atomically(tmp_path):
    unused = OutputDir(tmp_path / "unused")
    assert [p.name for p in (tmp_path / "unused").iterdir()] == [".hamrkq.lock"]  # claimed
    unused.close()
    assert not (tmp_path / "unused").exists()  # nothing written: nothing left behind
    out = OutputDir(tmp_path / "new")
    out.json("a.json", {"x": float("nan"), "y": np.float64(1.5), "z": np.arange(3)})
    assert json.loads((tmp_path / "new" / "a.json").read_text()) == {
        "x": None, "y": 1.5, "z": [0, 1, 2]
    }  # fmt: skip
    out.close()
    assert [p.name for p in (tmp_path / "new").iterdir()] == ["a.json"]  # no temp files
    with pytest.raises(hamrkq.errors.InputError, match="not a directory"):
        OutputDir(tmp_path / "new" / "a.json")


@pytest.mark.slow
def test_fixed_step_method_with_step(tmp_path, capsys):
    out = tmp_path / "gauss4"
    argv = ["run", "prentice2011", "--method", "gauss4", "--step", "0.1", "--t-end", "20",
            "--no-plots", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    summary = _summary(out)
    problem = hamrkq.load_problem("prentice2011")
    sol = solve(problem, method="gauss4", step=0.1, t_span=(0, 20))
    assert summary["nodes"] == len(sol) == 201
    assert without_timings(summary["diagnostics"]) == without_timings(
        jsonable(diagnose(sol, problem, reference="independent").to_dict())
    )
    # Gauss4 at h = 0.1: global error O(h^4), well below 1e-4 on this short span
    assert 1e-9 < max(summary["diagnostics"]["global_error"]["max_abs"].values()) < 1e-4
