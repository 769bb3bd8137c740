"""Hamiltonian: derived equations, validation, Poisson brackets, numeric functions."""

import numpy as np
import pytest
import sympy as sp

from hamrkq import Hamiltonian
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import HamiltonianError, InputError, UndeclaredSymbolError

q, p, a = sp.symbols("q p a")
q1, q2, p1, p2 = sp.symbols("q1 q2 p1 p2")


def prentice():
    return Hamiltonian(p**2 / 2 - (1 - p / 6) * sp.cos(q), q=[q], p=[p])


def test_equations_of_the_papers_problem():
    ham = prentice()
    # the paper: dq/dt = p + cos(q)/6, dp/dt = (p/6 - 1) sin q
    assert sp.simplify(ham.rhs[0] - (p + sp.cos(q) / 6)) == 0
    assert sp.simplify(ham.rhs[1] - (p / 6 - 1) * sp.sin(q)) == 0
    expected = sp.Matrix([[-sp.sin(q) / 6, 1], [(p / 6 - 1) * sp.cos(q), sp.sin(q) / 6]])
    assert sp.simplify(ham.jacobian - expected) == sp.zeros(2, 2)
    eqs = ham.equations
    assert [e.lhs for e in eqs] == [sp.Derivative(q, ham.t), sp.Derivative(p, ham.t)]
    assert [e.rhs for e in eqs] == list(ham.rhs)


def test_kepler_equations_and_first_integrals():
    r = sp.sqrt(q1**2 + q2**2)
    ham = Hamiltonian((p1**2 + p2**2) / 2 - 1 / r, q=[q1, q2], p=[p1, p2])
    assert list(ham.rhs[:2]) == [p1, p2]
    assert sp.simplify(ham.rhs[2] + q1 / r**3) == 0
    assert ham.is_first_integral(q1 * p2 - q2 * p1)  # angular momentum
    assert ham.is_first_integral(ham.H)
    assert not ham.is_first_integral(q1 * p1)
    assert ham.is_separable
    assert not prentice().is_separable
    # {q_i, p_j} = delta_ij
    assert ham.poisson_bracket(q1, p1) == 1 and ham.poisson_bracket(q1, p2) == 0


def test_time_dependent_hamiltonian():
    t = sp.Symbol("t")
    ham = Hamiltonian(p**2 / 2 + q**2 / 2 * (1 + sp.cos(t)), q=[q], p=[p])
    assert ham.time_dependent and ham.t == t
    assert not ham.is_first_integral(ham.H)  # dH/dt = -q^2 sin(t)/2 != 0
    assert sp.simplify(ham.time_derivative(ham.H) + q**2 * sp.sin(t) / 2) == 0
    f = numeric_of(ham).rhs(np.pi, np.array([1.0, 0.0]), np.array([]))
    assert f == pytest.approx([0.0, 0.0], abs=1e-15)


def test_validation_reports_every_problem_at_once():
    with pytest.raises(HamiltonianError) as info:
        Hamiltonian(sp.Matrix([p, q]), q=[q, q1], p=[p, q1, p1])
    message = str(info.value)
    assert "scalar" in message
    assert "q has 2 symbols but p has 3" in message
    assert "duplicated symbols: q1" in message
    assert len(info.value.problems) == 3


def test_undeclared_symbols_are_named():
    b = sp.Symbol("b")
    with pytest.raises(UndeclaredSymbolError, match=r"undeclared symbols: a, b") as info:
        Hamiltonian(p**2 / 2 + a * b * q, q=[q], p=[p])
    assert info.value.symbols == ("a", "b")
    assert isinstance(info.value, ValueError)


def test_string_hamiltonian_is_refused():
    with pytest.raises(HamiltonianError, match="never evaluates text"):
        Hamiltonian("p**2/2", q=[q], p=[p])


def test_immutable_and_cached():
    ham = prentice()
    with pytest.raises(AttributeError):
        ham.H = q
    assert ham.jacobian is ham.jacobian
    assert numeric_of(ham) is numeric_of(ham)


def test_parameters_are_arguments_not_regenerated():
    ham = Hamiltonian(p**2 / 2 - (1 - p / a) * sp.cos(q), q=[q], p=[p], parameters={a: 6.0})
    numeric = numeric_of(ham)
    y = np.array([0.3, 0.2])
    f6 = numeric.rhs(0.0, y, ham.parameter_values())
    f3 = numeric.rhs(0.0, y, ham.parameter_values({"a": 3.0}))
    assert numeric_of(ham) is numeric  # nothing regenerated
    assert f6[0] == pytest.approx(0.2 + np.cos(0.3) / 6)
    assert f3[0] == pytest.approx(0.2 + np.cos(0.3) / 3)
    with pytest.raises(InputError, match="unknown parameter b"):
        ham.parameter_values({"b": 1.0})
    # A symbol named like the parameter but with other assumptions is another
    # symbol to SymPy: the message said "unknown parameter a (parameters: a)".
    with pytest.raises(InputError, match=r"other assumptions \(positive=True\).*key it by name"):
        ham.parameter_values({sp.Symbol("a", positive=True): 3.0})
    # The same for initial values keyed by symbol: "unknown coordinate 'q';
    # the coordinates are q" before (QA).
    q_plain = sp.Symbol(ham.q[0].name, positive=True)
    with pytest.raises(InputError, match=r"q0: .* other assumptions \(positive=True\)"):
        ham.state_values({q_plain: 0.3}, [0.2])
    with pytest.raises(InputError, match="finite"):
        ham.parameter_values({a: np.inf})
    no_default = Hamiltonian(a * p**2, q=[q], p=[p], parameters=[a])
    with pytest.raises(InputError, match="no value for parameter"):
        no_default.parameter_values()


def test_vectorised_energy_and_gradient():
    ham = prentice()
    Y = np.array([[0.1, 0.2], [1.0, -0.5], [2.0, 0.0]])
    H = numeric_of(ham).energy(0.0, Y, [])
    expected = Y[:, 1] ** 2 / 2 - (1 - Y[:, 1] / 6) * np.cos(Y[:, 0])
    np.testing.assert_allclose(H, expected, rtol=1e-15)
    G = numeric_of(ham).gradient(0.0, Y, [])
    np.testing.assert_allclose(G[:, 0], (1 - Y[:, 1] / 6) * np.sin(Y[:, 0]), rtol=1e-15)
    np.testing.assert_allclose(G[:, 1], Y[:, 1] + np.cos(Y[:, 0]) / 6, rtol=1e-15)
    # gradient of H is S^T-rotated rhs: dH/dp = dq/dt, dH/dq = -dp/dt
    f = numeric_of(ham).rhs_many(0.0, Y, [])
    np.testing.assert_allclose(G, np.column_stack([-f[:, 1], f[:, 0]]), rtol=1e-15)


def test_initial_values_accept_sympy_numbers():
    ham = prentice()
    y0 = ham.state_values([sp.acos(sp.Rational(-4, 5))], [0])
    assert y0[0] == pytest.approx(np.arccos(-0.8), rel=1e-16)
    with pytest.raises(InputError, match="free symbols"):
        ham.state_values([q], [0])
    with pytest.raises(InputError, match="q0 has 2 values"):
        ham.state_values([1, 2], [0])
    with pytest.raises(InputError, match="finite"):
        ham.state_values([np.nan], [0])
