"""Expressions are ASCII: a Unicode look-alike is refused, not read as an
ASCII name (found by QA: ``ast.parse`` NFKC-normalises identifiers, so
``p**2/2 - cos(q) + ｑ`` with a fullwidth ``ｑ`` was read as ``... + q``, and
``ℯ`` bound to a parameter ``e``)."""

from __future__ import annotations

import contextlib
import io

import pytest
import sympy as sp

import hamrkq
from hamrkq.cli import main
from hamrkq.errors import ExpressionError
from hamrkq.symbolic.expressions import parse_expression

q, p, e = sp.symbols("q p e")
SYMBOLS = {"q": q, "p": p, "e": e}


@pytest.mark.parametrize(
    ("text", "char", "name", "position", "read_as"),
    [
        ("p**2/2 - cos(q) + \uff51", "\uff51", "FULLWIDTH LATIN SMALL LETTER Q", 19, "q"),
        ("e*\u212f", "\u212f", "SCRIPT SMALL E", 3, "e"),
        ("\U0001d45e + p", "\U0001d45e", "MATHEMATICAL ITALIC SMALL Q", 1, "q"),
        ("q*\u03c0", "\u03c0", "GREEK SMALL LETTER PI", 3, None),
        ("q\u00a0+ p", "\u00a0", "NO-BREAK SPACE", 2, None),
        ("q + p\u200b", "\u200b", "ZERO WIDTH SPACE", 6, None),
    ],
    ids=["fullwidth-q", "script-e", "math-italic-q", "pi", "nbsp", "zero-width"],
)
def test_a_non_ascii_character_is_named_with_its_position(text, char, name, position, read_as):
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, SYMBOLS)
    message = str(info.value)
    assert f"character {char!r} ({name}, U+{ord(char):04X}) at position {position}" in message
    assert ("Python would read it as" in message) == (read_as is not None)
    if read_as is not None:
        assert f"Python would read it as {read_as!r}" in message


def test_ascii_expressions_still_parse():
    assert parse_expression("p**2/2 - cos(q) + e", SYMBOLS) == p**2 / 2 - sp.cos(q) + e


def problem_file(tmp_path, hamiltonian):
    path = tmp_path / "uni.toml"
    path.write_text(
        'name = "uni"\ncoordinates = ["q"]\nmomenta = ["p"]\n'
        f'hamiltonian = "{hamiltonian}"\n[initial]\nq = 1\np = 0\n'
        "[integration]\nt_span = [0, 1]\n",
        encoding="utf-8",
    )
    return path


def test_a_problem_file_with_a_look_alike_is_refused_at_its_key(tmp_path):
    path = problem_file(tmp_path, "p**2/2 - cos(q) + \uff51")
    with pytest.raises(ExpressionError) as info:
        hamrkq.load_problem(path)
    assert info.value.key == "hamiltonian" and info.value.line == 4
    assert "FULLWIDTH LATIN SMALL LETTER Q" in str(info.value)


def test_cli_show_exits_2_with_file_and_key(tmp_path):
    path = problem_file(tmp_path, "p**2/2 - cos(q) + \uff51")
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["show", str(path)])
    assert status == 2
    assert err.getvalue().startswith(
        f"hamrkq: error: {path}:4, key 'hamiltonian': expressions must be ASCII: "
        "character '\uff51' (FULLWIDTH LATIN SMALL LETTER Q, U+FF51) at position 19"
    )
    assert "Traceback" not in err.getvalue()
