"""The methods :func:`hamrkq.solve` dispatches to, and the request each one receives.

:class:`Task` is a validated request; :class:`MethodSpec` describes one method
(its runner, the backends it has, whether it carries the RK8 track);
:data:`METHODS` maps every method name to its spec: the RKQ family (the
kernel of :mod:`hamrkq.rkq`, interpreted or compiled), the fixed-step
baselines of :mod:`hamrkq.fixed_step` and the SciPy baselines of
:mod:`hamrkq.baselines`.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.backends.numeric import numeric_of
from hamrkq.baselines import PREFIX as SCIPY_PREFIX
from hamrkq.baselines import SCIPY_SOLVER_HOMES
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS, solve_fixed
from hamrkq.options import SolveOptions
from hamrkq.result import Solution
from hamrkq.rkq.driver import (
    BUDGET,
    Integration,
    RunOutput,
    Settings,
    python_functions,
)
from hamrkq.rkq.family import MEMBERS, PAPER_METHOD
from hamrkq.rkq.witness_rules import needs_witness, time_rounding_matters
from hamrkq.solve.shadow import within_linear_shadow
from hamrkq.symbolic.hamiltonian import Hamiltonian

if TYPE_CHECKING:
    from hamrkq.backends.background import BackgroundCompile

__all__ = [
    "METHODS",
    "TERMINAL_BUDGET",
    "MethodSpec",
    "Task",
    "can_witness",
    "dense_tolerance",
    "integration",
    "member_of",
    "resolve_backend",
    "run_rk",
    "start_background",
    "time_rounding_limits",
    "time_scale",
    "uses_witness",
    "witness_rule_arguments",
]

#: Step attempts between checks for a terminal event.
TERMINAL_BUDGET = 64


@dataclass(frozen=True)
class Task:
    """A validated integration request, handed to a method's runner."""

    ham: Hamiltonian
    params: np.ndarray
    t0: float
    t_end: float
    y0: np.ndarray
    atol: np.ndarray
    rtol: np.ndarray
    options: SolveOptions
    t_eval: np.ndarray | None
    progress: Callable[[float, float], None] | None
    #: Makes the terminal events' ``stop(t, y)`` for a run
    #: (:func:`hamrkq.events.terminal_watch`), or None.
    stop: Callable[[], Callable[[np.ndarray, np.ndarray], bool]] | None = None
    #: On the "numba" backend, the helper compiling the code meanwhile
    #: (:mod:`hamrkq.backends.background`): the run starts interpreted.
    compiling: BackgroundCompile | None = None
    #: Abandon the run when Gamma projected to t_end fails (``method="auto"``,
    #: which then runs again: :func:`hamrkq.rkq.auto_rules.auto_abandon_substeps`).
    project: bool = False
    #: Run the rounding witness whatever the tolerance (``method="auto"``'s
    #: rerun of an orbit whose error grows exponentially:
    #: :func:`hamrkq.rkq.auto_rules.error_growth`); None: by the tolerance
    #: (:func:`hamrkq.rkq.witness_rules.needs_witness`).
    witness: bool | None = None
    #: Where the run before this one (``method="auto"``'s) ended, if its
    #: estimate grew exponentially (:func:`hamrkq.rkq.auto_rules.error_growth`),
    #: else None; a second such run in a row that reaches further makes auto
    #: measure the rounding instead of adding quencher steps
    #: (:func:`hamrkq.solve.auto.reads_growth_again`).
    exponential_until: float | None = None
    #: A run of this time-dependent H with the quencher in double-double read
    #: an exponential growth: the rounding of its stage times (doubles),
    #: amplified, is not measured there, so auto keeps the quencher in
    #: double with the witness from then on (:func:`hamrkq.solve.auto.rerun`).
    stage_times_amplified: bool = False
    #: Where auto's run in double before this one stopped at double
    #: precision's floor, after which the quencher runs in double-double
    #: (:func:`hamrkq.solve.auto.rerun`); else None.  What a stop's message
    #: offers in double must reach further than that.
    double_floor_at: float | None = None
    #: Run for ``method="auto"`` (``options.method`` is the member it chose).
    auto: bool = False
    #: The caller's ``t_eval`` where events or dense output need every node:
    #: the run keeps every node (``t_eval`` is then None), its values at these
    #: times are dense output, checked as the kernel checks an output time
    #: (:mod:`hamrkq.solve.output_times`), and they are the rows returned.
    output_times: np.ndarray | None = None

    @property
    def requested_times(self) -> np.ndarray | None:
        """The ``t_eval`` the caller gave: the kernel's, or the times sampled
        from the dense output (:attr:`output_times`)."""
        return self.t_eval if self.output_times is None else self.output_times

    @property
    def grew_exponentially(self) -> bool:
        """Whether the run before this one read an exponential growth."""
        return self.exponential_until is not None

    def projecting(self) -> Task:
        """This task with ``project=True``, its :attr:`runs_witness` carried
        over when known (the projection does not change it)."""
        task = replace(self, project=True)
        if "runs_witness" in self.__dict__:
            task.__dict__["runs_witness"] = self.runs_witness
        return task

    @functools.cached_property
    def runs_witness(self) -> bool:
        """:func:`uses_witness` of this task, computed once: a task does not
        change (another run is another task, ``replace``), and a call of
        :func:`hamrkq.solve` asked it four times (2 us each with the shadow
        estimate)."""
        return _witness_rule(self)


