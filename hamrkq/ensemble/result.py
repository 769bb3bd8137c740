"""The result of an ensemble: :class:`EnsembleSolution`, its pickling and its NPZ file.

An ensemble solution is immutable (every array read-only) and holds only
arrays, strings and numbers, so it pickles, crosses process boundaries and is
saved to an ``.npz`` file that loads without ``allow_pickle``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from hamrkq._files import atomic_file, open_npz
from hamrkq.errors import ResultFileError
from hamrkq.result import Status, frozen_copy

__all__ = ["FILE_FORMAT", "FILE_FORMAT_VERSION", "EnsembleSolution"]

#: Written into every ensemble file, so that a foreign ``.npz`` is recognised.
FILE_FORMAT = "hamrkq.EnsembleSolution"
#: Version of the ``.npz`` layout written by :meth:`EnsembleSolution.save`.
FILE_FORMAT_VERSION = 1

_STATUS_BY_CODE = {status.code: status for status in Status}
#: Array fields and their dtypes (the file stores exactly these).
_ARRAYS = {
    "t": float,
    "y": float,
    "y0": float,
    "t_last": float,
    "status": np.int8,
    "max_global_error": float,
    "energy0": float,
    "energy_drift": float,
    "failed": np.int64,
}
#: Arrays with one value per member.
_PER_MEMBER = ("t_last", "status", "max_global_error", "energy0", "energy_drift")


@dataclass(frozen=True, eq=False)
class EnsembleSolution:
    """Many members of one system, integrated with the same options.

    Attributes
    ----------
    t : ndarray, shape (T,)
        The kept times: ``t_eval``, or ``[t_end]`` when no ``t_eval`` was given.
    y : ndarray, shape (M, T, 2n)
        Member, time, state (all q then all p).  Without ``t_eval``, ``y[:, 0]``
        is each member's last state (at ``t_last``, which is ``t_end`` for the
        members that succeeded); with ``t_eval``, times a failed member never
        reached are NaN.
    y0 : ndarray, shape (M, 2n)
        Initial states.
    parameters : mapping of str to ndarray (M,)
        Parameter values of each member, by name.
    t_last : ndarray, shape (M,)
        The last time each member reached.
    status : ndarray of int8, shape (M,)
        :class:`~hamrkq.result.Status` codes (0 is success); see :meth:`member_status`.
    max_global_error : ndarray, shape (M,)
        The largest estimated global error ``max |y - z|`` over the member's
        kept nodes and components (NaN for methods without the RK8 track).
    energy0 : ndarray, shape (M,)
        H at each member's initial state.
    energy_drift : ndarray, shape (M,)
        ``max |H(y) - H(y0)|`` over the member's kept nodes.
    stats : mapping of str to ndarray (M,)
        Counters per member: ``steps``, ``rejected``, ``quenches``, ``nfev``, ``njev``.
    failed : ndarray of int, shape (F,)
        Indices of the members that did not succeed, in order.
    messages : tuple of str, shape (F,)
        Their messages, matching ``failed``.
    names : tuple of str
        Names of the state components.
    method : str
    options : mapping
        The options passed to :func:`hamrkq.solve` for every member (JSON-friendly).
    t_span : (float, float)
    """

    t: np.ndarray
    y: np.ndarray
    y0: np.ndarray
    t_last: np.ndarray
    status: np.ndarray
    max_global_error: np.ndarray
    energy0: np.ndarray
    energy_drift: np.ndarray
    failed: np.ndarray
    messages: tuple[str, ...]
    names: tuple[str, ...]
    method: str
    t_span: tuple[float, float]
    parameters: Mapping[str, np.ndarray] = field(default_factory=dict)
    stats: Mapping[str, np.ndarray] = field(default_factory=dict)
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for name, dtype in _ARRAYS.items():
            set_(self, name, frozen_copy(getattr(self, name), dtype))
        set_(self, "messages", tuple(str(m) for m in self.messages))
        set_(self, "names", tuple(str(m) for m in self.names))
        set_(self, "t_span", tuple(float(v) for v in self.t_span))
        set_(self, "method", str(self.method))
        set_(self, "stats", _frozen({k: frozen_copy(v, np.int64) for k, v in self.stats.items()}))
        set_(
            self,
            "parameters",
            _frozen({k: frozen_copy(v, float) for k, v in self.parameters.items()}),
        )
        set_(self, "options", _frozen(dict(self.options)))
        m, dim = self.y0.shape if self.y0.ndim == 2 else (-1, -1)
        problems = []
        if self.y.shape != (m, self.t.size, dim) or len(self.names) != dim or dim % 2:
            problems.append(f"y {self.y.shape}, y0 {self.y0.shape}, t {self.t.shape}")
        per_member = {
            **{name: getattr(self, name) for name in _PER_MEMBER},
            **self.stats,
            **self.parameters,
        }
        problems += [f"{k} {v.shape}" for k, v in per_member.items() if v.shape != (m,)]
        if self.failed.shape != (len(self.messages),):
            problems.append(f"failed {self.failed.shape} but {len(self.messages)} messages")
        if problems:
            raise ValueError(
                f"inconsistent ensemble arrays for {m} members: {'; '.join(problems)}"
            )

    # -- views ---------------------------------------------------------------
    @property
    def n(self) -> int:
        """Degrees of freedom."""
        return len(self.names) // 2

    @property
    def q(self) -> np.ndarray:
        """Coordinates, shape (M, T, n)."""
        return self.y[..., : self.n]

    @property
    def p(self) -> np.ndarray:
        """Momenta, shape (M, T, n)."""
        return self.y[..., self.n :]

    @property
    def success(self) -> np.ndarray:
        """True for each member that reached the end of the interval."""
        return self.status == Status.SUCCESS.code

    @property
    def all_success(self) -> bool:
        """True when every member succeeded."""
        return self.failed.size == 0

    def member_status(self, i: int) -> Status:
        """The :class:`~hamrkq.result.Status` of member ``i``."""
        return _STATUS_BY_CODE[int(self.status[i])]

    def message(self, i: int) -> str:
        """What happened to member ``i``: a failed member's message from
        :func:`hamrkq.solve` (it names ``t``); success messages are not
        stored, and are made here as :func:`hamrkq.solve` makes them (with
        its note where nothing certified the tolerance)."""
        where = np.searchsorted(self.failed, i)
        if where < self.failed.size and self.failed[where] == i:
            return self.messages[where]
        # here, not at import: reading a saved ensemble needs no solver
        from hamrkq.rkq.family import has_quencher
        from hamrkq.solve.messages import uncertified_note

        note = uncertified_note(
            has_quencher(self.method),
            self.options.get("global_error_estimate"),
            float(self.options.get("gamma_limit") or 0.0),
        )
        return (
            f"The integration reached the end of the interval (t = {float(self.t_last[i])!r})."
            + note
        )

    def __len__(self) -> int:
        return int(self.y0.shape[0])

    def __repr__(self) -> str:
        return (
            f"EnsembleSolution(method={self.method!r}, members={len(self)}, "
            f"times={self.t.size}, n={self.n}, failed={self.failed.size})"
        )

    # -- pickling and files ---------------------------------------------------
    def _fields(self) -> dict[str, Any]:
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in ("parameters", "stats", "options"):
            values[name] = dict(values[name])
        return values

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # The mapping proxies do not pickle, and the rebuilt arrays must be
        # read-only again: rebuild through the constructor.
        return (_rebuild, (self._fields(),))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the ensemble to an ``.npz`` file, atomically.

        The file is written under a temporary name in the same directory and
        renamed, so a crash never leaves a half-written file.  :meth:`load`
        gives back an equal ensemble, bit for bit.  Returns the path written
        (``.npz`` is appended when missing).
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(path.suffix + ".npz")
        arrays = {name: getattr(self, name) for name in _ARRAYS}
        arrays.update({f"stats.{k}": v for k, v in self.stats.items()})
        arrays.update({f"parameters.{k}": v for k, v in self.parameters.items()})
        meta = {
            "format": FILE_FORMAT,
            "format_version": FILE_FORMAT_VERSION,
            "messages": list(self.messages),
            "names": list(self.names),
            "method": self.method,
            "t_span": list(self.t_span),
            "stats": list(self.stats),
            "parameters": list(self.parameters),
            "options": dict(self.options),
        }
        arrays["meta"] = np.array(json.dumps(meta))
        with atomic_file(path) as handle:
            np.savez_compressed(handle, **arrays)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> EnsembleSolution:
        """Read an ensemble written by :meth:`save`.

        Raises
        ------
        ResultFileError
            The file is missing, is not an ``.npz`` archive, was not written by
            :meth:`save` (or by a newer version of it), or is damaged.
        """
        path = Path(path)
        try:
            with open_npz(
                path, "ensemble", lambda message: ResultFileError(f"{path}: {message}")
            ) as data:
                if "meta" not in data.files:
                    raise ResultFileError(f"{path}: not a hamrkq ensemble file (no 'meta')")
                meta = json.loads(str(data["meta"]))
                if not isinstance(meta, dict) or meta.get("format") != FILE_FORMAT:
                    raise ResultFileError(f"{path}: not a hamrkq ensemble file")
                version = meta.get("format_version")
                if version != FILE_FORMAT_VERSION:
                    raise ResultFileError(
                        f"{path}: ensemble file format version {version!r} is not supported "
                        f"(this hamrkq reads version {FILE_FORMAT_VERSION})"
                    )
                arrays = {name: data[name] for name in _ARRAYS}
                stats = {k: data[f"stats.{k}"] for k in meta["stats"]}
                parameters = {k: data[f"parameters.{k}"] for k in meta["parameters"]}
                return cls(
                    **arrays,
                    stats=stats,
                    parameters=parameters,
                    messages=tuple(meta["messages"]),
                    names=tuple(meta["names"]),
                    method=meta["method"],
                    t_span=tuple(meta["t_span"]),
                    options=meta["options"],
                )
        except ResultFileError:
            raise
        except FileNotFoundError:
            raise ResultFileError(f"{path}: no such file") from None
        except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
            # open_npz refuses a non-archive; np.load's ValueError here is an
            # object array, refused without allow_pickle; zipfile and zlib
            # complain about a truncated or corrupted member.
            raise ResultFileError(f"{path}: damaged or foreign ensemble file ({exc})") from None


def _frozen(mapping: dict[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(mapping)


def _rebuild(values: dict[str, Any]) -> EnsembleSolution:
    return EnsembleSolution(**values)
