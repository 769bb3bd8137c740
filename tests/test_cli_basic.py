"""`hamrkq list` and `hamrkq show` from the test process."""

import pytest

import hamrkq
from hamrkq.cli import main


def test_list_shows_every_problem(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in hamrkq.list_problems():
        assert name in out
    assert "prentice2011" in out


def test_show_prentice2011(capsys):
    assert main(["show", "prentice2011"]) == 0
    out = capsys.readouterr().out
    assert "p**2/2 - (1 - p/6)*cos(q)" in out
    assert "dq/dt = p + cos(q)/6" in out
    assert "[conserved]" in out


def test_show_latex(capsys):
    assert main(["show", "kepler", "--latex"]) == 0
    out = capsys.readouterr().out
    assert r"\frac" in out and r"\sqrt" in out


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [(["show", "no_such_problem"], "no problem named"), (["frobnicate"], "invalid choice")],
)
def test_bad_input_exits_2_without_traceback(capsys, argv, fragment):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err
