"""The catalogue loader on good and bad files: errors name file, line, key and piece."""

import textwrap

import numpy as np
import pytest

import hamrkq
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import ExpressionError, ProblemFileError, ProblemNotFoundError

GOOD = """\
name = "{name}"
title = "test oscillator"
references = ["a textbook"]
coordinates = ["x"]
momenta = ["px"]
hamiltonian = "px**2/(2*m) + k*x**2/2"

[parameters]
m = 2
k = "8*1"

[initial]
x = 1
q = ["sqrt(k)/2"]
p = [0]

[integration]
t_span = [0, "2*pi*sqrt(m/k)"]
atol = 1e-8

[invariants]
twice_H = "px**2/m + k*x**2"

[exact]
q = ["sqrt(k)/2*cos(t*sqrt(k/m))"]
p = ["-m*sqrt(k/m)*sqrt(k)/2*sin(t*sqrt(k/m))"]
"""


def write(tmp_path, text, name="osc"):
    path = tmp_path / f"{name}.toml"
    path.write_text(textwrap.dedent(text))
    return path


def good(tmp_path, name="osc", transform=lambda s: s):
    text = GOOD.format(name=name).replace("x = 1\n", "")
    return write(tmp_path, transform(text), name)


def test_a_good_file_loads(tmp_path):
    problem = hamrkq.load_problem(good(tmp_path))
    assert problem.name == "osc" and problem.hamiltonian.n == 1
    assert problem.q0 == pytest.approx([np.sqrt(8) / 2])
    assert problem.t_span == pytest.approx((0, 2 * np.pi / 2))
    assert problem.integration["atol"] == 1e-8
    t = np.linspace(0, 3, 7)
    exact = problem.exact(t)
    assert exact[0] == pytest.approx(problem.y0)
    # the exact solution solves Hamilton's equations: check by central differences
    h = 1e-5
    deriv = (problem.exact(t + h) - problem.exact(t - h)) / (2 * h)
    rhs = numeric_of(problem.hamiltonian).rhs_many(t, exact, problem.parameter_array)
    np.testing.assert_allclose(deriv, rhs, atol=1e-8)
    assert problem.hamiltonian.is_first_integral(problem.invariants["twice_H"])
    other = problem.with_parameters(k=2.0)
    assert other.q0 == pytest.approx([np.sqrt(2) / 2]) and problem.q0[0] != other.q0[0]


def test_a_parameter_is_the_double_nearest_its_value_a_decimal_in_h_is_exact(tmp_path):
    """What docs/catalogue.md says of [parameters] (QA: two files with
    Arenstorf's mu = 0.012277471, one as a parameter and one written into H,
    differ by 1e4 tolerances at atol 1e-12 over three periods)."""
    from fractions import Fraction

    import sympy as sp

    decimal = Fraction("0.012277471")
    as_parameter = hamrkq.load_problem("arenstorf")
    mu = as_parameter.parameters["mu"]
    assert mu == 0.012277471 and Fraction(mu) != decimal
    assert float(Fraction(mu) - decimal) == pytest.approx(-1.2948e-19, rel=1e-4)
    # an exact expression as the value is rounded alike
    expression = good(tmp_path, transform=lambda s: s.replace('k = "8*1"', 'k = "12277471/10**9"'))
    assert hamrkq.load_problem(expression).parameters["k"] == mu

    # written into H, the decimal stays an exact rational, folded exactly
    def into_h(text):  # without the invariant and exact solution in k
        return text.split("[invariants]")[0].replace("k*x**2/2", "0.012277471*x**2/2")

    inline = good(tmp_path, name="inline", transform=into_h)
    H = hamrkq.load_problem(inline).hamiltonian.H
    assert sp.Rational(12277471, 2 * 10**9) in H.atoms(sp.Rational)