@dataclass(frozen=True)
class MethodSpec:
    """A method :func:`hamrkq.solve` can dispatch to.

    ``run(task, backend) -> RunOutput`` (or a finished
    :class:`~hamrkq.result.Solution`, for the baselines); ``rk8`` says whether
    the method produces the quencher track (``z``, ``gamma``, ``quenched``).
    """

    name: str
    summary: str
    run: Callable[[Task, str], RunOutput | Solution]
    backends: tuple[str, ...]
    rk8: bool


def member_of(task: Task):
    return task.options.member()


def dense_tolerance(task: Task) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(atol, rtol, (relative, rule, theta, m))`` of a task, as its dense
    output's quench rule takes them, with the quencher's steps per step of
    the pair (:class:`hamrkq.rkq.dense.DenseOutput`, the kernel's
    configuration for the same run)."""
    o = task.options
    relative = float(np.any(task.rtol > 0))
    m = float(member_of(task).z_substeps)
    return task.atol, task.rtol, np.array([relative, o.codes()["rule"], o.quench_threshold, m])


def can_witness(options: SolveOptions) -> bool:
    """Whether a run with these options can run the rounding witness: the
    shadow's or the tangent's estimate, the quencher in double."""
    return options.gamma_name in ("shadow", "tangent") and not options.double_double


def uses_witness(task: Task) -> bool:
    """Whether an RKQ-family task runs the rounding witness (remembered by
    the task, :attr:`Task.runs_witness`): the shadow's or the tangent's
    estimate at a tolerance near double precision's floor, or with a
    quencher whose weights magnify its stages' rounding (:func:`needs_witness`;
    not for the paper's method ``rk34q8`` with the tangent estimate, its
    default, so that its runs at the paper's tolerances stay the paper's);
    or where a run is made again with it (``Task.witness``: after a run whose
    rounding could have reached the tolerance,
    :func:`hamrkq.solve.auto.witness_rerun_needed`).  The paper's own
    estimate never runs it."""
    return task.runs_witness


def _witness_rule(task: Task) -> bool:
    """:func:`uses_witness`, computed."""
    if task.witness is not None and can_witness(task.options):
        return task.witness
    rule = witness_rule_arguments(task)
    return rule is not None and needs_witness(task.atol, task.rtol, task.y0, **rule)


def witness_rule_arguments(task: Task) -> dict[str, Any] | None:
    """What, besides the tolerances and the state, decides whether ``task``
    runs the rounding witness from the start
    (:func:`~hamrkq.rkq.witness_rules.needs_witness` and its per-row form,
    which the ensemble's batch loop asks for each member): its keywords, or
    None where the estimate cannot run the witness (:func:`can_witness`).

    The tangent estimate follows the shadow's rule (it sees rounding no
    better: a ``max_step``, which makes it a member's default, turned a stop
    at the floor into SUCCESS 1.09 tolerances off, QA), except that the
    paper's method, whose quencher is DOP853's, runs the witness only near
    the floor: its runs at the paper's tolerances stay the paper's."""
    if not can_witness(task.options):
        return None
    member = member_of(task)
    paper = task.options.gamma_name == "tangent" and member.name == PAPER_METHOD
    return {
        "stage_rounding": member.stage_rounding_dominates and not paper,
        "substeps": member.z_substeps,
        "time_scale": time_scale(task),
    }


def time_scale(task: Task) -> float:
    """The largest ``|t|`` of ``task``'s run where Hamilton's equations
    depend on the time, else 0 (:func:`hamrkq.rkq.witness_rules.time_rounding_matters`)."""
    if not task.ham.equations_time_dependent:
        return 0.0
    return max(abs(task.t0), abs(task.t_end))


def time_rounding_limits(task: Task) -> bool:
    """Whether the rounding of ``task``'s stage times could reach its
    tolerance (:func:`hamrkq.rkq.witness_rules.time_rounding_matters`): the
    witness then runs, and the quencher in double-double, whose stage times
    are doubles too, does not go below that floor."""
    return time_rounding_matters(task.atol, task.rtol, task.y0, time_scale(task))


def _double_double_functions(task: Task, backend: str):
    """The kernel's functions with ``rhs_dd`` (f in double-double,
    :mod:`hamrkq.backends.dd_printer`) where the tangent goes."""
    from hamrkq.backends import codegen

    if backend == "numba" and task.compiling is not None:
        # auto's rerun in double-double after a first run that started
        # interpreted: wait for the helpers and load what they compiled, rather
        # than compile the kernel and the system again beside them (and then
        # report the compiled rerun as interpreted).
        task.compiling.wait()
        if task.compiling.functions("shadow") is None:  # unusable: warned once
            backend = "python"
    if backend == "numba":
        from hamrkq.backends import first_use

        return first_use.double_double_functions(task.ham)
    numeric = numeric_of(task.ham)
    functions = python_functions(_inplace(numeric.rhs, False), _inplace(numeric.jac, True))
    return functions._replace(tangent=codegen.load_module(task.ham).rhs_dd)


def integration(task: Task, backend: str) -> Integration:
    """The :class:`~hamrkq.rkq.driver.Integration` of an RKQ-family task on
    ``backend`` ("numba" or "python"), ready to run."""
    o = task.options
    settings = Settings(
        **o.codes(),
        safety=o.safety,
        theta=o.quench_threshold,
        max_step=o.max_step,
        max_steps=o.max_steps,
        gamma_limit=o.gamma_limit,
        keep_every=o.keep_every,
        t_eval=task.t_eval,
        first_step=o.first_step,
        witness=uses_witness(task),
        project=task.project,
        double_double=o.double_double,
    )
    functions, upgrade = None, None
    # The compiled rhs_jvp and jac only where the estimate of Gamma calls them.
    gamma = o.gamma_name
    if o.double_double:
        functions = _double_double_functions(task, backend)
    elif backend == "numba" and task.compiling is None:
        from hamrkq.backends import first_use

        functions = first_use.kernel_functions(task.ham, gamma)
    elif backend == "numba":
        # The helper's compiled code if it is ready; else start interpreted
        # and ask again between chunks.
        functions = task.compiling.functions(gamma)
        if functions is None:
            upgrade = functools.partial(task.compiling.functions, gamma)
    if functions is None:
        numeric = numeric_of(task.ham)
        functions = python_functions(_inplace(numeric.rhs, False), _inplace(numeric.jac, True))
    return Integration(
        functions,
        member_of(task),
        task.params,
        task.t0,
        task.y0,
        task.t_end,
        task.atol,
        task.rtol,
        settings,
        upgrade,
    )


def run_rk(task: Task, backend: str) -> RunOutput:
    """Run an RKQ-family task (the runner of every family member in :data:`METHODS`)."""
    started = time.perf_counter()
    run = integration(task, backend)
    # Loading the functions, or compiling them (f in double-double on its
    # first use), is the run's compiling, not its integration.
    building_s = time.perf_counter() - started
    # A new terminal watch for each run: it counts the crossings it sees.
    stop = task.stop() if task.stop is not None else None
    # With a terminal event, shorter chunks: the run stops soon after the event.
    out = run.run(task.progress, budget=TERMINAL_BUDGET if stop else BUDGET, stop=stop)
    out.stats["integrate_s"] = run.integrate_s
    out.stats["compile_wait_s"] = building_s + run.upgrade_s
    if task.compiling is not None:
        out.stats["interpreted_steps"] = run.steps_before_upgrade
    return within_linear_shadow(task, out)


def _inplace(fun: Callable, matrix: bool) -> Callable:
    """``fun(t, y, params) -> array`` as ``fun(t, y, params, out)``."""
    if matrix:

        def wrapped(t, y, params, out):
            out[:, :] = fun(t, y, params)

    else:

        def wrapped(t, y, params, out):
            out[:] = fun(t, y, params)

    return wrapped


def resolve_backend(
    backend: str, ham: Hamiltonian, spec: MethodSpec, gamma: str = "tangent"
) -> str:
    """``"auto"`` -> ``"numba"`` when the method has a compiled runner and
    numba can be used (else ``"python"``, with one HamrkqWarning when numba
    was expected but cannot be used); compiles what a run with the estimate
    of Gamma ``gamma`` calls (:func:`hamrkq.backends.first_use.kernel_functions`)."""
    if backend == "python" or "numba" not in spec.backends:
        return "python" if backend == "auto" else backend
    from hamrkq.backends import first_use

    return first_use.resolve_backend(backend, ham, gamma)


def start_background(
    backend: str, ham: Hamiltonian, spec: MethodSpec, gamma: str = "tangent"
) -> BackgroundCompile | None:
    """With ``backend="auto"`` and a method that has a compiled runner, the
    helper compiling ``ham``'s code on a first use while the run starts
    interpreted (:func:`hamrkq.backends.background.start`); None when there
    is nothing to compile, or the compile should be waited for.  ``gamma``:
    the run's estimate of Gamma."""
    if backend != "auto" or "numba" not in spec.backends:
        return None
    from hamrkq.backends import background

    return background.start(ham, gamma)


