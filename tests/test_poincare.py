"""Poincare sections: crossings on exact invariant curves, many orbits, the
energy initial conditions."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.analysis.energy_surface import energy_orbits
from hamrkq.analysis.poincare import poincare
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import ExpressionError, InputError

q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2", real=True)
OMEGA = math.sqrt(2.0)
TWO = hamrkq.Hamiltonian(
    (p1**2 + q1**2) / 2 + (p2**2 + OMEGA**2 * q2**2) / 2, q=[q1, q2], p=[p1, p2]
)


def test_uncoupled_oscillators_section_on_the_exact_invariant_curve():
    # Each oscillator keeps its energy: at every crossing of q1 = 0,
    # p2**2 + w**2 q2**2 = 2 E2 exactly, and p1 = +sqrt(2 E1) (direction +1).
    q0, p0 = [0.3, 0.4], [0.2, -0.1]
    e2 = (p0[1] ** 2 + OMEGA**2 * q0[1] ** 2) / 2
    e1 = (p0[0] ** 2 + q0[0] ** 2) / 2
    atol = 1e-10
    sec = poincare(TWO, "q1 = 0", q0, p0, (0.0, 200.0), atol=atol)
    # q1 = 0.3 cos t + 0.2 sin t = R cos(t - a) rises through 0 at a + 3 pi / 2 + 2 pi k.
    exact_t = math.atan2(0.2, 0.3) + 1.5 * math.pi + 2 * math.pi * np.arange(31)
    assert sec.t.size == 31
    np.testing.assert_allclose(sec.t, exact_t, atol=1e-9, rtol=0)
    curve = sec.column("p2") ** 2 + OMEGA**2 * sec.column("q2") ** 2 - 2 * e2
    # |q2|, |p2| < 0.6: an error delta in each moves the curve by < 4 delta.
    assert np.max(np.abs(curve)) < 4 * atol
    assert np.max(np.abs(sec.column("q1"))) < 2 * atol
    np.testing.assert_allclose(sec.column("p1"), math.sqrt(2 * e1), atol=2 * atol)


def test_many_orbits_and_n_crossings():
    q0 = np.array([[0.3, 0.4], [0.1, -0.2], [-0.2, 0.0]])
    p0 = np.array([[0.2, -0.1], [0.5, 0.1], [0.1, 0.3]])
    sec = poincare(TWO, "q1 = 0", q0, p0, (0.0, 100.0), atol=1e-9, n_crossings=4, direction=-1)
    assert sec.t.size == 12
    np.testing.assert_array_equal(sec.orbit, np.repeat([0, 1, 2], 4))
    assert all(s.status is hamrkq.Status.TERMINAL_EVENT for s in sec.solutions)
    assert np.all(sec.column("p1") < 0)  # direction -1: q1 decreasing
    assert sec.success
    assert repr(sec) == "PoincareSection(section='q1 = 0', crossings=12, orbits=3, success=True)"


def test_henon_heiles_energy_orbits_lie_on_the_energy_surface():
    problem = load_problem("henon_heiles")
    ham = problem.hamiltonian
    q0, p0 = energy_orbits(ham, 1 / 8, 6)
    y0 = np.hstack([q0, p0])
    energies = [numeric_of(ham).energy(0.0, row, problem.parameter_array) for row in y0]
    np.testing.assert_allclose(energies, 1 / 8, atol=1e-14)
    assert np.all(q0[:, 0] == 0) and np.all(p0[:, 0] > 0)
    sec = poincare(problem, "q1 = 0", q0[:2], p0[:2], (0.0, 200.0), atol=1e-9)
    assert sec.t.size > 10
    # Energy at the crossings: conserved to the tolerance.
    e = [numeric_of(ham).energy(0.0, row, problem.parameter_array) for row in sec.y]
    assert np.max(np.abs(np.array(e) - 1 / 8)) < 1e-8


def test_bad_sections_are_rejected():
    with pytest.raises(InputError, match="exactly one"):
        poincare(TWO, "q1", [0.1, 0.1], [0.1, 0.1], (0, 1))
    with pytest.raises(ExpressionError):
        poincare(TWO, "__import__('os') = 0", [0.1, 0.1], [0.1, 0.1], (0, 1))
    with pytest.raises(InputError, match="n_crossings"):
        poincare(TWO, "q1 = 0", [0.1, 0.1], [0.1, 0.1], (0, 1), n_crossings=0)


def test_cli_poincare_explains_what_it_needs_of_another_number_of_degrees_of_freedom(
    tmp_path, capsys
):
    # Before: "energy_orbits needs two degrees of freedom, got n = 1" (a
    # function the user never called), and nothing on what to do instead.
    from hamrkq.cli import main

    out = tmp_path / "pendulum"
    assert main(["poincare", "pendulum", "--section", "q = 0", "--out", str(out)]) == 2
    message = capsys.readouterr().err
    assert "two degrees of freedom" in message and "pendulum has 1" in message
    assert "hamrkq.poincare(" in message
    assert not out.exists()


def test_cli_poincare_says_a_section_fixes_a_coordinate_to_a_constant(tmp_path, capsys):
    # Before: "key 'section': unknown name (not a declared symbol, t, pi or
    # E): 'q2'", of a coordinate of the problem (found by QA).
    from hamrkq.cli import main

    out = tmp_path / "hh"
    argv = ["poincare", "henon_heiles", "--section", "q1=q2", "--out", str(out)]
    assert main(argv) == 2
    message = capsys.readouterr().err
    assert "the section 'q1=q2' sets q1 to 'q2', which depends on q2" in message
    assert "fixes a coordinate to a constant, 'q1 = c'" in message
    assert "hamrkq.poincare(" in message and "unknown name" not in message
    assert not out.exists()
    ham = hamrkq.load_problem("henon_heiles").hamiltonian
    with pytest.raises(InputError, match="which depends on p1, t"):
        energy_orbits(ham, 1 / 12, 3, "q1 = p1 + t")
    # a constant expression is still a section; an unknown name is still unknown
    q0, _ = energy_orbits(ham, 1 / 12, 3, "q1 = sqrt(2)/20")
    assert np.all(q0[:, 0] == pytest.approx(np.sqrt(2) / 20, abs=1e-16))
    with pytest.raises(ExpressionError, match="unknown name"):
        energy_orbits(ham, 1 / 12, 3, "q1 = zz")


def test_cli_poincare_writes_points_and_figure(tmp_path, capsys):
    from hamrkq.cli import main

    out = tmp_path / "hh"
    code = main(
        ["poincare", "henon_heiles", "--energy", "1/8", "--orbits", "3", "--t-end", "60",
         "--out", str(out), "--megno"]
    )  # fmt: skip
    assert code == 0
    data = np.load(out / "section.npz")
    assert set(np.unique(data["orbit"])) == {0, 1, 2}
    assert np.max(np.abs(data["y"][:, 0])) < 1e-8  # q1 = 0 at every crossing
    assert np.all(data["y"][:, 2] > 0)  # direction +1: p1 = dq1/dt > 0
    assert (out / "section.png").stat().st_size > 1000
    summary = __import__("json").loads((out / "summary.json").read_text())
    assert summary["crossings"] == data["t"].size and len(summary["megno"]) == 3
    assert "crossings of q1 = 0" in capsys.readouterr().out
    # each orbit's MEGNO from the section's own run is the same number as
    # megno() integrating the orbit again (events change no node)
    hh = hamrkq.load_problem("henon_heiles")
    options = {"atol": 1e-9, "gamma_limit": math.inf, "backend": "auto"}
    alone = [
        float(hamrkq.megno(hh, q, p, (0.0, 60.0), **options).value[-1])
        for q, p in zip(data["q0"], data["p0"], strict=True)
    ]
    assert summary["megno"] == alone


def test_section_figure_coloured_by_megno():
    from matplotlib import colormaps
    from matplotlib.colors import to_rgba

    from hamrkq.plotting.sections import MEGNO_RANGE, section_figure

    hh = hamrkq.load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 8, 2)
    sec = hamrkq.poincare(hh, "q1 = 0", q0, p0, (0, 30), atol=1e-8)
    fig = section_figure(sec, "q2", "p2", megno=[2.0, 9.0])
    ax, bar = fig.axes
    regular, chaotic = (to_rgba(line.get_color()) for line in ax.lines)
    turbo = colormaps["turbo"]
    low, high = MEGNO_RANGE
    assert regular == to_rgba(turbo((2.0 - low) / (high - low)))
    assert chaotic == to_rgba(turbo(1.0))  # 9 is above the scale: its top colour
    assert bar.get_ylim() == MEGNO_RANGE and "MEGNO" in bar.get_ylabel()
    with pytest.raises(ValueError, match="one value per orbit"):
        section_figure(sec, "q2", "p2", megno=[2.0])


def test_cli_poincare_method_auto_finds_the_same_crossings(tmp_path):
    from hamrkq.cli import main

    found = {}
    for method in ("rk34q8", "auto"):
        out = tmp_path / method
        argv = ["poincare", "henon_heiles", "--energy", "1/8", "--orbits", "2", "--t-end", "60",
                "--method", method, "--no-plots", "--out", str(out)]  # fmt: skip
        assert main(argv) == 0
        summary = json.loads((out / "summary.json").read_text())
        found[method] = (summary["method"], np.load(out / "section.npz")["y"])
    assert found["rk34q8"][0] == ["rk34q8"] and found["auto"][0] == ["rk78q12"]
    # over 60 time units both are within a few tolerances (1e-9) of the orbit
    np.testing.assert_allclose(found["auto"][1], found["rk34q8"][1], atol=1e-8)


def test_cli_poincare_energy_defaults_to_the_problems_initial_energy(tmp_path):
    from hamrkq.catalogue.problems import load_problem
    from hamrkq.cli import main

    out = tmp_path / "hh"
    argv = ["poincare", "henon_heiles", "--orbits", "2", "--t-end", "30", "--no-plots",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    problem = load_problem("henon_heiles")
    (q1, q2), (p1, p2) = problem.q0, problem.p0
    by_hand = (p1**2 + p2**2 + q1**2 + q2**2) / 2 + q1**2 * q2 - q2**3 / 3
    assert summary["energy"] == pytest.approx(by_hand, rel=1e-14)
    # every orbit starts on the section at that energy
    data = np.load(out / "section.npz")
    for q, p in zip(data["q0"], data["p0"], strict=True):
        assert q[0] == 0.0
        energy = (p @ p + q @ q) / 2 + q[0] ** 2 * q[1] - q[1] ** 3 / 3
        assert energy == pytest.approx(by_hand, rel=1e-12)


def test_cli_poincare_rejects_hostile_energy(tmp_path):
    from hamrkq.cli import main

    code = main(
        ["poincare", "henon_heiles", "--energy", "__import__('os')", "--out", str(tmp_path / "x")]
    )
    assert code != 0


def _section_g(ham, section):
    """The section's event function as the solver evaluates it (the path of
    hamrkq.events' expression events: NumPy, on columns of state rows)."""
    from hamrkq.analysis.poincare import section_expression

    f = sp.lambdify(
        (ham.t, ham.state, ham.parameters), section_expression(ham, section), modules="numpy"
    )
    return lambda Y: np.broadcast_to(f(np.zeros(len(Y)), list(Y.T), np.array([])), len(Y))


