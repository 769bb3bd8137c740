"""The extended reference's stated accuracy against its actual error.

``hamrkq.analysis.extended_reference.extended_reference`` (heyoka's Taylor
method in x86 long double at tol 1e-19) states an accuracy; this script
measures its actual error against the same equations integrated by heyoka in
quad precision (``heyoka.real128``, tol 1e-32, checked against a run at
1e-26) on 401 equally spaced times, and prints both the accuracy stated now
(3 times the larger difference from runs at 1e-17 and 1e-18) and the one
stated before (the difference from the run at 1e-17, at least half an ulp of
double), which QA found below the actual error by up to 5.8 times.  Needs
heyoka (the ``bench`` extra).  ``python benchmarks/extended_reference_accuracy.py``
(a minute or two) writes ``extended_reference_accuracy.txt``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp


def _quad(ham, params, y0, t, tol):
    """``ham``'s states at ``t`` (from ``y0`` at ``t[0]``) in quad precision,
    as an object array of ``heyoka.real128``; parameters and non-dyadic
    rationals as quad-precision constants (the extended reference's own
    translation, at another precision)."""
    import heyoka as hy
    import mpmath as mp

    from hamrkq.analysis.extended_reference import _products

    quad = hy.real128
    symbols = {s: hy.expression(f"y{k}") for k, s in enumerate(ham.state)}
    symbols[ham.t] = hy.time
    replacements = {}
    for symbol, value in zip(ham.parameters, np.asarray(params, dtype=float), strict=True):
        placeholder = sp.Dummy()
        symbols[placeholder] = hy.expression(quad(float(value)))
        replacements[symbol] = placeholder
    rhs = [e.xreplace(replacements) for e in ham.rhs]
    replacements = {}
    for rational in set().union(*(e.atoms(sp.Rational) for e in rhs)):
        if rational.q & (rational.q - 1):
            placeholder = sp.Dummy()
            mp.mp.prec = 120
            value = mp.nstr(mp.mpf(rational.p) / rational.q, 40)
            symbols[placeholder] = hy.expression(quad(value))
            replacements[rational] = placeholder
    rhs = [_products(e.xreplace(replacements)) for e in rhs]
    system = [(symbols[s], hy.from_sympy(e, symbols)) for s, e in zip(ham.state, rhs, strict=True)]
    ta = hy.taylor_adaptive(
        system,
        np.array([quad(float(v)) for v in y0]),
        time=quad(float(t[0])),
        fp_type=quad,
        tol=quad(tol),
    )
    states = ta.propagate_grid(np.array([quad(float(v)) for v in t]))[-1]
    assert states.shape[0] == t.size
    return states


def _difference(states, quad) -> np.ndarray:
    """``|states - quad|`` per node and component, the subtraction in quad precision."""
    import heyoka as hy

    ours = np.vectorize(lambda v: hy.real128(float(v)), otypes=[object])(states)
    return np.vectorize(lambda v: abs(float(v)))(ours - quad)


def measure(label: str, problem, t_end: float) -> str:
    """One line: stated before, stated now, actual, and their ratios."""
    from hamrkq.analysis.extended_reference import extended_reference, extended_states

    ham, params, y0 = problem.hamiltonian, problem.parameter_array, problem.y0
    t = np.linspace(problem.t_span[0], t_end, 401)
    ref = extended_reference(ham, params, y0, t)
    quad = _quad(ham, params, y0, t, 1e-32)
    self_check = float(np.max(_difference(_quad(ham, params, y0, t, 1e-26), quad)))
    actual = float(np.max(_difference(ref.y, quad)))
    # before: the difference from the run at 1e-17, at least half an ulp of double
    loose = extended_states(ham, params, y0, t, tol=1e-17)
    rounding = float(np.max(np.abs(ref.y))) * np.finfo(np.float64).eps / 2
    base = extended_states(ham, params, y0, t)
    before = max(float(np.max(np.abs(loose - base))), rounding)
    now = float(ref.estimated_error)
    return (
        f"| {label} | {before:.2e} | {before / actual:.2f} | {now:.2e} | {now / actual:.1f} "
        f"| {actual:.2e} | {self_check:.0e} |"
    )


def main() -> None:
    import hamrkq

    cases = [
        ("prentice2011 [0, 4000]", hamrkq.load_problem("prentice2011"), 4000.0),
        ("prentice2011 [0, 1000]", hamrkq.load_problem("prentice2011"), 1000.0),
        ("kepler, 10 orbits", hamrkq.load_problem("kepler"), None),
        ("arenstorf, one orbit", hamrkq.load_problem("arenstorf"), None),
        ("double_pendulum [0, 40]", hamrkq.load_problem("double_pendulum"), 40.0),
        ("henon_heiles (file's span)", hamrkq.load_problem("henon_heiles"), None),
        ("pleiades (file's span)", hamrkq.load_problem("pleiades"), None),
        ("fpu (file's span)", hamrkq.load_problem("fpu"), None),
    ]
    lines = [
        "Extended reference (heyoka, long double, tol 1e-19) on 401 equally spaced times: "
        "stated accuracy before (|run at 1e-17 - run at 1e-19|, at least half an ulp of "
        "double) and now (3 x the larger difference from the runs at 1e-17 and 1e-18), "
        "against the actual error (heyoka in quad precision, tol 1e-32; its self-check "
        "against tol 1e-26 in the last column). Ratios are stated / actual: below 1 the "
        "stated accuracy is not a bound.",
        "",
        "| case | stated before | before / actual | stated now | now / actual | actual "
        "| quad self-check |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, problem, t_end in cases:
        lines.append(measure(label, problem, t_end or problem.t_span[1]))
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    (Path(__file__).resolve().parent / "extended_reference_accuracy.txt").write_text(text)


if __name__ == "__main__":
    main()
