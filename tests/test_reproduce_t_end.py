"""``hamrkq reproduce --t-end``: a run longer than the paper's says so, and
an end at or before t = 0 is refused (found by QA: ``--t-end 4001`` was
labelled "a shortened run", the test being ``!=``, not ``<``; ``--t-end -5``
integrated backwards and ``--t-end 0`` nothing, both accepted)."""

from __future__ import annotations

import pytest
from helpers import run_cli

from hamrkq.cli.reproduce import _interval_note


@pytest.mark.parametrize("t_end", ["-5", "0", "-0", "nan", "inf"])
def test_an_end_at_or_before_the_start_exits_2_and_writes_nothing(tmp_path, t_end):
    out = tmp_path / "x"
    status, _, err = run_cli("reproduce", "prentice2011", "--t-end", t_end, "--out", out)
    assert status == 2
    assert err.startswith("hamrkq: error: --t-end must be a finite number above 0 ")
    assert not out.exists()


def test_the_note_says_shortened_or_longer():
    assert _interval_note(100.0).startswith(
        "**This is a shortened run (the paper's interval is [0, 4000], this run's [0, 100])"
    )
    longer = _interval_note(4001.0)
    assert longer.startswith(
        "**This is a longer run than the paper's (the paper's interval is [0, 4000], "
        "this run's [0, 4001])"
    )
    assert "shortened" not in longer


@pytest.mark.slow
def test_a_longer_run_is_labelled_longer(tmp_path):
    """The whole experiment to t = 4001 (about 20 s)."""
    out = tmp_path / "longer"
    status, _, _ = run_cli("reproduce", "prentice2011", "--t-end", "4001", "--out", out)
    assert status == 0
    text = (out / "comparison.md").read_text()
    assert "This is a longer run than the paper's" in text
    assert "shortened" not in text