@pytest.mark.parametrize("constant", ["sqrt(2)/10", "1/3", "pi/7", "0.3", "0.1 + 0.2"])
def test_energy_orbits_start_exactly_on_the_section(constant):
    # Before: q1 was SymPy's rounding of the constant, float(sp.N(...)), and
    # the event NumPy's, 0.1 * sqrt(2) one ulp above SymPy's 0.1414213562373095
    # for sqrt(2)/10: g = -2.8e-17 at the start, which counted as a crossing
    # at t = 6e-17.
    hh = load_problem("henon_heiles")
    section = f"q1 = {constant}"
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 8, 3, section)
    g = _section_g(hh.hamiltonian, section)(np.hstack([q0, p0]))
    np.testing.assert_array_equal(g, 0.0)
    sec = poincare(hh, section, q0, p0, (0.0, 10.0), direction=0, atol=1e-10)
    assert np.min(sec.t) > 0.5  # the first real crossing, not the start
    if constant == "sqrt(2)/10":
        assert q0[0, 0] == 0.1 * math.sqrt(2) != float(sp.N(sp.sqrt(2) / 10))


def test_cli_poincare_orbits_start_on_the_section_without_crossing_it(tmp_path):
    # Before: 11 crossings, 3 of them the orbits' starts at t = 6e-17.
    from hamrkq.cli import main

    out = tmp_path / "hh"
    argv = ["poincare", "henon_heiles", "--section", "q1 = sqrt(2)/10", "--energy", "1/8",
            "--orbits", "3", "--t-end", "20", "--no-plots", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    data = np.load(out / "section.npz")
    hh = load_problem("henon_heiles").hamiltonian
    g = _section_g(hh, "q1 = sqrt(2)/10")
    np.testing.assert_array_equal(g(np.hstack([data["q0"], data["p0"]])), 0.0)
    assert data["t"].size == 8 and np.min(data["t"]) > 6.0


def _henon_heiles_line_roots(c, energy):
    # H(q1 = c, q2, p = 0) = E: c**2/2 + q2**2/2 + c**2 q2 - q2**3/3 = E
    roots = np.roots([-1 / 3, 1 / 2, c**2, c**2 / 2 - energy])
    return np.sort(roots[np.abs(roots.imag) < 1e-12].real)


def test_energy_orbits_where_the_other_coordinate_0_is_not_allowed():
    # Before: "the point q = 0 on the section is above the energy 0.11"
    # (H(0.5, 0) = 0.125), though H(q1 = 0.5, q2, p = 0) has its minimum
    # 0.0976 at q2 = (1 - sqrt 2)/2: the interval around that minimum,
    # -0.33553 to -0.07037, is chosen now.
    hh = load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 0.11, 3, "q1 = 0.5")
    lo, hi, _ = _henon_heiles_line_roots(0.5, 0.11)
    assert lo == pytest.approx(-0.33553477, abs=1e-8) and hi == pytest.approx(
        -0.07036785, abs=1e-8
    )
    np.testing.assert_allclose(q0[:, 1], np.linspace(lo, hi, 5)[1:-1], atol=1e-12, rtol=0)
    assert np.all(q0[:, 0] == 0.5) and np.all(p0[:, 0] > 0) and np.all(p0[:, 1] == 0)
    energies = numeric_of(hh.hamiltonian).energy(0.0, np.hstack([q0, p0]), hh.parameter_array)
    np.testing.assert_allclose(energies, 0.11, atol=1e-14, rtol=0)
    # No point of the line allowed: the lowest energy on it, and where.
    with pytest.raises(InputError, match=r"lowest energy found on it is 0\.5, at q2 = 0 "):
        energy_orbits(TWO, 0.3, 2, "q1 = 1")
    # Below the well's minimum on the line, only the escape side is allowed.
    with pytest.raises(
        InputError, match=r"\(the lowest is 0\.0976311, at q2 = -0\.207107\).* from q2 = 1\.94506"
    ):
        energy_orbits(hh.hamiltonian, 0.05, 2, "q1 = 0.5")


