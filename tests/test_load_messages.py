"""Loading a file that is not an .npz archive says so plainly (found by QA:
a JSON text file given to ``Solution.load`` or ``EnsembleSolution.load``
raised an error quoting NumPy's "This file contains pickled (object) data.
If you trust the file you can load it unsafely using the allow_pickle=
keyword ...": wrong for a text file, and advice that contradicts the
promise that nothing in a file is unpickled)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hamrkq
from hamrkq.errors import ResultFileError, SolutionFileError

LOADS = [
    pytest.param(hamrkq.Solution.load, SolutionFileError, "solution", id="solution"),
    pytest.param(hamrkq.EnsembleSolution.load, ResultFileError, "ensemble", id="ensemble"),
]


@pytest.mark.parametrize(("load", "error", "what"), LOADS)
@pytest.mark.parametrize(
    ("content", "tail"),
    [
        (json.dumps({"a": 1}).encode(), ""),
        (b"", ": it is empty"),
        (b"t,q,p\n0,1,0\n", ""),
    ],
    ids=["json", "empty", "csv"],
)
def test_a_file_that_is_not_an_archive_is_named_plainly(
    tmp_path, load, error, what, content, tail
):
    path = tmp_path / "notnpz.json"
    path.write_bytes(content)
    with pytest.raises(error) as info:
        load(path)
    text = str(info.value)
    assert text == f"{path}: not a saved hamrkq {what} (.npz archive){tail}"
    assert "pickle" not in text


@pytest.mark.parametrize(("load", "error", "what"), LOADS)
def test_a_single_npy_array_is_named(tmp_path, load, error, what):
    path = tmp_path / "array.npy"
    np.save(path, np.arange(3))
    with pytest.raises(error, match=r"\(\.npz archive\): it is a single \.npy array$"):
        load(path)


@pytest.mark.parametrize(("load", "error", "what"), LOADS)
def test_a_damaged_archive_is_named(tmp_path, load, error, what):
    path = tmp_path / "broken.npz"
    path.write_bytes(b"PK\x03\x04" + b"\0" * 40)
    with pytest.raises(error) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: not a saved hamrkq {what}: damaged .npz archive")


def test_one_helper_serves_both_loads():
    """No copy of the check: both loads call hamrkq._files.open_npz."""
    import inspect

    from hamrkq import _files
    from hamrkq.ensemble import result as ensemble_result

    assert "open_npz(" in inspect.getsource(hamrkq.Solution.load)
    assert ensemble_result.open_npz is _files.open_npz
