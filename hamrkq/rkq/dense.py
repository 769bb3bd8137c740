"""Dense output by re-stepping: the solution between nodes from one quencher step.

For ``t_i <= t <= t_{i+1}``, ``y(t)`` is the member's quencher tableau
(order 8-12; the pair's high-order method for a member without one) over
``t - t_j`` from the quencher track's node ``z_j`` nearer to ``t``
(backward from ``t_{i+1}`` in the second half of the interval), in steps
no longer than the run's quencher took there
(:func:`hamrkq.rkq.steps.dense_substeps`), plus the difference ``y - z``
of the two nodes interpolated linearly:

    y(t) = z_j + steps(z_j, t - t_j) + (1 - w) (y_i - z_i) + w (y_{i+1} - z_{i+1}),
    w = (t - t_i) / (t_{i+1} - t_i),

and ``y_j`` itself at a node.  No state is added to the kernel: every node
the run kept is a starting point.  The quencher's value carries its own
error (Gamma, at most ``gamma_limit`` of the tolerance) over at most half a
step, and the interpolated difference is at most the larger of the two
nodes' ``|y - z|`` (below the tolerance, or the node was quenched): the
nodes' bound holds between them.  Stepping from ``y_j`` instead, as the
first versions did, carried ``y_j``'s error, up to the tolerance, through
the flow over half a step, which the long steps of the family's
higher-order pairs stretch: ``auto`` reached 1.19 delta on prentice2011 at
1e-6 (``docs/events.md``).  Without a quencher track (``z`` not given, or a
member without one) it steps from ``y_j``.

:func:`evaluate` is ``@jitable``: it runs interpreted, or compiled by numba
(:mod:`hamrkq.backends.extras`) with the compiled right-hand side.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from hamrkq._floats import EPS
from hamrkq.errors import warn
from hamrkq.rkq import steps
from hamrkq.rkq.family import Member
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import RULE_PRENTICE, TMP, TMP2, ZHI, ZLO, Tableaus, allocate_work

__all__ = [
    "DenseOutput",
    "attainability",
    "dense_tableaus",
    "evaluate",
    "node_index",
    "prepare_work",
]


@jitable
def evaluate(  # noqa: PLR0913 - the kernel's convention: arrays, no objects
    rhs, tab, params, t_nodes, y_nodes, z_nodes, index, tq, atol, rtol, rule, work, out
):
    """``out[k] = y(tq[k])``: ``tab``'s quencher over ``tq[k] -
    t_nodes[index[k]]`` from ``z_nodes[index[k]]``, in steps no longer than
    the run's (``rule[3]`` quencher steps per step of the pair,
    :func:`hamrkq.rkq.steps.dense_substeps`), plus ``y - z``
    of the two nodes around ``tq[k]`` interpolated linearly, or the
    quencher's value alone where that difference exceeds ``theta`` times the
    tolerance there (:func:`hamrkq.rkq.steps.dense_value`; ``rule`` is
    ``(relative, tolerance rule, theta, m)``); ``z_nodes`` is ``y_nodes`` where
    there is no quencher track.  Returns the number of right-hand-side
    evaluations."""
    tab, work = borrow(tab), borrow(work)
    d = y_nodes.shape[1]
    last = t_nodes.shape[0] - 1
    relative, tolerance_rule, theta, m = int(rule[0]), int(rule[1]), rule[2], int(rule[3])
    nfev = 0
    for k in range(tq.shape[0]):
        j = index[k]
        h = tq[k] - t_nodes[j]
        if h == 0.0:
            for c in range(d):
                out[k, c] = y_nodes[j, c]
            continue
        # The interval [t_i, t_i + 1] around tq[k]: j is one of its ends.
        forward = (h > 0.0) == (t_nodes[last] >= t_nodes[0])
        i = j if forward else j - 1
        i = min(max(i, 0), last - 1)
        w = (tq[k] - t_nodes[i]) / (t_nodes[i + 1] - t_nodes[i])
        zhi, zlo, gap = work.V[ZHI], work.V[ZLO], work.V[TMP]
        for c in range(d):
            zhi[c] = z_nodes[j, c]
            zlo[c] = 0.0
            gap[c] = (1.0 - w) * (y_nodes[i, c] - z_nodes[i, c]) + w * (
                y_nodes[i + 1, c] - z_nodes[i + 1, c]
            )
        substeps = steps.dense_substeps(h, t_nodes[i + 1] - t_nodes[i], m)
        evaluations, _ = steps.dense_value(
            rhs, t_nodes[j], zhi, zlo, h, substeps, tab, params, gap, atol, rtol, relative,
            tolerance_rule, theta, work, out[k], work.V[TMP2],
        )  # fmt: skip
        nfev += evaluations
    return nfev


def dense_tableaus(member: Member) -> Tableaus:
    """The tableau the dense output steps with: the member's quencher, or the
    pair's reported (high-order) method for a member without one."""
    tab = member.tableaus
    if member.use_z:
        return tab
    # The pair's coefficients are plain doubles (its low words are not kept).
    return tab._replace(
        Az=tab.A, bz=tab.b, cz=tab.c, Az_low=np.zeros_like(tab.A), bz_low=np.zeros_like(tab.b)
    )


