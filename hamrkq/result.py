"""The result of an integration: :class:`Solution` and its :class:`Status`.

A solution is immutable: every array it holds is read-only.  Arrays are
time-major (row ``i`` is node ``i``) and states are ordered all ``q`` then all
``p``.  Quantities a method does not produce (the RK8 track of ``"rk34"``, say)
are ``None``.
"""

from __future__ import annotations

import enum
import functools
import json
import os
import weakref
import zipfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from hamrkq._files import atomic_file, open_npz, plain
from hamrkq.errors import SolutionFileError

__all__ = [
    "FrozenDict",
    "Solution",
    "Status",
    "freeze_in_place",
    "frozen_copy",
    "kept_nodes_note",
    "owned",
]


def kept_nodes_note(count: int) -> str:
    """The sentence a run that ended early closes its message with: how many
    nodes it keeps (one node is not "1 nodes")."""
    if count == 1:
        return " The 1 node computed so far is kept."
    return f" The {count} nodes computed so far are kept."


#: Version of the ``.npz`` layout written by :meth:`Solution.save`.
FILE_FORMAT_VERSION = 1


class Status(enum.Enum):
    """Why an integration stopped.  ``value`` is a stable integer code,
    ``description`` a sentence for humans."""

    SUCCESS = (0, "The integration reached the end of the interval.")
    STEP_SIZE_UNDERFLOW = (1, "The step size fell below the floor set by roundoff.")
    NON_FINITE = (2, "The state or the right-hand side became non-finite (inf or nan).")
    MAX_STEPS = (3, "The step limit max_steps was reached.")
    INTERRUPTED = (4, "The run was interrupted (KeyboardInterrupt).")
    TOLERANCE_UNATTAINABLE = (
        5,
        "The tolerance cannot be met: the quencher track's own error is not small against it.",
    )
    NEWTON_FAILED = (6, "The Newton iteration of an implicit method did not converge.")
    EXTERNAL_FAILURE = (7, "An external solver reported a failure.")
    TERMINAL_EVENT = (8, "A terminal event ended the integration (see Solution.t_events).")
    # 9 is the step loop's own code for a run method="auto" abandons and runs again
    # (hamrkq.rkq.layout.ST_ABANDONED), never a final status: kept apart.
    ASSUMPTION_VIOLATED = (
        10,
        "The state contradicted an assumption declared on its symbol (positive, "
        "nonnegative, ...), under which SymPy had simplified H.",
    )

    def __init__(self, code: int, description: str):
        self.code = code
        self.description = description

    @property
    def success(self) -> bool:
        """True for :attr:`SUCCESS` and :attr:`TERMINAL_EVENT` (the run ended
        where it was asked to, as SciPy's ``solve_ivp`` counts it)."""
        return self is Status.SUCCESS or self is Status.TERMINAL_EVENT


class FrozenDict(Mapping):
    """A read-only mapping that pickles (``types.MappingProxyType`` does not).

    Holds a private copy of the items it was made from; compares equal to any
    mapping with the same items.
    """

    __slots__ = ("_data",)

    def __init__(self, items: Mapping[str, Any] | None = None):
        object.__setattr__(self, "_data", dict(items or {}))

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("FrozenDict is read-only")

    def __repr__(self) -> str:
        return f"FrozenDict({self._data!r})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenDict, (self._data,))


_ARRAY_FIELDS = ("t", "y", "z", "global_error", "gamma", "energy", "quenched")
#: Each array field with its dtype.
_ARRAY_DTYPES = tuple(
    (name, np.dtype(bool) if name == "quenched" else np.dtype(float)) for name in _ARRAY_FIELDS
)
#: Lists of arrays, one per event function: saved as ``t_events_0``, ...
_EVENT_FIELDS = ("t_events", "y_events", "event_bound")


def _events_from(data: Any, meta: Mapping[str, Any]) -> dict[str, Any]:
    """The event fields of a saved solution (none in a file without events)."""
    count = meta.get("events")
    if count is None:
        return {}
    events: dict[str, Any] = {"event_labels": tuple(meta["event_labels"])}
    for name in _EVENT_FIELDS:
        keys = [f"{name}_{k}" for k in range(int(count))]
        events[name] = [data[key] for key in keys] if all(k in data.files for k in keys) else None
    return events


