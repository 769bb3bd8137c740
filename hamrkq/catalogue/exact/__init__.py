"""Built-in analytic solutions, referenced by name from problem files.

A problem file may say ``[exact] builtin = "kepler"``; the catalogue then
looks the name up in :data:`BUILTIN_EXACT` (a lookup, never an evaluation of
text).  Each entry is a function ::

    exact(t, y0, params, t0=0.0) -> ndarray, shape (N, 2n)

that returns the exact state at the times ``t`` of the trajectory through
``y0`` at time ``t0``.  It raises :class:`~hamrkq.errors.InputError` when
``y0`` is outside the family of states it covers, so an exact solution is
never silently wrong.

Entries
-------
``"harmonic"``
    ``H = (p**2 + q**2)/2``, any initial state.
``"pendulum"``
    ``H = p**2/2 - cos(q)``, libration (``H < 1``), through Jacobi elliptic
    functions.
``"kepler"``
    ``H = (p1**2 + p2**2)/2 - 1/sqrt(q1**2 + q2**2)``, any bound (``H < 0``),
    non-collision planar state, through Kepler's equation and the Lagrange
    ``f`` and ``g`` coefficients.

Each lives in its own module (:mod:`~hamrkq.catalogue.exact.harmonic`,
:mod:`~hamrkq.catalogue.exact.pendulum`, :mod:`~hamrkq.catalogue.exact.kepler`,
with their references); this one holds the registry and what each
solution's values are stated accurate to (:func:`exact_accuracy`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

from hamrkq._floats import EPS
from hamrkq.catalogue.exact.harmonic import harmonic
from hamrkq.catalogue.exact.kepler import kepler, solve_kepler_equation
from hamrkq.catalogue.exact.pendulum import pendulum, pendulum_accuracy
from hamrkq.errors import OptionError

__all__ = [
    "BUILTIN_ASSUMES",
    "BUILTIN_EXACT",
    "ExactSolution",
    "builtin_exact_of",
    "exact_accuracy",
    "get_exact",
    "harmonic",
    "kepler",
    "pendulum",
    "pendulum_accuracy",
    "solve_kepler_equation",
]

#: Signature of a built-in exact solution.
ExactSolution = Callable[..., np.ndarray]


#: The registry, by name.  Read-only.
BUILTIN_EXACT: Mapping[str, ExactSolution] = MappingProxyType(
    {"harmonic": harmonic, "kepler": kepler, "pendulum": pendulum}
)


#: What each built-in solution assumes: the state's length and the
#: Hamiltonian whose flow it is (no parameter enters any of them).  A file's
#: ``[exact] builtin`` of another length is refused when the file is read; one
#: whose Hamiltonian differs is refused by the check of the solution against
#: Hamilton's equations (:func:`hamrkq.catalogue.problem.check_exact`).
BUILTIN_ASSUMES: Mapping[str, tuple[int, str]] = MappingProxyType(
    {
        "harmonic": (2, "H = (p**2 + q**2)/2 (unit mass and frequency)"),
        "kepler": (4, "H = (p1**2 + p2**2)/2 - 1/sqrt(q1**2 + q2**2) (G M = 1)"),
        "pendulum": (2, "H = p**2/2 - cos(q) (unit length and gravity), H < 1"),
    }
)


#: An exact solution's values are stated accurate to this many ulps of their
#: largest component, ``EXACT_ROUNDING * eps * max|y|``, unless it states its
#: own accuracy (:data:`BUILTIN_ACCURACY`).
EXACT_ROUNDING = 4.0

#: A solution written as expressions in ``t`` is stated accurate to
#: ``EXACT_PHASE * eps * max_i |t_i| |f(t_i, y_i)|`` more (``f`` the
#: right-hand side, max-norm): a phase such as ``w*t`` evaluated in doubles
#: loses up to ``eps |w t| / 2`` at each rounding (the product, a sum with a
#: constant), ``eps |t| |dy/dt|`` in the state over two of them.  Measured
#: against mpmath at 40 digits: ``sin(w*t)/w, cos(w*t)`` at w = 1.1, 0.3,
#: 2.7 up to t = 1e6 reach 0.46 of it (benchmarks/exact_accuracy.txt).
EXACT_PHASE = 1.0

#: The built-in solutions that state their own accuracy:
#: ``accuracy(y0, states) -> float``.  Read-only.
BUILTIN_ACCURACY: Mapping[str, Callable[[object, object], float]] = MappingProxyType(
    {"pendulum": pendulum_accuracy}
)


def exact_accuracy(
    states: object,
    builtin: str | None = None,
    y0: object = None,
    times: object = None,
    rates: object = None,
) -> float:
    """What an exact solution's ``states`` are stated accurate to (max-norm).

    ``builtin`` names the built-in solution they came from, ``y0`` its
    initial state: the pendulum states its own (:func:`pendulum_accuracy`),
    the harmonic oscillator and Kepler ``EXACT_ROUNDING * eps * max|y|``
    (their phase is carried in double-double from ``t - t0``, so their
    error does not grow with time: measured up to t = 1e6).  A solution
    written as expressions in ``t`` (``builtin`` None) evaluates its phase
    in doubles, which loses ``eps |w t|`` of a phase ``w*t``: given the
    node ``times`` and the ``rates`` ``f(t_i, y_i)`` of the Hamiltonian's
    right-hand side at the ``states`` (shape ``(N, 2n)``), it is stated
    accurate to ``eps (EXACT_ROUNDING max|y| + EXACT_PHASE max_i |t_i|
    |f(t_i, y_i)|)``; without them to ``EXACT_ROUNDING * eps * max|y|``,
    which holds only where the phase is exact (``sin(t)``) or ``|t|``
    small.  What ``hamrkq.diagnose`` and ``hamrkq compare`` report as the
    exact reference's accuracy.
    """
    if builtin in BUILTIN_ACCURACY and y0 is not None:
        return float(BUILTIN_ACCURACY[builtin](y0, states))
    states = np.asarray(states, dtype=float)
    accuracy = EXACT_ROUNDING * EPS * float(np.max(np.abs(states), initial=0.0))
    if builtin is None and times is not None and rates is not None:
        at = np.abs(np.asarray(times, dtype=float)).reshape(-1)
        rate = np.abs(np.asarray(rates, dtype=float)).reshape(at.size, -1)
        phase = float(np.max(at * np.max(rate, axis=1, initial=0.0), initial=0.0))
        accuracy += EXACT_PHASE * EPS * phase
    return accuracy


def builtin_exact_of(problem: object) -> tuple[str | None, object]:
    """``(name, y0)`` of the built-in solution that is ``problem.exact``
    (the flow of ``problem.y0``), or ``(None, None)`` for a problem whose
    exact solution is written as expressions, or that has none: the
    arguments of :func:`exact_accuracy` after the states."""
    spec = getattr(problem, "exact_spec", None) or {}
    if "builtin" not in spec:
        return None, None
    return str(spec["builtin"]), getattr(problem, "y0", None)


def get_exact(name: str) -> ExactSolution:
    """Look up a built-in exact solution by name.

    Raises
    ------
    OptionError
        If ``name`` is not in :data:`BUILTIN_EXACT`; the message lists the
        known names.
    """
    try:
        return BUILTIN_EXACT[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(BUILTIN_EXACT))
        raise OptionError(f"unknown built-in exact solution {name!r}; known: {known}") from None
