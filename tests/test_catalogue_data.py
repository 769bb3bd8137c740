"""The catalogue's data: every number in problems/*.toml checked against an
independent computation (hand-written Hamiltonians, symbolic derivations,
published values, a tight DOP853 integration)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import hamrkq
from hamrkq.backends.numeric import numeric_of, vectorized

NAMES = hamrkq.list_problems()

#: H at the initial values, where PROBLEMS.md or the source gives it exactly.
KNOWN_ENERGY = {
    "prentice2011": 0.8,
    "harmonic": 0.5,
    "pendulum": -0.5,
    "kepler": -0.5,
    "henon_heiles": 0.068688,
    "toda": 4.0,
}


@pytest.fixture(scope="module", params=NAMES)
def problem(request):
    return hamrkq.load_problem(request.param)


def energy(problem, y):
    """H at the rows of y.  Only H is lambdified: building the whole numeric
    layer (rhs, Jacobian) of the 18-dof problem would take seconds."""
    ham = problem.hamiltonian
    return vectorized(ham, [ham.H])(0.0, np.atleast_2d(y), problem.parameter_array)[:, 0]


# -- every file ------------------------------------------------------------------


def test_eleven_entries():
    assert NAMES == sorted(
        [
            "arenstorf", "double_pendulum", "fpu", "harmonic", "henon_heiles", "kepler",
            "outer_solar_system", "pendulum", "pleiades", "prentice2011", "toda",
        ]
    )  # fmt: skip


def test_metadata(problem):
    assert problem.name == problem.path.stem
    assert problem.title and len(problem.description) > 200
    assert problem.references and all(len(r) > 20 for r in problem.references)
    # the paper's problem keeps the paper's method; the others run the default, auto
    expected = {"method": "rk34q8"} if problem.name == "prentice2011" else {}
    assert {k: v for k, v in problem.integration.items() if k == "method"} == expected
    atol = np.asarray(problem.integration["atol"], dtype=float)
    assert atol.shape in {(), (problem.hamiltonian.dim,)}
    assert np.all(atol > 0) and problem.integration["rtol"] >= 0
    assert problem.t_span[0] == 0.0 < problem.t_span[1]
    assert "\n" not in problem.description  # line continuations, not line breaks


def test_every_expected_value_has_a_source(problem):
    values = {k for k in problem.expected if not k.endswith("_source")}
    sources = {k.removesuffix("_source") for k in problem.expected if k.endswith("_source")}
    assert values == sources
    for key in values:
        assert isinstance(problem.expected[key], int | float)
        assert len(problem.expected[f"{key}_source"]) > 10


def test_invariants_are_first_integrals(problem):
    ham = problem.hamiltonian
    for name, expr in problem.invariants.items():
        assert ham.is_first_integral(expr), f"{problem.name}: {name} is not conserved"


def test_a_non_invariant_is_refused():
    """The symbolic check is not vacuous: q1*p1 is not conserved by Kepler."""
    ham = hamrkq.load_problem("kepler").hamiltonian
    q1, p1 = ham.q[0], ham.p[0]
    assert not ham.is_first_integral(q1 * p1)


@pytest.mark.parametrize("name", sorted(KNOWN_ENERGY))
def test_energy_at_the_initial_values(name):
    problem = hamrkq.load_problem(name)
    assert energy(problem, problem.y0)[0] == pytest.approx(KNOWN_ENERGY[name], abs=1e-14)
    if "energy" in problem.expected:
        assert problem.expected["energy"] == pytest.approx(KNOWN_ENERGY[name], abs=1e-15)


def test_henon_heiles_is_in_the_regular_regime():
    problem = hamrkq.load_problem("henon_heiles")
    assert energy(problem, problem.y0)[0] < 1 / 12 < 1 / 8 < problem.expected["escape_energy"]


# -- exact solutions ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "params"),
    [("harmonic", {}), ("pendulum", {}), ("kepler", {}), ("kepler", {"e": 0.9})],
)
def test_exact_solution_matches_the_file(name, params):
    problem = hamrkq.load_problem(name, **params)
    exact = problem.exact
    assert np.max(np.abs(exact(0.0)[0] - problem.y0)) <= 1e-14
    # The exact solution solves *this file's* Hamiltonian system: compare its
    # fourth-order central difference with the file's derived right-hand side.
    ham, prm = problem.hamiltonian, problem.parameter_array
    t = np.linspace(*problem.t_span, 9)[1:]
    h = 1e-4
    dy = (exact(t - 2 * h) - 8 * exact(t - h) + 8 * exact(t + h) - exact(t + 2 * h)) / (12 * h)
    f = np.array([numeric_of(ham).rhs(ti, yi, prm) for ti, yi in zip(t, exact(t), strict=True)])
    assert np.max(np.abs(dy - f) / np.maximum(1.0, np.abs(f))) < 1e-8
    # H and the invariants are constant along it.
    Y = exact(np.linspace(*problem.t_span, 501))
    assert np.ptp(energy(problem, Y)) < 1e-13
    for name_inv, fn in problem.invariant_functions().items():
        assert np.ptp(fn(0.0, Y)) < 1e-12, name_inv


def test_kepler_invariants_have_their_published_values():
    for e in (0.6, 0.9):
        problem = hamrkq.load_problem("kepler", e=e)
        values = {k: f(0.0, problem.y0[None])[0] for k, f in problem.invariant_functions().items()}
        assert values["angular_momentum"] == pytest.approx(np.sqrt(1 - e * e), abs=1e-15)
        assert values["runge_lenz_1"] == pytest.approx(e, abs=1e-14)
        assert values["runge_lenz_2"] == 0.0
        assert energy(problem, problem.y0)[0] == pytest.approx(-0.5, abs=1e-14)


def test_harmonic_exact_is_sin_cos():
    problem = hamrkq.load_problem("harmonic")
    t = np.linspace(0, 20, 41)
    assert np.max(np.abs(problem.exact(t) - np.column_stack([np.sin(t), np.cos(t)]))) < 1e-15


def test_pendulum_period_matches_expected():
    problem = hamrkq.load_problem("pendulum")
    period = problem.expected["period"]
    assert np.max(np.abs(problem.exact(period)[0] - problem.y0)) < 1e-14
    assert np.max(np.abs(problem.exact(period / 2)[0] - problem.y0)) > 1.0


# -- individual problems -------------------------------------------------------------


def test_double_pendulum_is_the_legendre_transform_of_its_lagrangian():
    problem = hamrkq.load_problem("double_pendulum")
    ham = problem.hamiltonian
    q1, q2 = ham.q
    p1, p2 = ham.p
    sym = {s.name: s for s in ham.parameters}
    l1, l2, m1, m2, g = (sym[k] for k in ("l1", "l2", "m1", "m2", "g"))
    w1, w2 = sp.symbols("w1 w2", real=True)
    # Two point masses on rods, angles from the downward vertical.
    x1, y1 = l1 * sp.sin(q1), -l1 * sp.cos(q1)
    x2, y2 = x1 + l2 * sp.sin(q2), y1 - l2 * sp.cos(q2)

    def velocity(expr):
        return sp.diff(expr, q1) * w1 + sp.diff(expr, q2) * w2

    T = m1 * (velocity(x1) ** 2 + velocity(y1) ** 2) / 2
    T += m2 * (velocity(x2) ** 2 + velocity(y2) ** 2) / 2
    L = T - (m1 * g * y1 + m2 * g * y2)
    momenta = [sp.diff(L, w1), sp.diff(L, w2)]
    A, b = sp.linear_eq_to_matrix([momenta[0] - p1, momenta[1] - p2], [w1, w2])
    w = A.LUsolve(b)
    H_legendre = p1 * w[0] + p2 * w[1] - L.subs({w1: w[0], w2: w[1]})
    # Prove H_legendre - H == 0: expand the trigonometric functions of sums,
    # name c_k = cos q_k, s_k = sin q_k, and reduce the numerator modulo the
    # ideal (s_k**2 + c_k**2 - 1), which is its own Groebner basis.  A zero
    # remainder is a proof (and ten times faster than sympy.simplify).
    c1, s1, c2, s2 = sp.symbols("c1 s1 c2 s2", real=True)
    names = {sp.cos(q1): c1, sp.sin(q1): s1, sp.cos(q2): c2, sp.sin(q2): s2}
    difference = sp.expand_trig(H_legendre - ham.H).subs(names)
    assert not difference.has(q1, q2)
    numerator, _ = sp.fraction(sp.together(difference))
    ideal = [s1**2 + c1**2 - 1, s2**2 + c2**2 - 1]
    _, remainder = sp.reduced(sp.expand(numerator), ideal, s1, s2, c1, c2)
    assert remainder == 0
    # The file's initial momenta are p = dL/dw at (pi/4, pi/2), w = (0, pi/8).
    subs = {q1: sp.pi / 4, q2: sp.pi / 2, w1: 0, w2: sp.pi / 8}
    subs.update({s: problem.parameters[s.name] for s in ham.parameters})
    expected_p = [float(m.subs(subs)) for m in momenta]
    assert np.allclose(problem.p0, expected_p, rtol=1e-15, atol=0)
    assert np.allclose(problem.q0, [np.pi / 4, np.pi / 2], rtol=1e-16, atol=0)


def test_fpu_initial_values_match_gni_variables():
    for omega in (50.0, 20.0):
        problem = hamrkq.load_problem("fpu", omega=omega)
        q, p = problem.q0, problem.p0
        # x_{0,i} = (q_{2i} + q_{2i-1})/sqrt 2, x_{1,i} = (q_{2i} - q_{2i-1})/sqrt 2.
        x0 = (q[1::2] + q[0::2]) / np.sqrt(2)
        x1 = (q[1::2] - q[0::2]) / np.sqrt(2)
        y0 = (p[1::2] + p[0::2]) / np.sqrt(2)
        y1 = (p[1::2] - p[0::2]) / np.sqrt(2)
        np.testing.assert_allclose(x0, [1, 0, 0], atol=1e-15)
        np.testing.assert_allclose(x1, [1 / omega, 0, 0], atol=1e-15)
        np.testing.assert_allclose(y0, [1, 0, 0], atol=1e-15)
        np.testing.assert_allclose(y1, [1, 0, 0], atol=1e-15)


def test_fpu_hamiltonian_matches_gni_formula():
    problem = hamrkq.load_problem("fpu")
    omega, rng = 50.0, np.random.default_rng(5)
    for _ in range(5):
        y = rng.standard_normal(12)
        q, p = y[:6], y[6:]
        qq = np.concatenate([[0.0], q, [0.0]])  # q_0 = q_7 = 0
        stiff = sum((qq[2 * i] - qq[2 * i - 1]) ** 2 for i in range(1, 4))
        soft = sum((qq[2 * i + 1] - qq[2 * i]) ** 4 for i in range(0, 4))
        h = 0.5 * p @ p + omega**2 / 4 * stiff + soft
        assert energy(problem, y)[0] == pytest.approx(h, rel=1e-14)


def nbody_energy(y, masses, G, dim):
    """H = sum |p_i|^2/(2 m_i) - G sum_{i<j} m_i m_j/|q_i - q_j|, body-major layout."""
    n = len(masses)
    q = y[: n * dim].reshape(n, dim)
    p = y[n * dim :].reshape(n, dim)
    kinetic = sum(p[i] @ p[i] / (2 * masses[i]) for i in range(n))
    potential = sum(
        masses[i] * masses[j] / np.linalg.norm(q[i] - q[j])
        for i in range(n)
        for j in range(i + 1, n)
    )
    return kinetic - G * potential


OSS_MASSES = [
    1.00000597682, 0.000954786104043, 0.000285583733151,
    0.0000437273164546, 0.0000517759138449, 1 / 1.3e8,
]  # fmt: skip
OSS_V = [
    [0, 0, 0],
    [0.00565429, -0.00412490, -0.00190589],
    [0.00168318, 0.00483525, 0.00192462],
    [0.00354178, 0.00137102, 0.00055029],
    [0.00288930, 0.00114527, 0.00039677],
    [0.00276725, -0.00170702, -0.00136504],
]
OSS_Q = [
    [0, 0, 0],
    [-3.5023653, -3.8169847, -1.5507963],
    [9.0755314, -3.0458353, -1.6483708],
    [8.3101420, -16.2901086, -7.2521278],
    [11.4707666, -25.7294829, -10.8169456],
    [-15.5387357, -25.2225594, -3.1902382],
]


def test_outer_solar_system_data():
    problem = hamrkq.load_problem("outer_solar_system")
    assert problem.hamiltonian.n == 18
    assert problem.parameters["G"] == 2.95912208286e-4
    masses = [problem.parameters[f"m{i}"] for i in range(6)]
    np.testing.assert_allclose(masses, OSS_MASSES, rtol=1e-15)
    np.testing.assert_array_equal(problem.q0, np.ravel(OSS_Q))
    expected_p = (np.array(OSS_MASSES)[:, None] * np.array(OSS_V)).ravel()
    np.testing.assert_allclose(problem.p0, expected_p, rtol=1e-15, atol=0)
    # Momentum floors are m_i * 1e-11 (a velocity floor of 1e-11 AU/day), rounded.
    floors = np.asarray(problem.integration["atol"])[18:].reshape(6, 3)
    np.testing.assert_allclose(floors / np.array(OSS_MASSES)[:, None], 1e-11, rtol=0.1)
    rng = np.random.default_rng(7)
    for y in (problem.y0, problem.y0 * (1 + 0.1 * rng.standard_normal(36))):
        assert energy(problem, y)[0] == pytest.approx(
            nbody_energy(y, OSS_MASSES, 2.95912208286e-4, 3), rel=1e-13
        )


def test_pleiades_data():
    problem = hamrkq.load_problem("pleiades")
    masses = np.arange(1.0, 8.0)
    x = [3, 3, -1, -3, 2, -2, 2]
    y = [3, -3, 2, 0, 0, -4, 4]
    vx = [0, 0, 0, 0, 0, 1.75, -1.5]
    vy = [0, 0, 0, -1.25, 1, 0, 0]
    np.testing.assert_array_equal(problem.q0, np.column_stack([x, y]).ravel())
    p = (masses[:, None] * np.column_stack([vx, vy])).ravel()
    np.testing.assert_array_equal(problem.p0, p)
    rng = np.random.default_rng(11)
    for state in (problem.y0, problem.y0 + 0.3 * rng.standard_normal(28)):
        assert energy(problem, state)[0] == pytest.approx(
            nbody_energy(state, masses, 1.0, 2), rel=1e-13
        )
    values = {k: f(0.0, problem.y0[None])[0] for k, f in problem.invariant_functions().items()}
    assert values == {"momentum_x": 0.0, "momentum_y": 0.0, "angular_momentum": 109.0}


def flaschka_matrix(y):
    """Flaschka's Lax matrix of the periodic 3-particle Toda lattice."""
    q, p = y[:3], y[3:]
    a = 0.5 * np.exp(0.5 * (q - np.roll(q, -1)))  # a_k couples k and k+1 (mod 3)
    L = np.diag(-0.5 * p)
    for k in range(3):
        L[k, (k + 1) % 3] = L[(k + 1) % 3, k] = a[k]
    return L


