"""Splitting methods for separable ``H = T(p) + V(q)``: Stormer-Verlet and
Yoshida's fourth-order triple jump, as data (:class:`SplittingScheme`) and one
loop (:func:`splitting_integrate`).

The loop calls the full right-hand side
``f = (dH/dp, -dH/dq)``: for a separable H the upper half depends on p only
and the lower half on q only, so a *drift* (q advanced with dH/dp) may read
the upper half of ``f`` at any q and a *kick* (p advanced with -dH/dq) the
lower half at any p.  Each call yields one useful half; ``nfev`` counts calls.

References
----------
L. Verlet, Phys. Rev. 159 (1967) 98-103; E. Hairer, C. Lubich & G. Wanner,
"Geometric numerical integration illustrated by the Stormer-Verlet method",
Acta Numerica 12 (2003) 399-450.
H. Yoshida, "Construction of higher order symplectic integrators",
Phys. Lett. A 150 (1990) 262-268 (also E. Forest & R. D. Ruth, Physica D 43
(1990) 105-117).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from hamrkq._interruption import interrupted_near
from hamrkq.fixed_step.implicit_rk import LoopOutcome, Mesh, Rhs

__all__ = ["SPLITTING_SCHEMES", "SplittingScheme", "splitting_integrate"]


@dataclass(frozen=True)
class SplittingScheme:
    """A symmetric kick-drift composition for separable H, as data.

    One step of length h is ``K(k_0 h) D(d_0 h) K(k_1 h) ... D(d_{m-1} h) K(k_m h)``
    where K kicks p with -dV/dq and D drifts q with dT/dp.

    Attributes
    ----------
    name : str
        Method name.
    order : int
        Classical order.
    kicks : tuple of float
        m + 1 kick coefficients (sum 1).
    drifts : tuple of float
        m drift coefficients (sum 1).
    reference : str
        Where the scheme is published.
    """

    name: str
    order: int
    kicks: tuple[float, ...]
    drifts: tuple[float, ...]
    reference: str


def _yoshida4() -> SplittingScheme:
    # Triple jump: Verlet(w1 h) Verlet(w0 h) Verlet(w1 h) with 2 w1 + w0 = 1 and
    # 2 w1^3 + w0^3 = 0, so the h^3 error terms cancel (Yoshida 1990, eq. 5.19).
    cbrt2 = 2.0 ** (1.0 / 3.0)
    w1 = 1.0 / (2.0 - cbrt2)
    w0 = -cbrt2 / (2.0 - cbrt2)
    return SplittingScheme(
        name="yoshida4",
        order=4,
        kicks=(w1 / 2, (w1 + w0) / 2, (w0 + w1) / 2, w1 / 2),
        drifts=(w1, w0, w1),
        reference="Yoshida, Phys. Lett. A 150 (1990) 262-268; Forest & Ruth, Physica D 43 (1990)",
    )


#: The splitting methods by name.
SPLITTING_SCHEMES: Mapping[str, SplittingScheme] = MappingProxyType(
    {
        "verlet": SplittingScheme(
            name="verlet",
            order=2,
            kicks=(0.5, 0.5),
            drifts=(1.0,),
            reference="Verlet, Phys. Rev. 159 (1967); Hairer, Lubich & Wanner, Acta Numer. 2003",
        ),
        "yoshida4": _yoshida4(),
    }
)


def splitting_integrate(scheme: SplittingScheme, rhs: Rhs, y0, mesh: Mesh, params):
    """The splitting loop; same contract as
    :func:`hamrkq.fixed_step.implicit_rk.gauss_integrate`."""
    dim = y0.size
    n = dim // 2
    out = LoopOutcome()
    ys = np.empty((mesh.n_kept(mesh.stop), dim))
    y = np.array(y0, dtype=float)
    q, p = y[:n], y[n:]  # views: rhs(t, y) always sees the current (q, p)
    last = y.copy()  # the state at mesh point `reached`, kept for early stops
    ys[0] = y
    stored = 1
    kicks, drifts = scheme.kicks, scheme.drifts
    nsub = len(drifts)
    reached = 0
    try:
        force = rhs(mesh.t0, y, params)[n:]
        out.nfev = 1
        for i in range(mesh.stop):
            t = mesh.time(i)
            h = mesh.step_length(i)
            tau = t
            for j in range(nsub):
                p += (kicks[j] * h) * force
                dh = drifts[j] * h
                # Drift velocity at the middle of the drift's time interval (second
                # order also when T depends on t); the next force at its end.
                q += dh * rhs(tau + 0.5 * dh, y, params)[:n]
                tau = tau + dh if j + 1 < nsub else t + h
                force = rhs(tau, y, params)[n:]
            p += (kicks[nsub] * h) * force
            out.nfev += 2 * nsub
            if not np.isfinite(y).all():
                out.failure = "non_finite"
                out.reason = f"the state became non-finite at t={float(mesh.time(i + 1))!r}"
                break
            last[:] = y
            reached = i + 1
            if mesh.kept(reached):
                ys[stored] = y
                stored += 1
    except KeyboardInterrupt:
        out.failure = "interrupted"
        out.reason = interrupted_near(mesh.time(reached))
    return mesh.stored_rows(ys, stored, reached, last), reached, out
