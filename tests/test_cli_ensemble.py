"""``hamrkq ensemble``: the product grid, the same numbers as the library call,
files written whole, exit status 1 when a member fails and 2 on bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hamrkq
from hamrkq.cli import main

FALL_TOML = """
name = "fall"
coordinates = ["q"]
momenta = ["p"]
hamiltonian = "p**2/2 - 1/q"
[initial]
q = [1]
p = [0]
[integration]
t_span = [0, 2]
atol = 1e-8
"""


def test_grid_members_equal_the_library_call(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["ensemble", "pendulum", "--grid", "q=-1:1:3", "--grid", "p=0:0.5:2",
            "--t-end", "4", "--samples", "5", "--workers", "1", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    ens = hamrkq.EnsembleSolution.load(out / "ensemble.npz")
    # The first --grid varies slowest.
    q0 = [-1, -1, 0, 0, 1, 1]
    p0 = [0, 0.5, 0, 0.5, 0, 0.5]
    np.testing.assert_array_equal(ens.y0, np.column_stack([q0, p0]))
    api = hamrkq.ensemble(
        hamrkq.load_problem("pendulum"), q0=np.array(q0)[:, None], p0=np.array(p0)[:, None],
        t_span=(0, 4), t_eval=np.linspace(0, 4, 5), workers=1,
    )  # fmt: skip
    np.testing.assert_array_equal(ens.y, api.y)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["members"] == 6 and summary["failed"] == 0
    # the method that ran, named where the file names none (the default)
    assert summary["method"] == api.method == "auto"
    assert summary["max_energy_drift"] == float(api.energy_drift.max())
    assert sorted(summary["files"]) == sorted(
        ["ensemble.npz", "ensemble_map.png", "ensemble_orbits.png", "summary.json"]
    )
    for name in summary["files"]:
        assert (out / name).stat().st_size > 0
    assert "6 members, 0 failed" in capsys.readouterr().out


def test_a_parameter_grid_moves_the_problem_s_initial_values(tmp_path):
    out = tmp_path / "kepler"
    argv = ["ensemble", "kepler", "--grid", "e=0.1:0.5:3", "--t-end", "1", "--workers", "1",
            "--no-plots", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    ens = hamrkq.EnsembleSolution.load(out / "ensemble.npz")
    grid = np.linspace(0.1, 0.5, 3)  # what LO:HI:N means
    np.testing.assert_array_equal(ens.parameters["e"], grid)
    kepler = hamrkq.load_problem("kepler")
    for i, e in enumerate(grid):
        np.testing.assert_array_equal(ens.y0[i], kepler.with_parameters(e=e).y0)
    assert sorted(p.name for p in out.iterdir()) == ["ensemble.npz", "summary.json"]


def test_a_failed_member_gives_exit_status_1_and_everything_is_written(tmp_path, capsys):
    problem = tmp_path / "fall.toml"
    problem.write_text(FALL_TOML)
    out = tmp_path / "fall"
    argv = ["ensemble", str(problem), "--grid", "p=0:3:2", "--workers", "1", "--out", str(out)]
    assert main(argv) == 1
    ens = hamrkq.EnsembleSolution.load(out / "ensemble.npz")
    assert ens.failed.tolist() == [0] and ens.success.tolist() == [False, True]
    assert "member 0 (q=1, p=0)" in capsys.readouterr().out
    assert json.loads((out / "summary.json").read_text())["failed_members"] == [0]


@pytest.mark.parametrize(
    ("grid", "match"),
    [
        ("q=-1:1", "expected NAME=LO:HI:N"),
        ("q=-1:x:3", "LO and HI must be finite numbers"),
        ("q=-1:1:0", "N must be a positive integer"),
        # said "expected NAME=LO:HI:N with finite LO, HI", where N is at fault
        ("q=-3:3:2.5", "N must be a positive integer, got '2.5'"),
        ("q=-1:inf:3", "finite"),
        ("zeta=0:1:3", "'zeta' is not a coordinate, momentum or parameter"),
        ("q", "expected NAME=LO:HI:N"),
    ],
)
def test_bad_grids_exit_2_and_name_the_grid(tmp_path, capsys, grid, match):
    argv = ["ensemble", "pendulum", "--grid", grid, "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and "--grid" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--grid", "q=0:1:100000000000"], "100000000000 members is more than 100000000"),
        (
            ["--grid", "q=0:1:3", "--samples", "100000000000"],
            "more than half this machine's memory",
        ),
        (["--grid", "q=0:1:3", "--samples", "0"], "--samples must be a positive integer"),
    ],
)
def test_sizes_beyond_the_machine_are_refused_before_any_array(tmp_path, capsys, extra, match):
    # N = 1e11 asked NumPy for 745 GiB (np.linspace before the size check)
    # and --samples had no limit: a MemoryError traceback, exit 1.
    argv = ["ensemble", "pendulum", *extra, "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    assert match in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_name_given_twice_is_refused(tmp_path, capsys):
    argv = ["ensemble", "pendulum", "--grid", "q=0:1:2", "--grid", "q=0:1:3",
            "--out", str(tmp_path / "x")]  # fmt: skip
    assert main(argv) == 2
    assert "given twice" in capsys.readouterr().err


def test_a_problem_files_events_end_members_and_the_left_out_ones_are_noted(tmp_path, capsys):
    # QA: the file's terminal event was ignored (every member SUCCESS at
    # t_end, exit 0, no note); its other events are left out, and the
    # summary says so as run's does.
    path = tmp_path / "oscillator_events.toml"
    path.write_text(
        'name = "oscillator_events"\ncoordinates = ["q"]\nmomenta = ["p"]\n'
        'hamiltonian = "p**2/2 + q**2/2"\n[initial]\nq = 1\np = 0\n'
        "[integration]\nt_span = [0, 7]\n"
        '[[events]]\nexpression = "q"\nterminal = true\n[[events]]\nexpression = "p"\n'
    )
    out = tmp_path / "run"
    argv = ["ensemble", str(path), "--grid", "q=0.5:1.5:3", "--workers", "1", "--no-plots",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    ens = hamrkq.EnsembleSolution.load(out / "ensemble.npz")
    assert np.all(ens.status == hamrkq.Status.TERMINAL_EVENT.code)
    np.testing.assert_allclose(ens.t_last, np.pi / 2, atol=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert any("'p'" in note and "not located" in note for note in summary["notes"])
    printed = capsys.readouterr()
    assert "note: the events of problem" in printed.out and "not located" in printed.err
