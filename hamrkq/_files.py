"""Files written whole or not at all, saved archives read safely, and values
made plain for JSON.

One home for what every writer and reader of hamrkq's files needs:
:func:`atomic_file` (a temporary file in the target's directory, renamed
into place, removed on any failure, so a crash or a signal never leaves half
a file under the final name), :func:`open_npz` (a saved ``.npz`` opened
without unpickling anything) and :func:`plain` / :func:`jsonable` (NumPy
scalars and arrays as plain Python values).
"""

from __future__ import annotations

import contextlib
import math
import os
import pickle
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = ["atomic_file", "jsonable", "open_npz", "plain", "write_atomic"]


def _umask() -> int:
    mask = os.umask(0o022)  # reading the umask means setting it; restore at once
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` and rename it to ``path`` when the
    block ends without an exception (else remove it).  The file gets the
    ordinary permissions of a new file (0666 less the umask), not
    ``mkstemp``'s private 0600."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as handle:
            yield handle
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` whole or not at all."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_file(path) as handle:
        handle.write(raw)
    return Path(path)


def plain(value: Any) -> Any:
    """NumPy scalars and arrays inside ``value`` as plain Python values
    (non-finite floats kept: ``json.dumps`` writes them as NaN/Infinity)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def jsonable(value: Any) -> Any:
    """Strict JSON values: as :func:`plain`, and nan and inf become None (so
    ``summary.json`` is strict JSON, readable anywhere)."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        number = float(value)
        return number if math.isfinite(number) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


#: The first bytes of a zip archive, which an .npz is: a local file header,
#: or the end record of an empty archive.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
#: The first bytes of a single .npy array.
_NPY_MAGIC = b"\x93NUMPY"


def open_npz(path: Path, what: str, fail: Callable[[str], Exception]) -> Any:
    """Open a saved ``.npz`` archive for reading, without unpickling anything.

    Shared by :meth:`hamrkq.result.Solution.load` and
    :meth:`hamrkq.ensemble.EnsembleSolution.load`.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        What the file should hold ("solution", "ensemble"), for the message.
    fail : callable
        Makes the exception to raise from a message that does not name the
        path (the caller's exception class names it).

    Returns
    -------
    numpy.lib.npyio.NpzFile
        The open archive (a context manager); its members are read lazily.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, PermissionError
        As :func:`open`.
    Exception
        ``fail(message)``: the file is not a zip archive, or its directory
        is damaged.
    """
    with open(path, "rb") as file:
        head = file.read(len(_NPY_MAGIC))
    if not head.startswith(_ZIP_MAGIC):
        # Checked here, not left to np.load: for a file that is neither an
        # archive nor an .npy, NumPy tries pickle and, refused, says "This
        # file contains pickled (object) data. If you trust the file you can
        # load it unsafely ...": wrong for a text file, and advice to unpickle
        # what nobody should.
        kind = {_NPY_MAGIC: ": it is a single .npy array", b"": ": it is empty"}.get(head, "")
        raise fail(f"not a saved hamrkq {what} (.npz archive){kind}")
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, pickle.UnpicklingError) as exc:
        raise fail(f"not a saved hamrkq {what}: damaged .npz archive ({exc})") from None