def test_toda_invariants_are_traces_of_the_lax_matrix():
    problem = hamrkq.load_problem("toda")
    fns = problem.invariant_functions()
    rng = np.random.default_rng(3)
    for y in rng.standard_normal((5, 6)):
        L = flaschka_matrix(y)
        for power, name in ((1, "trace_L"), (2, "trace_L2"), (3, "trace_L3")):
            ref = np.trace(np.linalg.matrix_power(L, power))
            assert fns[name](0.0, y[None])[0] == pytest.approx(ref, rel=1e-13, abs=1e-14)
        assert fns["trace_L2"](0.0, y[None])[0] == pytest.approx(energy(problem, y)[0] / 2)


def test_toda_spectrum_is_conserved_along_the_flow():
    problem = hamrkq.load_problem("toda")
    ham, prm = problem.hamiltonian, problem.parameter_array
    sol = solve_ivp(
        lambda t, y: numeric_of(ham).rhs(t, y, prm),
        (0.0, 10.0),
        problem.y0,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=np.linspace(0.0, 10.0, 21),
    )
    spectra = np.array([np.linalg.eigvalsh(flaschka_matrix(y)) for y in sol.y.T])
    assert np.max(np.abs(spectra - spectra[0])) < 1e-9
    assert np.ptp(sol.y[0]) > 0.5  # the particles did move