def test_unknown_name_lists_the_catalogue():
    with pytest.raises(ProblemNotFoundError, match="no problem named 'nope'"):
        hamrkq.load_problem("nope")
    with pytest.raises(ProblemNotFoundError, match="does not exist"):
        hamrkq.load_problem("missing/file.toml")


BAD_FILES = [
    # (transform of the good text, error class, fragments that must all appear)
    (
        lambda s: s.replace(
            'hamiltonian = "px**2/(2*m) + k*x**2/2"',
            "hamiltonian = \"__import__('os').system('touch pwned')\"",
        ),
        ExpressionError,
        ["osc.toml:6", "key 'hamiltonian'", "__import__"],
    ),
    (
        lambda s: s.replace('twice_H = "px**2/m + k*x**2"', 'twice_H = "x.__class__"'),
        ExpressionError,
        ["key 'invariants.twice_H'", "attribute access", "x.__class__"],
    ),
    (
        lambda s: s.replace('q = ["sqrt(k)/2"]', "q = [\"open('f')\"]"),
        ExpressionError,
        ["initial.q[0]", "open"],
    ),
    (
        lambda s: s.replace('t_span = [0, "2*pi*sqrt(m/k)"]', 't_span = [0, "lambda: 0"]'),
        ExpressionError,
        ["integration.t_span", "lambda"],
    ),
    (
        lambda s: s.replace('name = "osc"', 'name = "other"'),
        ProblemFileError,
        ["name 'other' must equal the file stem 'osc'", ":1"],
    ),
    (lambda s: "surprise = 1\n" + s, ProblemFileError, ["unknown key(s): surprise", ":1"]),
    (
        lambda s: s.replace("atol = 1e-8", "atol = 1e-8\nbogus = 2"),
        ProblemFileError,
        ["integration.bogus", "unknown key"],
    ),
    (
        lambda s: s.replace('title = "test oscillator"', 'title = "unterminated'),
        ProblemFileError,
        ["osc.toml:2", "TOML syntax error"],
    ),
    (
        lambda s: s.replace('momenta = ["px"]', 'momenta = ["px", "py"]'),
        ProblemFileError,
        ["osc.toml:5", "key 'momenta'", "1 coordinate (x) but 2 momenta (px, py)", "conjugate"],
    ),
    (
        lambda s: s.replace("k*x**2/2", "k*x**2/2 + zeta"),
        ProblemFileError,
        ["unknown name", "zeta"],
    ),
    (
        lambda s: s.replace('coordinates = ["x"]', 'coordinates = ["t"]'),
        ProblemFileError,
        ["reserved"],
    ),
    (
        lambda s: s.replace('coordinates = ["x"]', 'coordinates = ["__x"]'),
        ProblemFileError,
        ["underscore"],
    ),
    (lambda s: s.replace("p = [0]", "p = [0, 1]"), ProblemFileError, ["initial.p"]),
    (
        lambda s: s.replace('q = ["sqrt(k)/2"]', 'q = ["x"]'),
        ExpressionError,
        ["initial.q[0]", "the coordinate 'x' is not allowed here", "may use the parameters"],
    ),
    (lambda s: s.replace("m = 2", 'm = "sin"'), ExpressionError, ["parameters.m"]),
]


@pytest.mark.parametrize(("transform", "error", "fragments"), BAD_FILES)
def test_bad_files_are_refused_with_file_line_key(
    tmp_path, monkeypatch, transform, error, fragments
):
    monkeypatch.chdir(tmp_path)
    path = good(tmp_path, transform=transform)
    with pytest.raises(error) as info:
        hamrkq.load_problem(path)
    message = str(info.value)
    assert str(path) in message or "osc.toml" in message
    for fragment in fragments:
        assert fragment in message, message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["osc.toml"]  # no side effect


def test_oversized_file_is_refused(tmp_path):
    path = good(tmp_path, transform=lambda s: s + "#" * 1_100_000 + "\n")
    with pytest.raises(ProblemFileError, match="limit"):
        hamrkq.load_problem(path)