def _run_fixed(task: Task, backend: str) -> Solution:
    o = task.options
    return solve_fixed(
        task.ham,
        task.y0,
        (task.t0, task.t_end),
        o.method,
        o.step,
        task.params,
        keep_every=o.keep_every,
        max_steps=o.max_steps,
    )


#: Options of :func:`hamrkq.solve` that hamrkq's RK34Q8 takes in its SciPy form too.
_RKQ_OPTIONS = (
    "quench",
    "quench_threshold",
    "safety",
    "tolerance_rule",
    "global_error_estimate",
    "z_method",
    "gamma_limit",
)


def _run_scipy(task: Task, backend: str) -> Solution:
    from hamrkq.baselines.scipy_ivp import solve_scipy  # imports scipy.integrate: 0.3 s

    o = task.options
    name = o.method[len(SCIPY_PREFIX) :]
    return solve_scipy(
        task.ham,
        task.y0,
        (task.t0, task.t_end),
        name,
        task.params,
        atol=task.atol,
        rtol=task.rtol,
        first_step=o.first_step,
        max_step=o.max_step,
        max_steps=o.max_steps,
        keep_every=o.keep_every,
        t_eval=task.t_eval,
        progress=task.progress,
        options=(
            {k: v for k in _RKQ_OPTIONS if (v := getattr(o, k)) is not None}
            if name == "RK34Q8"
            else None
        ),
    )


