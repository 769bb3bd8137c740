"""An invariant may not be named like the energy (found by QA: ``[invariants]
H = "p**2"`` replaced H's own row in ``hamrkq show``, and the run's table
printed two rows "max |H - H(0)|"; ``diagnose(..., invariants={"energy":
f})`` printed a second "energy error" row)."""

from __future__ import annotations

import pytest
from helpers import oscillator_file, run_cli

import hamrkq
from hamrkq.errors import InputError, ProblemFileError


def write(tmp_path, name):
    return oscillator_file(tmp_path / "inv.toml", extra=f'[invariants]\n{name} = "p**2"\n')


@pytest.mark.parametrize("name", ["H", "energy"])
def test_a_file_invariant_named_like_the_energy_is_refused_at_load(tmp_path, name):
    path = write(tmp_path, name)
    with pytest.raises(ProblemFileError) as info:
        hamrkq.load_problem(path)
    assert info.value.key == f"invariants.{name}" and info.value.line == 11
    assert f"an invariant may not be named {name!r}" in str(info.value)


def test_cli_show_exits_2(tmp_path):
    path = write(tmp_path, "H")
    status, _, err = run_cli("show", path)
    assert status == 2
    assert err.startswith(
        f"hamrkq: error: {path}:11, key 'invariants.H': an invariant may not be named 'H'"
    )


def test_other_names_still_load_and_show_beside_h(tmp_path):
    path = write(tmp_path, "P2")
    assert set(hamrkq.load_problem(path).invariants) == {"P2"}
    status, out, _ = run_cli("show", path)
    assert status == 0
    assert "  H = p**2/2 + q**2/2   [conserved]" in out
    assert "  P2 = p**2   [NOT proved conserved]" in out


@pytest.mark.parametrize("name", ["H", "energy"])
def test_diagnose_refuses_an_invariant_named_like_the_energy(name):
    problem = hamrkq.load_problem("harmonic")
    sol = hamrkq.solve(problem, t_span=(0, 1))
    with pytest.raises(InputError, match=rf"diagnose: invariants: .*named {name!r}"):
        hamrkq.diagnose(sol, problem, invariants={name: lambda t, y: y[:, 1] ** 2})
    report = hamrkq.diagnose(sol, problem, invariants={"P2": lambda t, y: y[:, 1] ** 2})
    assert [s.name for s in report.invariants] == ["P2"]
