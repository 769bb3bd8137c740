"""Chaos indicators from the variational equations: the maximal Lyapunov
exponent and MEGNO.

Both integrate the orbit with :func:`hamrkq.solve` (every node kept), then
carry a tangent vector ``v`` along the quencher track's nodes (``z``; ``y``
for a method without one) with the exact linearisation of the quencher's
steps (:mod:`hamrkq.rkq.variational`; the symbolic Jacobian gives ``J v``),
renormalised every step.  With ``l_i = log(|v_{i+1}|/|v_i|)``:

- the maximal Lyapunov exponent ``lambda(t_k) = sum_{i<k} l_i / |t_k - t0|``
  (Benettin et al. 1980), which tends to 0 like ``1/t`` on a regular orbit;
- MEGNO ``Y(t) = (2/t) int_0^t s (v.v'/v.v) ds`` and its running mean
  ``<Y>(t) = (1/t) int_0^t Y ds`` (Cincotta & Simo 2000, the definition
  REBOUND uses), the integrand ``v.v'/v.v = d log|v|/ds`` taken constant
  over each step (``l_i / h_i``), so ``int s (...) ds`` over the step is
  ``l_i (t_i + t_{i+1}) / 2``; ``<Y>`` by the trapezoidal rule.  ``<Y>``
  tends to 0 for a harmonic (isochronous) orbit, to 2 for a quasi-periodic
  one, and grows like ``lambda t / 2`` for a chaotic one.

Time is counted from ``t0``, as ``|t - t0|``: a run backward in time
measures the same growth of ``|v|`` over the same elapsed time (the
exponent of the time-reversed orbit), positive on a chaotic orbit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hamrkq._validate import show
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problems import Problem
from hamrkq.errors import InputError, OptionError
from hamrkq.result import Solution, Status
from hamrkq.rkq.dense import dense_tableaus, prepare_work
from hamrkq.rkq.family import MEMBERS
from hamrkq.rkq.variational import sweep
from hamrkq.solve import solve

__all__ = ["ChaosIndicator", "indicator_of", "lyapunov", "megno", "tangent_growth"]


@dataclass(frozen=True)
class ChaosIndicator:
    """An indicator along an orbit.

    Attributes
    ----------
    t : ndarray, shape (N,)
        The nodes of the orbit's run.
    value : ndarray, shape (N,)
        The indicator at each node (``value[-1]`` the estimate at the end;
        ``value[0]`` is 0 by convention).
    status : Status
        The orbit's run's status (the indicator covers the nodes computed).
    message : str
    solution : Solution
        The orbit.
    """

    t: np.ndarray
    value: np.ndarray
    status: Status
    message: str
    solution: Solution

    def __repr__(self) -> str:
        # One line, like Solution's (the generated one printed both arrays).
        end = ""
        if len(self.t):
            end = f"t={float(self.t[-1])!r}, value={float(self.value[-1]):.6g}, "
        return f"ChaosIndicator({end}nodes={len(self.t)}, status={self.status.name})"

    @property
    def success(self) -> bool:
        return self.status.success


def tangent_growth(
    sol: Solution, system: Any, v0: Any = None, backend: str | None = None
) -> np.ndarray:
    """``l_i = log(|v_{i+1}| / |v_i|)`` along the nodes of ``sol`` (a run of
    :func:`hamrkq.solve` of ``system`` with every node; its quencher track
    ``z`` where it has one, else ``y``), from the unit vector along ``v0``
    (default: all components equal)."""
    from hamrkq.rkq.family import get_member

    ham = system.hamiltonian if isinstance(system, Problem) else system
    options = sol.options
    _check_method(options.get("method", sol.method), "the run's method")
    member = get_member(str(options["method"]), options.get("z_method"), options.get("z_substeps"))
    tab = dense_tableaus(member)
    params = np.array(list(options["parameters"].values()), dtype=np.float64)
    d = ham.dim
    v = tangent_direction(v0, d)
    t = np.array(sol.t, dtype=np.float64)
    # Along the quencher's own track where the run has one: the tangent map
    # of its steps from z_i is then the linearisation of the very map
    # that took z_i to z_{i+1}.  The reported track y is not that map's
    # orbit (the pair's steps, and quenches that jump it onto z): at atol
    # 1e-6 on Kepler e = 0.6, MEGNO at t = 2000 read 2.35 (auto) and 1.61
    # (rk34q8) along y, 1.998 along z, as at every tolerance.
    y = np.array(sol.y if sol.z is None else sol.z, dtype=np.float64)
    # as many steps an interval as the quencher took (the pair's one without)
    substeps = member.z_substeps if sol.z is not None else 1
    growth = np.zeros(max(t.size - 1, 0))
    work = prepare_work(d, tab)
    backend = backend or str(options.get("backend", "python"))
    if backend == "numba":
        from hamrkq.backends import compiled, extras

        system_fns = compiled.compile_system(ham)
        system_fns.prepare("tangent")  # generates and compiles rhs_jvp
        args = (system_fns.rhs_jvp, tab, params, t, y, substeps, v, work, growth)
        extras.compiled_helper(sweep, ("rhs_jvp",), *args)(*args)
    else:
        numeric = numeric_of(ham)

        def tangent(t, y, params, v, out, dout, JM):
            out[:] = numeric.rhs(t, y, params)
            JM[:, :] = numeric.jac(t, y, params)
            dout[:] = JM @ v

        sweep(tangent, tab, params, t, y, substeps, v, work, growth)
    return growth


def tangent_direction(v0: Any, dim: int) -> np.ndarray:
    """The unit vector along ``v0`` (``dim`` finite numbers, not all zero;
    default all components equal)."""
    if v0 is None:
        return np.full(dim, 1.0 / np.sqrt(dim))
    try:
        v = np.array(v0, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"v0 must be {dim} numbers, got {show(v0)}") from None
    if v.shape != (dim,):
        raise InputError(f"v0 must be {dim} numbers (one per q and p), got {show(v0)}")
    norm = float(np.linalg.norm(v)) if np.all(np.isfinite(v)) else np.nan
    if not (np.isfinite(norm) and norm > 0):
        raise InputError(f"v0 must be finite and not zero, got {show(v0)}")
    return v / norm


def _check_method(method: Any, what: str = "method") -> None:
    """The indicators step the tangent vector with an RKQ family member's
    own tableau: a baseline's run (``verlet``, ``scipy:*``) has none."""
    if method is None or method == "auto" or method in MEMBERS:
        return
    valid = ", ".join(repr(k) for k in ("auto", *MEMBERS))
    raise OptionError(
        f"{what} {method!r} is not an RKQ method: the Lyapunov exponent and MEGNO carry the "
        f"tangent vector with the steps of the RKQ family's tableaus; valid: {valid}"
    )


