"""Fixed-step symplectic baselines: one driver for Gauss collocation and splittings.

Five methods, all symplectic and symmetric, all with a constant step h:

============  =====  ===================================================
name          order  method
============  =====  ===================================================
``midpoint``  2      implicit midpoint rule (1-stage Gauss)
``gauss4``    4      2-stage Gauss-Legendre collocation
``gauss6``    6      3-stage Gauss-Legendre collocation
``verlet``    2      Stormer-Verlet, kick-drift-kick (separable H only)
``yoshida4``  4      Yoshida's triple jump of Verlet (separable H only)
============  =====  ===================================================

The methods' loops live beside this module: the Gauss methods (simplified
Newton on the stage equations) in :mod:`hamrkq.fixed_step.implicit_rk`, the
splittings (``H = T(p) + V(q)``) in :mod:`hamrkq.fixed_step.splitting`.  This
module validates a request, builds the mesh, runs the method's loop and packs
a :class:`FixedStepResult` (:func:`integrate_fixed`) or a
:class:`~hamrkq.result.Solution` (:func:`solve_fixed`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from hamrkq._validate import positive, span
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import InputError, InputTypeError, OptionError
from hamrkq.fixed_step.implicit_rk import (
    GAUSS_TABLEAUS,
    MAX_NEWTON_ITER,
    NEWTON_FLOOR,
    NEWTON_TOL,
    Mesh,
    Rhs,
    gauss_integrate,
)
from hamrkq.fixed_step.splitting import SPLITTING_SCHEMES, SplittingScheme, splitting_integrate
from hamrkq.result import Solution, Status, kept_nodes_note

__all__ = [
    "FIXED_STEP_METHODS",
    "SPLITTING_SCHEMES",
    "FixedStepResult",
    "SplittingScheme",
    "integrate_fixed",
    "solve_fixed",
]

#: When (t1 - t0) / h is within this relative distance of an integer N, the mesh
#: has N steps (the last one equal to h up to rounding) rather than N + 1 steps
#: with a last step of length ~0.
MESH_SLACK = 1e-9


#: Every fixed-step method, name -> classical order.
FIXED_STEP_METHODS: Mapping[str, int] = MappingProxyType(
    {name: tab.order for name, tab in GAUSS_TABLEAUS.items()}
    | {name: scheme.order for name, scheme in SPLITTING_SCHEMES.items()}
)


@dataclass(frozen=True, eq=False)
class FixedStepResult:
    """Output of :func:`integrate_fixed`: plain arrays and counters.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Times of the stored mesh points.
    y : ndarray, shape (K, dim)
        States there.
    status : Status
        ``SUCCESS``, ``NEWTON_FAILED``, ``NON_FINITE``, ``MAX_STEPS`` or
        ``INTERRUPTED``.
    message : str
        What happened, naming t on failure.
    steps, nfev, njev, newton_iterations : int
        Steps taken, right-hand-side calls, Jacobian calls, Newton iterations
        (the last two are 0 for splitting methods).
    """

    t: np.ndarray
    y: np.ndarray
    status: Status
    message: str
    steps: int
    nfev: int
    njev: int
    newton_iterations: int

    @property
    def success(self) -> bool:
        """True when the run reached t1."""
        return self.status.success

    @property
    def stats(self) -> dict[str, int]:
        """The counters in the form :class:`hamrkq.result.Solution` uses."""
        return {
            "steps": self.steps,
            "rejected": 0,
            "quenches": 0,
            "nfev": self.nfev,
            "njev": self.njev,
            "newton_iterations": self.newton_iterations,
        }


def _make_mesh(t0: float, t1: float, h: float, keep_every: int, max_steps: int | None) -> Mesh:
    span = abs(t1 - t0)
    ratio = span / h
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= MESH_SLACK * ratio:
        steps = int(nearest)
    else:
        steps = max(1, math.ceil(ratio))
    if t1 == t0:
        steps = 0
    stop = steps if max_steps is None else min(steps, max_steps)
    return Mesh(t0, t1, math.copysign(h, t1 - t0), steps, keep_every, stop)


def _steps_taken(mesh: Mesh) -> str:
    """The steps of a run over the whole ``mesh`` as taken: signed (negative
    backward), and the last where it was shortened to land on ``t1`` (beyond
    the slack of a mesh that divides the interval).  The step asked for was
    said before: ``gauss4`` with ``step=20`` over (10, 0) took one step of
    -10 and said "in 1 steps of 20.0"."""
    if mesh.steps == 0:
        return "0 steps"
    last = mesh.step_length(mesh.steps - 1)
    if mesh.steps == 1:
        return f"1 step of {last!r}"
    text = f"{mesh.steps} steps of {mesh.h!r}"
    if abs(last - mesh.h) > MESH_SLACK * abs(mesh.t1 - mesh.t0):
        text += f", the last {last!r}"
    return text


_STATUS = {
    None: Status.SUCCESS,
    "newton": Status.NEWTON_FAILED,
    "non_finite": Status.NON_FINITE,
    "interrupted": Status.INTERRUPTED,
}

#: What helps a run that failed, by failure (the messages named none; QA).
_REMEDIES = {
    "newton": (
        " What works: a smaller step (the Newton iteration of an implicit step converges "
        "where the step is short against the motion's time scales)."
    ),
    "non_finite": (
        " What works: a smaller step (an explicit splitting grows without bound where its "
        "step is too long for the fastest oscillation: verlet needs h omega < 2), unless "
        "the state leaves the domain of H there."
    ),
    "interrupted": "",
    "max_steps": " What works: a larger max_steps, or a longer step.",
}


def integrate_fixed(
    method: str,
    rhs: Rhs,
    jac: Rhs | None,
    y0: Any,
    t0: float,
    t1: float,
    h: float,
    params: Any = (),
    keep_every: int = 1,
    *,
    max_newton_iter: int = MAX_NEWTON_ITER,
    max_steps: int | None = None,
) -> FixedStepResult:
    """Integrate ``dy/dt = rhs(t, y, params)`` with a fixed-step symplectic method.

    Parameters
    ----------
    method : {"midpoint", "gauss4", "gauss6", "verlet", "yoshida4"}
        The method (see the module docstring).  ``"verlet"`` and ``"yoshida4"``
        assume, without checking, that the system comes from a separable
        ``H = T(p) + V(q)`` with state ``(q, p)``; :func:`solve_fixed` checks it.
    rhs : callable
        ``rhs(t, y, params) -> ndarray (dim,)``; must return a fresh array.
    jac : callable or None
        ``jac(t, y, params) -> ndarray (dim, dim)``, needed by the Gauss methods
        (evaluated once per step at the step's start).
    y0 : array_like, shape (dim,)
        Initial state (all q then all p).
    t0, t1 : float
        Start and end of the interval; ``t1 < t0`` integrates backward.
    h : float
        Step size, positive; its sign is taken from ``t1 - t0``.  h need not
        divide the interval: the mesh is ``t0 + i h`` and the last step is
        shortened to land exactly on t1 (when ``|t1 - t0| / h`` is an integer up
        to a relative 1e-9, the last step is h up to rounding).
    params : array_like
        Passed to rhs and jac unchanged.
    keep_every : int
        Store every ``keep_every``-th mesh point (and always the first and the
        last reached).  Memory only: the integration is the same.
    max_newton_iter : int
        Newton iteration limit per step (Gauss methods).
    max_steps : int, optional
        Stop with ``Status.MAX_STEPS`` after this many steps.

    Returns
    -------
    FixedStepResult
        Numerical failures (Newton not converging, a non-finite state) are
        reported in ``status`` and ``message`` with the nodes computed so far;
        they never raise.

    Raises
    ------
    OptionError
        Unknown method.
    InputError, InputTypeError
        Bad y0, interval, step, keep_every or limits.
    """
    if method not in FIXED_STEP_METHODS:
        known = ", ".join(repr(m) for m in FIXED_STEP_METHODS)
        raise OptionError(f"unknown fixed-step method {method!r} (known: {known})")
    t0, t1 = span((t0, t1))
    h = positive("step", h)
    try:
        y0 = np.array(y0, dtype=float)
    except (TypeError, ValueError):
        raise InputTypeError(f"y0 must be an array of real numbers, got {y0!r}") from None
    if y0.ndim != 1 or y0.size == 0:
        raise InputError(f"y0 must be a non-empty 1-D array, got shape {y0.shape}")
    if not np.isfinite(y0).all():
        raise InputError(f"y0 must be finite, got {y0!r}")
    for name, value, low in (
        ("keep_every", keep_every, 1),
        ("max_newton_iter", max_newton_iter, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise InputError(f"{name} must be an integer >= {low}, got {value!r}")
    if max_steps is not None and (
        isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1
    ):
        raise InputError(f"max_steps must be a positive integer or None, got {max_steps!r}")
    params = np.asarray(params, dtype=float)
    mesh = _make_mesh(t0, t1, h, int(keep_every), None if max_steps is None else int(max_steps))

    if method in SPLITTING_SCHEMES:
        if y0.size % 2:
            raise InputError(f"{method} needs a state (q, p) of even length, got {y0.size}")
        ys, reached, out = splitting_integrate(SPLITTING_SCHEMES[method], rhs, y0, mesh, params)
    else:
        if jac is None:
            raise InputError(f"{method} is implicit and needs jac, got None")
        tab = GAUSS_TABLEAUS[method]
        ys, reached, out = gauss_integrate(tab, rhs, jac, y0, mesh, params, int(max_newton_iter))

    status = _STATUS[out.failure]
    if out.failure is not None:
        reason = out.reason[:1].upper() + out.reason[1:].rstrip(".") + "."
        message = reason + _REMEDIES[out.failure]
    elif mesh.stop < mesh.steps:
        status = Status.MAX_STEPS
        message = (
            f"{method}: max_steps={mesh.stop} reached at t={float(mesh.time(reached))!r} "
            f"({mesh.steps} steps needed to reach t1={t1!r})." + _REMEDIES["max_steps"]
        )
    else:
        message = f"{method} reached t={t1!r} in {_steps_taken(mesh)}"
    idx = mesh.kept_indices(reached)
    if status is not Status.SUCCESS:
        message += kept_nodes_note(idx.size)
    t = mesh.t0 + idx * mesh.h
    if reached == mesh.steps:
        t[-1] = mesh.t1
    return FixedStepResult(
        t=t,
        y=ys,
        status=status,
        message=message,
        steps=reached,
        nfev=out.nfev,
        njev=out.njev,
        newton_iterations=out.iterations,
    )


def solve_fixed(
    ham: Any,
    y0: Any,
    t_span: tuple[float, float],
    method: str,
    step: float,
    params: Any = None,
    *,
    keep_every: int = 1,
    max_newton_iter: int = MAX_NEWTON_ITER,
    max_steps: int | None = None,
) -> Solution:
    """Run a fixed-step symplectic method on a :class:`~hamrkq.Hamiltonian`.

    The adapter :func:`hamrkq.solve` calls for methods ``"midpoint"``,
    ``"gauss4"``, ``"gauss6"``, ``"verlet"`` and ``"yoshida4"``.

    Parameters
    ----------
    ham : Hamiltonian
        The system (uses ``numeric_of(ham)``, ``ham.n``, ``ham.is_separable``,
        ``ham.names``, ``ham.parameter_values``).
    y0 : array_like, shape (2n,)
        Initial state, all q then all p.
    t_span : (float, float)
        Start and end times.
    method : str
        One of :data:`FIXED_STEP_METHODS`.
    step : float
        The step size h > 0 (see :func:`integrate_fixed` for the last step).
    params : mapping or array_like, optional
        Parameter values: a mapping of overrides for ``ham.parameter_values``, or
        the ready array; None takes the defaults.
    keep_every, max_newton_iter, max_steps
        As in :func:`integrate_fixed`.

    Returns
    -------
    Solution
        With ``z``, ``global_error``, ``gamma`` and ``quenched`` None, and
        ``atol``/``rtol`` NaN: a fixed-step method has no tolerance.

    Raises
    ------
    OptionError
        Unknown method, or ``"verlet"``/``"yoshida4"`` on a non-separable H.
    """
    if method not in FIXED_STEP_METHODS:
        known = ", ".join(repr(m) for m in FIXED_STEP_METHODS)
        raise OptionError(f"unknown fixed-step method {method!r} (known: {known})")
    if method in SPLITTING_SCHEMES and not ham.is_separable:
        raise OptionError(
            f"method {method!r} needs a separable Hamiltonian H = T(p) + V(q), and this H "
            "has mixed derivatives d2H/dq dp != 0; use 'midpoint', 'gauss4' or 'gauss6'"
        )
    if params is None or isinstance(params, Mapping):
        values = ham.parameter_values(params)
    else:
        values = np.asarray(params, dtype=float)
        if values.shape != (len(ham.parameters),):
            raise InputError(
                f"params must have {len(ham.parameters)} values, got shape {values.shape}"
            )
    y0 = np.asarray(y0, dtype=float)
    if y0.shape != (ham.dim,):
        raise InputError(f"y0 must have shape ({ham.dim},), got {y0.shape}")
    try:
        t0, t1 = t_span
    except (TypeError, ValueError):
        raise InputError(f"t_span must be a pair (t0, t1), got {t_span!r}") from None
    num = numeric_of(ham)
    res = integrate_fixed(
        method,
        num.rhs,
        num.jac,
        y0,
        t0,
        t1,
        step,
        values,
        keep_every,
        max_newton_iter=max_newton_iter,
        max_steps=max_steps,
    )
    energy = num.energy(res.t, res.y, values)
    nan = np.full(ham.dim, np.nan)
    return Solution(
        t=res.t,
        y=res.y,
        energy=energy,
        status=res.status,
        message=res.message,
        method=method,
        n=ham.n,
        names=ham.names,
        atol=nan,
        rtol=nan,
        stats=res.stats,
        options={
            "step": float(step),
            "order": FIXED_STEP_METHODS[method],
            "keep_every": int(keep_every),
            "max_newton_iter": int(max_newton_iter),
            "max_steps": max_steps,
            "newton_tol": NEWTON_TOL,
            "newton_floor": NEWTON_FLOOR,
        },
    )
