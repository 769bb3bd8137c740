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
    from hamrkq.analysis.extended_reference import available as package_available

    return package_available()


def reference(problem, t_nodes, tol: float = 1e-19, fold_parameters: bool = False) -> np.ndarray:
    """States of ``problem`` (its y0 and parameters, as doubles, with exact
    arithmetic on them) at ``t_nodes`` (increasing, starting at or after
    t0 = 0), rounded to double: :func:`hamrkq.analysis.extended_reference.extended_states`.
    ``fold_parameters`` substitutes them as SymPy Floats instead, whose sums
    SymPy rounds to 53 bits (how the references were made before;
    ``constant_offsets.py`` compares the two)."""
    import sympy as sp

    from hamrkq import Hamiltonian
    from hamrkq.analysis.extended_reference import extended_states

    ham, params = problem.hamiltonian, problem.parameter_array
    if fold_parameters:
        values = {s: sp.Float(float(v)) for s, v in zip(ham.parameters, params, strict=True)}
        ham = Hamiltonian(ham.H.subs(values), q=list(ham.q), p=list(ham.p), t=ham.t)
        params = np.zeros(0)
    states = extended_states(ham, params, problem.y0, t_nodes, t0=0.0, tol=tol)
    return np.asarray(states, dtype=np.float64)


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
