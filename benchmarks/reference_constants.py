"""The reference with H's parameters folded into heyoka numbers, against the
same with them as runtime parameters (``hamrkq.analysis.extended_reference._equations``),
on the double pendulum's chaotic orbit over [0, 100].

heyoka folds products and sums of numbers as it builds an expression, in the
numbers' precision: with the parameters as long-double numbers, ``g (m1 +
m2) l1`` became one rounded long double.  The orbit moves 4.9e-4 at
t = 96.86 for an ulp of its start, so that rounding shows.  Both references
run in 160-bit floats; ``auto``'s nodes at 1e-8 and 1e-10 (``atol`` =
``rtol``) are measured against each.

Run: ``python benchmarks/reference_constants.py > benchmarks/reference_constants.txt``
(about three minutes).
"""

from __future__ import annotations

import time

import numpy as np
import sympy as sp

import hamrkq
from hamrkq.analysis.extended_reference import _equations, _products

BITS = 160


def folded_equations(ham, params):
    """The equations as the reference built them before: parameters as
    long-double numbers in the expressions (no non-dyadic rationals here)."""
    import heyoka as hy

    symbols = {s: hy.expression(f"y{k}") for k, s in enumerate(ham.state)}
    replacements = {}
    for symbol, value in zip(ham.parameters, params, strict=True):
        placeholder = sp.Dummy()
        symbols[placeholder] = hy.expression(np.longdouble(value))
        replacements[symbol] = placeholder
    rhs = [_products(e.xreplace(replacements)) for e in ham.rhs]
    return [(symbols[s], hy.from_sympy(e, symbols)) for s, e in zip(ham.state, rhs, strict=True)]


def states(equations, pars, y0, times):
    import heyoka as hy

    ta = hy.taylor_adaptive(
        equations, np.array([hy.real(float(v), BITS) for v in y0]), fp_type=hy.real, prec=BITS,
        tol=hy.real(2.0 ** (16 - BITS), BITS), time=hy.real(0.0, BITS), pars=pars,
    )  # fmt: skip
    grid = np.array([hy.real(float(t), BITS) for t in times])
    return np.array([[float(v) for v in row] for row in ta.propagate_grid(grid)[-1]])


def main() -> None:
    import heyoka as hy

    problem = hamrkq.load_problem("double_pendulum")
    ham, y0 = problem.hamiltonian, problem.y0
    params = np.asarray(problem.parameter_array, dtype=float).ravel()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; double pendulum over [0, 100]")
    runs = {tol: hamrkq.solve(problem, t_span=(0.0, 100.0), atol=tol, rtol=tol)
            for tol in (1e-8, 1e-10)}  # fmt: skip
    times = np.unique(np.concatenate([[0.0, 96.86], *(sol.t for sol in runs.values())]))
    system = _equations(ham, params)
    exact = states(system.equations, system.pars(hy.real, BITS), y0, times)
    folded = states(folded_equations(ham, params), np.zeros(0, dtype=object), y0, times)
    at = int(np.searchsorted(times, 96.86))
    print(f"folded against runtime parameters at t = 96.86: "
          f"{np.abs(folded[at] - exact[at]).max():.2g}; over [0, 100]: "
          f"{np.abs(folded - exact).max():.2g}")  # fmt: skip
    for tol, sol in runs.items():
        rows = np.searchsorted(times, sol.t)
        for name, ref in (("runtime parameters", exact), ("folded", folded)):
            delta = np.maximum(tol, tol * np.abs(ref[rows]))
            worst = np.max(np.abs(sol.y - ref[rows]) / delta)
            print(f"auto at {tol:g} ({sol.status.name}, {sol.t.size} nodes), worst node against "
                  f"the reference with {name}: {worst:.3g} delta")  # fmt: skip


if __name__ == "__main__":
    main()
