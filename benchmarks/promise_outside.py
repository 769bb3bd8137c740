"""Runs outside the catalogue where the promise fails silently (found by QA, 2026-11-27).

Each case is a run that reports SUCCESS (or stops) with returned nodes more
than 1.05 delta from an independent reference, the reproducer for a known
failure that docs/algorithm.md ("Known silent failures") describes; the
eccentric Kepler orbit's is fixed since (the witness's close-approach rule,
``benchmarks/close_approach.py``) and shows the run as it is now.  References:
Kepler's exact solution (``hamrkq.catalogue.exact.kepler``), mpmath's Taylor
integrator at 40 digits, and SciPy's DOP853 at rtol 1e-13 with a step bound
far below the feature it must resolve.

Run: ``python benchmarks/promise_outside.py`` (about eight minutes, most of it the
separatrix librations' 40-digit Taylor references).  Output:
``promise_outside.txt``.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import mpmath
import numpy as np
import sympy as sp
from measure import head_commit

import hamrkq
from hamrkq.catalogue.exact import kepler

HERE = Path(__file__).resolve().parent


def over(sol, truth, atol, rtol=0.0):
    """Each returned node's largest error over delta (delta at the reference)."""
    delta = np.maximum(atol, rtol * np.abs(truth))
    return (np.abs(sol.y - truth) / delta).max(axis=1)


def describe(sol, ratios):
    worst = int(np.argmax(ratios))
    return (
        f"{sol.status.name} ({sol.method}, {sol.options['z_substeps']} quencher steps, quencher "
        f"in {sol.options['quencher_precision']}), {len(sol.t)} nodes to t = {sol.t[-1]:.6g}, "
        f"the worst {ratios[worst]:.4g} delta at t = {sol.t[worst]:.6g}, "
        f"{int((ratios > 1.05).sum())} above 1.05 delta; Gamma there "
        f"{np.abs(sol.gamma[worst]).max():.2g}"
    )


def barrier():
    """A particle against a narrow barrier it cannot cross (energy 0.5 < 2)."""
    from scipy.integrate import solve_ivp

    q, p = sp.symbols("q p")
    ham = hamrkq.Hamiltonian(p**2 / 2 + 2 * sp.exp(-((q / sp.Rational(1, 10)) ** 2)), q=[q], p=[p])

    def f(_t, y):
        # dp/dt = -dH/dq = 400 q exp(-(q/0.1)^2)
        return [y[1], 400 * y[0] * math.exp(-((y[0] / 0.1) ** 2))]

    yield "H = p^2/2 + 2 exp(-(q/0.1)^2) from q = -30, p = 1, t in [0, 60], atol 1e-6"
    truth_end = solve_ivp(f, (0, 60), [-30.0, 1.0], method="DOP853", rtol=1e-13, atol=1e-14,
                          max_step=0.01).y[:, -1]  # fmt: skip
    yield (
        f"reference end state (DOP853, max_step 0.01): q = {truth_end[0]:.6f}, "
        f"p = {truth_end[1]:.6f}"
    )
    for extra in ({}, {"max_step": 0.05}):
        sol = hamrkq.solve(ham, q0=[-30.0], p0=[1.0], t_span=(0, 60), atol=1e-6, **extra)
        error = np.abs(sol.y[-1] - truth_end).max() / 1e-6
        yield (
            f"auto{', max_step 0.05' if extra else ''}: {sol.status.name}, {len(sol.t) - 1} steps "
            f"(largest {np.diff(sol.t).max():.3g}), end state q = {sol.y[-1, 0]:.6f}, p = "
            f"{sol.y[-1, 1]:.6f}: {error:.3g} delta off"
        )