_FIXED_SUMMARIES = {
    "midpoint": "implicit midpoint rule, fixed step (symplectic, order 2)",
    "gauss4": "2-stage Gauss-Legendre collocation, fixed step (symplectic, order 4)",
    "gauss6": "3-stage Gauss-Legendre collocation, fixed step (symplectic, order 6)",
    "verlet": "Stormer-Verlet, fixed step (symplectic, order 2; separable H only)",
    "yoshida4": "Yoshida's triple jump of Verlet, fixed step (symplectic, order 4; separable H)",
}

#: Dispatch table: method name -> :class:`MethodSpec`.
METHODS: dict[str, MethodSpec] = {
    **{
        name: MethodSpec(name, member.summary, run_rk, ("python", "numba"), member.use_z)
        for name, member in MEMBERS.items()
    },
    **{
        name: MethodSpec(name, _FIXED_SUMMARIES[name], _run_fixed, ("python",), rk8=False)
        for name in FIXED_STEP_METHODS
    },
    **{
        SCIPY_PREFIX + name: MethodSpec(
            SCIPY_PREFIX + name,
            f"SciPy solver {home}.{name}",
            _run_scipy,
            ("python",),
            rk8=name == "RK34Q8",
        )
        for name, home in SCIPY_SOLVER_HOMES.items()
    },
}