def prepare_work(d: int, tab: Tableaus):
    """Work arrays for :func:`evaluate` on a state of ``d`` components."""
    return allocate_work(np.zeros(d), tab.b.shape[0], tab.bz.shape[0])


def attainability(
    times: np.ndarray,
    values: np.ndarray,
    t_nodes: np.ndarray,
    nodes: np.ndarray,
    gamma: np.ndarray,
    tolerance: tuple,
    rounding: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For each dense value ``values[j]`` at ``times[j]`` (an event state,
    a value of ``sol.sol``): ``max_k (|Gamma_k| + rho_k + eps u_k) /
    delta_k``, Gamma the quencher's estimated error interpolated linearly
    between the nodes ``t_nodes`` around the time (as the kernel
    interpolates it at an output time inside a step,
    :func:`hamrkq.rkq.certify.dense_attainability`), ``rho`` the quencher's
    rounding, modelled and measured, at the later of the two nodes
    (``rounding``, per node; it only grows along a run), ``eps u_k`` the
    value's own rounding: it is stepped in double from a node's stored
    double (``nodes``, the quencher track at ``t_nodes``), so ``u_k`` is the
    largest of ``|y_k|`` and the two nodes' ``|z_k|`` (an ulp of the value
    alone says nothing where the component crosses zero); ``delta`` the
    tolerance at the value (``tolerance``: the run's ``(atol, rtol,
    (relative, rule, theta, m))``).  The promise holds at the value where
    this is at most ``gamma_limit``.  Returns that ratio, its rounding's
    part ``(rho_k + eps u_k) / delta_k``, the component ``k`` it is largest
    at, and ``max_k eps u_k / delta_k``, the value's own rounding alone
    (which neither more quencher steps nor a quencher in double-double
    reduce), one entry per value.  Under
    ``rtol`` a value where a component crosses zero sits where that
    component's tolerance is ``atol`` alone, far below the nodes' on either
    side, which is why the nodes' check does not cover it."""
    if times.size == 0:
        return np.empty(0), np.empty(0), np.empty(0), np.empty(0, dtype=np.int64)
    atol, rtol, rule = tolerance
    forward = t_nodes[-1] >= t_nodes[0]
    s, x = (t_nodes, times) if forward else (-t_nodes, -times)
    i = np.clip(np.searchsorted(s, x, side="right") - 1, 0, max(t_nodes.size - 2, 0))
    after = np.minimum(i + 1, t_nodes.size - 1)
    span = s[after] - s[i]
    w = np.divide(x - s[i], span, out=np.zeros_like(x), where=span != 0)[:, None]
    stored = EPS * np.maximum(np.abs(values), np.maximum(np.abs(nodes[i]), np.abs(nodes[after])))
    share = stored if rounding is None else stored + np.maximum(rounding[i], rounding[after])
    estimate = np.abs((1.0 - w) * gamma[i] + w * gamma[after]) + share
    # arith.tolerance, row by row: max(atol, rtol |y|) (atol alone without
    # rtol); the paper's scalar rule takes the smallest component's
    delta = (
        np.maximum(atol, rtol * np.abs(values)) if rule[0] else np.broadcast_to(atol, values.shape)
    )
    if int(rule[1]) == RULE_PRENTICE:
        delta = np.broadcast_to(delta.min(axis=1, keepdims=True), values.shape)
    ratio = estimate / delta
    k = np.argmax(ratio, axis=1)[:, None]
    return (
        np.take_along_axis(ratio, k, axis=1)[:, 0],
        np.take_along_axis(share / delta, k, axis=1)[:, 0],
        k[:, 0],
        np.max(stored / delta, axis=1),
    )


#: How far (in units of the last place of the larger end's time) a query
#: time may lie outside the nodes and still be a time of the run: times
#: computed in floating point miss the end by an ulp (``np.arange(4) * 0.1``
#: ends at 0.30000000000000004 for a run to 0.3, which SciPy evaluates).
END_SLACK_ULPS = 4


