"""RKQ as a SciPy solver: ``solve_ivp(fun, t_span, y0, method=hamrkq.RK34Q8)``.

:class:`RK34Q8` is a :class:`scipy.integrate.OdeSolver` whose steps are
hamrkq's RKQ steps (J.S.C. Prentice, arXiv:1111.6996): RK3/RK4 local
extrapolation, an RK8 track on the same mesh, and quenching of the reported
solution to the RK8 value wherever they differ by more than the tolerance.
The algorithm is not re-implemented here: each call of :meth:`step` runs
:class:`hamrkq.rkq.driver.Integration` until it has accepted exactly one step.

It works on any first-order system (nothing needs to be Hamiltonian), so
``solve_ivp``'s ``t_eval``, ``dense_output``, ``events`` and ``args`` behave as
with SciPy's own methods.  What SciPy's methods do not have is exposed on the
solver object after every step (and to an ``on_step`` callback, since
``solve_ivp`` does not hand its solver back):

- ``solver.z``: the RK8 track at ``solver.t``;
- ``solver.global_error``: ``y - z``, the estimated global error of ``y``
  (the paper's sign, numerical minus exact; zero at a quenched node);
- ``solver.gamma``: the estimated global error of the RK8 track itself
  (``None`` when it is not propagated, e.g. without ``jac``);
- ``solver.quenched``: whether the last step was quenched;
- ``solver.stats``: accepted and rejected steps, quenches, nfev, njev.

Tolerances mean what they mean in :func:`hamrkq.solve`, not what they mean in
SciPy: per component ``delta_k = max(atol_k, rtol_k |y_k|)`` and a max-norm,
and the defaults are the paper's ``atol=1e-6, rtol=0``.  Every node of ``y``
is within ``delta`` of the RK8 track.

Dense output is :mod:`hamrkq.rkq.dense`'s, as in :func:`hamrkq.solve`: a
value between two nodes is the RK8 track stepped from the nearer node over
at most half the step (one RK8 step: 12 evaluations of ``fun`` a value),
plus the difference ``y - z`` of the two nodes interpolated linearly, so the
nodes' bound holds between them (the RK8 track's own error, and the larger
of the two nodes' ``|y - z|``).  The cubic Hermite interpolant of the end
values and slopes it replaced cost nothing, but its error is of the order of
RK3's local error with other constants: up to 5.3 and 11 times the
tolerance between nodes on the van der Pol oscillator (mu = 5) at atol 1e-6
and 1e-8, 1.4 times on Kepler's e = 0.9 orbit, where the nodes were within
it (``benchmarks/scipy_dense.txt``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver

from hamrkq._floats import MIN_RTOL
from hamrkq._validate import choice, tolerance
from hamrkq.errors import InputError, OptionError, warn
from hamrkq.result import Status
from hamrkq.rkq import dense, layout
from hamrkq.rkq.config import Settings
from hamrkq.rkq.driver import Integration, python_functions
from hamrkq.rkq.family import PAPER_METHOD, Z_METHODS, get_member
from hamrkq.rkq.layout import GAM, K1, ZHI, U
from hamrkq.rkq.start import initial_step

__all__ = ["RK34Q8", "StepDenseOutput"]

#: As in :func:`hamrkq.solve`: relative tolerances below 100 eps are raised.
#: Step attempts per call of the kernel before control comes
#: back to Python (a Ctrl-C is seen between calls).
BUDGET = 1000
#: No limit on steps: SciPy's callers stop a solver themselves.
NO_STEP_LIMIT = 1 << 62

_QUENCH = {"node": layout.QUENCH_NODE, "redo": layout.QUENCH_REDO}
_RULES = {"componentwise": layout.RULE_COMPONENTWISE, "prentice": layout.RULE_PRENTICE}
_GAMMA = {"tangent": layout.GAMMA_TANGENT, "paper": layout.GAMMA_PAPER, "off": layout.GAMMA_OFF}
_STATUS_BY_CODE = {status.code: status for status in Status}
_NO_PARAMS = np.zeros(0)


class RK34Q8(OdeSolver):
    """Prentice's RKQ algorithm (RK3/RK4 local extrapolation, RK8 quench) for SciPy.

    Use it as ``scipy.integrate.solve_ivp(fun, t_span, y0, method=RK34Q8,
    jac=jac, atol=..., rtol=...)`` or step by step like any
    :class:`~scipy.integrate.OdeSolver`.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> array_like (n,)``.
    t0 : float
        Initial time.
    y0 : array_like, shape (n,)
        Initial state (real).
    t_bound : float
        End of the interval; the last step lands on it exactly.
    max_step : float, default inf
        Largest step size.
    rtol : float or array_like, default 0
        Relative tolerance, zero or positive (values below 100 eps are raised to
        100 eps with a warning).
    atol : float or array_like, default 1e-6
        Absolute tolerance, positive.  Per component,
        ``delta_k = max(atol_k, rtol_k |y_k|)``.
    jac : callable, array_like or None
        ``jac(t, y) -> (n, n)`` (or a constant matrix).  Used only to propagate
        ``gamma``, the RK8 track's own error estimate (one Jacobian per RK8
        stage for ``"tangent"``).
    vectorized : bool
        As in SciPy (``fun`` is then called with single columns).
    first_step : float, optional
        Initial step; default Hairer-Norsett-Wanner's heuristic for order 3.
    quench : {"node", "redo"}, default "node"
    quench_threshold : float, default 1
    safety : float, default 0.9
    tolerance_rule : {"componentwise", "prentice"}, default "componentwise"
    global_error_estimate : {"tangent", "paper", "off"}, optional
        Default ``"tangent"`` with ``jac``, ``"off"`` without.
    z_method : {"dop853", "cooper_verner"}, default "dop853"
    gamma_limit : float, default 0.05
        The solver fails (``status == "failed"``) once the RK8 track's estimated
        error plus rounding exceeds this fraction of the tolerance; ``inf``
        disables the check.  See :func:`hamrkq.solve`.
    on_step : callable, optional
        ``on_step(solver)`` after every accepted step: the way to read
        ``solver.global_error`` and friends through ``solve_ivp``.

    Attributes
    ----------
    z, global_error, gamma, quenched, stats
        See the module docstring.
    order : int
        3, the order of the error-controlled method (the RK4 value is
        propagated).

    References
    ----------
    J.S.C. Prentice, "Global Error Control in the Runge-Kutta Solution of a
    Hamiltonian System using the RKQ Algorithm", arXiv:1111.6996 (2011).
    """

    order = 3

    def __init__(  # noqa: PLR0913 - the OdeSolver interface: SciPy passes these by keyword
        self,
        fun: Callable,
        t0: float,
        y0: Any,
        t_bound: float,
        max_step: float = np.inf,
        rtol: Any = 0.0,
        atol: Any = 1e-6,
        jac: Any = None,
        vectorized: bool = False,
        first_step: float | None = None,
        quench: str = "node",
        quench_threshold: float = 1.0,
        safety: float = 0.9,
        tolerance_rule: str = "componentwise",
        global_error_estimate: str | None = None,
        z_method: str = "dop853",
        gamma_limit: float = 0.05,
        on_step: Callable[[RK34Q8], None] | None = None,
        **extraneous: Any,
    ):
        if extraneous:
            warn(
                "The following arguments have no effect for RK34Q8: "
                + ", ".join(f"`{name}`" for name in extraneous)
            )
        super().__init__(fun, t0, y0, t_bound, vectorized, support_complex=False)
        n = self.n
        atol = tolerance("atol", atol, n, positive=True)
        rtol = tolerance("rtol", rtol, n, positive=False)
        if np.any((rtol > 0) & (rtol < MIN_RTOL)):
            warn(f"rtol is below 100 eps and is raised to {MIN_RTOL:.3g}")
            rtol = np.where((rtol > 0) & (rtol < MIN_RTOL), MIN_RTOL, rtol)
        max_step = float(max_step)
        if not max_step > 0:
            raise InputError(f"max_step must be positive, got {max_step!r}")
        for name, value in (("quench_threshold", quench_threshold), ("safety", safety)):
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive number, got {value!r}")
        if safety > 1:
            raise InputError(f"safety must be at most 1, got {safety!r}")
        if not gamma_limit > 0:
            raise InputError(f"gamma_limit must be positive, got {gamma_limit!r}")
        if on_step is not None and not callable(on_step):
            raise InputError(f"on_step must be callable, got {on_step!r}")
        self._jac = self._wrap_jac(jac)
        if global_error_estimate is None:
            global_error_estimate = "off" if self._jac is None else "tangent"
            if self._jac is None:
                warn(
                    "RK34Q8 without jac cannot estimate the RK8 track's own global error "
                    "(Gamma), so the safeguard that stops a run whose tolerance cannot be "
                    "certified is off; pass jac= to keep it (or "
                    "global_error_estimate='off' to silence this warning)"
                )
        gamma = _GAMMA[choice("global_error_estimate", global_error_estimate, _GAMMA)]
        if gamma != layout.GAMMA_OFF and self._jac is None:
            raise InputError(
                f"global_error_estimate={global_error_estimate!r} needs jac, got None"
            )
        rule = _RULES[choice("tolerance_rule", tolerance_rule, _RULES)]
        if z_method not in Z_METHODS:
            valid = ", ".join(map(repr, Z_METHODS))
            raise OptionError(f"z_method={z_method!r} is not valid; valid values: {valid}")
        self.on_step = on_step
        self.global_error_estimate = global_error_estimate
        # As SciPy's explicit methods expose them (per component here).
        self.atol, self.rtol, self.max_step = atol, rtol, max_step
        # fun as given, for a pickled dense output (SciPy's wrapper of it
        # is a local function, which does not pickle).
        self._plain_rhs = _PlainRhs(fun, vectorized)
        settings = Settings(
            quench=_QUENCH[choice("quench", quench, _QUENCH)],
            rule=rule,
            gamma=gamma,
            safety=float(safety),
            theta=float(quench_threshold),
            max_step=max_step,
            max_steps=NO_STEP_LIMIT,
            gamma_limit=float(gamma_limit),
        )
        jac_inplace = self._jac if self._jac is not None else _no_jacobian
        member = get_member(PAPER_METHOD, z_method)
        self._run = Integration(
            python_functions(self._rhs, jac_inplace),
            member,
            _NO_PARAMS,
            float(t0),
            self.y.astype(float),
            float(t_bound),
            atol,
            rtol,
            settings,
        )
        self._out = layout.allocate_output(1, n, True)
        self._y_old = self._z_old = None
        # The dense output's quench rule and quencher steps, as hamrkq.solve's.
        self._dense_tableaus = dense.dense_tableaus(member)
        rule_codes = [float(np.any(rtol > 0)), rule, settings.theta, member.z_substeps]
        self._dense_tolerance = (atol, rtol, np.array(rule_codes, dtype=float))
        self.quenched = False
        self._start(t0, t_bound, first_step, atol, rtol, max_step)

    # -- set-up ------------------------------------------------------------------
    def _wrap_jac(self, jac: Any) -> Callable | None:
        """``jac`` as an in-place ``jac(t, y, params, out)`` that counts njev."""
        if jac is None:
            return None
        n = self.n
        if callable(jac):

            def evaluate(t, y):
                value = jac(t, y)
                return value.toarray() if hasattr(value, "toarray") else value

        else:
            constant = jac.toarray() if hasattr(jac, "toarray") else np.asarray(jac, float)
            if constant.shape != (n, n):
                raise InputError(f"jac must have shape ({n}, {n}), got {constant.shape}")

            def evaluate(t, y):
                return constant

        def inplace(t, y, params, out):
            self.njev += 1
            # A copy, as SciPy's own methods hand out: y is a reused work
            # buffer, and a jac that keeps it (memoised on (t, y)) would see
            # it overwritten by the next stage.
            out[:, :] = evaluate(t, y.copy())

        return inplace

    def _rhs(self, t, y, params, out):
        # A fresh array per call, as SciPy's own methods give: y is one of
        # the loop's work buffers (stages 2 and 3 share t + h/2 and a buffer),
        # and a fun memoised on (t, y) that keeps y by reference returned
        # stage 2's f for stage 3: a run off by 16 reported SUCCESS.
        out[:] = self.fun(t, y.copy())

    def _start(self, t0, t_bound, first_step, atol, rtol, max_step) -> None:
        run = self._run
        s, work = run.record, run.work
        interval = abs(t_bound - t0)
        if t_bound == t0:
            return
        self._rhs(t0, work.V[U], _NO_PARAMS, work.V[K1])
        s["nfev"] += 1
        finite = bool(np.all(np.isfinite(work.V[K1])))
        # With a non-finite f(t0, y0) the first step recomputes it and fails
        # with a message; otherwise f(t0, y0) is its first stage.
        s["k1_valid"] = int(finite)
        if first_step is not None:
            h0 = float(first_step)
            if not (h0 > 0 and h0 <= interval):
                raise InputError(
                    f"first_step must be positive and at most |t_bound - t0| = {interval!r}, "
                    f"got {first_step!r}"
                )
        elif finite:
            # The config's error exponent is 1/4: the heuristic for order 3.
            h0 = float(initial_step(self._rhs, t0, t_bound, run.inputs, run.config[0], work))
            s["nfev"] += 1
        else:
            h0 = interval
        self.first_step = h0
        s["h"] = self.direction * h0

    # -- stepping ------------------------------------------------------------------

    def _step_impl(self) -> tuple[bool, str | None]:
        run = self._run
        s, work = run.record, run.work
        self._y_old = self.y.copy()
        self._z_old = work.V[ZHI].copy()
        s["nout"] = 0
        # One output row: the kernel returns as soon as one step is accepted.
        while True:
            ret = run.advance(self._out, BUDGET)
            if ret != layout.RET_BUDGET:
                break
        status = int(s["status"])
        if ret == layout.RET_DONE and status != layout.ST_SUCCESS:
            return False, self._failure(_STATUS_BY_CODE[status])
        self.t = float(self._out.t[0])
        self.y = self._out.y[0].copy()
        self.quenched = bool(self._out.quenched[0])
        if self.on_step is not None:
            self.on_step(self)
        return True, None

    def _failure(self, status: Status) -> str:
        s = self._run.record
        t = float(s["t"])
        if status is Status.STEP_SIZE_UNDERFLOW:
            return (
                f"RK34Q8: the step size {abs(s['failed_h']):.3g} fell below the "
                f"roundoff floor at t = {float(t)!r}."
            )
        if status is Status.TOLERANCE_UNATTAINABLE:
            return (
                f"RK34Q8: at t = {float(t)!r} the RK8 track's estimated error plus rounding would "
                f"reach {s['max_ratio']:.3g} x the tolerance (gamma_limit); a smaller "
                "max_step or a shorter interval is what helps."
            )
        return f"RK34Q8: {status.description.rstrip('.')} (t = {float(t)!r})."

    def _dense_output_impl(self) -> StepDenseOutput:
        nodes = dense.DenseOutput(
            np.array([self.t_old, self.t]),
            np.array([self._y_old, self.y]),
            np.array([self._z_old, self._run.work.V[ZHI]]),
            self._rhs,
            self._dense_tableaus,
            _NO_PARAMS,
            recipe=(_step_nodes, (self._plain_rhs, self._dense_tableaus, self._dense_tolerance)),
            tolerance=self._dense_tolerance,
            extrapolate=True,
        )
        return StepDenseOutput(self.t_old, self.t, nodes)

    # -- what SciPy's methods do not have -------------------------------------------
    @property
    def z(self) -> np.ndarray:
        """The RK8 track at ``self.t``."""
        return self._run.work.V[ZHI].copy()

    @property
    def global_error(self) -> np.ndarray:
        """Estimated global error of ``y``: ``y - z`` (numerical minus exact)."""
        return self.y - self._run.work.V[ZHI]

    @property
    def gamma(self) -> np.ndarray | None:
        """Estimated global error of the RK8 track (None when not propagated)."""
        if self.global_error_estimate == "off":
            return None
        return self._run.work.V[GAM].copy()

    @property
    def stats(self) -> dict[str, int]:
        """Accepted and rejected steps, quenches, f and Jacobian evaluations."""
        s = self._run.record
        return {
            "steps": int(s["steps"]),
            "rejected": int(s["rejected"]),
            "quenches": int(s["quenches"]),
            "nfev": int(self.nfev),
            "njev": int(self.njev),
        }


class _PlainRhs:
    """``fun(t, y)`` as the dense output calls it, ``rhs(t, y, params,
    out)``, picklable where ``fun`` is (SciPy's own wrapper of ``fun`` is
    not); ``vectorized`` as SciPy's ``OdeSolver`` takes it."""

    def __init__(self, fun: Callable, vectorized: bool):
        self.fun, self.vectorized = fun, vectorized

    def __call__(self, t, y, params, out):
        if self.vectorized:
            out[:] = np.asarray(self.fun(t, y.copy()[:, None]), dtype=float).ravel()
        else:
            out[:] = np.asarray(self.fun(t, y.copy()), dtype=float)