def test_toda_description_says_which_invariants_its_start_tests():
    """The symmetric start keeps the motion where tr L^3 = 3/4 at every
    state: any Runge-Kutta method keeps it to rounding, which the file now
    says (it called the problem a test of the invariants besides H; QA).
    The start the description suggests makes it a test."""
    problem = hamrkq.load_problem("toda")
    trace_l3 = problem.invariant_functions()["trace_L3"]
    spreads = []
    for q0, p0 in ((None, None), ([0.0, 0.2, -0.1], [1.0, 0.3, -0.5])):
        sol = hamrkq.solve(problem, q0=q0, p0=p0, method="scipy:RK45", atol=1e-4, rtol=1e-4)
        spreads.append(np.ptp(trace_l3(sol.t, sol.y)))
    assert spreads[0] < 1e-14 < 1e-4 < spreads[1]
    assert "tr L**3 is 3/4 at every state" in problem.description


def test_arenstorf_orbit_closes_after_one_period():
    problem = hamrkq.load_problem("arenstorf")
    ham, prm = problem.hamiltonian, problem.parameter_array
    period = problem.expected["period"]
    assert problem.t_span == (0.0, period)
    # p2 = y' + x with HNW's velocity form y'(0) = -2.00158510637908252240537862224.
    assert problem.p0[1] == pytest.approx(-2.00158510637908252240537862224 + 0.994, abs=1e-15)
    sol = solve_ivp(
        lambda t, y: numeric_of(ham).rhs(t, y, prm),
        (0.0, period),
        problem.y0,
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
        t_eval=[period / 2, period],
    )
    assert sol.success
    assert np.max(np.abs(sol.y[:, 1] - problem.y0)) < 1e-8
    # Half-way it is far from the start: the check is not trivial.
    assert np.max(np.abs(sol.y[:, 0] - problem.y0)) > 0.5
