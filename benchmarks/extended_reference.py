"""Reference solutions in extended precision, for the benchmarks.

heyoka (the optional ``bench`` extra) integrates Hamilton's equations,
converted from hamrkq's own SymPy right-hand side with ``heyoka.from_sympy``,
by its Taylor method in x86 extended precision (``numpy.longdouble``: a
64-bit mantissa, eps = 1.1e-19) at a tolerance of 1e-19.  ``error_bound`` compares it with the
same run at 1e-17; run this file (``python benchmarks/extended_reference.py``,
about a minute) to write those bounds for the benchmarks' problems and
intervals to ``extended_reference.txt``.  They are far below the quenchers'
rounding floor in double that the reference exposes (the "quencher error"
column of ``family.md``: 5e-12 to 2e-10 on prentice2011 over [0, 4000]).
"""

from __future__ import annotations

from pathlib import Path

import measure  # noqa: F401 - compiles a first use before timing (HAMRKQ_COMPILE=wait)
import numpy as np


def available() -> bool:
    """Whether heyoka is installed and numpy's longdouble is wider than double."""
    try:
        import heyoka  # noqa: F401
    except ImportError:
        return False
    return np.finfo(np.longdouble).eps < 1e-18


def reference(problem, t_nodes, tol: float = 1e-19, fold_parameters: bool = False) -> np.ndarray:
    """States of ``problem`` (its y0 and parameters, as doubles, with exact
    arithmetic on them) at ``t_nodes`` (increasing, starting at or after
    t0 = 0), rounded to double.  ``fold_parameters`` substitutes them as
    SymPy Floats instead, whose sums SymPy rounds to 53 bits (how the
    references were made before; ``constant_offsets.py`` compares the two)."""
    import heyoka as hy
    import sympy as sp

    ham = problem.hamiltonian
    state = list(ham.state)
    rhs = list(ham.rhs)
    symbols = {s: hy.expression(str(s)) for s in state}
    # The parameters' doubles enter as extended-precision constants, so that
    # sums of them (1 - mu) are exact: substituted into SymPy as Floats, they
    # would be folded to 53 bits, a different problem (on the Arenstorf orbit
    # the two end 3.5e-11 apart, benchmarks/constant_offsets.txt).
    for symbol, value in zip(ham.parameters, problem.parameter_array, strict=True):
        if fold_parameters:
            rhs = [e.subs(symbol, float(value)) for e in rhs]
            continue
        placeholder = sp.Dummy()
        symbols[placeholder] = hy.expression(np.longdouble(value))
        rhs = [e.xreplace({symbol: placeholder}) for e in rhs]
    # heyoka takes only dyadic rationals; others (1/6) become constants in
    # extended precision, through placeholders.
    for rational in set().union(*(e.atoms(sp.Rational) for e in rhs)):
        if rational.q & (rational.q - 1):
            placeholder = sp.Dummy()
            value = np.longdouble(rational.p) / np.longdouble(rational.q)
            symbols[placeholder] = hy.expression(value)
            rhs = [e.xreplace({rational: placeholder}) for e in rhs]
    heyoka_vars = [symbols[s] for s in state]
    equations = [(v, hy.from_sympy(e, symbols)) for v, e in zip(heyoka_vars, rhs, strict=True)]
    y0 = np.array(problem.y0, dtype=np.longdouble)
    ta = hy.taylor_adaptive(equations, y0, fp_type=np.longdouble, tol=np.longdouble(tol))
    grid = np.asarray(t_nodes, dtype=np.longdouble)
    start = 0 if grid[0] == 0 else 1  # propagate_grid starts at the current time
    out = ta.propagate_grid(np.concatenate([np.zeros(start, np.longdouble), grid]))
    if out[-1].shape[0] != grid.size + start:
        raise RuntimeError(f"heyoka stopped early ({out[0]}) on {problem.name}")
    return np.asarray(out[-1][start:], dtype=np.float64)


def error_bound(problem, t_nodes) -> float:
    """max |reference at 1e-19 - reference at 1e-17|: a bound on the
    reference's own error (the tighter run is far more accurate still)."""
    return float(np.abs(reference(problem, t_nodes) - reference(problem, t_nodes, 1e-17)).max())


def main() -> None:
    import hamrkq

    cases = [
        ("kepler e=0.6, 10 orbits", hamrkq.load_problem("kepler", e=0.6), 20 * np.pi),
        ("prentice2011, t <= 4000", hamrkq.load_problem("prentice2011"), 4000.0),
        ("outer_solar_system, 500 000 days", hamrkq.load_problem("outer_solar_system"), 5e5),
    ]
    lines = ["max |reference at tol 1e-19 - at tol 1e-17| on 201 equally spaced times:"]
    for label, problem, t_end in cases:
        lines.append(f"{label}: {error_bound(problem, np.linspace(0.0, t_end, 201)):.1e}")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    (Path(__file__).resolve().parent / "extended_reference.txt").write_text(text)


if __name__ == "__main__":
    main()