def node_index(
    t_nodes: np.ndarray, tq: np.ndarray, nearest: bool = True, extrapolate: bool = False
) -> np.ndarray:
    """For each query time the node it is stepped from: the nearer of the two
    nodes around it (``nearest``; a step backward from the later one, so that
    no value is more than half a step from its node), or the last node at or
    before it in the direction of integration (``t_nodes`` monotonic).
    Raises ValueError for a time outside ``[t_nodes[0], t_nodes[-1]]`` by
    more than :data:`END_SLACK_ULPS` ulps, unless ``extrapolate`` (then such
    a time is stepped from the nearer end, as SciPy's dense output
    extrapolates its first and last steps), and for one that is not finite."""
    forward = t_nodes[-1] >= t_nodes[0]
    s = t_nodes if forward else -t_nodes
    x = tq if forward else -tq
    slack = END_SLACK_ULPS * np.spacing(max(abs(float(s[0])), abs(float(s[-1]))))
    bad = ~np.isfinite(x)
    if not extrapolate:
        bad |= (x < s[0] - slack) | (x > s[-1] + slack)
    if np.any(bad):
        first = float(tq[np.argmax(bad)])
        raise ValueError(
            f"t={first!r} is outside the integrated interval "
            f"[{float(t_nodes[0])!r}, {float(t_nodes[-1])!r}]"
        )
    index = np.clip(np.searchsorted(s, x, side="right") - 1, 0, t_nodes.size - 1)
    if nearest:
        after = np.minimum(index + 1, t_nodes.size - 1)
        index = np.where(s[after] - x < x - s[index], after, index)
    return index.astype(np.int64)