def test_cli_poincare_energy_with_the_other_coordinate_0_not_allowed(tmp_path):
    from hamrkq.cli import main

    out = tmp_path / "hh"
    argv = ["poincare", "henon_heiles", "--energy", "0.11", "--section", "q1 = 0.5",
            "--orbits", "2", "--t-end", "30", "--no-plots", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    data = np.load(out / "section.npz")
    assert data["t"].size > 0 and np.max(np.abs(data["y"][:, 0] - 0.5)) < 1e-8


@pytest.mark.parametrize("orbits", [1, 3, 5])
def test_energy_orbits_step_past_a_singular_point(orbits):
    """Kepler on q1 = 0 at E = -1/2: the allowed interval -2 < q2 < 2 holds
    the centre, where H = -inf; the middle of an odd number of orbits sat on
    it and the momentum's solve failed with a traceback (QA).  It starts half
    a spacing further up, on the energy surface like the others."""
    kepler = load_problem("kepler")
    q0, p0 = energy_orbits(kepler.hamiltonian, -0.5, orbits, "q1 = 0", kepler.parameters)
    spacing = 4.0 / (orbits + 1)
    middle = orbits // 2
    assert q0[middle, 1] == pytest.approx(0.5 * spacing, abs=1e-12)
    assert np.all(q0[:, 0] == 0.0) and np.all(q0[:, 1] != 0.0) and np.all(p0[:, 0] > 0.0)
    energy = numeric_of(kepler.hamiltonian).energy(
        0.0, np.hstack([q0, p0]), kepler.parameter_array
    )
    np.testing.assert_allclose(energy, -0.5, rtol=1e-14)


def test_energy_orbits_interval_ends_are_the_roots():
    # Before: the ends were points of a grid of step 1e-3 (the seeds off by
    # up to 1e-3 from evenly spread between -0.43969 and 0.67365).
    hh = load_problem("henon_heiles")
    q0, _ = energy_orbits(hh.hamiltonian, 1 / 8, 4)
    lo, hi, _ = _henon_heiles_line_roots(0.0, 1 / 8)
    np.testing.assert_allclose(q0[:, 1], np.linspace(lo, hi, 6)[1:-1], atol=1e-12, rtol=0)


def test_energy_orbits_interval_beyond_the_first_grid_and_unbounded_ones():
    # Before: the grid [-10, 10] cut every interval there.  A well of
    # half-width 30 now gets seeds at -15, 0, 15 ...
    wide = hamrkq.Hamiltonian(
        (p1**2 + q1**2) / 2 + p2**2 / 2 + (q2 / 30) ** 2 / 2, q=[q1, q2], p=[p1, p2]
    )
    q0, _ = energy_orbits(wide, 0.5, 3)
    np.testing.assert_allclose(q0[:, 1], [-15.0, 0.0, 15.0], atol=1e-12)
    # ... and an unbounded one is refused: Henon-Heiles above its escape
    # energy 1/6 (before: seeds at q2 = 1.2 ... 8.2, beyond the saddle at
    # q2 = 1, whose orbits ran 27 s to MAX_STEPS with states up to 1e9).
    hh = load_problem("henon_heiles")
    with pytest.raises(
        InputError, match=r"unbounded along q2: it runs from q2 = -0\.542053 up past 1e6.*escape"
    ):
        energy_orbits(hh.hamiltonian, 0.2, 5)
    # the double pendulum's q2, an angle, at an energy where it goes round
    dp = load_problem("double_pendulum")
    with pytest.raises(InputError, match=r"unbounded along q2: it runs over the whole line"):
        energy_orbits(dp.hamiltonian, 100.0, 5, "q1 = 0", dp.parameters)


def test_cli_poincare_refuses_an_energy_above_the_escape_energy(tmp_path, capsys):
    from hamrkq.cli import main

    out = tmp_path / "hh"
    argv = ["poincare", "henon_heiles", "--energy", "0.2", "--orbits", "3", "--t-end", "50",
            "--no-plots", "--out", str(out)]  # fmt: skip
    assert main(argv) == 2
    assert "above the escape energy" in capsys.readouterr().err
    assert not out.exists()


def test_poincare_needs_orbits():
    hh = load_problem("henon_heiles")
    # Before: ValueError "need at least one array to concatenate".
    with pytest.raises(InputError, match=r"need at least one orbit, got shapes \(0, 2\)"):
        poincare(hh, "q1 = 0", np.zeros((0, 2)), np.zeros((0, 2)), (0, 10))
    # Before: "q0 and p0 must both be 1-D ..., got shapes () and ()".
    with pytest.raises(InputError, match=r"needs q0 and p0 .*; q0 and p0 not given \(a Problem"):
        poincare(hh.hamiltonian, "q1 = 0")
    with pytest.raises(InputError, match=r"; p0 not given"):
        poincare(hh.hamiltonian, "q1 = 0", [0.0, 0.1])
    with pytest.raises(InputError, match="t_span must be given"):
        poincare(hh.hamiltonian, "q1 = 0", [0.0, 0.1], [0.3, 0.0])


def test_direction_along_a_backward_run():
    # SciPy's convention: direction is along the integration.  Backward on
    # q = sin t, +1 picks q = 0 where q decreases in time (p = -1), -1 where
    # it increases; the docstring now says so.
    h = load_problem("harmonic")
    span = (0.0, -4 * math.pi - 0.5)
    up = poincare(h, "q = 0", [0.0], [1.0], span, direction=1, atol=1e-10)
    down = poincare(h, "q = 0", [0.0], [1.0], span, direction=-1, atol=1e-10)
    np.testing.assert_allclose(up.t, [-math.pi, -3 * math.pi], atol=1e-8, rtol=0)
    np.testing.assert_allclose(up.column("p"), -1.0, atol=1e-8)
    np.testing.assert_allclose(down.t, [-2 * math.pi, -4 * math.pi], atol=1e-8, rtol=0)
    np.testing.assert_allclose(down.column("p"), 1.0, atol=1e-8)
    assert "backward run" in " ".join(poincare.__doc__.split())


def test_an_interrupted_orbit_ends_the_section_with_the_orbits_run_so_far(monkeypatch):
    # A run of solve that comes back INTERRUPTED (Ctrl-C or SIGTERM in its
    # step loop) ends the section: its crossings so far stand and no other
    # orbit starts.  The library function ran the remaining orbits to the end.
    import hamrkq.analysis.poincare as module

    hh = hamrkq.load_problem("henon_heiles")
    q0, p0 = energy_orbits(hh.hamiltonian, 1 / 12, 4)
    runs = []

    def solve(*args, **kwargs):
        sol = hamrkq.solve(*args, **kwargs)
        runs.append(sol)
        return sol.replace(status=hamrkq.Status.INTERRUPTED) if len(runs) == 2 else sol

    monkeypatch.setattr(module, "solve", solve)
    sec = hamrkq.poincare(hh, "q1 = 0", q0, p0, (0.0, 300.0), atol=1e-9)
    assert len(runs) == 2
    assert [s.status for s in sec.solutions] == [hamrkq.Status.SUCCESS, hamrkq.Status.INTERRUPTED]
    for k in range(2):
        np.testing.assert_array_equal(sec.t[sec.orbit == k], runs[k].t_events[0])

    def interrupt(*args, **kwargs):  # Ctrl-C between two orbits
        if runs:
            raise KeyboardInterrupt
        runs.append(hamrkq.solve(*args, **kwargs))
        return runs[-1]

    runs.clear()
    monkeypatch.setattr(module, "solve", interrupt)
    sec = hamrkq.poincare(hh, "q1 = 0", q0, p0, (0.0, 300.0), atol=1e-9)
    assert len(sec.solutions) == 1 and sec.t.size == runs[0].t_events[0].size


def test_cli_poincare_with_a_method_without_quencher_names_what_sections_need(tmp_path, capsys):
    """poincare passed its --gamma-limit to every method, and a SciPy or
    fixed-step method, which refuses gamma_limit, failed on that; the
    sections' own need (the RKQ family's dense output) is what to say."""
    from hamrkq.cli import main

    out = tmp_path / "pc"
    argv = ["poincare", "henon_heiles", "--orbits", "2", "--t-end", "10", "--out", str(out)]
    for method in ("scipy:DOP853", "gauss4"):  # gauss4 said "step (h) must be given"
        assert main([*argv, "--method", method]) == 2
        err = capsys.readouterr().err
        assert "dense output of the RKQ family" in err and "gamma_limit" not in err
        assert not out.exists()
    # an explicit --gamma-limit is solve's to refuse where it does not apply
    # (it was dropped silently for rk34)
    assert main([*argv, "--method", "rk34", "--gamma-limit", "0.05"]) == 2
    assert "gamma_limit=0.05 does not apply to method='rk34'" in capsys.readouterr().err