def _step_nodes(rhs, tableaus, tolerance, t, y, z, certificate) -> dense.DenseOutput:
    """A step's continuous extension rebuilt from a pickle
    (:meth:`hamrkq.rkq.dense.DenseOutput.__reduce__`'s recipe)."""
    return dense.DenseOutput(
        t, y, z, rhs, tableaus, _NO_PARAMS, tolerance=tolerance, certificate=certificate,
        extrapolate=True,
    )  # fmt: skip


class StepDenseOutput(DenseOutput):
    """One step's continuous extension for SciPy: values of
    :class:`hamrkq.rkq.dense.DenseOutput` over the step's two nodes (the RK8
    track stepped from the nearer node, plus ``y - z`` interpolated).  A time
    outside the step is stepped from the nearer node (and ``y - z``
    extrapolated), as SciPy's methods extrapolate their first and last
    steps: ``solve_ivp``'s ``sol(t)`` outside the interval, where no bound
    holds.

    Parameters
    ----------
    t_old, t : float
        Ends of the step.
    nodes : hamrkq.rkq.dense.DenseOutput
        The continuous extension through ``t_old`` and ``t``.
    """

    def __init__(self, t_old: float, t: float, nodes: dense.DenseOutput):
        super().__init__(t_old, t)
        self.nodes = nodes

    def _call_impl(self, t):
        return self.nodes(t)


def _no_jacobian(t, y, params, out):  # pragma: no cover - never called with Gamma off
    raise InputError("this solver has no Jacobian")