def eccentric_kepler():
    """Kepler at e = 0.97 over 100 orbits: the quencher's rounding near pericentre."""
    problem = hamrkq.load_problem("kepler", e=0.97)
    for precision in (None, "double-double"):
        extra = {"quencher_precision": precision} if precision else {}
        sol = hamrkq.solve(problem, t_span=(0, 200 * np.pi), atol=1e-8, **extra)
        truth = kepler(sol.t, problem.y0)
        ratios = over(sol, truth, 1e-8)
        label = "auto" + (", quencher_precision double-double" if precision else "")
        yield f"Kepler e = 0.97, 100 orbits, atol 1e-8, {label}: " + describe(sol, ratios)
        yield f"  its quencher's largest true error {np.abs(sol.z - truth).max():.3g}"


def pendulum_truth(q0, times, p0=0.0):
    """The pendulum from (q0, p0) at mpmath's 40 digits (its Taylor integrator)."""
    with mpmath.workdps(40):
        start = [mpmath.mpf(float(q0)), mpmath.mpf(float(p0))]
        flow = mpmath.odefun(lambda _t, v: [v[1], -mpmath.sin(v[0])], 0, start)
        return np.array([[float(x) for x in flow(mpmath.mpf(float(t)))] for t in times])


def unstable_equilibrium():
    """The pendulum from the double nearest pi, at rest: less than an ulp from the top."""
    pendulum = hamrkq.load_problem("pendulum")
    with mpmath.workdps(40):
        below = float(mpmath.pi - mpmath.mpf(np.pi))
    yield f"pi minus the double nearest it: {below:.3g}"
    for t_end in (25.0, 60.0):
        sol = hamrkq.solve(pendulum, q0=[np.pi], p0=[0.0], t_span=(0, t_end), atol=1e-8)
        ratios = over(sol, pendulum_truth(np.pi, sol.t), 1e-8)
        yield f"pendulum from q = pi (the double), p = 0, [0, {t_end:g}], atol 1e-8: " + describe(
            sol, ratios
        )
    sol = hamrkq.solve(pendulum, q0=[np.pi], p0=[0.0], t_span=(0, 25.0), atol=1e-8,
                       quencher_precision="double-double")  # fmt: skip
    ratios = over(sol, pendulum_truth(np.pi, sol.t), 1e-8)
    yield "the same to 25, quencher_precision double-double: " + describe(sol, ratios)


def long_steps_of_a_named_member():
    """rk78q10 named at a loose tolerance: the shadow's premise fails at its
    long steps and Gamma reads a tenth of the quencher's error."""
    problem = hamrkq.load_problem("kepler", e=0.5)
    sol = hamrkq.solve(problem, t_span=(0, 400 * np.pi), method="rk78q10", atol=1e-4)
    truth = kepler(sol.t, problem.y0)
    yield "Kepler e = 0.5, 200 orbits, atol 1e-4, rk78q10: " + describe(
        sol, over(sol, truth, 1e-4)
    )
    error = np.abs(sol.z - truth).max(axis=1)
    gamma = np.abs(sol.gamma).max(axis=1)
    read = gamma[error > 0] / error[error > 0]
    yield (
        f"  Gamma over the quencher's true error at the nodes: median {np.median(read):.3g}, "
        f"smallest {read.min():.3g}; the quencher's largest true error {error.max():.3g}"
    )
    sol = hamrkq.solve(problem, t_span=(0, 400 * np.pi), atol=1e-4)
    yield "The same with auto: " + describe(sol, over(sol, kepler(sol.t, problem.y0), 1e-4))


