"""SciPy baselines: any ``solve_ivp`` method on a Hamiltonian, as a :class:`Solution`.

``hamrkq.solve(problem, method="scipy:DOP853")`` (or ``"scipy:RK45"``,
``"scipy:Radau"``, ...) lands here.  The system's right-hand side comes from
the symbolic layer, and so does the Jacobian, which is passed to the methods
that use one (``Radau``, ``BDF``, ``LSODA``; and ``RK34Q8``, hamrkq's own
solver in SciPy form, for its Gamma estimate).

The solver is stepped here rather than through :func:`scipy.integrate.solve_ivp`
so that hamrkq's failure policy holds: a failed step, a non-finite state, the
step limit or Ctrl-C end the run with the nodes computed so far kept, and a
status and message that say where.  Requested times (``t_eval``) are read off
each step's dense output, as ``solve_ivp`` does.

Tolerances are handed to SciPy unchanged except that ``rtol`` is raised to
100 eps (SciPy's floor, without its warning).  Note that SciPy's error test is
an RMS norm of ``err / (atol + rtol |y|)``, not hamrkq's max norm of
``err / max(atol, rtol |y|)``: equal numbers are not equal demands, which is
why :mod:`hamrkq.analysis.comparison` compares methods over a sweep of tolerances.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolver, Radau

from hamrkq._floats import MIN_RTOL
from hamrkq._interruption import interrupted_near
from hamrkq.backends.numeric import numeric_of
from hamrkq.baselines import PREFIX, SCIPY_SOLVER_HOMES
from hamrkq.errors import InputError, OptionError
from hamrkq.result import Solution, Status, kept_nodes_note
from hamrkq.rkq.scipy_solver import RK34Q8

__all__ = ["PREFIX", "SCIPY_METHODS", "USES_JACOBIAN", "solve_scipy"]

_BY_NAME = {solver.__name__: solver for solver in (RK23, RK45, DOP853, Radau, BDF, LSODA, RK34Q8)}
#: The SciPy solvers by name, in the order of :data:`SCIPY_SOLVER_HOMES`.
SCIPY_METHODS: Mapping[str, type[OdeSolver]] = MappingProxyType(
    {name: _BY_NAME[name] for name in SCIPY_SOLVER_HOMES}
)
#: Solvers that take ``jac``; they get the symbolic Jacobian.
USES_JACOBIAN = frozenset({"Radau", "BDF", "LSODA", "RK34Q8"})
#: Solvers whose ``rtol`` must be a scalar.
SCALAR_RTOL = frozenset({"Radau", "BDF"})
#: SciPy raises smaller relative tolerances to this, with a warning.
SCIPY_MIN_RTOL = MIN_RTOL
#: Steps between calls of ``progress``.
PROGRESS_EVERY = 1000


def _attempts_counter(solver: OdeSolver) -> Callable[[int], int | None]:
    """Rejected attempts of the last step, for SciPy's explicit Runge-Kutta pairs.

    Their ``_step_impl`` evaluates ``f`` exactly ``n_stages`` times per attempt
    (the first stage is the previous step's last, FSAL), so the evaluations a
    step made tell how many attempts it took.  The implicit methods do not say;
    for them the count is None.
    """
    stages = getattr(solver, "n_stages", None)
    if stages is None or type(solver) not in (RK23, RK45, DOP853):
        return lambda nfev: None
    return lambda nfev: max(nfev // stages - 1, 0)


class _Nodes:
    """The kept nodes (and, for RK34Q8, its track and estimates)."""

    def __init__(self, track: bool):
        self.t: list[float] = []
        self.y: list[np.ndarray] = []
        self.track = track
        self.z: list[np.ndarray] = []
        self.gamma: list[np.ndarray] = []
        self.quenched: list[bool] = []

    def add(self, t: float, y: np.ndarray, solver: Any = None) -> None:
        self.t.append(float(t))
        self.y.append(np.array(y, dtype=float))
        if self.track:
            self.z.append(solver.z)
            gamma = solver.gamma
            self.gamma.append(np.zeros_like(y) if gamma is None else gamma)
            self.quenched.append(bool(solver.quenched))


def _final_message(
    status: Status, message: str, method: str, t_end: float, steps: int, kept: list, output: bool
) -> str:
    """The run's message: where it ended, and for a partial run the nodes
    kept (with ``t_eval``, the last output time kept too: it comes before
    where the steps reached)."""
    if status is Status.SUCCESS:
        return f"scipy:{method} reached t = {float(t_end)!r} in {steps} steps."
    if kept:
        if output:
            message += f" The last output time kept is t = {float(kept[-1])!r}."
        message += kept_nodes_note(len(kept))
    return message


def solve_scipy(
    ham: Any,
    y0: Any,
    t_span: tuple[float, float],
    method: str,
    params: Any = None,
    *,
    atol: Any = 1e-6,
    rtol: Any = 0.0,
    first_step: float | None = None,
    max_step: float = math.inf,
    max_steps: int | None = None,
    keep_every: int = 1,
    t_eval: Any = None,
    progress: Callable[[float, float], None] | None = None,
    options: Mapping[str, Any] | None = None,
) -> Solution:
    """Integrate a :class:`~hamrkq.Hamiltonian` with a SciPy ``OdeSolver``.

    Parameters
    ----------
    ham : Hamiltonian
    y0 : array_like, shape (2n,)
        Initial state, all q then all p.
    t_span : (t0, t_end)
    method : str
        A key of :data:`SCIPY_METHODS` (without the ``"scipy:"`` prefix).
    params : array_like or mapping, optional
        Parameter values (an array ordered like ``ham.parameters`` or a mapping
        for ``ham.parameter_values``); default the Hamiltonian's defaults.
    atol, rtol : float or array_like
        Passed to SciPy (``rtol`` raised to at least 100 eps).
    first_step, max_step : float, optional
        Passed to SciPy.
    max_steps : int, optional
        Stop with ``Status.MAX_STEPS`` after this many accepted steps.
    keep_every : int
        Keep every k-th step's node (and the first and last).
    t_eval : array_like, optional
        Keep only these times (monotonic in the direction of integration,
        inside ``t_span``), read off the dense output.
    progress : callable, optional
        ``progress(fraction, t)`` every :data:`PROGRESS_EVERY` steps.
    options : mapping, optional
        Further keywords for the solver (``{"quench": "redo"}`` for RK34Q8, ...).

    Returns
    -------
    Solution
        ``stats``: ``steps`` (accepted), ``rejected`` (None for the implicit
        methods, which do not report it), ``quenches``, ``nfev``, ``njev``,
        ``nlu``.  For ``"RK34Q8"`` also ``z``, ``global_error``, ``gamma`` and
        ``quenched``.  A failure of the solver is ``Status.EXTERNAL_FAILURE``
        with SciPy's message; nothing is raised.
    """
    if method not in SCIPY_METHODS:
        known = ", ".join(repr(PREFIX + m) for m in SCIPY_METHODS)
        raise OptionError(f"unknown SciPy method {method!r}; valid: {known}")
    if params is None or isinstance(params, Mapping):
        params = ham.parameter_values(params)
    params = np.asarray(params, dtype=float)
    y0 = np.asarray(y0, dtype=float)
    if y0.shape != (ham.dim,) or not np.all(np.isfinite(y0)):
        raise InputError(f"y0 must be {ham.dim} finite numbers, got {y0.tolist()}")
    t0, t_end = (float(v) for v in t_span)
    if isinstance(keep_every, bool) or not isinstance(keep_every, int) or keep_every < 1:
        raise InputError(f"keep_every must be a positive integer, got {keep_every!r}")
    times = None if t_eval is None else np.asarray(t_eval, dtype=float).ravel()
    num = numeric_of(ham)
    fun = lambda t, y: num.rhs(t, y, params)  # noqa: E731
    kwargs: dict[str, Any] = {
        "atol": np.broadcast_to(np.asarray(atol, dtype=float), (ham.dim,)).copy(),
        "rtol": np.maximum(np.asarray(rtol, dtype=float), SCIPY_MIN_RTOL),
        "max_step": max_step,
        **dict(options or {}),
    }
    if method == "RK34Q8":
        kwargs["rtol"] = np.asarray(rtol, dtype=float)  # hamrkq's own rule, rtol 0 allowed
    rtols = np.ravel(kwargs["rtol"])
    if rtols.size and np.all(rtols == rtols[0]):
        kwargs["rtol"] = float(rtols[0])  # Radau and BDF take a scalar only
    elif method in SCALAR_RTOL:
        raise OptionError(
            f"scipy:{method} takes one relative tolerance for all components, got "
            f"rtol={rtols.tolist()}"
        )
    if first_step is not None:
        kwargs["first_step"] = first_step
    if method in USES_JACOBIAN:
        kwargs["jac"] = lambda t, y: num.jac(t, y, params)
    # RK34Q8's track is kept at its own nodes; at t_eval times (interpolated) it is not.
    track = method == "RK34Q8" and times is None
    nodes = _Nodes(track)
    status, message = Status.SUCCESS, ""
    solver = None
    if t0 == t_end:
        nodes.t.append(t0)
        nodes.y.append(y0.copy())
        if track:
            nodes.z.append(y0.copy())
            nodes.gamma.append(np.zeros_like(y0))
            nodes.quenched.append(False)
        steps, rejected = 0, 0
    else:
        solver = SCIPY_METHODS[method](fun, t0, y0, t_end, **kwargs)
        status, message, steps, rejected = _drive(
            solver, nodes, times, keep_every, max_steps, progress, t0, t_end
        )
        if isinstance(solver, RK34Q8):
            rejected = solver.stats["rejected"]
    message = _final_message(status, message, method, t_end, steps, nodes.t, times is not None)
    t = np.array(nodes.t)
    y = np.array(nodes.y).reshape(t.size, ham.dim)
    z = np.array(nodes.z).reshape(t.size, ham.dim) if track else None
    stats = {
        "steps": steps,
        "rejected": rejected,
        "quenches": solver.stats["quenches"] if isinstance(solver, RK34Q8) else 0,
        "nfev": 0 if solver is None else int(solver.nfev),
        "njev": 0 if solver is None else int(solver.njev),
        "nlu": 0 if solver is None else int(solver.nlu),
    }
    scalar_rtol = np.asarray(kwargs["rtol"], dtype=float)
    return Solution(
        t=t,
        y=y,
        energy=num.energy(t, y, params) if t.size else t,
        status=status,
        message=message,
        method=PREFIX + method,
        n=ham.n,
        names=ham.names,
        atol=kwargs["atol"],
        rtol=np.broadcast_to(scalar_rtol, (ham.dim,)).copy(),
        stats=stats,
        options={
            "method": PREFIX + method,
            "t_span": [t0, t_end],
            "y0": np.asarray(y0, dtype=float).tolist(),
            "atol": kwargs["atol"].tolist(),
            "rtol": np.broadcast_to(scalar_rtol, (ham.dim,)).tolist(),
            "rtol_rule": "SciPy: RMS norm of err / (atol + rtol |y|), rtol >= 100 eps"
            if not track
            else "hamrkq: max norm of err / max(atol, rtol |y|)",
            "jacobian": "symbolic" if method in USES_JACOBIAN else None,
            "first_step": first_step,
            "max_step": None if math.isinf(max_step) else max_step,
            "max_steps": max_steps,
            "keep_every": keep_every,
            "t_eval": None if times is None else times.tolist(),
            "parameters": {s.name: float(v) for s, v in zip(ham.parameters, params, strict=True)},
            **{k: v for k, v in (options or {}).items() if isinstance(v, str | int | float)},
        },
        z=z,
        global_error=None if z is None else y - z,
        gamma=np.array(nodes.gamma).reshape(t.size, ham.dim)
        if track and solver is not None and solver.gamma is not None
        else None,
        quenched=np.array(nodes.quenched, dtype=bool) if track else None,
    )


def _drive(solver, nodes, times, keep_every, max_steps, progress, t0, t_end):
    """Step ``solver`` to the end; returns (status, message, steps, rejected)."""
    track = solver if nodes.track else None
    count_rejected = _attempts_counter(solver)
    rejected: int | None = 0
    next_eval = 0
    if times is None or (times.size and times[0] == t0):
        nodes.add(t0, solver.y, track)
        next_eval = 0 if times is None else 1
    steps = since_kept = 0
    good = (solver.t, solver.y)  # the last accepted, finite node
    status, message = Status.SUCCESS, ""
    try:
        while solver.status == "running":
            if max_steps is not None and steps >= max_steps:
                status = Status.MAX_STEPS
                message = (
                    f"The step limit max_steps = {max_steps} was reached at "
                    f"t = {float(good[0])!r}."
                )
                break
            before = solver.nfev
            text = solver.step()
            if solver.status == "failed":
                status = Status.EXTERNAL_FAILURE
                message = f"SciPy's solver failed at t = {float(solver.t)!r}: {text}"
                break
            if not np.all(np.isfinite(solver.y)):
                status = Status.NON_FINITE
                message = f"The state became non-finite (inf or nan) at t = {float(solver.t)!r}."
                break
            steps += 1
            good = (solver.t, solver.y)
            extra = count_rejected(solver.nfev - before)
            rejected = None if extra is None or rejected is None else rejected + extra
            if times is None:
                since_kept += 1
                if since_kept >= keep_every or solver.status == "finished":
                    nodes.add(solver.t, solver.y, track)
                    since_kept = 0
            else:
                next_eval = _dense_nodes(solver, nodes, times, next_eval)
            if progress is not None and steps % PROGRESS_EVERY == 0:
                progress(float((solver.t - t0) / (t_end - t0)), float(solver.t))
    except KeyboardInterrupt:
        status = Status.INTERRUPTED
        message = interrupted_near(good[0])
    if since_kept:
        # A run that stopped early keeps its last accepted node whatever keep_every says.
        nodes.add(good[0], good[1], track)
    return status, message, steps, rejected


def _dense_nodes(solver, nodes, times, index: int) -> int:
    """Add the requested times inside the last step; returns the next index."""
    interpolant = None
    while index < times.size and solver.direction * (times[index] - solver.t) <= 0:
        if times[index] == solver.t:
            nodes.add(solver.t, solver.y)
        else:
            interpolant = interpolant or solver.dense_output()
            nodes.add(times[index], interpolant(times[index]))
        index += 1
    return index
