"""docs/errors.md against the code: every failure class is listed, with its code.

The page's three tables (exceptions, statuses, exit statuses) are read back
and compared with :mod:`hamrkq.errors`, :class:`hamrkq.Status` and the
``EXIT_*`` constants of :mod:`hamrkq.cli`, so adding a class, a status or an
exit status without documenting it (or documenting one that does not exist)
fails here.  The limits quoted on the page are compared with the constants.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import hamrkq.cli
from hamrkq import errors
from hamrkq.io.report import MAX_DPI, MAX_FIGURE_PIXELS, MIN_DPI
from hamrkq.options import MIN_ATOL
from hamrkq.result import Status
from hamrkq.symbolic import expressions

PAGE = (Path(__file__).resolve().parent.parent / "docs" / "errors.md").read_text()


def table_after(heading: str) -> list[list[str]]:
    """The rows (cells stripped) of the first table after ``heading``."""
    start = PAGE.index(heading)
    rows, started = [], False
    for line in PAGE[start:].splitlines()[1:]:
        if line.startswith("|"):
            started = True
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if not set("".join(cells)) <= set("-: "):
                rows.append(cells)
        elif started:
            break
    return rows[1:]  # without the header


def exception_classes() -> dict[str, type]:
    return {
        name: getattr(errors, name)
        for name in errors.__all__
        if isinstance(getattr(errors, name), type)
        and issubclass(getattr(errors, name), BaseException)
        and not issubclass(getattr(errors, name), Warning)
    }


def test_every_exception_class_is_documented_with_its_bases():
    rows = table_after("## The exceptions")
    documented = {row[0].strip("`"): row for row in rows}
    assert set(documented) == set(exception_classes()) - {"HamrkqError"}
    for name, cls in exception_classes().items():
        if name == "HamrkqError":
            continue
        also = re.findall(r"`(\w+)`", documented[name][1])
        bases = {klass.__name__ for klass in cls.__mro__}
        assert also and set(also) <= bases, (name, also)
        assert documented[name][2] and documented[name][3]  # when, and what to do


def test_the_warning_class_is_documented():
    warnings_section = PAGE[PAGE.index("### Warnings") : PAGE.index("## The statuses")]
    assert "`hamrkq.errors.HamrkqWarning`" in warnings_section
    assert "`hamrkq.errors.warn`" in warnings_section


def test_every_status_is_documented_with_its_code():
    rows = table_after("## The statuses of a run")
    documented = {row[1].strip("`"): int(row[0]) for row in rows}
    assert documented == {status.name: status.code for status in Status}


def test_every_exit_status_is_documented():
    rows = table_after("## The command line")
    documented = {int(row[0]) for row in rows}
    constants = {value for name, value in vars(hamrkq.cli).items() if name.startswith("EXIT_")}
    assert documented == constants == {0, 1, 2, 3, 141}
    assert hamrkq.cli.EXIT_WRITE_FAILED == 3 and "cannot write output" in PAGE


@pytest.mark.parametrize(
    "text",
    [
        f"below {MIN_ATOL:g}",
        f"between {MIN_DPI} and {MAX_DPI}",
        f"{MIN_DPI}..{MAX_DPI}",
        f"{MAX_FIGURE_PIXELS // 1_000_000} megapixels",
        f"at most {expressions.MAX_LENGTH:,} characters".replace(",", " "),
        f"at most {expressions.MAX_DEPTH} levels",
        f"at most {expressions.MAX_EXPONENT} in magnitude",
        f"at most {expressions.MAX_DIGITS} digits",
        f"past {expressions.MAX_NUMBER_BITS} bits",
    ],
)
def test_the_limits_quoted_are_the_codes(text):
    assert text in PAGE
