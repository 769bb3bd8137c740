"""Count options (``max_steps``, ``keep_every``, ``z_substeps``) have an
upper bound, 2**62: they end in int64 fields of the kernel's configuration,
and a count of 2**63 or more failed deep in the run with NumPy's
``OverflowError`` (a traceback and exit 1 on the command line) instead of a
message naming the option (found by QA)."""

from __future__ import annotations

import contextlib
import io

import pytest

import hamrkq
from hamrkq._validate import MAX_COUNT, count
from hamrkq.cli import main
from hamrkq.errors import InputError, ProblemFileError

COUNTS = ("max_steps", "keep_every", "z_substeps")


def run(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


def test_the_bound_is_2_to_the_62():
    assert MAX_COUNT == 2**62
    assert count("max_steps", 2**62) == 2**62
    with pytest.raises(InputError, match=r"max_steps must be at most 2\*\*62"):
        count("max_steps", 2**62 + 1)


@pytest.mark.parametrize("name", COUNTS)
@pytest.mark.parametrize("value", [2**63, 10**23])
def test_solve_refuses_a_count_beyond_int64_by_name(name, value):
    problem = hamrkq.load_problem("harmonic")
    with pytest.raises(
        InputError, match=rf"{name} must be at most 2\*\*62 = {2**62}, got {value}"
    ):
        hamrkq.solve(problem, t_span=(0, 1), **{name: value})


def test_ensemble_refuses_a_count_beyond_int64():
    problem = hamrkq.load_problem("harmonic")
    with pytest.raises(InputError, match=r"max_steps must be at most 2\*\*62"):
        hamrkq.ensemble(
            problem, q0={"q": [0.0, 1.0]}, t_span=(0, 1), max_steps=2**63, progress=False
        )


def test_the_largest_count_runs():
    problem = hamrkq.load_problem("harmonic")
    solution = hamrkq.solve(problem, t_span=(0, 1), max_steps=2**62, keep_every=2**62)
    assert solution.success


@pytest.mark.parametrize(
    ("option", "name"), [("--max-steps", "max_steps"), ("--keep-every", "keep_every")]
)
def test_cli_exits_2_naming_the_option(tmp_path, option, name):
    status, _, err = run("run", "harmonic", option, 10**23, "--no-plots", "--out", tmp_path / "x")
    assert status == 2
    assert err.startswith(f"hamrkq: error: {name} must be at most 2**62")
    assert "Traceback" not in err and "OverflowError" not in err


def test_problem_file_count_beyond_int64_is_refused_at_load(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text(
        'name = "big"\ncoordinates = ["q"]\nmomenta = ["p"]\n'
        'hamiltonian = "p**2/2 + q**2/2"\n[initial]\nq = 0\np = 1\n'
        "[integration]\nt_span = [0, 1]\nmax_steps = 99999999999999999999999\n"
    )
    with pytest.raises(ProblemFileError, match=r"integration\.max_steps.*at most 2\*\*62"):
        hamrkq.load_problem(path)
    status, _, err = run("run", path, "--no-plots", "--out", tmp_path / "x")
    assert status == 2
    assert "key 'integration.max_steps': max_steps must be at most 2**62" in err
