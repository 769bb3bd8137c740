"""A warning on the command line has one ``hamrkq:`` prefix (found by QA:
``hamrkq: warning: hamrkq: the cached file ... is damaged``: the CLI put its
prefix before warnings that already named hamrkq for library users)."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

from hamrkq.cli import _warnings_as_messages
from hamrkq.errors import HamrkqWarning


def test_a_warning_that_names_hamrkq_gets_one_prefix(capsys):
    with _warnings_as_messages():
        warnings.warn("hamrkq: the cached file x is damaged", HamrkqWarning, stacklevel=1)
        warnings.warn("tolerance raised", HamrkqWarning, stacklevel=1)
    assert capsys.readouterr().err.splitlines() == [
        "hamrkq: warning: the cached file x is damaged",
        "hamrkq: warning: tolerance raised",
    ]


def test_a_damaged_cache_file_is_reported_with_one_prefix(tmp_path):
    env = {**os.environ, "HAMRKQ_CACHE_DIR": str(tmp_path / "cache"),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # fmt: skip
    argv = [sys.executable, "-m", "hamrkq", "run", "harmonic", "--backend", "python",
            "--no-plots", "--out"]  # fmt: skip
    first = subprocess.run([*argv, tmp_path / "o1"], env=env, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    (generated,) = (tmp_path / "cache").glob("hamrkq_gen_*.py")
    generated.write_text(generated.read_text()[:100])
    second = subprocess.run([*argv, tmp_path / "o2"], env=env, capture_output=True, text=True)
    assert second.returncode == 0, second.stderr
    assert second.stderr.startswith(f"hamrkq: warning: the cached file {generated} is damaged")
    assert "hamrkq: warning: hamrkq:" not in second.stderr
