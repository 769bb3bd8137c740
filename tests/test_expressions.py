"""The restricted expression parser: what it accepts, what it refuses, and that
refusing never runs anything."""

import os
import re

import pytest
import sympy as sp

from hamrkq.errors import ExpressionError, ProblemFileError
from hamrkq.symbolic.expressions import MAX_DEPTH, check_name, parse_expression

q, p, a = sp.symbols("q p a")
t = sp.Symbol("t")
SYMS = {"q": q, "p": p, "a": a, "t": t}


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("p**2/2 - (1 - p/6)*cos(q)", p**2 / 2 - (1 - p / 6) * sp.cos(q)),
        ("-q + +p", -q + p),
        ("atan2(q, p) + Abs(a)", sp.atan2(q, p) + sp.Abs(a)),
        ("sqrt(2)*pi*E", sp.sqrt(2) * sp.pi * sp.E),
        (
            "exp(log(q)) * sinh(t) / tanh(a) + cosh(p) + tan(q) + asin(q) + atan(p)",
            q * sp.sinh(t) / sp.tanh(a) + sp.cosh(p) + sp.tan(q) + sp.asin(q) + sp.atan(p),
        ),
        ("0.994", sp.Rational(497, 500)),
        ("2.95912208286e-4", sp.Rational(295912208286, 10**15)),
        ("acos(-0.8)", sp.acos(sp.Rational(-4, 5))),
        (3, sp.Integer(3)),
        (0.5, sp.Rational(1, 2)),
    ],
)
def test_accepts_the_documented_language(text, expected):
    assert sp.simplify(parse_expression(text, SYMS) - expected) == 0


HOSTILE = [
    ("__import__('os').system('touch hamrkq_pwned')", "only the listed functions"),
    ("__import__('os')", "function '__import__'"),
    ("().__class__", "attribute access"),
    ("q.__class__", "attribute access"),
    ("lambda: 0", "lambda"),
    ("[x for x in ()]", "comprehension"),
    ("{x for x in ()}", "comprehension"),
    ("(x for x in ())", "generator"),
    ('"a"', "string"),
    ("b'a'", "string"),
    ("open('f')", "function 'open'"),
    ("eval('1')", "function 'eval'"),
    ("exec('1')", "function 'exec'"),
    ("sympify('q')", "function 'sympify'"),
    ("getattr(q, 'x')", "function 'getattr'"),
    ("__builtins__", "dunder"),
    ("q[0]", "subscripting"),
    ("sin(x=q)", "keyword arguments"),
    ("sin(*q)", "starred"),
    ("q if p else a", "conditional"),
    ("q < p", "comparison"),
    ("q and p", "boolean"),
    ("(y := 3)", "assignment"),
    ("f'{q}'", "f-string"),
    ("q // p", "'//'"),
    ("q % p", "'%'"),
    ("~q", "'~'"),
    ("import os", "not a valid expression"),
    ("q; p", "not a valid expression"),
    ("unknown_name + 1", "unknown name"),
    ("sin", "without arguments"),
    ("sin(q, p)", "takes 1 argument"),
    ("atan2(q)", "takes 2 arguments"),
    ("2**2**2**100", "power too large"),
    ("9**9**9", "exponent"),
    ("1" * 200, "digits"),
    ("sin(" * (MAX_DEPTH + 5) + "q" + ")" * (MAX_DEPTH + 5), "nested"),
    ("(" * 250 + "q" + ")" * 250, "cannot be parsed|not a valid"),
    ("-" * (MAX_DEPTH + 5) + "q", "nested"),
    ("", "empty"),
    ("q\np", "one line"),
    ("1e999", "finite"),
    ("True", "bool"),
    ("[q, p]", "a list"),
]


@pytest.mark.parametrize(("text", "fragment"), HOSTILE)
def test_rejects_everything_else(text, fragment, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, SYMS, path="bad.toml", key="hamiltonian")
    message = str(info.value)
    assert re.search(fragment, message)
    assert "bad.toml" in message and "hamiltonian" in message
    assert isinstance(info.value, ProblemFileError) and isinstance(info.value, ValueError)
    assert os.listdir(tmp_path) == []  # nothing ran, nothing was written


def test_error_names_the_offending_piece():
    with pytest.raises(ExpressionError) as info:
        parse_expression("p**2/2 + q.real", SYMS)
    assert info.value.piece == "q.real"


def test_names_must_be_plain_identifiers():
    assert check_name("q1") is None
    for bad in ("t", "pi", "sin", "lambda", "_x", "__x", "x y", "1x", "é", 3):
        assert check_name(bad) is not None
