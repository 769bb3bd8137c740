"""An ensemble request, validated once (its chunks run in :mod:`hamrkq.ensemble.chunk`).

:func:`build_request` turns what a user passes to :func:`hamrkq.ensemble` into
a :class:`Request`: the Hamiltonian, one row of initial values and one row of
parameter values per member, the time span, the kept times and the options of
:func:`hamrkq.solve`.  Every check happens here, before any member runs, and
every message names the parameter (and the member) at fault.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from hamrkq._files import plain
from hamrkq._validate import real as _real
from hamrkq._validate import show as _show
from hamrkq._validate import span as _span
from hamrkq.errors import InputError, InputTypeError, OptionError, warn
from hamrkq.events import event_specs
from hamrkq.options import applicable_settings
from hamrkq.result import freeze_in_place
from hamrkq.solve import solve
from hamrkq.solve.arguments import checked_eval_times
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["Request", "build_request"]

#: Keywords of :func:`hamrkq.solve` an ensemble decides itself: it keeps only
#: ``t_eval`` (or the last node), and draws its own progress bar over members.
_OWN_KEYWORDS = ("keep_every", "progress", "q0", "p0", "t_span", "parameters", "t_eval")


@dataclass(frozen=True, eq=False)
class Request:
    """A validated ensemble: everything :func:`run_chunk` needs, and nothing
    that does not pickle (the Hamiltonian travels as its SymPy declaration).

    Attributes
    ----------
    ham : Hamiltonian
    y0 : ndarray, shape (M, 2n)
        Initial state of each member, all q then all p.
    params : ndarray, shape (M, P)
        Parameter values of each member, ordered like ``ham.parameters``.
    t_span : (float, float)
    t_eval : ndarray or None
        The kept times; None keeps each member's last node only.
    options : mapping
        Keyword options passed to :func:`hamrkq.solve` for every member.
    start : int
        Index of the first member of this request in the whole ensemble
        (non-zero for a :meth:`subset`).
    events_note : str or None
        Why a problem file's events are left out of the members' runs (the
        words of the warning), or None.
    """

    ham: Hamiltonian
    y0: np.ndarray
    params: np.ndarray
    t_span: tuple[float, float]
    t_eval: np.ndarray | None
    options: dict[str, Any] = field(default_factory=dict)
    start: int = 0
    events_note: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "y0", freeze_in_place(np.asarray(self.y0, dtype=float)))
        object.__setattr__(self, "params", freeze_in_place(np.asarray(self.params, dtype=float)))
        if self.t_eval is not None:
            object.__setattr__(
                self, "t_eval", freeze_in_place(np.asarray(self.t_eval, dtype=float))
            )

    @property
    def size(self) -> int:
        """Number of members."""
        return int(self.y0.shape[0])

    @property
    def times(self) -> np.ndarray:
        """The times kept for every member: ``t_eval``, or ``[t_end]``."""
        if self.t_eval is not None:
            return self.t_eval
        return np.array([self.t_span[1]])

    def record(self) -> dict[str, Any]:
        """The options as an :class:`EnsembleSolution` records them,
        JSON-friendly: events by their label, terminal count and direction
        (a callable has no JSON form: saving an ensemble with one raised
        TypeError), and why a problem file's events were left out
        (``events_not_located``, as a Solution's options)."""
        options = dict(self.options)
        if options.get("events") is not None:
            params = self.params[0] if self.size else np.zeros(self.params.shape[1])
            options["events"] = [
                {"label": spec.label, "terminal": int(spec.terminal),
                 "direction": float(spec.direction)}
                for spec in event_specs(options["events"], self.ham, params)
            ]  # fmt: skip
        if self.events_note is not None:
            options["events_not_located"] = self.events_note
        return plain(options)

    def subset(self, start: int, stop: int) -> Request:
        """Members ``start:stop`` (indices into this request) as a request of their own."""
        return Request(
            self.ham,
            self.y0[start:stop],
            self.params[start:stop],
            self.t_span,
            self.t_eval,
            self.options,
            self.start + start,
        )

    def take(self, indices: np.ndarray) -> Request:
        """The members at ``indices`` (into this request) as a request of
        their own.  Its ``start`` is this request's: a caller puts their
        results back by index (:func:`hamrkq.ensemble.chunk.run_chunk`)."""
        return Request(
            self.ham,
            self.y0[indices],
            self.params[indices],
            self.t_span,
            self.t_eval,
            self.options,
            self.start,
        )

    def member_kwargs(self, i: int) -> dict[str, Any]:
        """The arguments of :func:`hamrkq.solve` that integrate member ``i``
        (an index into this request) on its own."""
        n = self.ham.n
        names = [s.name for s in self.ham.parameters]
        return dict(
            q0=self.y0[i, :n],
            p0=self.y0[i, n:],
            t_span=self.t_span,
            parameters=dict(zip(names, self.params[i].tolist(), strict=True)),
            t_eval=self.t_eval,
            **self.options,
        )


# -- validation --------------------------------------------------------------------


def build_request(
    system: Any,
    q0: Any,
    p0: Any,
    t_span: Any,
    parameters: Mapping[Any, Any] | None,
    t_eval: Any,
    options: Mapping[str, Any],
) -> Request:
    """Validate an ensemble request (see :func:`hamrkq.ensemble`)."""
    from hamrkq.catalogue.problems import Problem

    for name in _OWN_KEYWORDS:
        if name in options:
            raise OptionError(
                f"{name}= is not an option of ensemble (it keeps t_eval or the last node "
                "of every member, and draws its own progress bar)"
            )
    if isinstance(system, Problem):
        ham = system.hamiltonian
        # The problem's [integration] settings are defaults, where they apply
        # to the method (a file's atol means nothing to verlet); keywords win.
        settings = dict(system.integration)
        method = options.get("method") or settings.get("method") or "auto"
        options = {**applicable_settings(method, settings), **options}
        base_params = np.asarray(system.parameter_array, dtype=float)
        t_span = system.t_span if t_span is None else t_span
        events_note = _file_events(system, options)
    elif isinstance(system, Hamiltonian):
        ham = system
        missing = [k for k, v in (("q0", q0), ("p0", p0), ("t_span", t_span)) if v is None]
        if missing:
            raise InputError(
                f"{', '.join(missing)} must be given for an ensemble of a Hamiltonian"
            )
        base_params = None
        events_note = None
    else:
        raise InputTypeError(
            "problem_or_hamiltonian must be a hamrkq.Hamiltonian or a hamrkq.Problem, "
            f"got {type(system).__name__}"
        )
    options.pop("t_span", None)  # a file's [integration] may hold it; it is an argument here
    t0, t_end = _span(t_span)
    columns = _parameter_columns(ham, parameters)
    n = ham.n
    q_cols = _state_columns("q0", q0, [s.name for s in ham.q])
    p_cols = _state_columns("p0", p0, [s.name for s in ham.p])
    size = _common_size({**q_cols, **p_cols, **columns})
    params = _parameter_rows(ham, base_params, columns, size)
    y0 = np.empty((size, 2 * n))
    defaults = _problem_initial(system, ham, params, q_cols, p_cols)
    for k, name in enumerate(ham.names):
        col = {**q_cols, **p_cols}.get(name)
        if col is None:
            if defaults is None:
                label = "q0" if k < n else "p0"
                raise InputError(f"{label} gives no value for {name!r}")
            y0[:, k] = defaults[:, k]
        else:
            y0[:, k] = col
    bad = ~np.isfinite(y0)
    if bad.any():
        member, k = map(int, np.argwhere(bad)[0])
        raise InputError(
            f"initial value {ham.names[k]} of member {member} is not finite "
            f"({float(y0[member, k])!r})"
        )
    # (terminality does not depend on the values: any row, or zeros for none)
    _check_kept(ham, params[0] if size else np.zeros(params.shape[1]), options)
    request = Request(
        ham, y0, params, (t0, t_end), _t_eval(t_eval, t0, t_end), dict(options),
        events_note=events_note,
    )  # fmt: skip
    _probe(request)
    return request


def _file_events(problem: Any, options: dict[str, Any]) -> str | None:
    """A problem file's ``[[events]]`` as the members' default ``events=``,
    as :func:`hamrkq.solve` takes them (found by QA: an ensemble ignored
    them, and a member whose terminal event solve alone stops at returned
    SUCCESS at t_end): the terminal ones end their members; the others,
    whose roots an ensemble would locate and throw away, are left out with
    a warning, whose words are returned (None: nothing left out).  Events
    given to :func:`hamrkq.ensemble` (``events=[]`` for none) win."""
    if options.get("events") is not None or not problem.events:
        return None
    terminal = [event for event in problem.events if event.get("terminal")]
    left = [event for event in problem.events if not event.get("terminal")]
    if terminal:
        options["events"] = terminal
    if not left:
        return None
    labels = ", ".join(repr(str(event["expression"])) for event in left)
    note = (
        f"the events of problem {problem.name!r} that do not end a member ({labels}) are "
        "not located: an ensemble keeps states, not event times (ensemble(..., events=[]) "
        "runs without the file's events, and without this warning)"
    )
    warn(note)
    return note


def _check_kept(ham: Hamiltonian, params: np.ndarray, options: Mapping[str, Any]) -> None:
    """Refuse what a member would compute and the ensemble throw away: an
    :class:`EnsembleSolution` keeps states at ``t_eval`` (or the last node),
    so a dense output, or the roots of an event that does not end its member,
    would be computed for nothing.  A terminal event does end its member
    (``t_last``, status ``TERMINAL_EVENT``) and is allowed."""
    if options.get("dense_output"):
        raise OptionError(
            "dense_output= is not an option of ensemble: it keeps each member's states at "
            "t_eval (or its last node), and a continuous solution would be thrown away"
        )
    if options.get("events") is None:
        return
    kept = [
        spec.label for spec in event_specs(options["events"], ham, params) if not spec.terminal
    ]
    if kept:
        raise OptionError(
            f"events {', '.join(map(repr, kept))} do not end their member (terminal=False): "
            "an ensemble keeps states, not event times, so they would be located and "
            "thrown away; in an ensemble events can only end members (terminal=True); "
            "for event times solve each member (hamrkq.solve(..., events=...))"
        )


def _probe(request: Request) -> None:
    """Run member 0 over a sliver of the interval with the ensemble's options.

    :func:`hamrkq.solve` checks the options (a bad one fails here, before any
    member runs), and the compiled kernel is prepared here, once, for the
    argument types every member will use: threads that each prepared it on
    their first member raced inside numba ("compilation disabled").
    """
    if request.size == 0:
        return
    kwargs = request.member_kwargs(0)
    t0, t_end = request.t_span
    length = abs(t_end - t0)
    sliver = min(length, max(1e-6 * length, kwargs.get("first_step") or 0.0))
    t_short = t0 + math.copysign(sliver, t_end - t0)
    kwargs.update(t_span=(t0, t_short), t_eval=None if request.t_eval is None else [t_short])
    solve(request.ham, **kwargs)


def _column(name: str, value: Any) -> np.ndarray:
    """A 1-D float array (a scalar gives one value) from numbers or SymPy numbers."""
    if isinstance(value, str | bytes):
        raise InputTypeError(f"{name} must be numbers, not the string {value!r}")
    if isinstance(value, sp.Basic) or isinstance(value, numbers.Number):
        return np.array([_real(name, value)])
    array = np.asarray(value)
    if array.dtype == object:
        array = np.array([_real(name, v) for v in array.ravel()]).reshape(array.shape)
    elif array.dtype.kind not in "iuf":
        raise InputTypeError(f"{name} must be real numbers, got {_show(value)}")
    if array.ndim > 1:
        raise InputError(f"{name} must be a number or a 1-D array, got shape {array.shape}")
    return np.atleast_1d(array.astype(float))


def _state_columns(label: str, value: Any, names: list[str]) -> dict[str, np.ndarray]:
    """``q0``/``p0`` as columns by name: an (n,) or (M, n) array, or a mapping
    of names to numbers or (M,) arrays."""
    if value is None:
        return {}
    if isinstance(value, Mapping):
        unknown = sorted(str(k) for k in value if str(k) not in names)
        if unknown:
            raise InputError(
                f"{label} names {', '.join(unknown)}, which are not among {', '.join(names)}"
            )
        return {str(k): _column(f"{label}[{k!s}]", v) for k, v in value.items()}
    if isinstance(value, str | bytes):
        raise InputTypeError(f"{label} must be an array of numbers, not the string {value!r}")
    array = np.asarray(value, dtype=object) if not isinstance(value, np.ndarray) else value
    if array.ndim == 0:
        array = array.reshape(1)
    if array.ndim == 1:
        array = array.reshape(1, -1)
    if array.ndim != 2 or array.shape[1] != len(names):
        raise InputError(
            f"{label} must have shape ({len(names)},) or (M, {len(names)}), "
            f"got shape {np.shape(value)}"
        )
    return {name: _column(f"{label}[:, {k}]", array[:, k]) for k, name in enumerate(names)}


def _parameter_columns(ham: Hamiltonian, parameters: Any) -> dict[str, np.ndarray]:
    if parameters is None:
        return {}
    if not isinstance(parameters, Mapping):
        raise InputTypeError(
            "parameters must be a mapping of names (or symbols) to numbers or arrays, "
            f"got {_show(parameters)}"
        )
    known = [s.name for s in ham.parameters]
    columns = {}
    for key, value in parameters.items():
        name = key.name if isinstance(key, sp.Symbol) else key
        if name not in known:
            raise InputError(
                f"unknown parameter {key!s} (parameters: {', '.join(known) or 'none'})"
            )
        columns[name] = _column(f"parameters[{name!r}]", value)
    return columns


def _common_size(columns: Mapping[str, np.ndarray]) -> int:
    """M: the one length (other than 1) shared by every column given."""
    sizes = {name: col.size for name, col in columns.items()}
    long = {size for size in sizes.values() if size != 1}
    if len(long) > 1:
        listing = ", ".join(f"{name}: {size}" for name, size in sizes.items())
        raise InputError(f"members disagree in number ({listing}); give one length M, or 1")
    if 0 in sizes.values():
        return 0
    return long.pop() if long else 1


def _parameter_rows(
    ham: Hamiltonian, base: np.ndarray | None, columns: Mapping[str, np.ndarray], size: int
) -> np.ndarray:
    if base is None:
        given = {name: float(col[0]) for name, col in columns.items()}
        base = ham.parameter_values(given)  # names a parameter with no value
    params = np.repeat(np.asarray(base, dtype=float)[None, :], size, axis=0)
    for j, symbol in enumerate(ham.parameters):
        if symbol.name in columns:
            params[:, j] = columns[symbol.name]
    bad = ~np.isfinite(params)
    if bad.any():
        member, j = map(int, np.argwhere(bad)[0])
        raise InputError(
            f"parameter {ham.parameters[j].name} of member {member} is not finite "
            f"({float(params[member, j])!r})"
        )
    return params


def _problem_initial(
    system: Any, ham: Hamiltonian, params: np.ndarray, q_cols: Mapping, p_cols: Mapping
) -> np.ndarray | None:
    """A Problem's initial values for each member's parameters (they may depend
    on them), evaluated once per distinct parameter row; None for a Hamiltonian
    or when q0 and p0 give every component."""
    from hamrkq.catalogue.problems import Problem

    if not isinstance(system, Problem) or len(q_cols) + len(p_cols) == ham.dim:
        return None
    out = np.empty((params.shape[0], ham.dim))
    if params.shape[1] == 0:
        out[:] = system.y0
        return out
    rows, inverse = np.unique(params, axis=0, return_inverse=True)
    names = [s.name for s in ham.parameters]
    for r, row in enumerate(rows):
        values = dict(zip(names, row.tolist(), strict=True))
        out[np.ravel(inverse) == r] = system.with_parameters(**values).y0
    return out


def _t_eval(t_eval: Any, t0: float, t_end: float) -> np.ndarray | None:
    if t_eval is None:
        return None
    return checked_eval_times(_column("t_eval", t_eval), t_eval, t0, t_end)
