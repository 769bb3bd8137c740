"""The disk cache of independent references: one computed, read back by every later run.

A report's independent reference (:func:`~hamrkq.analysis.reference.hamiltonian_reference`)
is the same numbers every time the same Hamiltonian, parameters, initial state
and node times are asked for: ``hamrkq run prentice2011`` recomputed it
(0.18 s) and imported ``scipy.integrate`` to do so (0.3 s) on every run.  It is
kept here instead, beside the generated code in
:func:`~hamrkq.backends.source_cache.cache_dir` (folder ``references``).

The file name hashes everything the reference depends on: the Hamiltonian's
cache key (its expressions, and the versions of hamrkq, SymPy, numba and
Python), SciPy's and NumPy's versions, :data:`REFERENCE_CACHE_VERSION`, and the
bytes of the parameters, initial state and times.  Each file carries the
SHA-256 of its contents, checked on reading: a damaged file is recomputed and
rewritten with a warning, never trusted.  References of more than
:data:`MAX_CACHED_NUMBERS` numbers are not kept.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq._files import atomic_file
from hamrkq.backends.codegen import cache_key
from hamrkq.backends.source_cache import cache_dir
from hamrkq.errors import HamrkqWarning

__all__ = ["MAX_CACHED_NUMBERS", "REFERENCE_CACHE_VERSION", "cached", "reference_path"]

#: Bump when the way references are computed changes: old files are then ignored.
REFERENCE_CACHE_VERSION = 1
#: Larger references (``y.size``) are recomputed each time rather than written.
MAX_CACHED_NUMBERS = 1 << 20


def _versions() -> str:
    import scipy  # the package only: its subpackages load lazily

    return (
        f"reference-cache={REFERENCE_CACHE_VERSION};scipy={scipy.__version__};"
        f"numpy={np.__version__}"
    )


def reference_path(
    ham: Any, params: Any, y0: np.ndarray, t: np.ndarray, t0: float, periodic: bool | None
) -> Path:
    """Where the reference of these inputs is kept (whether or not it exists)."""
    digest = hashlib.sha256(cache_key(ham, _versions()).encode())
    for array in (np.zeros(0) if params is None else params, y0, t):
        values = np.ascontiguousarray(array, dtype=float)
        digest.update(f"{values.shape}".encode())
        digest.update(values.tobytes())
    digest.update(f"t0={float(t0).hex()};periodic={periodic}".encode())
    return cache_dir() / "references" / f"{digest.hexdigest()[:40]}.npz"


def _checksum(t: np.ndarray, y: np.ndarray, meta: str) -> str:
    digest = hashlib.sha256(np.ascontiguousarray(t).tobytes())
    digest.update(np.ascontiguousarray(y).tobytes())
    digest.update(meta.encode())
    return digest.hexdigest()


def _read(path: Path) -> dict[str, Any]:
    """The fields of a kept reference; ValueError if the file is damaged."""
    try:
        with np.load(path, allow_pickle=False) as data:
            t, y = data["t"], data["y"]
            meta, checksum = str(data["meta"]), str(data["checksum"])
    except Exception as exc:  # a damaged zip raises any of half a dozen types
        raise ValueError(f"it cannot be read ({type(exc).__name__}: {exc})") from exc
    if checksum != _checksum(t, y, meta):
        raise ValueError("its checksum does not match its contents")
    return {"t": t, "y": y, **json.loads(meta)}


def _write(path: Path, fields: dict[str, Any]) -> None:
    meta = json.dumps({k: v for k, v in fields.items() if k not in ("t", "y")})
    t, y = np.asarray(fields["t"], dtype=float), np.asarray(fields["y"], dtype=float)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(path, "wb") as handle:
            np.savez(handle, t=t, y=y, meta=np.str_(meta), checksum=np.str_(_checksum(t, y, meta)))
    except OSError:
        pass  # a read-only or full cache: the reference is simply not kept


def cached(path: Path, compute: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """The reference kept at ``path``, or ``compute()``'s, kept there.

    ``compute`` returns the fields of a
    :class:`~hamrkq.analysis.reference.Reference` (``t``, ``y``,
    ``estimated_error``, ``method``, ``details`` of plain numbers and text).
    A damaged file is reported with a :class:`~hamrkq.errors.HamrkqWarning`,
    recomputed and rewritten.
    """
    if path.exists():
        try:
            return _read(path)
        except ValueError as exc:
            warnings.warn(
                f"hamrkq: the cached reference {path} is damaged ({exc}); recomputing it",
                HamrkqWarning,
                stacklevel=3,
            )
    fields = compute()
    if np.size(fields["y"]) <= MAX_CACHED_NUMBERS:
        _write(path, fields)
    return fields
