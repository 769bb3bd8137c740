"""Test-session settings shared by every test module.

The suite never writes to the user's cache: generated modules and numba's
machine code go to one temporary directory for the whole session (shared by
pytest-xdist's workers, so each system compiles once per run), whatever
``HAMRKQ_CACHE_DIR`` or ``NUMBA_CACHE_DIR`` say in the calling environment,
and a first use compiles before it runs (``HAMRKQ_COMPILE=wait``).
Subprocesses started by tests inherit the same settings through
``os.environ``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

# Set at import, before any test module imports hamrkq: a module-level
# HAMRKQ_CACHE_DIR read at import time would otherwise see the user's value.
_SESSION_CACHE = Path(
    os.environ.get("HAMRKQ_TEST_CACHE") or tempfile.mkdtemp(prefix="hamrkq-test-cache-")
)
os.environ["HAMRKQ_TEST_CACHE"] = str(_SESSION_CACHE)  # xdist workers share it
os.environ["HAMRKQ_CACHE_DIR"] = str(_SESSION_CACHE / "hamrkq")
os.environ["NUMBA_CACHE_DIR"] = str(_SESSION_CACHE / "numba")
# A first use compiles in the calling process, as with backend="numba": the
# suite's tests (counts of compiles, notices, timings of first uses) expect
# it, and helper processes would compete with pytest's workers.
# tests/test_background.py turns the background compile on where it tests it.
os.environ["HAMRKQ_COMPILE"] = "wait"


@pytest.fixture(scope="session")
def session_cache_dir() -> Path:
    """The temporary cache directory of this test session."""
    return _SESSION_CACHE
