"""A catalogue entry: :class:`Problem`, a Hamiltonian with initial values and settings.

A Problem keeps its initial values and time span as expressions in the
parameters, so :meth:`Problem.with_parameters` gives the same problem at other
parameter values with the initial values following; its exact solution, where
the file gives one, is built on first use.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, ProblemFileError
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["Problem", "check_exact", "exact_function", "finite_real"]

#: Where an exact solution is checked against Hamilton's equations: these
#: fractions of the time span, inside it (a hand-written solution such as
#: ``sqrt(t)`` may hold on the span alone) and off its symmetric points.
EXACT_CHECK_FRACTIONS = (0.1234, 0.4567, 0.7891)
#: The steps of the central differences, as fractions of the span.  A central
#: difference with step ``h`` is off by ``h**2 |y'''|/6`` (truncation) plus
#: ``eps |y|/h`` (rounding): at its best, near ``h = eps**(1/3)`` times the
#: solution's own time scale, some ``eps**(2/3)`` (4e-11) of the scale.  The
#: time scale may be far below the span's (Kepler's pericentre passage in a
#: span of many orbits), so every step from 1e-2 to 1e-10 of the span is
#: tried and the best one counts.
EXACT_CHECK_STEPS = tuple(10.0**-k for k in range(2, 11))
#: Largest difference accepted between the central differences and Hamilton's
#: equations, relative to the scale ``max |f| + max |y| / span`` (``f`` the
#: right-hand side at the sample times): five orders above what a true
#: solution's differences reach, and far below what a wrong frequency,
#: amplitude, sign or Hamiltonian gives (a relative difference of order one).
EXACT_CHECK_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class Problem:
    """A catalogue entry: a Hamiltonian with initial values and settings.

    Attributes
    ----------
    name, title, description : str
    references : tuple of str
    hamiltonian : Hamiltonian
    q0, p0 : ndarray
        Initial values for the current parameter values.
    t_span : tuple of float
    integration : mapping
        Default settings for :func:`hamrkq.solve` (method, atol, rtol, ...).
    invariants : mapping of str to sympy.Expr
        First integrals besides H.
    exact : callable or None
        ``exact(t) -> ndarray (N, 2n)``, the exact solution for these initial
        values and parameters, where the file gives one.
    expected : mapping
        Published reference values, with their sources.
    events : tuple of mapping
        The ``[[events]]`` tables: ``expression`` (a SymPy expression in the
        state, parameters and ``t``), ``direction`` and ``terminal``; the
        default ``events=`` of :func:`hamrkq.solve`.
    parameters : mapping of str to float
        The parameter values in use.
    path : Path or None
        The file it came from.
    """

    name: str
    title: str
    description: str
    references: tuple[str, ...]
    hamiltonian: Hamiltonian
    initial_exprs: tuple[sp.Expr, ...]
    t_span_exprs: tuple[sp.Expr, sp.Expr]
    integration: Mapping[str, Any]
    invariants: Mapping[str, sp.Expr]
    exact_spec: Mapping[str, Any] | None
    expected: Mapping[str, Any]
    parameters: Mapping[str, float]
    path: Path | None = None
    #: The file's key of each initial value ("initial.x" or "initial.q[0]"), for messages.
    initial_keys: tuple[str, ...] = ()
    events: tuple[Mapping[str, Any], ...] = ()
    _values: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        ham = self.hamiltonian
        params = ham.parameter_values(self.parameters)
        subs = dict(zip(ham.parameters, params, strict=True))
        n = ham.n
        keys = list(self.initial_keys) or [
            f"initial.{'qp'[i >= n]}[{i % n}]" for i in range(2 * n)
        ]
        y0 = np.array(
            [self._value(e, subs, k) for e, k in zip(self.initial_exprs, keys, strict=True)]
        )
        t_span = tuple(self._value(e, subs, "integration.t_span") for e in self.t_span_exprs)
        self._values.update(y0=y0, t_span=t_span, params=params)
        y0.setflags(write=False)
        object.__setattr__(self, "integration", MappingProxyType(dict(self.integration)))
        object.__setattr__(self, "invariants", MappingProxyType(dict(self.invariants)))
        object.__setattr__(self, "expected", MappingProxyType(dict(self.expected)))
        object.__setattr__(self, "parameters", MappingProxyType(dict(self.parameters)))

    def _value(self, expr: sp.Expr, subs: Mapping, key: str) -> float:
        """A finite real number, or an error naming the key and the parameters
        (``kepler`` with ``e = 1`` makes ``sqrt((1 + e)/(1 - e))`` infinite)."""
        value = finite_real(expr.subs(subs))
        if value is None:
            shown = ", ".join(f"{k} = {v:g}" for k, v in self.parameters.items())
            raise ProblemFileError(
                f"{expr} is not a finite real number"
                + (f" for the parameters {shown}" if shown else ""),
                path=self.path,
                key=key,
            )
        return value

    @property
    def y0(self) -> np.ndarray:
        """Initial state, all q then all p."""
        return self._values["y0"]

    @property
    def q0(self) -> np.ndarray:
        """Initial coordinates."""
        return self.y0[: self.hamiltonian.n]

    @property
    def p0(self) -> np.ndarray:
        """Initial momenta."""
        return self.y0[self.hamiltonian.n :]

    @property
    def t_span(self) -> tuple[float, float]:
        """Default time interval."""
        return self._values["t_span"]

    @property
    def parameter_array(self) -> np.ndarray:
        """Parameter values ordered like ``hamiltonian.parameters``."""
        return self._values["params"]

    @property
    def exact(self) -> Callable[[Any], np.ndarray] | None:
        """The exact solution ``t -> (N, 2n)``, or None.

        Raises
        ------
        ProblemFileError
            The file's ``[exact]`` does not solve Hamilton's equations of its
            Hamiltonian at these parameter values (:func:`check_exact`).
        """
        if self.exact_spec is None:
            return None
        if "exact" not in self._values:
            exact = exact_function(self)
            check_exact(self, exact)
            self._values["exact"] = exact
        return self._values["exact"]

    def invariant_functions(self) -> dict[str, Callable]:
        """Each invariant as ``f(t, Y) -> (N,)`` at the current parameters."""
        from hamrkq.backends.numeric import vectorized

        params = self.parameter_array
        result = {}
        for name, expr in self.invariants.items():
            fn = vectorized(self.hamiltonian, [expr])
            result[name] = lambda t, Y, fn=fn: fn(t, Y, params)[..., 0]
        return result

    def with_parameters(self, **values: float) -> Problem:
        """The same problem with other parameter values (initial values follow)."""
        unknown = sorted(set(values) - {s.name for s in self.hamiltonian.parameters})
        if unknown:
            raise InputError(f"problem {self.name!r} has no parameter(s) {', '.join(unknown)}")
        ham = self.hamiltonian
        # parameter_values names the parameter and the value of a non-number.
        checked = ham.parameter_values({**self.parameters, **values})
        merged = {s.name: float(v) for s, v in zip(ham.parameters, checked, strict=True)}
        return replace(self, parameters=merged, _values={})

    def __repr__(self) -> str:
        return f"Problem({self.name!r}, n={self.hamiltonian.n}, t_span={self.t_span})"


def finite_real(expr: sp.Expr) -> float | None:
    """The value of a closed-form expression as a float, or None when it is not
    a finite real number (``1/(1 - e)`` at ``e = 1``, ``acos(2)``, ...)."""
    try:
        value = complex(sp.N(expr, 17))
    except (TypeError, ValueError):  # free symbols, zoo
        return None
    if value.imag != 0 or not math.isfinite(value.real):
        return None
    return value.real


def exact_function(problem: Problem) -> Callable[[Any], np.ndarray]:
    spec = problem.exact_spec
    ham = problem.hamiltonian
    params = problem.parameter_array
    if "builtin" in spec:
        from hamrkq.catalogue.exact import BUILTIN_EXACT

        solver = BUILTIN_EXACT[spec["builtin"]]
        y0 = problem.y0.copy()
        named = {s.name: float(v) for s, v in zip(ham.parameters, params, strict=True)}
        t0 = problem.t_span[0]

        def exact(t):
            return solver(np.atleast_1d(np.asarray(t, dtype=float)), y0, named, t0=t0)

        return exact
    raw = sp.lambdify((ham.t, list(ham.parameters)), list(spec["expressions"]), dummify=True)

    def exact(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        columns = raw(t, params)
        return np.column_stack([np.broadcast_to(c, t.shape) for c in columns]).astype(float)

    return exact


def check_exact(problem: Problem, exact: Callable[[Any], np.ndarray]) -> None:
    """A ProblemFileError naming ``[exact]`` unless ``exact`` solves Hamilton's
    equations of ``problem``: at the times :data:`EXACT_CHECK_FRACTIONS` of
    the span, its central differences must agree with the right-hand side
    ``f(t, exact(t))`` to :data:`EXACT_CHECK_TOLERANCE` of the scale
    ``max |f| + max |y| / span``, with the best of :data:`EXACT_CHECK_STEPS`.

    Whether it starts at a run's initial state is checked where a run is
    measured against it (:func:`hamrkq.diagnose`).  A built-in solution that
    refuses the initial state (the pendulum's beyond libration) is left to
    refuse it where it is used.
    """
    from hamrkq.backends.numeric import vectorized

    ham = problem.hamiltonian
    t0, t1 = problem.t_span
    span = t1 - t0
    if not (math.isfinite(span) and span != 0.0):
        return
    times = np.array([t0 + fraction * span for fraction in EXACT_CHECK_FRACTIONS])
    steps = np.array(EXACT_CHECK_STEPS) * abs(span)
    after = (times[:, None] + steps[None, :]).reshape(-1)
    before = (times[:, None] - steps[None, :]).reshape(-1)
    every = np.concatenate([times, after, before])
    try:
        with np.errstate(all="ignore"):
            states = np.asarray(exact(every), dtype=float).reshape(every.size, ham.dim)
    except InputError:
        return
    shown = ", ".join(f"{k} = {v:g}" for k, v in problem.parameters.items())
    at_params = f" at the parameters {shown}" if shown else ""
    bad = ~np.all(np.isfinite(states), axis=1)
    if np.any(bad):
        raise ProblemFileError(
            f"the exact solution is not finite at t = {every[np.argmax(bad)]:.6g}{at_params}",
            path=problem.path,
            key="exact",
        )
    count, size = times.size, steps.size
    at = states[:count]
    plus = states[count : count + after.size].reshape(count, size, ham.dim)
    minus = states[count + after.size :].reshape(count, size, ham.dim)
    # the steps as the floats they are: (t + h) - (t - h) is exact; a step
    # below an ulp of t leaves no interval (t = 1e8: 2e-10 against 1.5e-8),
    # and its 0/0 is no reading (it was taken for the best one)
    with np.errstate(all="ignore"):
        slopes = (plus - minus) / (after - before).reshape(count, size, 1)
    with np.errstate(all="ignore"):
        rhs = vectorized(ham, list(ham.rhs))(times, at, problem.parameter_array)
    if not np.all(np.isfinite(rhs)):
        return  # a singularity of H: nothing to compare with
    scale = float(np.max(np.abs(rhs))) + float(np.max(np.abs(at))) / abs(span)
    off = np.max(np.abs(slopes - rhs[:, None, :]), axis=2)  # (times, steps)
    off[~np.isfinite(off)] = np.inf
    best = np.argmin(off, axis=1)  # each time's best step
    worst = int(np.argmax(off[np.arange(count), best]))
    if off[worst, best[worst]] <= EXACT_CHECK_TOLERANCE * scale:
        return
    slope = slopes[worst, best[worst]]
    k = int(np.argmax(np.abs(slope - rhs[worst])))
    builtin = problem.exact_spec.get("builtin") if problem.exact_spec else None
    assumes = ""
    if builtin is not None:
        from hamrkq.catalogue.exact import BUILTIN_ASSUMES

        assumes = f"; the builtin {builtin!r} is the flow of {BUILTIN_ASSUMES[builtin][1]}"
    raise ProblemFileError(
        f"the exact solution does not solve Hamilton's equations{at_params}: at "
        f"t = {float(times[worst])!r} its d{ham.names[k]}/dt is {slope[k]:.6g} (central "
        f"differences) where the Hamiltonian gives {rhs[worst, k]:.6g}{assumes}",
        path=problem.path,
        key="exact",
    )