def frozen_copy(value: Any, dtype: Any = float) -> np.ndarray:
    """A read-only copy of ``value`` as an array of ``dtype``: always a copy,
    so that nothing the caller holds can change it (:class:`Solution` and
    :class:`hamrkq.ensemble.EnsembleSolution` keep their arrays so)."""
    array = np.array(value, dtype=dtype, copy=True)
    array.setflags(write=False)
    return array


def freeze_in_place(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only where it is, not copied (unless it is not
    C-contiguous: then a contiguous copy is made read-only): whoever else
    holds it can no longer write to it either."""
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


#: The arrays :func:`_solution_array` made, by id, as weak references: a
#: :class:`Solution`'s own, which a ``replace()`` passes on without a copy.
#: (Read-only alone does not tell: a caller's read-only array that owns its
#: data can be made writable again by its owner.)  A plain dict whose entry
#: the reference's callback removes when the array dies, rather than a
#: ``WeakValueDictionary``, whose entries are made in Python: 4 us of each
#: Solution's 9 arrays.  An id is not reused before the callback has run.
_KEPT: dict[int, weakref.ref] = {}


def _kept(array: Any, dtype: Any) -> bool:
    """Whether ``array`` is an array of ``dtype`` that a Solution keeps
    already (:func:`owned`, or made by :func:`_solution_array`)."""
    known = _KEPT.get(id(array))
    return known is not None and known() is array and array.dtype == dtype


def _solution_array(array: np.ndarray | None, dtype=float) -> np.ndarray | None:
    """An array of a :class:`Solution`: None stays None, an array a Solution
    already keeps is passed on as it is, any other becomes a
    :func:`frozen_copy` (so nothing the caller holds can change it)."""
    if array is None:
        return None
    if _kept(array, dtype):
        return array
    kept = frozen_copy(array, dtype)
    key = id(kept)
    # the callback is called with the dead reference: _KEPT.pop(key, ref)
    _KEPT[key] = weakref.ref(kept, functools.partial(_KEPT.pop, key))
    return kept


def owned(array: np.ndarray) -> np.ndarray:
    """``array``, made by the caller for a :class:`Solution` and held by no
    one else, made read-only where it is and taken as the Solution's own
    (:func:`_solution_array` passes it on without a copy): the arrays a run
    returns (:func:`hamrkq.solve.outcome.solution`; a copy each was a
    third of building the Solution of a tiny problem).  An array that is
    not a float64 or bool array owning its data is left as it is (the
    Solution copies it)."""
    if (
        type(array) is np.ndarray
        and array.base is None
        and array.flags.c_contiguous
        and (array.dtype == np.float64 or array.dtype == np.bool_)
        and _KEPT.get(id(array)) is None
    ):
        array.setflags(write=False)
        key = id(array)
        _KEPT[key] = weakref.ref(array, functools.partial(_KEPT.pop, key))
    return array


@dataclass(frozen=True, eq=False)
class Solution:
    """Nodes, states and error estimates of one integration.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Node times.
    y : ndarray, shape (N, 2n)
        The reported solution (for RKQ: the quenched RK4 solution), columns
        ``q_1..q_n, p_1..p_n``.
    z : ndarray, shape (N, 2n) or None
        The RK8 track (RKQ only).
    global_error : ndarray, shape (N, 2n) or None
        Estimated global error of ``y``: ``y - z`` (numerical minus exact,
        the paper's sign).  Zero at quenched nodes.
    gamma : ndarray, shape (N, 2n) or None
        Estimated global error of the RK8 track ``z`` (Gamma).
    energy : ndarray, shape (N,)
        The Hamiltonian evaluated along ``y``.
    quenched : ndarray of bool, shape (N,) or None
        True where the node was quenched (``y`` replaced by ``z``).
    stats : mapping
        ``steps`` (accepted), ``rejected``, ``quenches``, ``nfev``, ``njev``
        and any method-specific counters; seconds of the call: ``compile_s``
        (compiling or loading code, in every run made), ``integrate_s`` (the
        returned run's integration) and, where ``method="auto"`` ran again,
        ``discarded_s`` (the integration of the runs it discarded, whose
        evaluations are ``discarded_evaluations``).
    status : Status
        Why the run stopped.
    message : str
        Human-readable account, naming ``t`` where a failure happened.
    method : str
        The method that ran: the name passed to :func:`hamrkq.solve`, or for
        ``method="auto"`` the member it chose (``"rk78q12"``, ...).
    options : mapping
        The settings actually used (tolerances, safety, ...), JSON-friendly.
    n : int
        Degrees of freedom.
    names : tuple of str
        Names of the state components, ``q``'s then ``p``'s.
    atol, rtol : ndarray, shape (2n,)
        The tolerances, per component.
    q, p : ndarray, shape (N, n)
        The coordinates and the momenta: the halves of ``y``.
    success : bool
        True for ``SUCCESS`` and ``TERMINAL_EVENT`` (the run ended where it
        was asked to, as SciPy counts it).
    partial : bool
        True when the run stopped early (the nodes are those computed so far).
    sol : callable or None
        With ``solve(..., dense_output=True)``: the continuous solution
        (:class:`hamrkq.rkq.dense.DenseOutput`), ``sol(t)`` of shape ``(2n,)``
        for a number and ``(2n, m)`` for ``m`` times, as SciPy's.
    t_events, y_events : list of ndarray or None
        With ``events=``: per event function, the times (shape ``(m,)``) and
        states (``(m, 2n)``) of its roots, as SciPy's names.
    event_bound : list of ndarray or None
        Per event, RKQ's error bound at each event state, ``max(atol,
        rtol |y|)`` per component (shape ``(m, 2n)``).
    event_labels : tuple of str
        The event functions' names (the expression text for strings).
    """

    t: np.ndarray
    y: np.ndarray
    energy: np.ndarray
    status: Status
    message: str
    method: str
    n: int
    names: tuple[str, ...]
    atol: np.ndarray
    rtol: np.ndarray
    stats: Mapping[str, int] = field(default_factory=dict)
    options: Mapping[str, Any] = field(default_factory=dict)
    z: np.ndarray | None = None
    global_error: np.ndarray | None = None
    gamma: np.ndarray | None = None
    quenched: np.ndarray | None = None
    sol: Any = None
    t_events: list[np.ndarray] | None = None
    y_events: list[np.ndarray] | None = None
    event_bound: list[np.ndarray] | None = None
    event_labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for name, dtype in _ARRAY_DTYPES:
            value = getattr(self, name)
            if value is not None and not _kept(value, dtype):
                set_(self, name, _solution_array(value, dtype))
        shape = (2 * self.n,)
        for name in ("atol", "rtol"):
            value = getattr(self, name)
            if np.shape(value) != shape:
                value = np.broadcast_to(value, shape)
            if not _kept(value, np.float64):
                set_(self, name, _solution_array(value))
        set_(self, "stats", FrozenDict(self.stats))
        set_(self, "options", FrozenDict(self.options))
        set_(self, "names", tuple(self.names))
        set_(self, "event_labels", tuple(self.event_labels))
        for name in ("t_events", "y_events", "event_bound"):
            if getattr(self, name) is not None:
                set_(self, name, [_solution_array(a) for a in getattr(self, name)])
        if self.y.ndim != 2 or self.y.shape != (self.t.size, 2 * self.n):
            raise ValueError(f"y has shape {self.y.shape}, expected ({self.t.size}, {2 * self.n})")

    # -- views -------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        """Coordinates, shape (N, n)."""
        return self.y[:, : self.n]

    @property
    def p(self) -> np.ndarray:
        """Momenta, shape (N, n)."""
        return self.y[:, self.n :]

    @property
    def success(self) -> bool:
        """True when the run ended where it was asked to: at the end of the
        interval, or at a terminal event (:attr:`Status.success`)."""
        return self.status.success

    @property
    def partial(self) -> bool:
        """True when the run stopped early because of a failure (a terminal
        event is not one)."""
        return not self.status.success

    @property
    def nfev(self) -> int:
        """Number of right-hand-side evaluations."""
        return int(self.stats.get("nfev", 0))

    @property
    def njev(self) -> int:
        """Number of Jacobian evaluations (for the RKQ family, the
        Jacobian-vector products of the tangent estimate of Gamma), as
        SciPy's ``solve_ivp`` result has it."""
        return int(self.stats.get("njev", 0))

    @property
    def nlu(self) -> int:
        """Number of LU decompositions, as SciPy's ``solve_ivp`` result has
        it: 0, hamrkq's methods are explicit (SciPy's implicit baselines
        count theirs)."""
        return int(self.stats.get("nlu", 0))

    def __len__(self) -> int:
        return int(self.t.size)

    def __reduce__(self) -> tuple[Any, ...]:
        # Rebuild through the constructor: pickle's default would restore the
        # arrays writeable (the flag is not pickled) and skip the checks.
        return (_rebuild, (type(self), {f.name: getattr(self, f.name) for f in fields(self)}))

    def __repr__(self) -> str:
        return (
            f"Solution(method={self.method!r}, nodes={self.t.size}, n={self.n}, "
            f"status={self.status.name}, stats={dict(self.stats)})"
        )

    # -- persistence -------------------------------------------------------
    def save(self, path: str | os.PathLike) -> Path:
        """Write the solution to an ``.npz`` file, atomically.

        The file is written to a temporary name in the same directory and
        renamed, so a crash never leaves a half-written file.  Loading it with
        :meth:`load` gives back an equal solution, bit for bit, events
        included; the dense output ``sol`` is not kept (it needs the
        Hamiltonian's compiled functions: solve again with
        ``dense_output=True``, or pickle the solution).

        Parameters
        ----------
        path : str or path-like
            Where to write.  A path without a suffix gets ``.npz``; any other
            path is used as given.

        Returns
        -------
        Path
            The file written.  Its permissions are those of any new file
            (``0666`` less the umask), as for the files of ``hamrkq run``.
        """
        path = Path(path)
        if not path.suffix:
            path = path.with_suffix(".npz")
        arrays = {
            name: getattr(self, name) for name in _ARRAY_FIELDS if getattr(self, name) is not None
        }
        meta = {
            "format_version": FILE_FORMAT_VERSION,
            "status": self.status.name,
            "message": self.message,
            "method": self.method,
            "n": self.n,
            "names": list(self.names),
            "stats": dict(self.stats),
            "options": plain(dict(self.options)),
            "partial": self.partial,
        }
        arrays["atol"] = self.atol
        arrays["rtol"] = self.rtol
        if self.t_events is not None:
            meta["event_labels"] = list(self.event_labels)
            meta["events"] = len(self.t_events)
            for name in _EVENT_FIELDS:
                for k, values in enumerate(getattr(self, name) or ()):
                    arrays[f"{name}_{k}"] = values
        arrays["meta"] = np.array(json.dumps(meta))
        # Not savez_compressed: float arrays shrink by about 16 % and deflating
        # them took 0.3-0.9 s of a 2 s `hamrkq run prentice2011`.
        with atomic_file(path) as handle:
            np.savez(handle, **arrays)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> Solution:
        """Read a solution written by :meth:`save`.

        Raises
        ------
        FileNotFoundError
            No file at ``path``.
        SolutionFileError
            The file is not a solution written by :meth:`save` (another
            ``.npz``, a damaged or truncated file, a newer format).  Nothing in
            the file is unpickled or executed.
        """
        path = Path(path)
        data = open_npz(path, "solution", lambda message: SolutionFileError(path, message))
        try:
            with data:
                meta = json.loads(str(data["meta"][()]))
                version = meta.get("format_version")
                if not isinstance(version, int) or version > FILE_FORMAT_VERSION:
                    raise SolutionFileError(
                        path,
                        f"format version {version!r}; this hamrkq reads up to "
                        f"{FILE_FORMAT_VERSION}",
                    )
                arrays = {name: data[name] for name in _ARRAY_FIELDS if name in data.files}
                atol, rtol = data["atol"], data["rtol"]
                events = _events_from(data, meta)
                return cls(
                    status=Status[meta["status"]],
                    message=str(meta["message"]),
                    method=str(meta["method"]),
                    n=int(meta["n"]),
                    names=tuple(meta["names"]),
                    stats=dict(meta["stats"]),
                    options=dict(meta["options"]),
                    atol=atol,
                    rtol=rtol,
                    **arrays,
                    **events,
                )
        except SolutionFileError:
            raise
        except (
            KeyError,
            ValueError,
            TypeError,
            AttributeError,
            IndexError,
            EOFError,
            OSError,
            zipfile.BadZipFile,
        ) as exc:
            # A foreign .npz (no "meta"), a damaged member, object arrays that
            # would need pickle, metadata of the wrong shape: all one answer.
            what = str(exc)
            if isinstance(exc, KeyError):  # NumPy's: "meta is not a file in the archive"
                entry = str(exc.args[0]) if exc.args else ""
                what = f"missing entry {entry.removesuffix(' is not a file in the archive')!r}"
            raise SolutionFileError(path, f"not a hamrkq solution file ({what})") from None

    def replace(self, **changes: Any) -> Solution:
        """A copy with some fields changed (like :func:`dataclasses.replace`)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return type(self)(**values)


def _rebuild(cls: type[Solution], values: dict[str, Any]) -> Solution:
    """Unpickle a :class:`Solution` through its constructor (read-only arrays)."""
    return cls(**values)