class DenseOutput:
    """The continuous solution ``sol(t)`` of one run (SciPy's ``OdeSolution``
    convention: a scalar ``t`` gives shape ``(2n,)``, an array of ``m`` times
    gives ``(2n, m)``).

    Parameters
    ----------
    t, y : ndarray
        Every node of the run (time-major ``y``, as :attr:`Solution.y`).
    z : ndarray, optional
        The quencher track at the same nodes (:attr:`Solution.z`): the
        values are stepped from it (module docstring); from ``y`` without.
    rhs : callable
        ``rhs(t, y, params, out)``, interpreted or compiled.
    tableaus : Tableaus
        From :func:`dense_tableaus`.
    params : ndarray
    compiled : callable, optional
        :func:`evaluate` compiled for these argument types (by
        :func:`hamrkq.backends.extras.compiled_helper`); interpreted without.
    recipe : tuple, optional
        ``(build, args)`` with ``build(*args, t, y, z, certificate)`` returning this dense
        output: how a pickled copy is rebuilt (compiled functions and the
        interpreted backend's closures do not pickle; the recipe's
        Hamiltonian and method do).  Without it the copy is rebuilt from
        ``rhs``, interpreted.
    tolerance : tuple, optional
        ``(atol, rtol, rule)`` of the run, ``rule`` as :func:`evaluate`
        takes it: a value whose interpolated ``y - z`` exceeds the tolerance
        there is the quencher's (:func:`hamrkq.rkq.steps.dense_value`).
        Without it, never.
    certificate : tuple, optional
        ``(gamma, rounding, gamma_limit)`` of the run: Gamma and the
        quencher's rounding at each node (``rounding`` may be None) and the
        limit the run held them to.  With it, :meth:`values` (and calling
        the object) checks each value as the run checks an output time
        (:func:`attainability`) and warns (``HamrkqWarning``) where that
        fails: under ``rtol``, where a component passes zero between two
        nodes, its tolerance is ``atol`` alone, below the nodes'.
    extrapolate : bool
        Whether a time outside the nodes is stepped from the nearer end
        (SciPy's ``OdeSolver`` steps, :mod:`hamrkq.rkq.scipy_solver`) instead
        of refused (:func:`node_index`).
    """

    def __init__(  # noqa: PLR0913 - a run's arrays, functions and rules
        self,
        t: np.ndarray,
        y: np.ndarray,
        z: np.ndarray | None,
        rhs: Callable,
        tableaus: Tableaus,
        params: np.ndarray,
        compiled: Callable | None = None,
        recipe: tuple[Callable, tuple] | None = None,
        tolerance: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        certificate: tuple | None = None,
        extrapolate: bool = False,
    ):
        self.t = np.array(t, dtype=np.float64, order="C")
        self.y = np.array(y, dtype=np.float64, order="C")
        self.z = None if z is None else np.array(z, dtype=np.float64, order="C")
        if self.t.size == 0:
            raise ValueError("dense output needs at least one node")
        if self.z is not None and self.z.shape != self.y.shape:
            raise ValueError(f"z has shape {self.z.shape}, y {self.y.shape}")
        self.t_min, self.t_max = float(self.t.min()), float(self.t.max())
        self._rhs = rhs
        self._tab = tableaus
        self._params = np.require(params, np.float64, ("C", "W"))
        self._compiled = compiled
        self._evaluate = compiled if compiled is not None else evaluate
        self._recipe = recipe
        d = self.y.shape[1]
        if tolerance is None:  # no quench rule (theta = inf), one quencher step a step
            tolerance = (np.ones(d), np.zeros(d), np.array([0.0, 0.0, np.inf, 1.0]))
        self._tolerance = tuple(np.array(a, dtype=np.float64, order="C") for a in tolerance)
        self._count = threading.Lock()
        self.nfev = 0
        self._certificate = certificate
        #: Whether a time outside the nodes is stepped from the nearer end
        #: (:func:`node_index`) instead of refused.
        self.extrapolate = extrapolate

    def through(
        self, t: np.ndarray, y: np.ndarray, z: np.ndarray | None, certificate: tuple | None = None
    ) -> DenseOutput:
        """The same continuous extension through other nodes (a truncated
        run; ``z`` its quencher track, or None to step from ``y``;
        ``certificate`` for those nodes, or None: no check)."""
        return DenseOutput(
            t, y, z, self._rhs, self._tab, self._params, self._compiled, self._recipe,
            self._tolerance, certificate, self.extrapolate,
        )  # fmt: skip

    @property
    def certificate(self) -> tuple | None:
        """``(gamma, rounding, gamma_limit)`` the values are checked against, or None."""
        return self._certificate

    def __reduce__(self):
        if self._recipe is not None:
            build, args = self._recipe
            return (build, (*args, self.t, self.y, self.z, self._certificate))
        return (
            DenseOutput,
            (self.t, self.y, self.z, self._rhs, self._tab, self._params, None, None,
             self._tolerance, self._certificate, self.extrapolate),
        )  # fmt: skip

    def values(self, t) -> np.ndarray:
        """Time-major values: shape ``(m, 2n)`` for ``m`` times.  Warns
        (``HamrkqWarning``) where a value cannot be certified (the
        ``certificate``)."""
        tq = np.array(np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel(), order="C")
        out = self.values_unchecked(tq)
        if self._certificate is not None:
            self._check(tq, out)
        return out

    def _check(self, tq: np.ndarray, out: np.ndarray) -> None:
        gamma, rounding, limit = self._certificate
        if not limit < np.inf or self.t.size < 2:
            return
        nodes = self.y if self.z is None else self.z
        ratios = attainability(tq, out, self.t, nodes, gamma, self._tolerance, rounding)[0]
        bad = np.flatnonzero(~(ratios <= limit))
        if bad.size == 0:
            return
        first = int(bad[0])
        warn(
            f"sol.sol: {bad.size} of {tq.size} values cannot be certified (the first at "
            f"t = {float(tq[first])!r}: the quencher's estimated error and rounding there are "
            f"{float(ratios[first]):.3g} x the tolerance at the value, above gamma_limit = "
            f"{limit:g}; under rtol a component passing zero between two nodes has the "
            "tolerance atol alone there, below the nodes'). Ask for these times with t_eval, "
            "which the run checks (and auto runs again where needed), or give atol the size "
            "of the error acceptable near zero."
        )

    def values_unchecked(self, t) -> np.ndarray:
        """:meth:`values` without the certificate's check (the event states,
        checked on their own by :mod:`hamrkq.solve.event_check`, and the
        points a root finder tries)."""
        tq = np.array(np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel(), order="C")
        out = np.empty((tq.size, self.y.shape[1]))
        if tq.size:
            index = node_index(self.t, tq, extrapolate=self.extrapolate)
            # Work arrays of this call's own (about 9 us): the compiled
            # evaluation runs without the GIL, so threads evaluating one
            # solution at once would otherwise share, and corrupt, them.
            work = prepare_work(self.y.shape[1], self._tab)
            z = self.y if self.z is None else self.z
            nfev = self._evaluate(
                self._rhs, self._tab, self._params, self.t, self.y, z, index, tq,
                *self._tolerance, work, out,
            )  # fmt: skip
            with self._count:
                self.nfev += int(nfev)
        return out

    def __call__(self, t) -> np.ndarray:
        values = self.values(t)
        if np.ndim(t) == 0:
            return values[0]
        return values.T.reshape((self.y.shape[1], *np.shape(t)))

    def __repr__(self) -> str:
        return f"DenseOutput(nodes={self.t.size}, t=[{float(self.t[0])!r}, {float(self.t[-1])!r}])"
