"""The disk cache of independent references (hamrkq.analysis.reference_cache).

A kept reference must be the very numbers a fresh computation gives, found
only for the same inputs, never trusted when damaged, and read without
importing ``scipy.integrate`` (the point of keeping it: a warm ``hamrkq run``).
"""

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import hamrkq
from hamrkq.analysis import reference as reference_module
from hamrkq.analysis.reference import hamiltonian_reference
from hamrkq.analysis.reference_cache import reference_path
from hamrkq.errors import HamrkqWarning

ROOT = Path(hamrkq.__file__).parents[1]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache folder of this test's own."""
    monkeypatch.setenv("HAMRKQ_CACHE_DIR", str(tmp_path))
    return tmp_path / "references"


@pytest.fixture(scope="module")
def kepler():
    return hamrkq.load_problem("kepler")


def _same(a, b):
    assert np.array_equal(a.t, b.t) and np.array_equal(a.y, b.y)
    assert a.estimated_error == b.estimated_error and a.method == b.method
    assert dict(a.details) == dict(b.details)


def _refuse_to_compute(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the reference was computed, not read from the cache")

    monkeypatch.setattr(reference_module, "periodic_reference", refuse)
    monkeypatch.setattr(reference_module, "integrate_reference", refuse)


def test_a_kept_reference_is_read_back_bit_for_bit(cache, kepler, monkeypatch):
    t = np.linspace(0.0, 20.0, 41)
    fresh = hamiltonian_reference(kepler, kepler.y0, t, cache=False)
    first = hamiltonian_reference(kepler, kepler.y0, t)
    assert len(list(cache.iterdir())) == 1
    _refuse_to_compute(monkeypatch)
    again = hamiltonian_reference(kepler, kepler.y0, t)
    _same(fresh, first)
    _same(first, again)
    assert again.estimated_error > 0 and "rtol" in again.details


def test_other_inputs_are_other_references(cache, kepler):
    t = np.linspace(0.0, 5.0, 11)
    y0 = np.array(kepler.y0, dtype=float)
    moved = y0.copy()
    moved[2] = np.nextafter(moved[2], 1.0)  # one ulp of a momentum
    params = kepler.parameter_array
    paths = {
        reference_path(kepler.hamiltonian, params, y0, t, 0.0, None),
        reference_path(kepler.hamiltonian, params, moved, t, 0.0, None),
        reference_path(kepler.hamiltonian, params, y0, t[:-1], 0.0, None),
        reference_path(kepler.hamiltonian, params, y0, t, 0.0, False),
        reference_path(kepler.hamiltonian, params, y0, t, 1e-300, None),
        reference_path(kepler.hamiltonian, params * (1 + 1e-15), y0, t, 0.0, None),
        reference_path(hamrkq.load_problem("harmonic").hamiltonian, params, y0, t, 0.0, None),
    }
    assert len(paths) == 7


@pytest.mark.parametrize(
    "damage",
    ["empty", "truncated", "garbage", "edited"],
)
def test_a_damaged_reference_is_recomputed_with_a_warning(cache, kepler, damage):
    t = np.linspace(0.0, 10.0, 21)
    fresh = hamiltonian_reference(kepler, kepler.y0, t)
    (path,) = cache.iterdir()
    raw = path.read_bytes()
    if damage == "empty":
        path.write_bytes(b"")
    elif damage == "truncated":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        path.write_bytes(os.urandom(len(raw)))
    else:  # a valid file whose numbers were changed: only the checksum tells
        with np.load(path) as data:
            fields = {name: data[name] for name in data.files}
        fields["y"] = fields["y"] + 1e-9
        with open(path, "wb") as handle:
            np.savez(handle, **fields)
    with pytest.warns(HamrkqWarning, match="damaged"):
        again = hamiltonian_reference(kepler, kepler.y0, t)
    _same(fresh, again)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _same(fresh, hamiltonian_reference(kepler, kepler.y0, t))  # rewritten intact


def test_an_unwritable_cache_still_gives_the_reference(tmp_path, kepler, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("HAMRKQ_CACHE_DIR", str(blocker))
    t = np.linspace(0.0, 5.0, 11)
    _same(hamiltonian_reference(kepler, kepler.y0, t, cache=False),
          hamiltonian_reference(kepler, kepler.y0, t))  # fmt: skip


def test_a_kept_reference_is_read_without_importing_scipy_integrate(tmp_path):
    script = (
        "import sys, numpy as np, hamrkq\n"
        "from hamrkq.analysis.reference import hamiltonian_reference\n"
        "problem = hamrkq.load_problem('harmonic')\n"
        "ref = hamiltonian_reference(problem, problem.y0, np.linspace(0, 3, 7))\n"
        "print(ref.estimated_error, 'scipy.integrate' in sys.modules)\n"
    )
    env = {**os.environ, "HAMRKQ_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    runs = [
        subprocess.run(
            [sys.executable, "-c", script],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
            cwd=tmp_path,
        )
        for _ in range(2)
    ]
    for done in runs:
        assert done.returncode == 0, done.stderr
    computed, read = (done.stdout.split() for done in runs)
    assert computed == [computed[0], "True"] and read == [computed[0], "False"]