def _orbit(system, q0, p0, t_span, v0, solve_options) -> Solution:
    for key in ("dense_output", "events", "keep_every", "t_eval"):
        if key in solve_options:
            raise TypeError(f"{key} cannot be given: the indicators need every node")
    _check_method(solve_options.get("method"))
    ham = system.hamiltonian if isinstance(system, Problem) else system
    tangent_direction(v0, ham.dim)  # before the run, not after it
    return solve(system, q0, p0, t_span, **solve_options)


#: The indicators' names in messages.
_NAMES = {"lyapunov": "Lyapunov exponent", "megno": "MEGNO"}


def _indicator(kind: str, system, q0, p0, t_span, v0, solve_options) -> ChaosIndicator:
    sol = _orbit(system, q0, p0, t_span, v0, dict(solve_options))
    indicator = indicator_of(kind, sol, system, v0)
    if sol.status is Status.TOLERANCE_UNATTAINABLE and "gamma_limit" not in solve_options:
        message = sol.message + (
            f" The {_NAMES[kind]} ends with the orbit. It needs the orbit past where its "
            "error can be certified: gamma_limit=numpy.inf runs it to t_end (on a chaotic "
            "orbit the later points are those of a nearby orbit, and the indicator, a "
            "property of the region, is still measured; docs/events.md)."
        )
        indicator = replace(indicator, message=message)
    return indicator