def witness_reading_low():
    """The rounding witness, one sample of the quencher's rounding, reading
    low near the floor (QA, 2026-11-27, round 3)."""
    problem = hamrkq.load_problem("kepler", e=0.3)
    atol = np.array([1e-7, 1e-7, 1e-7, 1e-12])
    sol = hamrkq.solve(problem, t_span=(0, 20 * np.pi), method="rk45q8", atol=atol)
    truth = kepler(sol.t, problem.y0)
    yield "Kepler e = 0.3, 10 orbits, atol [1e-7, 1e-7, 1e-7, 1e-12], rk45q8: " + describe(
        sol, over(sol, truth, atol)
    )
    yield f"  its quencher's largest true error in p2 {np.abs(sol.z - truth)[:, 3].max():.3g}"
    for method in ("rk45q8", "auto"):
        atol = 1e-12 if method == "rk45q8" else np.array([1e-7, 1e-7, 1e-7, 1e-12])
        sol = hamrkq.solve(problem, t_span=(0, 20 * np.pi), method=method, atol=atol)
        yield f"  the same with {method}, atol {atol}: " + describe(
            sol, over(sol, kepler(sol.t, problem.y0), atol)
        )
    harmonic = hamrkq.load_problem("harmonic")
    sol = hamrkq.solve(
        harmonic, t_span=(0, 3000), method="rk34q8", atol=1e-12, max_steps=3_000_000
    )
    truth = harmonic.exact(sol.t)
    yield "harmonic oscillator, [0, 3000], atol 1e-12, rk34q8: " + describe(
        sol, over(sol, truth, 1e-12)
    )
    yield f"  its quencher's largest true error {np.abs(sol.z - truth).max():.3g}"


def near_the_separatrix():
    """Named members on librations just below the separatrix (QA, session
    18): the quencher's rounding, amplified by the orbit's sensitivity to
    its energy (the period grows like log 1/(1 - E)), which no rule for
    running the witness covers there."""
    pendulum = hamrkq.load_problem("pendulum")
    cases = [
        ([0.0, math.sqrt(4 - 2e-9)], "1 - 1e-9", "rk45q12", 1e-9, 0.0, 60.0),
        ([math.pi - math.sqrt(2e-6), 0.0], "1 - 1e-6", "rk67q12", 1e-9, 0.0, 150.0),
        ([math.pi - math.sqrt(2e-6), 0.0], "1 - 1e-6", "rk45q12", 1e-8, 1e-8, 150.0),
        ([math.pi - math.sqrt(2e-6), 0.0], "1 - 1e-6", "auto", 1e-9, 0.0, 150.0),
    ]
    for y0, energy, method, atol, rtol, t_end in cases:
        sol = hamrkq.solve(pendulum, q0=y0[:1], p0=y0[1:], t_span=(0, t_end), method=method,
                           atol=atol, rtol=rtol)  # fmt: skip
        truth = pendulum_truth(y0[0], sol.t, y0[1])
        yield (
            f"pendulum at E = {energy}, [0, {t_end:g}], atol {atol:g}, rtol {rtol:g}, "
            f"{method}: " + describe(sol, over(sol, truth, atol, rtol))
        )
        yield f"  its quencher's largest true error {np.abs(sol.z - truth).max():.3g}"


def quench_threshold():
    """quench_threshold above 1: nodes up to theta delta."""
    problem = hamrkq.load_problem("kepler", e=0.6)
    for theta in (1.0, 3.0):
        sol = hamrkq.solve(problem, t_span=(0, 20 * np.pi), atol=1e-6, quench_threshold=theta)
        ratios = over(sol, kepler(sol.t, problem.y0), 1e-6)
        yield f"Kepler e = 0.6, 10 orbits, atol 1e-6, quench_threshold {theta:g}: " + describe(
            sol, ratios
        )


CASES = [
    ("A narrow barrier the steps jump over", barrier),
    ("Rounding near pericentre on a very eccentric orbit", eccentric_kepler),
    ("A start less than an ulp from an unstable equilibrium", unstable_equilibrium),
    ("A named member's long steps at a loose tolerance", long_steps_of_a_named_member),
    ("quench_threshold above 1", quench_threshold),
    ("The rounding witness reading low near the floor", witness_reading_low),
    ("Named members just below the separatrix", near_the_separatrix),
]


def main() -> None:
    warnings.simplefilter("ignore")
    commit = head_commit()
    lines = [
        "# Silent failures outside the catalogue (generated by benchmarks/promise_outside.py)",
        "",
        f"Run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on commit {commit}.",
    ]
    for title, case in CASES:
        lines += ["", f"## {title}", ""]
        for line in case():
            print(line, flush=True)
            lines.append(f"- {line}")
    (HERE / "promise_outside.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
