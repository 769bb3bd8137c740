"""Dense output by re-stepping: the solution between nodes from one quencher step.

``y(t)`` for ``t_i <= t <= t_{i+1}`` is one step of the member's quencher
tableau (order 8-12; the pair's high-order method for a member without one) of
size ``t - t_j`` from the reported node ``y_j`` nearer to ``t`` (backward from
``t_{i+1}`` in the second half of the interval).  No state is added to the
kernel: every node the run kept is a starting point.  The error of the value
is ``y_j``'s (at most the tolerance delta at the node, RKQ's promise) carried
over at most half a step, plus the local error of that partial step of a
high-order method; ``docs/events.md`` gives the measured worst cases (within
1.03 delta on Kepler e = 0.6 and Prentice's problem).

:func:`evaluate` is ``@jitable``: it runs interpreted, or compiled by numba
(:mod:`hamrkq.backends.extras`) with the compiled right-hand side.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from hamrkq.rkq import steps
from hamrkq.rkq.family import Member
from hamrkq.rkq.jit import borrow, jitable
from hamrkq.rkq.layout import INC, ZHI, ZLO, Tableaus, allocate_work

__all__ = ["DenseOutput", "dense_tableaus", "evaluate", "node_index", "prepare_work"]


@jitable
def evaluate(rhs, tab, params, t_nodes, y_nodes, index, tq, work, out):
    """``out[k] = y(tq[k])``: one step of ``tab``'s quencher of size
    ``tq[k] - t_nodes[index[k]]`` from ``y_nodes[index[k]]``.  Returns the
    number of right-hand-side evaluations."""
    tab, work = borrow(tab), borrow(work)
    d = y_nodes.shape[1]
    nfev = 0
    for k in range(tq.shape[0]):
        i = index[k]
        h = tq[k] - t_nodes[i]
        if h == 0.0:
            for c in range(d):
                out[k, c] = y_nodes[i, c]
            continue
        zhi, zlo, inc = work.V[ZHI], work.V[ZLO], work.V[INC]
        for c in range(d):
            zhi[c] = y_nodes[i, c]
            zlo[c] = 0.0
        nfev += steps.explicit_increment(
            rhs, t_nodes[i], zhi, zlo, h, tab, params, work, inc, False
        )
        for c in range(d):
            out[k, c] = y_nodes[i, c] + inc[c]
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


def node_index(t_nodes: np.ndarray, tq: np.ndarray, nearest: bool = True) -> np.ndarray:
    """For each query time the node it is stepped from: the nearer of the two
    nodes around it (``nearest``; a step backward from the later one, so that
    no value is more than half a step from its node), or the last node at or
    before it in the direction of integration (``t_nodes`` monotonic).
    Raises ValueError for a time outside ``[t_nodes[0], t_nodes[-1]]``."""
    forward = t_nodes[-1] >= t_nodes[0]
    s = t_nodes if forward else -t_nodes
    x = tq if forward else -tq
    bad = (x < s[0]) | (x > s[-1]) | ~np.isfinite(x)
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
    rhs : callable
        ``rhs(t, y, params, out)``, interpreted or compiled.
    tableaus : Tableaus
        From :func:`dense_tableaus`.
    params : ndarray
    compiled : callable, optional
        :func:`evaluate` compiled for these argument types (by
        :func:`hamrkq.backends.extras.compiled_helper`); interpreted without.
    recipe : tuple, optional
        ``(build, args)`` with ``build(*args, t, y)`` returning this dense
        output: how a pickled copy is rebuilt (compiled functions and the
        interpreted backend's closures do not pickle; the recipe's
        Hamiltonian and method do).  Without it the copy is rebuilt from
        ``rhs``, interpreted.
    """

    def __init__(
        self,
        t: np.ndarray,
        y: np.ndarray,
        rhs: Callable,
        tableaus: Tableaus,
        params: np.ndarray,
        compiled: Callable | None = None,
        recipe: tuple[Callable, tuple] | None = None,
    ):
        self.t = np.array(t, dtype=np.float64, order="C")
        self.y = np.array(y, dtype=np.float64, order="C")
        if self.t.size == 0:
            raise ValueError("dense output needs at least one node")
        self.t_min, self.t_max = float(self.t.min()), float(self.t.max())
        self._rhs = rhs
        self._tab = tableaus
        self._params = np.require(params, np.float64, ("C", "W"))
        self._compiled = compiled
        self._evaluate = compiled if compiled is not None else evaluate
        self._recipe = recipe
        self._count = threading.Lock()
        self.nfev = 0

    def through(self, t: np.ndarray, y: np.ndarray) -> DenseOutput:
        """The same continuous extension through other nodes (a truncated run)."""
        return DenseOutput(t, y, self._rhs, self._tab, self._params, self._compiled, self._recipe)

    def __reduce__(self):
        if self._recipe is not None:
            build, args = self._recipe
            return (build, (*args, self.t, self.y))
        return (DenseOutput, (self.t, self.y, self._rhs, self._tab, self._params))

    def values(self, t) -> np.ndarray:
        """Time-major values: shape ``(m, 2n)`` for ``m`` times."""
        tq = np.array(np.atleast_1d(np.asarray(t, dtype=np.float64)).ravel(), order="C")
        out = np.empty((tq.size, self.y.shape[1]))
        if tq.size:
            index = node_index(self.t, tq)
            # Work arrays of this call's own (about 9 us): the compiled
            # evaluation runs without the GIL, so threads evaluating one
            # solution at once would otherwise share, and corrupt, them.
            work = prepare_work(self.y.shape[1], self._tab)
            nfev = self._evaluate(
                self._rhs, self._tab, self._params, self.t, self.y, index, tq, work, out
            )
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
