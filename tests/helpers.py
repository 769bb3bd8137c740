"""Small helpers shared by the test modules."""

from __future__ import annotations

import contextlib
import io
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mpmath
import numpy as np


def run_cli(*argv: Any) -> tuple[int, str, str]:
    """``hamrkq argv...`` in this process: (exit status, stdout, stderr)."""
    from hamrkq.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


def oscillator_file(path: Path, *, hamiltonian: str = "p**2/2 + q**2/2", extra: str = "") -> Path:
    """A problem file at ``path`` (its stem the problem's name): one degree
    of freedom, ``q = 1, p = 0``, ``t_span = [0, 1]``, H at line 4 and
    ``extra`` from line 10 on."""
    path.write_text(
        f'name = "{path.stem}"\ncoordinates = ["q"]\nmomenta = ["p"]\n'
        f'hamiltonian = "{hamiltonian}"\n[initial]\nq = 1\np = 0\n'
        f"[integration]\nt_span = [0, 1]\n{extra}",
        encoding="utf-8",
    )
    return path


def counters(stats: Mapping[str, Any]) -> dict[str, Any]:
    """A solution's stats without its timings (``compile_s``, ``integrate_s``),
    which differ from run to run."""
    return {key: value for key, value in stats.items() if not key.endswith("_s")}


def without_timings(report: Mapping[str, Any]) -> dict[str, Any]:
    """A diagnostics or summary mapping whose ``stats`` lost their timings."""
    report = dict(report)
    if "stats" in report:
        report["stats"] = counters(report["stats"])
    return report


def kepler_flow_mpmath(y0, times) -> np.ndarray:
    """Kepler's flow (``H = |p|^2/2 - 1/|q|``) from ``y0`` (doubles, taken
    as exact) at ``t = 0`` to ``times``, to 30 digits (mpmath): Kepler's
    equation in the eccentric anomaly relative to the initial one, solved by
    ``findroot``, and the Lagrange f and g coefficients with ``g`` from
    ``t``, independent of the catalogue's closed form."""
    ctx = mpmath.MPContext()
    ctx.dps = 30
    q1, q2, p1, p2 = (ctx.mpf(float(v)) for v in y0)
    r0 = ctx.sqrt(q1**2 + q2**2)
    a = -1 / (2 * ((p1**2 + p2**2) / 2 - 1 / r0))
    n = a ** ctx.mpf(-1.5)
    ec, es = 1 - r0 / a, (q1 * p1 + q2 * p2) / ctx.sqrt(a)
    rows = []
    for time in times:
        t = ctx.mpf(float(time))
        mean = n * t
        dE = ctx.findroot(lambda d, m=mean: d - ec * ctx.sin(d) + es * (1 - ctx.cos(d)) - m, mean)
        r = a * (1 - ec * ctx.cos(dE) + es * ctx.sin(dE))
        f, g = 1 - a / r0 * (1 - ctx.cos(dE)), t - (dE - ctx.sin(dE)) / n
        fd, gd = -ctx.sqrt(a) / (r * r0) * ctx.sin(dE), 1 - a / r * (1 - ctx.cos(dE))
        rows.append([float(v) for v in (f * q1 + g * p1, f * q2 + g * p2,
                                         fd * q1 + gd * p1, fd * q2 + gd * p2)])  # fmt: skip
    return np.array(rows)


def pendulum_flow_mpmath(y0, times) -> np.ndarray:
    """The pendulum's libration (``H = p^2/2 - cos q``) from ``y0`` (doubles,
    taken as exact, ``|q0| < pi``) at ``t = 0`` to ``times``, to 30 digits:
    mpmath's Jacobi functions ``sn`` and ``cn`` of ``t + F(phi0, m)``."""
    ctx = mpmath.MPContext()
    ctx.dps = 30
    q0, p0 = (ctx.mpf(float(v)) for v in y0)
    m = p0**2 / 4 + ctx.sin(q0 / 2) ** 2
    k = ctx.sqrt(m)
    u0 = ctx.ellipf(ctx.atan2(ctx.sin(q0 / 2), p0 / 2), m)
    rows = []
    for time in times:
        u = u0 + ctx.mpf(float(time))
        sn, cn = ctx.ellipfun("sn", u, m=m), ctx.ellipfun("cn", u, m=m)
        rows.append([float(2 * ctx.asin(k * sn)), float(2 * k * cn)])
    return np.array(rows)


def pendulum_rotation_mpmath(p0, times) -> np.ndarray:
    """The pendulum (``H = p^2/2 - cos q``) going over the top from
    ``q = 0, p = p0`` (``p0 > 2``, a double taken as exact) at ``t = 0`` to
    ``times``, to 30 digits: ``q = 2 am(t/k | k^2)``, ``p = (2/k) dn(t/k |
    k^2)`` with ``k = 2/p0``, the amplitude from ``am(u + 2K) = am(u) + pi``."""
    ctx = mpmath.MPContext()
    ctx.dps = 30
    k = 2 / ctx.mpf(float(p0))
    m = k**2
    period = 2 * ctx.ellipk(m)
    rows = []
    for time in times:
        u = ctx.mpf(float(time)) / k
        n = ctx.nint(u / period)
        r = u - n * period
        sn, cn, dn = (ctx.ellipfun(name, r, m=m) for name in ("sn", "cn", "dn"))
        rows.append([float(2 * (n * ctx.pi + ctx.atan2(sn, cn))), float(2 / k * dn)])
    return np.array(rows)


def multiprecision_states(ham, params, y0, times, bits: int = 160) -> np.ndarray:
    """The states of ``ham`` from ``y0`` (doubles, taken as exact) at ``t =
    0`` to ``times``, by heyoka's Taylor integrator in ``bits``-bit floats
    (``heyoka.real``), rounded to double; checked against the same run at
    ``bits + 64`` bits.  For chaotic orbits, where the long-double reference
    (:mod:`hamrkq.analysis.extended_reference`) loses digits: on the
    Henon-Heiles orbit at E = 1/6 its own error is 1.4e-7 at t = 300."""
    import heyoka as hy

    from hamrkq.analysis.extended_reference import _equations

    system = _equations(ham, np.asarray(params, dtype=float).ravel())

    def run(precision: int) -> np.ndarray:
        real = [hy.real(float(v), precision) for v in np.asarray(y0, dtype=float)]
        tol = hy.real(2.0 ** (16 - precision), precision)
        ta = hy.taylor_adaptive(system.equations, np.array(real), fp_type=hy.real, prec=precision,
                                tol=tol, time=hy.real(0.0, precision),
                                pars=system.pars(hy.real, precision))  # fmt: skip
        grid = np.array([hy.real(float(t), precision) for t in times])
        states = ta.propagate_grid(grid)[-1]
        assert states.shape[0] == grid.size
        return np.array([[float(v) for v in row] for row in states])

    states = run(bits)
    check = run(bits + 64)
    scale = np.abs(check).max()
    assert np.abs(states - check).max() <= 1e-15 * scale
    return states
