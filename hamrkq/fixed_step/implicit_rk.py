"""Gauss-Legendre collocation (implicit midpoint, orders 4 and 6) with fixed steps.

The s-stage Gauss method (Butcher 1964; Hairer, Norsett & Wanner, *Solving
ODEs I*, Section II.7, Table 7.4) has order 2s and is symplectic and symmetric
(Sanz-Serna 1988; Hairer, Lubich & Wanner, *Geometric Numerical Integration*,
Theorem VI.4.3).  With one stage it is the implicit midpoint rule.

The stage equations are solved by simplified Newton iterations
(Hairer & Wanner, *Solving ODEs II*, Section IV.8): in the stage increments
``Z_i = Y_i - y_n`` the system is

    Z = h (A (x) I) F(Z),        F_i = f(t_n + c_i h, y_n + Z_i),

and each iteration solves ``(I - h A (x) J) dZ = -Z + h (A (x) I) F(Z)`` with
``J = f_y(t_n, y_n)``: one Jacobian and one LU factorisation (LAPACK getrf) per step.

Two details keep the long-run energy behaviour of the method intact:

- the iteration is run to roundoff (increments near machine precision, or until
  they stop shrinking), because a loosely solved implicit method is no longer
  symplectic and drifts;
- the new value is ``y_n + h sum_i b_i F_i`` accumulated with compensated
  (Kahan) summation (Hairer, McLachlan & Razakarivony, BIT 48 (2008) 231-243),
  so that rounding in ``y`` does not accumulate linearly with the step count.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import sympy as sp

from hamrkq._floats import EPS
from hamrkq._interruption import interrupted_near

__all__ = [
    "GAUSS_TABLEAUS",
    "CollocationTableau",
    "LoopOutcome",
    "Mesh",
    "gauss_integrate",
]

Rhs = Callable[[float, np.ndarray, np.ndarray], np.ndarray]

#: Newton has converged when every component of the increment is below
#: NEWTON_TOL times the size of that component (of y_n or of the stages).
NEWTON_TOL = 10.0 * EPS
#: That per-component test can be out of reach: a component that is zero by
#: symmetry carries pure rounding noise (1e-20, say) that no iteration removes.
#: So contraction is watched in the global measure max|dZ| / max|y, Z|: once it
#: stops shrinking below NEWTON_FLOOR the iteration has reached its roundoff
#: floor and is accepted; a global increment that stops shrinking above it means
#: the iteration does not contract, and the step fails.
NEWTON_FLOOR = 1.0e4 * EPS
#: In the per-component test a component is weighed with at least this fraction
#: of the largest component: one that small is below the resolution of the state
#: as a vector (zero by symmetry, say) and needs no relative accuracy of its own,
#: while genuinely small components (a planet's momentum, 1e-12 of the positions)
#: keep their own scale.
WEIGHT_FLOOR = 1.0e-14
#: Smallest weight of all (a state that is exactly zero).
TINY = float(np.finfo(float).tiny)
#: Default iteration limit.  Simplified Newton contracts at a rate of order
#: h * ||J(Y) - J(y_n)||, so well-resolved steps need 3 to 8 iterations.
MAX_NEWTON_ITER = 50


def _exact_tableau(s: int) -> tuple[list, list, list]:
    """Exact Gauss coefficients (c, A, b) for s = 1, 2, 3 as SymPy numbers."""
    half = sp.Rational(1, 2)
    if s == 1:
        return [half], [[half]], [sp.Integer(1)]
    if s == 2:
        r3 = sp.sqrt(3)
        quarter = sp.Rational(1, 4)
        c = [half - r3 / 6, half + r3 / 6]
        a = [[quarter, quarter - r3 / 6], [quarter + r3 / 6, quarter]]
        return c, a, [half, half]
    if s == 3:
        r15 = sp.sqrt(15)
        f536, f29 = sp.Rational(5, 36), sp.Rational(2, 9)
        c = [half - r15 / 10, half, half + r15 / 10]
        a = [
            [f536, f29 - r15 / 15, f536 - r15 / 30],
            [f536 + r15 / 24, f29, f536 - r15 / 24],
            [f536 + r15 / 30, f29 + r15 / 15, f536],
        ]
        b = [sp.Rational(5, 18), sp.Rational(4, 9), sp.Rational(5, 18)]
        return c, a, b
    raise ValueError(f"no Gauss tableau with s={s} stages")


def _to_float(values) -> np.ndarray:
    # evalf(30) then float: correctly rounded doubles, not products of rounded sqrt.
    out = np.array([float(sp.N(v, 30)) for v in np.ravel(np.array(values, dtype=object))])
    out = out.reshape(np.shape(np.array(values, dtype=object)))
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class CollocationTableau:
    """A Gauss-Legendre collocation method as frozen, exact data.

    Butcher tableau layout (c | A over b)::

        c_1 | a_11 ... a_1s
        ... |  ...      ...
        c_s | a_s1 ... a_ss
        ----+--------------
            | b_1  ...  b_s

    Attributes
    ----------
    name : str
        Method name used by :func:`hamrkq.solve` (``"midpoint"``, ...).
    stages, order : int
        Number of stages s and classical order 2s.
    c_exact, a_exact, b_exact : tuple
        The coefficients as exact SymPy numbers (rationals, sqrt(3), sqrt(15)).
    c, a, b : ndarray
        Read-only float64 versions, correctly rounded.
    reference : str
        Where the coefficients are published.
    """

    name: str
    stages: int
    order: int
    reference: str

    # Everything numeric on first use, not at import: building the surds in
    # SymPy (which imports sympy.tensor on the way) and evaluating them to 30
    # digits took 170 ms of every `import hamrkq.options`, which only needs
    # the method names.
    @cached_property
    def _exact(self) -> tuple[list, list, list]:
        return _exact_tableau(self.stages)

    @cached_property
    def c_exact(self) -> tuple:
        return tuple(self._exact[0])

    @cached_property
    def a_exact(self) -> tuple:
        return tuple(tuple(row) for row in self._exact[1])

    @cached_property
    def b_exact(self) -> tuple:
        return tuple(self._exact[2])

    @cached_property
    def c(self) -> np.ndarray:
        return _to_float(self.c_exact)

    @cached_property
    def a(self) -> np.ndarray:
        return _to_float([list(row) for row in self.a_exact])

    @cached_property
    def b(self) -> np.ndarray:
        return _to_float(self.b_exact)

    @classmethod
    def gauss(cls, name: str, s: int) -> CollocationTableau:
        """The s-stage Gauss-Legendre method (s = 1, 2, 3)."""
        if s not in (1, 2, 3):
            raise ValueError(f"no Gauss tableau with s={s} stages")
        return cls(
            name=name,
            stages=s,
            order=2 * s,
            reference=(
                "Butcher, Math. Comp. 18 (1964) 50-64; Hairer, Norsett & Wanner, "
                "Solving ODEs I, Table II.7.4"
            ),
        )

    def extrapolation(self, ratio: float) -> np.ndarray:
        """Matrix E giving starting increments for the next step from the last ones.

        The collocation polynomial u of the last step (u(0) = 0, u(c_i) = Z_i in
        units of the last step) is extrapolated to the next step's nodes:
        ``Z_new_j = u(1 + ratio c_j) - u(1)``, where ratio = h_new / h_old.
        """
        if ratio == 1.0:
            return self._extrapolation_unit
        return self._extrapolation(ratio)

    @cached_property
    def _extrapolation_unit(self) -> np.ndarray:
        return self._extrapolation(1.0)

    def _extrapolation(self, ratio: float) -> np.ndarray:
        nodes = np.concatenate(([0.0], self.c))
        targets = np.concatenate(([1.0], 1.0 + ratio * self.c))
        # Lagrange basis on {0, c_1..c_s}; the basis function of node 0 is dropped
        # because u(0) = 0.
        basis = np.ones((targets.size, nodes.size))
        for k, node in enumerate(nodes):
            for m, other in enumerate(nodes):
                if m != k:
                    basis[:, k] *= (targets - other) / (node - other)
        values = basis[:, 1:]
        out = values[1:] - values[0]
        out.setflags(write=False)
        return out


#: The three Gauss methods by name.
GAUSS_TABLEAUS: dict[str, CollocationTableau] = {
    "midpoint": CollocationTableau.gauss("midpoint", 1),
    "gauss4": CollocationTableau.gauss("gauss4", 2),
    "gauss6": CollocationTableau.gauss("gauss6", 3),
}


@dataclass
class LoopOutcome:
    """Counters and the way a fixed-step loop ended (mutable, internal).

    ``failure`` is None on success, else ``"newton"``, ``"non_finite"`` or
    ``"interrupted"``; ``reason`` is a sentence naming t.
    """

    nfev: int = 0
    njev: int = 0
    iterations: int = 0
    failure: str | None = None
    reason: str = ""


class Mesh:
    """Fixed-step mesh ``t_i = t0 + i h`` (i < N) ending exactly on ``t_N = t1``.

    Times are computed from the index, never accumulated, so they carry no
    rounding drift; every step has the nominal length h except the last, which
    is ``t1 - t_{N-1}``.
    """

    __slots__ = ("h", "keep_every", "steps", "stop", "t0", "t1")

    def __init__(self, t0: float, t1: float, h: float, steps: int, keep_every: int, stop: int):
        self.t0, self.t1, self.h, self.steps = t0, t1, h, steps
        self.keep_every = keep_every
        #: the loops take ``stop`` steps (fewer than ``steps`` when max_steps cuts in)
        self.stop = stop

    def step_length(self, i: int) -> float:
        """Length of step i (from point i to point i + 1), signed."""
        return self.h if i + 1 < self.steps else self.t1 - self.time(i)

    def time(self, i: int) -> float:
        """The time of mesh point i."""
        return self.t1 if i == self.steps else self.t0 + i * self.h

    def kept(self, i: int) -> bool:
        """Whether mesh point i is stored: every keep_every-th point and the last."""
        return i % self.keep_every == 0 or i == self.steps

    def kept_indices(self, reached: int) -> np.ndarray:
        """Indices of the stored points of a run that reached point ``reached``."""
        idx = np.arange(0, reached + 1, self.keep_every)
        if idx[-1] != reached:
            idx = np.append(idx, reached)
        return idx

    def stored_rows(self, ys: np.ndarray, stored: int, reached: int, last: np.ndarray):
        """The rows a loop stored, ``ys[:stored]``, plus ``last`` (the state at
        point ``reached``) when the run stopped at a point ``keep_every``
        skips: a run that stopped early keeps its last good state."""
        if not self.kept(reached):
            ys[stored] = last
            stored += 1
        return ys[:stored]

    def n_kept(self, upto: int) -> int:
        """How many points a run that reaches point ``upto`` stores."""
        count = upto // self.keep_every + 1
        if upto % self.keep_every:
            count += 1
        return count


def _newton(rhs, params, t, y, h, tab, lu, piv, z, max_iter, out):
    """Solve the stage equations from the starting increments z (modified in place).

    Returns ``(F, "")`` with the stage derivatives F (s, dim) at the last iterate
    but one (their difference from F at the final iterate is at roundoff level),
    or ``(None, why)``.
    """
    from scipy.linalg import lapack  # see gauss_integrate

    s = tab.stages
    # Per-step constants hoisted out of the iteration: the loop runs millions of
    # times on long runs and NumPy's per-call overhead dominates small systems.
    stage_t = [t + ci * h for ci in tab.c.tolist()]
    ha = h * tab.a
    f = np.empty_like(z)
    flat = s * z.shape[1]
    prev = np.inf
    # Component-wise relative size: state components may differ by many orders
    # of magnitude (planet momenta), so a single norm would hide small ones.
    abs_y = np.abs(y)
    amax = np.maximum.reduce
    for k in range(1, max_iter + 1):
        for i in range(s):
            f[i] = rhs(stage_t[i], y + z[i], params)
        out.nfev += s
        residual = ha @ f
        residual -= z
        dz = lapack.dgetrs(lu, piv, residual.reshape(flat))[0].reshape(z.shape)
        z += dz
        out.iterations += 1
        weight = np.maximum(abs_y, amax(np.abs(z), axis=0))
        scale = max(float(amax(weight)), TINY)
        np.maximum(weight, WEIGHT_FLOOR * scale, out=weight)
        absdz = np.abs(dz)
        size = float(amax(absdz, axis=None)) / scale
        if not math.isfinite(size):
            return None, f"the iteration produced non-finite values after {k} iterations"
        if float(amax(absdz / weight, axis=None)) <= NEWTON_TOL:
            return f, ""
        if k > 1 and size >= prev:
            if size <= NEWTON_FLOOR:
                return f, ""  # stalled at its roundoff floor: as good as it gets
            return None, (
                f"the iteration stopped contracting after {k} iterations "
                f"(relative increment {size:.3g}, previous {prev:.3g})"
            )
        prev = size
    return None, f"no convergence in {max_iter} iterations (relative increment {prev:.3g})"


def gauss_integrate(
    tab: CollocationTableau,
    rhs: Rhs,
    jac: Rhs,
    y0: np.ndarray,
    mesh: Mesh,
    params: np.ndarray,
    max_newton_iter: int = MAX_NEWTON_ITER,
) -> tuple[np.ndarray, int, LoopOutcome]:
    """Integrate over a fixed-step mesh with a Gauss method; the low-level loop.

    Parameters
    ----------
    tab : CollocationTableau
        The method.
    rhs, jac : callable
        ``rhs(t, y, params) -> (dim,)`` and ``jac(t, y, params) -> (dim, dim)``.
    y0 : ndarray, shape (dim,)
        Initial state.
    mesh : Mesh
        The mesh and which of its points to store.
    params : ndarray
        Passed through to rhs and jac.
    max_newton_iter : int
        Iteration limit per step.

    Returns
    -------
    ys : ndarray, shape (K, dim)
        States at the stored mesh points (see :meth:`Mesh.kept_indices`), up to
        and including the last one reached.
    reached : int
        Index of the last mesh point reached (``mesh.steps`` on success).
    outcome : LoopOutcome
        Counters, and why the loop stopped early if it did.
    """
    # scipy.linalg takes 0.2 s to import: only when a Gauss method runs, not
    # whenever the method names are read.
    from scipy.linalg import lapack

    dim = y0.size
    s = tab.stages
    out = LoopOutcome()
    ys = np.empty((mesh.n_kept(mesh.stop), dim))
    y = np.array(y0, dtype=float)
    ys[0] = y
    stored = 1
    comp = np.zeros(dim)  # Kahan compensation of y
    eye = np.eye(s * dim)
    # kron(A, J) written through a 4-D view: block (i, j) of the Newton matrix is
    # a_ij J, and the broadcast product avoids np.kron's per-call overhead.
    a4 = tab.a[:, None, :, None]
    kron = np.empty((s, dim, s, dim))
    z = np.zeros((s, dim))
    h_old = 0.0
    reached = 0
    try:
        for i in range(mesh.stop):
            t = mesh.time(i)
            h = mesh.step_length(i)
            jn = jac(t, y, params)
            out.njev += 1
            np.multiply(a4, jn[None, :, None, :], out=kron)
            # LAPACK getrf/getrs are what scipy.linalg.lu_factor/lu_solve wrap;
            # called directly they cost ~1 us instead of ~10 us on small systems.
            lu, piv, info = lapack.dgetrf(eye - h * kron.reshape(s * dim, s * dim))
            if info != 0:
                out.failure = "newton"
                out.reason = (
                    f"Newton failed at t={float(t)!r} (step {float(h)!r}): singular Newton matrix"
                )
                break
            if h_old:
                z = tab.extrapolation(h / h_old) @ z
            f, why = _newton(rhs, params, t, y, h, tab, lu, piv, z, max_newton_iter, out)
            if f is None and h_old:
                # The extrapolated guess can lie outside the basin of convergence
                # (a sharp turn of the solution): try once more from zero increments.
                z = np.zeros((s, dim))
                f, why = _newton(rhs, params, t, y, h, tab, lu, piv, z, max_newton_iter, out)
            if f is None:
                out.failure = "newton"
                out.reason = f"Newton failed at t={float(t)!r} (step {float(h)!r}): {why}"
                break
            increment = h * (tab.b @ f) + comp
            y_new = y + increment
            comp = increment - (y_new - y)
            if not np.all(np.isfinite(y_new)):
                out.failure = "non_finite"
                out.reason = f"the state became non-finite at t={float(mesh.time(i + 1))!r}"
                break
            y = y_new
            h_old = h
            reached = i + 1
            if mesh.kept(reached):
                ys[stored] = y
                stored += 1
    except KeyboardInterrupt:
        out.failure = "interrupted"
        out.reason = interrupted_near(mesh.time(reached))
    return mesh.stored_rows(ys, stored, reached, y), reached, out
