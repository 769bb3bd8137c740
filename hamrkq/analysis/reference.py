"""Independent high-accuracy reference trajectories, each with its accuracy.

A diagnostic that reports the *true* error of a run needs a yardstick far more
accurate than the run's tolerance.  This module computes one with SciPy's
DOP853 (Hairer, Norsett & Wanner's 8(5,3) pair), which shares no code with
hamrkq's own integrators, and says how accurate it is:

- :func:`periodic_reference` for autonomous systems on a periodic orbit
  (``prentice2011``, the pendulum, the harmonic oscillator, Kepler): one
  period is integrated at the tightest tolerance double precision allows, the
  period is refined by Newton's method on a Poincare section, and the state at
  any time is read off that one period.  The error does not accumulate over
  thousands of periods the way a long integration's does.
- :func:`integrate_reference` for anything else: a tight DOP853 integration
  over the whole interval, checked against a second run at a ten times looser
  tolerance.

Both take a plain callable ``rhs(t, y, params) -> ndarray`` so that they do
not depend on the symbolic layer; :func:`hamiltonian_reference` is the thin
convenience for a :class:`hamrkq.Hamiltonian` or a catalogue problem.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from hamrkq._files import plain
from hamrkq._floats import EPS, MIN_RTOL
from hamrkq.analysis import reference_cache
from hamrkq.analysis.periodic_orbit import PILOT_RTOL, find_return, periodic_orbit
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, IntegrationError

__all__ = [
    "REFERENCE_RTOL",
    "TIGHTEST_RTOL",
    "Accuracy",
    "Reference",
    "hamiltonian_reference",
    "integrate_reference",
    "periodic_reference",
]

Rhs = Callable[[float, np.ndarray, Any], np.ndarray]

#: SciPy raises any rtol below 100 eps to this value (with a warning): the
#: tightest relative tolerance DOP853 honours in double precision.
TIGHTEST_RTOL = MIN_RTOL
#: Default relative tolerance of :func:`integrate_reference`.
REFERENCE_RTOL = 1e-13
#: Factor between the tolerance of the reference run and of the check run.
CHECK_FACTOR = 10.0
#: The mesh of a periodic reference is refined until two periods agree to
#: this many times the random-walk rounding ``sqrt(steps) eps T``.
SETTLE_FACTOR = 8.0
#: The check orbit of a periodic reference runs at this many times the rtol.
CHECK_RTOL_FACTOR = 4.0
#: After Newton, an orbit whose return mismatch exceeds this fraction of its
#: extent is not periodic (quasi-periodic or chaotic), and we say so.
CLOSURE_LIMIT = 1e-7


class Accuracy(float):
    """A reference's estimated error: the float is the largest over all
    components (the max-norm reports quote), ``components`` the estimate per
    component, or None where only the max-norm is known.

    A float, so that everything that compares or prints an accuracy keeps
    working; the components travel with it to
    :func:`~hamrkq.analysis.summaries.error_summary`, which judges each
    component against its own tolerance.  Before, a system whose components
    differ by orders of magnitude (the outer solar system: positions of 30
    AU, Pluto's momentum of 1e-9) had the positions' rounding compared with
    Pluto's momentum's tolerance, and its true error was never measured.
    """

    components: tuple[float, ...] | None

    def __new__(cls, value: Any, components: Any = None) -> Accuracy:
        self = super().__new__(cls, float(value))
        self.components = None if components is None else tuple(float(v) for v in components)
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        return (Accuracy, (float(self), self.components))


@dataclass(frozen=True, eq=False)
class Reference:
    """A reference trajectory and how accurate it is.

    Attributes
    ----------
    t : ndarray, shape (N,)
        The requested times.
    y : ndarray, shape (N, 2n)
        Reference states, time-major, columns ``q`` then ``p``.
    estimated_error : Accuracy
        Estimated maximum absolute error of any component of ``y`` over all
        nodes (max-norm), see the function that produced it; its
        ``components`` are the estimate per component (as
        ``component_error``).
    method : str
        One line saying how ``y`` was computed.
    details : mapping
        Plain numbers: tolerances, ``nfev``, and for periodic references the
        ``period`` and its estimated error ``period_error``.
    component_error : tuple of float or None
        Estimated maximum absolute error of each component over all nodes,
        or None where only the max-norm is known (then every component is
        taken to be as inaccurate as the worst).
    """

    t: np.ndarray
    y: np.ndarray
    estimated_error: float
    method: str
    details: Mapping[str, Any] = field(default_factory=dict)
    component_error: Any = None

    def __post_init__(self) -> None:
        for name in ("t", "y"):
            array = np.array(getattr(self, name), dtype=float, copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        components = self.component_error
        if components is None:
            components = getattr(self.estimated_error, "components", None)
        if components is not None:
            components = tuple(float(v) for v in np.asarray(components, dtype=float).ravel())
            if self.y.ndim != 2 or len(components) != self.y.shape[1]:
                raise InputError(
                    f"component_error must have one value per component, got {len(components)}"
                )
        object.__setattr__(self, "component_error", components)
        object.__setattr__(self, "estimated_error", Accuracy(self.estimated_error, components))
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))

    def describe(self) -> str:
        """One line for a report: ``"<method>; accurate to ~X"``."""
        return f"{self.method}; accurate to ~{self.estimated_error:.1e}"


# -- input checks ------------------------------------------------------------
def _state(value: Any, name: str) -> np.ndarray:
    y = np.asarray(value, dtype=float)
    if y.ndim != 1 or y.size == 0 or y.size % 2:
        raise InputError(f"{name} must be a 1-D array of even length 2n, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise InputError(f"{name} must be finite, got {y.tolist()}")
    return y


def _times(value: Any) -> np.ndarray:
    t = np.atleast_1d(np.asarray(value, dtype=float))
    if t.ndim != 1 or t.size == 0:
        raise InputError(f"t_nodes must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError("t_nodes must be finite")
    return t


def _check_rtol(rtol: float) -> float:
    rtol = float(rtol)
    if not rtol >= TIGHTEST_RTOL:
        raise InputError(
            f"rtol must be at least {TIGHTEST_RTOL:.3g} (DOP853 in double precision), got {rtol!r}"
        )
    return rtol


def _vector_field(rhs: Rhs, params: Any, dim: int) -> Callable[[float, np.ndarray], np.ndarray]:
    params = np.empty(0) if params is None else params

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        return np.asarray(rhs(t, y, params), dtype=float).reshape(dim)

    return fun


def _scales(samples: np.ndarray) -> np.ndarray:
    """Per-component magnitude for a scale-aware atol.

    A component that stays zero, or at rounding level (within 100 ulps of
    the largest component, e.g. one that is zero by symmetry but picks up
    rounding noise), borrows the largest scale: a pure relative tolerance on
    rounding noise would ask DOP853 for steps that never end.
    """
    scale = np.max(np.abs(samples), axis=0)
    top = float(scale.max())
    return np.where(scale > 100 * EPS * top, scale, top if top > 0 else 1.0)


def periodic_reference(
    rhs: Rhs,
    y0: Any,
    t_nodes: Any,
    params: Any = None,
    *,
    t0: float = 0.0,
    shift: Any = None,
    rtol: float = TIGHTEST_RTOL,
    steps_per_period: int = 128,
    max_steps_per_period: int = 16384,
    max_period: float | None = None,
) -> Reference:
    """Reference states on a periodic orbit of an autonomous system.

    The period ``T`` is found from the first return to the section through
    ``y0`` normal to the flow, then refined by Newton's method on that section
    with DOP853 at ``rtol`` (by default the tightest SciPy honours) and a
    per-component ``atol = rtol * scale``.  The step is capped at ``T / N``.
    Near eps DOP853's error control alone does not deliver its tolerance
    (Kepler at e = 0.6 and rtol 2.2e-14 is 7e-12 off after one period); a
    finer mesh does.  So ``N`` starts at twice ``steps_per_period`` and
    doubles until the period agrees, to rounding (``8 sqrt(steps) eps T``),
    with that of a check orbit at ``N/2`` and a 4x looser rtol.  The finest
    orbit gives ``y(t) = y(t0 + (t - t0) mod T) + k shift`` with
    ``k = floor((t - t0) / T)``.

    Parameters
    ----------
    rhs : callable
        ``rhs(t, y, params) -> ndarray (2n,)``; must not depend on ``t``.
    y0 : array_like, shape (2n,)
        State at ``t0``; a point of a periodic orbit (not an equilibrium).
    t_nodes : array_like, shape (N,)
        Times at which the reference is wanted, any order, either side of t0.
    params : optional
        Passed to ``rhs`` unchanged.
    t0 : float
        Time of ``y0``.
    shift : array_like, shape (2n,), optional
        For rotations of an angle (a pendulum going over the top):
        ``y(t + T) = y(t) + shift``, e.g. ``(2 pi, 0)``.  Default zero.
    rtol : float
        Relative tolerance (at least :data:`TIGHTEST_RTOL`).
    steps_per_period, max_steps_per_period : int
        First and largest ``N`` (the step cap is ``T / N``).
    max_period : float, optional
        How far to search for the first return; default ``max(100, 2 span)``
        where ``span`` is the largest ``|t_nodes - t0|``.

    Returns
    -------
    Reference
        ``estimated_error`` is the largest difference between the orbit and
        its check over ``t_nodes`` (an overestimate: the check is the less
        accurate), or the rounding floor if that is larger (``w =
        sqrt(steps) eps``: ``w max|y| + k_max w T max|f|``), plus ``k_max``
        times the return mismatch left after Newton.  It grows linearly with
        the number of periods ``k``: a period error ``dT`` shifts the phase by
        ``k dT``.  ``details`` holds ``period``, ``period_error`` (difference
        of the two periods), ``steps_per_period`` (the final ``N``),
        ``closure``, ``rounding_floor``, ``nfev``.

    Raises
    ------
    InputError
        Bad shapes or values, an equilibrium, no return within
        ``max_period``, or an orbit that does not close (not periodic).

    Notes
    -----
    On ``prentice2011`` (``T = 10.4705173155918047``) the period comes out
    within about 1e-14 of an independent quadrature and the states at
    ``t = 4000`` within about 1e-12 of a 25-digit Taylor integration, with an
    estimate of a few 1e-11 (see ``tests/test_reference.py``).
    """
    y0 = _state(y0, "y0")
    t = _times(t_nodes)
    rtol = _check_rtol(rtol)
    steps = int(steps_per_period)
    if steps < 8 or int(max_steps_per_period) < steps:
        raise InputError(
            f"steps_per_period must be at least 8 and at most max_steps_per_period, got "
            f"{steps_per_period!r} and {max_steps_per_period!r}"
        )
    shift = np.zeros_like(y0) if shift is None else _state(shift, "shift")
    if shift.shape != y0.shape:
        raise InputError(f"shift must have shape {y0.shape}, got {shift.shape}")
    fun = _vector_field(rhs, params, y0.size)
    if not np.any(fun(t0, y0)):
        raise InputError(f"y0={y0.tolist()} is an equilibrium: there is no period to find")
    span = float(np.max(np.abs(t - t0)))
    max_period = max(100.0, 2.0 * span) if max_period is None else float(max_period)
    if not max_period > 0:
        raise InputError(f"max_period must be positive, got {max_period!r}")

    pilot_atol = PILOT_RTOL * _scales(y0[None, :])
    guess, peak, nfev = find_return(fun, t0, y0, shift, max_period, pilot_atol)
    scale = _scales(peak[None, :])
    atol = rtol * scale
    period = guess
    while True:
        steps *= 2
        # The check orbit is coarser in both respects: half the mesh (where
        # the step cap binds) and a looser rtol (where DOP853's own control
        # binds, e.g. at a Kepler pericentre); refining only one of them can
        # leave both orbits wrong by the same amount.
        coarse = periodic_orbit(
            fun, t0, y0, shift, period, CHECK_RTOL_FACTOR * rtol, CHECK_RTOL_FACTOR * atol,
            steps // 2,
        )  # fmt: skip
        fine = periodic_orbit(fun, t0, y0, shift, coarse.period, rtol, atol, steps)
        nfev += coarse.nfev + fine.nfev
        period = fine.period
        settled = SETTLE_FACTOR * np.sqrt(fine.steps) * EPS * fine.period
        if abs(fine.period - coarse.period) <= settled or 2 * steps > max_steps_per_period:
            break
    if fine.closure > CLOSURE_LIMIT * float(np.max(scale)):
        raise InputError(
            f"the orbit through y0 does not close: after the period T={fine.period:.17g} it "
            f"misses y0 by {fine.closure:.3g}; use integrate_reference instead"
        )
    y = fine.evaluate(t)
    k_max = float(np.max(np.abs(np.floor((t - t0) / fine.period))))
    floor = fine.rounding_floor(k_max)
    difference = float(np.max(np.abs(coarse.evaluate(t) - y)))
    error = max(difference, floor) + k_max * fine.closure
    details: dict[str, Any] = {
        "period": fine.period,
        "period_error": abs(fine.period - coarse.period),
        "closure": fine.closure,
        "rtol": rtol,
        "steps_per_period": steps,
        "periods": k_max,
        "rounding_floor": floor,
        "nfev": nfev,
    }
    method = (
        f"DOP853 over one period T={fine.period:.16g} (rtol={rtol:.2g}, {steps} steps, "
        f"Newton on a Poincare section), {k_max:.0f} periods"
    )
    return Reference(t=t, y=y, estimated_error=error, method=method, details=details)


# -- general integration -----------------------------------------------------
def _run(fun, t0, t_end, y0, t, rtol, atol, max_step):
    from scipy.integrate import solve_ivp  # 0.3 s to import: only when computing

    if t_end == t0:
        return np.tile(y0, (t.size, 1)), 0, 0
    sol = solve_ivp(
        fun, (t0, t_end), y0, method="DOP853", rtol=rtol, atol=atol,
        max_step=max_step, dense_output=True,
    )  # fmt: skip
    if not sol.success:
        raise IntegrationError(f"reference integration failed: {sol.message}")
    y = sol.sol(t).T
    y[t == t0] = y0  # the interpolant reproduces y0 only to rounding
    return y, sol.nfev, sol.t.size - 1


def integrate_reference(
    rhs: Rhs,
    y0: Any,
    t_nodes: Any,
    params: Any = None,
    *,
    t0: float | None = None,
    rtol: float = REFERENCE_RTOL,
    atol: Any = None,
    max_step: float = np.inf,
    estimate_error: bool = True,
) -> Reference:
    """Reference states from one tight DOP853 integration, with a check run.

    Parameters
    ----------
    rhs : callable
        ``rhs(t, y, params) -> ndarray (2n,)``.
    y0 : array_like, shape (2n,)
        State at ``t0``.
    t_nodes : array_like, shape (N,)
        Times wanted, all on one side of ``t0`` (any order).
    params : optional
        Passed to ``rhs`` unchanged.
    t0 : float, optional
        Time of ``y0``; default ``t_nodes[0]`` (a solution's first node).
    rtol : float
        Relative tolerance, default 1e-13 (at least :data:`TIGHTEST_RTOL`).
    atol : float or array_like, optional
        Absolute tolerance.  Default scale-aware: ``rtol * scale_k`` with
        ``scale_k`` the largest ``|y_k|`` seen by a pilot run at rtol 1e-10
        (a component that stays zero borrows the largest scale).
    max_step : float
        Passed to DOP853.
    estimate_error : bool
        Run the check integration; without it ``estimated_error`` is nan.

    Returns
    -------
    Reference
        ``component_error`` is, per component, the largest difference over
        the nodes between this run and a second run at 10x looser ``rtol``
        and ``atol``, but at least the random-walk rounding floor
        ``sqrt(steps) * eps * scale_k``; ``estimated_error`` the largest of
        those (max-norm).

    Notes
    -----
    Honest limits.  The difference from the looser run measures *that* run's
    error, so for a smooth problem it overstates this run's error by up to
    about ten times: a safe estimate.  It can understate it when both runs are
    dominated by the same rounding (very long runs at rtol near
    :data:`TIGHTEST_RTOL`), which the floor covers only statistically.  On a
    long oscillatory run the error grows about linearly with time; on a
    chaotic one it grows exponentially, and the estimate shows that honestly
    rather than hiding it.  For a periodic orbit prefer
    :func:`periodic_reference`, whose error does not accumulate.  Cost: about
    a million function evaluations for ``prentice2011`` to t = 4000 (seconds
    to tens of seconds in pure Python).
    """
    y0 = _state(y0, "y0")
    t = _times(t_nodes)
    rtol = _check_rtol(rtol)
    t0 = float(t[0]) if t0 is None else float(t0)
    offsets = t - t0
    if np.any(offsets > 0) and np.any(offsets < 0):
        raise InputError("t_nodes must all lie on one side of t0")
    t_end = float(t[np.argmax(np.abs(offsets))])
    fun = _vector_field(rhs, params, y0.size)
    nfev = 0
    if atol is None:
        from scipy.integrate import solve_ivp  # 0.3 s to import: only when computing

        pilot = solve_ivp(
            fun, (t0, t_end), y0, method="DOP853", rtol=PILOT_RTOL,
            atol=PILOT_RTOL * _scales(y0[None, :]),
        ) if t_end != t0 else None  # fmt: skip
        if pilot is not None and not pilot.success:
            raise IntegrationError(f"reference pilot integration failed: {pilot.message}")
        scale = _scales(y0[None, :] if pilot is None else pilot.y.T)
        nfev += 0 if pilot is None else pilot.nfev
        atol_arr = rtol * scale
    else:
        atol_arr = np.broadcast_to(np.asarray(atol, dtype=float), y0.shape).copy()
        if not np.all(atol_arr > 0):
            raise InputError(f"atol must be positive, got {atol!r}")
        scale = atol_arr / rtol
    y, run_nfev, steps = _run(fun, t0, t_end, y0, t, rtol, atol_arr, max_step)
    nfev += run_nfev
    # The rounding floor per component, on that component's own scale: the
    # outer solar system's positions (30 AU) round some 1e-14, its momenta
    # (1e-9) some 1e-25; one floor on the largest scale for all of them
    # hid that the momenta are known far better than the positions.
    floor = np.sqrt(max(steps, 1)) * EPS * scale
    components = None
    if estimate_error:
        check, check_nfev, _ = _run(
            fun, t0, t_end, y0, t, CHECK_FACTOR * rtol, CHECK_FACTOR * atol_arr, max_step
        )
        nfev += check_nfev
        components = np.maximum(np.max(np.abs(check - y), axis=0), floor)
        error = float(np.max(components))
    else:
        error = float("nan")
    details = {"rtol": rtol, "atol": atol_arr.tolist(), "steps": steps, "nfev": nfev}
    method = f"DOP853 over [{t0:g}, {t_end:g}] (rtol={rtol:.2g}, scale-aware atol)"
    return Reference(
        t=t, y=y, estimated_error=error, method=method, details=details,
        component_error=components,
    )  # fmt: skip


# -- convenience for the symbolic layer ---------------------------------------
def hamiltonian_reference(
    system: Any,
    y0: Any,
    t_nodes: Any,
    *,
    params: Any = None,
    t0: float | None = None,
    periodic: bool | None = None,
    cache: bool = True,
) -> Reference:
    """Reference for a :class:`hamrkq.Hamiltonian` or a catalogue ``Problem``.

    Parameters
    ----------
    system : Hamiltonian or Problem
        A problem supplies its parameter values; a Hamiltonian its defaults.
    y0 : array_like, shape (2n,)
        State at ``t0`` (for a solution: ``sol.y[0]``).
    t_nodes : array_like
        Times wanted (for a solution: ``sol.t``).
    params : array_like or mapping, optional
        Parameter values (an array ordered like ``ham.parameters``, or a
        mapping for ``ham.parameter_values``).
    t0 : float, optional
        Time of ``y0``; default ``t_nodes[0]``.
    periodic : bool, optional
        Use :func:`periodic_reference`.  Default: yes for an autonomous
        system with one degree of freedom (its bounded orbits are periodic),
        falling back to :func:`integrate_reference` if the orbit does not
        return (an unbounded rotation, a separatrix); no otherwise.
    cache : bool
        Keep the reference on disk and read it back when the same one is
        asked for again (same Hamiltonian, parameters, ``y0``, times, ``t0``,
        ``periodic``, and versions of hamrkq, SciPy, NumPy, SymPy):
        :mod:`hamrkq.analysis.reference_cache`.  Default yes.
    """
    ham = getattr(system, "hamiltonian", system)
    if params is None:
        params = (
            system.parameter_array if hasattr(system, "parameter_array")
            else ham.parameter_values()
        )  # fmt: skip
    elif isinstance(params, Mapping):
        params = ham.parameter_values(params)
    t = _times(t_nodes)
    y0 = _state(y0, "y0")
    t0 = float(t[0]) if t0 is None else float(t0)
    if not cache:
        return _reference_of(ham, params, y0, t, t0, periodic)
    path = reference_cache.reference_path(ham, params, y0, t, t0, periodic)
    fields = reference_cache.cached(
        path, lambda: _fields(_reference_of(ham, params, y0, t, t0, periodic))
    )
    if "component_error" not in fields:
        # kept before references had per-component accuracies: replaced, so
        # that a multi-scale system is judged per component here too
        path.unlink(missing_ok=True)
        fields = reference_cache.cached(
            path, lambda: _fields(_reference_of(ham, params, y0, t, t0, periodic))
        )
    return Reference(**fields)


def _fields(ref: Reference) -> dict[str, Any]:
    return {
        "t": ref.t,
        "y": ref.y,
        "estimated_error": float(ref.estimated_error),
        "method": ref.method,
        "details": plain(dict(ref.details)),
        "component_error": None if ref.component_error is None else list(ref.component_error),
    }


def _reference_of(ham, params, y0, t, t0, periodic) -> Reference:
    auto = periodic is None
    if auto:
        periodic = ham.n == 1 and not ham.time_dependent
    rhs = numeric_of(ham).rhs
    if periodic:
        try:
            return periodic_reference(rhs, y0, t, params, t0=t0)
        except InputError:
            if not auto:
                raise
    return integrate_reference(rhs, y0, t, params, t0=t0)