def indicator_of(kind: str, sol: Solution, system: Any, v0: Any = None) -> ChaosIndicator:
    """The indicator ``kind`` (``"lyapunov"`` or ``"megno"``) along an orbit
    already integrated: ``sol``, a run of :func:`hamrkq.solve` of ``system``
    with every node (events and dense output change no node, so a run made
    for a Poincare section serves: ``hamrkq poincare --megno`` integrates
    each orbit once).  :func:`lyapunov` and :func:`megno` are this after
    their own run."""
    if kind not in _NAMES:
        raise ValueError(f"kind must be one of {sorted(_NAMES)}, got {kind!r}")
    if sol.options.get("keep_every", 1) != 1 or sol.options.get("t_eval") is not None:
        raise ValueError("the indicators need every node: a run without keep_every or t_eval")
    growth = tangent_growth(sol, system, v0)
    t = np.asarray(sol.t)
    elapsed = np.abs(t - t[0])  # a backward run's time runs forward here
    value = np.zeros(t.size)
    with np.errstate(invalid="ignore", divide="ignore"):
        if kind == "lyapunov":
            value[1:] = np.cumsum(growth) / elapsed[1:]
        else:
            weighted = np.cumsum(growth * 0.5 * (elapsed[:-1] + elapsed[1:]))
            Y = np.zeros(t.size)
            Y[1:] = 2.0 * weighted / elapsed[1:]
            trapezoids = 0.5 * (Y[1:] + Y[:-1]) * np.diff(elapsed)
            integral = np.concatenate([[0.0], np.cumsum(trapezoids)])
            value[1:] = integral[1:] / elapsed[1:]
    return ChaosIndicator(t=t, value=value, status=sol.status, message=sol.message, solution=sol)


def lyapunov(
    system: Any,
    q0: Any = None,
    p0: Any = None,
    t_span: Any = None,
    *,
    v0: Any = None,
    **solve_options: Any,
) -> ChaosIndicator:
    """The maximal Lyapunov exponent along an orbit, at every node.

    Parameters
    ----------
    system : Hamiltonian or Problem
    q0, p0, t_span
        As for :func:`hamrkq.solve` (a Problem's by default).
    v0 : array of 2n, optional
        Initial tangent direction (default: all components equal).
    **solve_options
        For :func:`hamrkq.solve` (``atol``, ``method``, ``gamma_limit``, ...).

    Returns
    -------
    ChaosIndicator
        ``value[k] = sum_{i<k} log(|v_{i+1}|/|v_i|) / |t_k - t0|``.

    Raises
    ------
    InputError
        ``v0`` not ``2n`` finite numbers, or zero.
    OptionError
        A ``method`` outside the RKQ family (the tangent vector is stepped
        with the member's tableau).
    """
    return _indicator("lyapunov", system, q0, p0, t_span, v0, solve_options)


def megno(
    system: Any,
    q0: Any = None,
    p0: Any = None,
    t_span: Any = None,
    *,
    v0: Any = None,
    **solve_options: Any,
) -> ChaosIndicator:
    """The mean MEGNO ``<Y>(t)`` along an orbit, at every node (Cincotta &
    Simo 2000): about 2 on a quasi-periodic orbit, 0 on a harmonic one,
    growing like ``lambda t / 2`` on a chaotic one.  Parameters as
    :func:`lyapunov`."""
    return _indicator("megno", system, q0, p0, t_span, v0, solve_options)
