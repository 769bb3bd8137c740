"""`hamrkq run` options users reach for (issue 16): --t-start, --max-step,
--first-step, --keep-every, --atol NAME=VALUE, --csv, --json, --quiet, --method,
--z-substeps, --global-error-estimate, --quencher-precision passed through; a
file with named initial values gives the positional numbers."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

import hamrkq
from hamrkq.cli import main

FILE = """\
name = "{name}"
coordinates = ["x", "y"]
momenta = ["u", "v"]
hamiltonian = "(u**2 + v**2)/2 + (x**2 + 4*y**2)/2 + x**2*y/5"

[initial]
{initial}

[integration]
t_span = [0, 6]
atol = 1e-8
"""


def write(tmp_path, name, initial):
    path = tmp_path / f"{name}.toml"
    path.write_text(FILE.format(name=name, initial=initial))
    return path


def run(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("files")
    named = write(folder, "named", 'v = 0.1\nu = 0\ny = "1/4"\nx = 0.5')
    listed = write(folder, "listed", 'q = [0.5, "1/4"]\np = [0, 0.1]')
    return folder, named, listed


def test_named_file_runs_like_the_positional_one(files, tmp_path):
    _, named, listed = files
    for path in (named, listed):
        status, _, _ = run("run", path, "--no-plots", "--quiet", "--out", tmp_path / path.stem)
        assert status == 0
    a = hamrkq.Solution.load(tmp_path / "named" / "solution.npz")
    b = hamrkq.Solution.load(tmp_path / "listed" / "solution.npz")
    assert a.y[0].tolist() == [0.5, 0.25, 0.0, 0.1]
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.y, b.y)


def test_step_and_span_options_reach_solve(files, tmp_path):
    _, named, _ = files
    argv = ["--t-start", 1, "--t-end", 4, "--max-step", 0.05, "--first-step", 1e-3]
    argv += ["--keep-every", 3, "--atol", "1e-9", "--atol", "v=1e-11", "--rtol", 0]
    status, stdout, _ = run("run", named, *argv, "--no-plots", "--quiet", "--out", tmp_path)
    assert status == 0 and stdout == ""
    cli = hamrkq.Solution.load(tmp_path / "solution.npz")
    lib = hamrkq.solve(
        hamrkq.load_problem(named),
        t_span=(1, 4),
        max_step=0.05,
        first_step=1e-3,
        keep_every=3,
        atol=[1e-9, 1e-9, 1e-9, 1e-11],
        rtol=0,
    )
    np.testing.assert_array_equal(cli.t, lib.t)
    np.testing.assert_array_equal(cli.y, lib.y)
    assert cli.t[0] == 1 and cli.t[-1] == 4
    assert np.max(np.diff(lib.t)) <= 3 * 0.05 + 1e-12  # keep_every 3 of steps <= 0.05
    assert cli.atol.tolist() == [1e-9, 1e-9, 1e-9, 1e-11]


def test_quencher_options_reach_solve(files, tmp_path):
    """--z-substeps, --global-error-estimate and --quencher-precision are
    solve's keywords: a run of QA's case from the command line."""
    _, named, _ = files
    argv = ["--method", "rk78q12", "--z-substeps", 5, "--global-error-estimate", "tangent"]
    status, _, _ = run("run", named, *argv, "--no-plots", "--quiet", "--out", tmp_path / "a")
    assert status == 0
    cli = hamrkq.Solution.load(tmp_path / "a" / "solution.npz")
    problem = hamrkq.load_problem(named)
    lib = hamrkq.solve(problem, method="rk78q12", z_substeps=5, global_error_estimate="tangent")
    np.testing.assert_array_equal(cli.y, lib.y)
    np.testing.assert_array_equal(cli.gamma, lib.gamma)
    argv = ["--method", "rk67q9", "--quencher-precision", "double-double", "--json"]
    status, stdout, _ = run("run", named, *argv, "--no-plots", "--out", tmp_path / "b")
    assert status == 0
    used = json.loads(stdout)["settings"]["solve"]
    assert used["quencher_precision"] == "double-double" and used["z_method"] == "vern98"
    status, _, err = run("run", named, "--global-error-estimate", "exact", "--out", tmp_path / "c")
    assert status == 2 and "invalid choice: 'exact'" in err


def test_named_atol_alone_keeps_the_problems_atol(files, tmp_path):
    _, named, _ = files
    run("run", named, "--atol", "x=1e-10", "--no-plots", "--quiet", "--out", tmp_path)
    sol = hamrkq.Solution.load(tmp_path / "solution.npz")
    assert sol.atol.tolist() == [1e-10, 1e-8, 1e-8, 1e-8]  # the file's atol = 1e-8


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--atol", "w=1e-9"], "'w' is not a coordinate or momentum of 'named' (names: x, y, u"),
        (["--atol", "x=-1"], "expected a positive finite number"),
        (["--atol", "-1e-6"], "expected a positive finite number"),  # not "expected one argument"
        (["--atol", "1e-8", "--atol", "1e-9"], "a plain --atol was already given"),
        (["--atol", "x=1e-9", "--atol", "x=1e-8"], "x was already given"),
        (["--method", "nope"], "method='nope' is not valid; valid values: "),
        (["--method", "rk67q9", "--z-substeps", "0"], "z_substeps"),
        (["--method", "rk34q8", "--quencher-precision", "double-double"], "double-double"),
    ],
)
def test_bad_options_exit_2_with_the_culprit(files, tmp_path, argv, fragment):
    _, named, _ = files
    status, _, err = run("run", named, *argv, "--no-plots", "--out", tmp_path / "x")
    assert status == 2 and fragment in err, err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("argv", "dest", "value"),
    [
        (["run", "harmonic", "--t-end", "-1e1"], "t_end", -10.0),
        (["run", "harmonic", "--t-start", "-.5e-3"], "t_start", -5e-4),
        (["poincare", "kepler", "--energy", "-1/2"], "energy", "-1/2"),
        (["poincare", "kepler", "--energy", "-sqrt(2)/20"], "energy", "-sqrt(2)/20"),
    ],
)
def test_a_negative_value_after_an_option_is_its_value(argv, dest, value):
    """argparse took ``-1e1`` and ``-1/2`` for options ("expected one
    argument"; QA): Kepler's bound orbits have negative energies."""
    from hamrkq.cli import build_parser

    assert getattr(build_parser().parse_args(argv), dest) == value


def test_method_auto_is_passed_through(files, tmp_path):
    from hamrkq.options import METHOD_NAMES

    if "auto" not in METHOD_NAMES:
        pytest.skip("solve has no method 'auto' yet")
    _, named, _ = files
    argv = ["--method", "auto", "--quiet", "--no-plots", "--out", tmp_path]
    status, _, _ = run("run", named, *argv)
    assert status == 0
    cli = hamrkq.Solution.load(tmp_path / "solution.npz")
    lib = hamrkq.solve(hamrkq.load_problem(named), method="auto")
    assert cli.method == lib.method
    np.testing.assert_array_equal(cli.y, lib.y)


def test_method_list_comes_from_solve():
    from hamrkq.options import METHOD_NAMES

    status, stdout, _ = run("run", "--help")
    assert status == 0
    for name in METHOD_NAMES:
        assert name in stdout.replace("\n", " ")


def test_json_prints_the_summary_and_csv_matches_npz(files, tmp_path):
    _, named, _ = files
    status, stdout, err = run("run", named, "--json", "--csv", "--no-plots", "--out", tmp_path)
    assert status == 0 and err == ""
    printed = json.loads(stdout)
    assert printed == json.loads((tmp_path / "summary.json").read_text())
    assert "solution.csv" in printed["files"]
    sol = hamrkq.Solution.load(tmp_path / "solution.npz")
    header = (tmp_path / "solution.csv").read_text().splitlines()[0]
    assert header == "t,x,y,u,v,H"
    table = np.loadtxt(tmp_path / "solution.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table, np.column_stack([sol.t, sol.y, sol.energy]))


def test_a_run_from_another_start_is_measured_against_the_independent_reference(tmp_path):
    # --reference auto (the default) is the exact solution where there is
    # one, otherwise the independent reference (docs/cli.md).  From
    # --t-start 1 the harmonic oscillator's exact solution (which starts at
    # t = 0) does not apply: the report said "true error not reported".
    status, stdout, _ = run(
        "run", "harmonic", "--t-start", 1, "--t-end", 5, "--no-plots", "--json", "--out", tmp_path
    )
    assert status == 0
    summary = json.loads(stdout)
    assert summary["settings"]["reference"] == "independent"
    measured = summary["diagnostics"]["global_error"]
    assert measured["source"] == "independent" and summary["diagnostics"]["true_error_measured"]
    assert 1e-11 < max(measured["max_abs"].values()) <= 1.05e-8  # the problem's atol, 1e-8
    notes = summary["notes"]
    assert any("reference 'exact' unavailable" in n and "'independent'" in n for n in notes)
