"""Numbers quoted in docs/algorithm.md, each measured by a short run.

    python benchmarks/algorithm_facts.py [FACT ...]

Each fact is one function below, titled after the part of the page that
quotes it; every line it yields is labelled with the page's wording.  The
runs are short (seconds each, compiled; about a minute in all once the code
is compiled).  True errors are against an exact solution or against heyoka
in extended precision (``benchmarks/extended_reference.py``), as each fact
says.  Writes ``benchmarks/algorithm_facts.txt`` (only when every fact ran:
naming some prints them and writes nothing).  The page's "## Example" block
is run as it stands on the page, and its printed output is the last section.
"""

from __future__ import annotations

import contextlib
import io
import math
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import extended_reference
import numpy as np
import sympy as sp
from measure import head_commit

import hamrkq
from hamrkq.rkq import auto_rules
from hamrkq.rkq.layout import FLOOR, RHO2
from hamrkq.rkq.witness_rules import WITNESS_SAFETY
from hamrkq.solve import prepare
from hamrkq.solve.dispatch import integration

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PAGE = ROOT / "docs" / "algorithm.md"
OUT = HERE / "algorithm_facts.txt"

FACTS: list[tuple[str, Callable[[], Iterator[str]], bool]] = []


def fact(title: str, raw: bool = False):
    """Register a fact: ``title`` names the part of the page that quotes it;
    ``raw``: its lines are printed output, written as a fenced block."""

    def register(function):
        FACTS.append((title, function, raw))
        return function

    return register


def g(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}g}"


def worst(a) -> float:
    return float(np.abs(np.asarray(a)).max())


def over_tolerance(y, truth, atol: float, rtol: float = 0.0) -> float:
    """The largest ``|y - truth|`` over ``max(atol, rtol |truth|)``."""
    delta = np.maximum(atol, rtol * np.abs(truth))
    return float((np.abs(y - truth) / delta).max())


def kernel_run(problem, **options):
    """One run of the kernel as ``solve`` sets it up (no reruns), with its
    work arrays: the witness's divergence and the modelled rounding."""
    prepared = prepare(problem, **options)
    run = integration(prepared.task, prepared.backend)
    out = run.run()
    return out, run.work


def witness_reading(work) -> float:
    """The witness's largest divergence (its floor over its safety factor)."""
    return float(work.V[FLOOR].max()) / WITNESS_SAFETY


def as_auto(member: str, problem, **options):
    """``method="auto"`` with ``member`` as the member it runs (as
    ``benchmarks/auto_member.py`` does)."""
    chosen = auto_rules.AUTO_MEMBER, auto_rules.AUTO_LARGE_MEMBER
    auto_rules.AUTO_MEMBER = auto_rules.AUTO_LARGE_MEMBER = member
    try:
        return hamrkq.solve(problem, method="auto", **options)
    finally:
        auto_rules.AUTO_MEMBER, auto_rules.AUTO_LARGE_MEMBER = chosen


def work(sol) -> int:
    """Evaluations, a discarded run's included."""
    stats = sol.stats
    return int(stats["nfev"] + stats["njev"] + stats.get("discarded_evaluations", 0))


def first_run(message: str) -> str:
    """The part of auto's message that says where its first run was
    abandoned or stopped."""
    found = re.search(r"the run with z_substeps=\d+ (was abandoned|stopped)[^(;]*", message)
    return found.group(0).strip().rstrip(",") if found else "(run once)"


# -- "One step, from t_i to t_i + h" ----------------------------------------------
@fact('"A blind spot of this pair": H = p^2/2 - q cos t from 0, 0, atol 1e-8, t in [0, 10]')
def blind_spot():
    q, p, t = sp.symbols("q p t")
    ham = hamrkq.Hamiltonian(p**2 / 2 - q * sp.cos(t), q=[q], p=[p], t=t)

    def run(method, **options):
        return hamrkq.solve(ham, q0=[0.0], p0=[0.0], t_span=(0.0, 10.0), atol=1e-8,
                            method=method, **options)  # fmt: skip

    def error(sol):
        return worst(sol.y - np.column_stack([1 - np.cos(sol.t), np.sin(sol.t)]))

    sol = run("rk34")
    largest = np.diff(sol.t).max()
    yield f"rk34: {sol.status.name}, max true error {g(error(sol))}, largest step {g(largest)}"
    sol = run("rk34q8")
    yield f"rk34q8: {sol.status.name} at t = {g(sol.t[-1], 3)}, max true error {g(error(sol))}"
    sol = run("rk34", max_step=0.5)
    yield f"rk34, max_step 0.5: {sol.status.name}, max true error {g(error(sol))}"
    for label, method, extra in (("rk34q8, max_step 0.5", "rk34q8", {"max_step": 0.5}),
                                 ("auto", "auto", {}), ("rk45q12", "rk45q12", {})):  # fmt: skip
        sol = run(method, **extra)
        yield f"{label}: {sol.status.name}, max true error / tol {error(sol) / 1e-8:.3f}"


# -- "When the tolerance cannot be met" --------------------------------------------
@fact("\"When the tolerance cannot be met\": y' = y^2, y(0) = 1, atol 1e-6, rk34q8's kernel")
def blow_up():
    from hamrkq.rkq import layout
    from hamrkq.rkq.config import Settings
    from hamrkq.rkq.driver import Integration, python_functions
    from hamrkq.rkq.family import get_member

    def f(t, y, params, out):
        out[...] = y**2

    def jac(t, y, params, out):
        out[...] = np.array([[2 * y[0]]])

    settings = Settings(quench=layout.QUENCH_NODE, rule=layout.RULE_COMPONENTWISE,
                        gamma=layout.GAMMA_TANGENT)  # fmt: skip
    run = Integration(python_functions(f, jac), get_member("rk34q8"), np.zeros(0), 0.0,
                      np.array([1.0]), 2.0, np.full(1, 1e-6), np.zeros(1), settings)  # fmt: skip
    with np.errstate(all="ignore"):
        out = run.run(budget=2000, buffer_rows=4096)
    exact = 1 / (1 - out.t[-1])
    z_error = out.z[-1, 0] - exact
    yield f"stops at t = {out.t[-1]:.6f}, y = {g(out.y[-1, 0], 3)} (exact {g(exact, 3)})"
    ratio = out.gamma[-1, 0] / z_error
    yield f"the track's own error there {g(z_error)}; Gamma over it {ratio:.3f}"


# -- "The rounding witness" ---------------------------------------------------------
@fact('"The rounding witness": the quencher\'s rounding on prentice2011 over [0, 4000]')
def quencher_rounding():
    """The quencher in double against the same run's quencher in
    double-double on 201 times (their truncation error the same), on three
    meshes (tolerances), Gamma's limit off; rho_k, the modelled rounding, at
    the end."""
    problem = hamrkq.load_problem("prentice2011")
    grid = np.linspace(0.0, 4000.0, 201)
    for tol in (1e-10, 1e-11, 1e-12):
        common = dict(method="rk78q12", atol=tol, rtol=0.0, z_substeps=2, t_eval=grid,
                      gamma_limit=np.inf)  # fmt: skip
        out, work_arrays = kernel_run(problem, **common)
        dd = hamrkq.solve(problem, quencher_precision="double-double", **common)
        rounding = worst(out.z - dd.z)
        rho = math.sqrt(float(work_arrays.V[RHO2].max()))
        yield (
            f"rk78q12, 2 quencher steps, atol {tol:g}: the quencher's rounding error "
            f"{g(rounding)} (largest over 201 times, against the same in double-double), "
            f"rho_k at the end {g(rho)}: {rounding / rho:.0f} times rho_k"
        )


@fact('"The rounding witness": its cost in evaluations a step (options["nfev_per_step"])')
def witness_cost():
    kepler = hamrkq.load_problem("kepler", e=0.6)
    for member in ("rk67q9", "rk78q12"):
        runs = [hamrkq.solve(kepler, t_span=(0, 10), method=member, z_substeps=2, atol=tol)
                for tol in (1e-8, 1e-10)]  # fmt: skip
        assert [sol.options["rounding_witness"] for sol in runs] == [False, True]
        a, b = (sol.options["nfev_per_step"] for sol in runs)
        yield (
            f"{member}, 2 quencher steps: {a} without the witness, {b} with it: "
            f"{100 * (b / a - 1):.0f} % more"
        )


@fact('"The rounding witness": rk45q8 on the FPU chain, rtol 1e-6, atol 1e-9, against heyoka')
def dop853_witness():
    fpu = hamrkq.load_problem("fpu")
    times = np.linspace(*fpu.t_span, 201)
    truth = extended_reference.reference(fpu, times)
    sol = hamrkq.solve(fpu, method="rk45q8", atol=1e-9, rtol=1e-6, t_eval=times)
    floor = "names the floor" if "floor" in sol.message else "does not name the floor"
    yield (
        f"rk45q8 on 201 times: {sol.status.name} at t = {g(sol.t[-1], 4)} ({floor}), "
        f"witness ran: {sol.options['rounding_witness']}, largest node "
        f"{over_tolerance(sol.y, truth[: sol.t.size], 1e-9, 1e-6):.3f} delta"
    )


def driven_exact(times, t0, q0=0.5, p0=-0.2, w=1.7, forcing=0.3):
    """H = p^2/2 + q^2/2 - forcing q cos(w t) from (q0, p0) at t0."""
    k = forcing / (1 - w**2)
    a, b = q0 - k * math.cos(w * t0), p0 + k * w * math.sin(w * t0)
    c1 = math.cos(t0) * a - math.sin(t0) * b
    c2 = math.sin(t0) * a + math.cos(t0) * b
    q = c1 * np.cos(times) + c2 * np.sin(times) + k * np.cos(w * times)
    p = -c1 * np.sin(times) + c2 * np.cos(times) - k * w * np.sin(w * times)
    return np.column_stack([q, p])


@fact('"The rounding witness": H = p^2/2 + q^2/2 - 0.3 q cos(1.7 t) from 0.5, -0.2, auto')
def time_rounding():
    q, p, t = sp.symbols("q p t")
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 - 0.3 * q * sp.cos(1.7 * t), q=[q], p=[p], t=t)
    for t0, tol, span in ((1e8, 1e-9, 300.0), (2.45e6, 1e-10, 300.0), (0.0, 1e-12, 2000.0)):
        sol = hamrkq.solve(ham, q0=[0.5], p0=[-0.2], t_span=(t0, t0 + span), atol=tol)
        error = over_tolerance(sol.y, driven_exact(sol.t, t0), tol)
        names = "names the time" if "H depends on t" in sol.message else "does not name it"
        yield (
            f"from t0 = {t0:g} over {span:g} at {tol:g}: {sol.status.name}, last node "
            f"{sol.t[-1] - t0:.6g} after t0 ({names}; witness ran: "
            f"{sol.options['rounding_witness']}), largest node {error:.3f} delta"
        )


@fact('"The rounding witness", "Measured": its largest divergence, the quencher\'s true error')
def witness_accuracy():
    def line(label, out, work_arrays, truth):
        z_error = worst(out.z - truth[: out.t.size])
        witness = witness_reading(work_arrays)
        return (
            f"{label}: witness {g(witness)} against {g(z_error)} "
            f"({witness / z_error:.2f} of the truth)"
        )

    common = dict(method="auto", rtol=0.0, gamma_limit=np.inf)
    harmonic = hamrkq.load_problem("harmonic")
    span = (0.0, 1000 * 2 * np.pi)
    grid = np.linspace(*span, 201)
    out, work_arrays = kernel_run(harmonic, t_span=span, atol=1e-12, t_eval=grid, **common)
    label = "harmonic oscillator, 1000 periods, auto at 1e-12, 201 times"
    yield line(label, out, work_arrays, harmonic.exact(out.t))
    kepler = hamrkq.load_problem("kepler", e=0.6)
    span = (0.0, 20 * np.pi)
    grid = np.linspace(*span, 201)
    out, work_arrays = kernel_run(kepler, t_span=span, atol=1e-12, t_eval=grid, **common)
    yield line("Kepler e = 0.6, ten orbits, auto at 1e-12, 201 times", out, work_arrays,
               kepler.exact(out.t))  # fmt: skip
    prentice = hamrkq.load_problem("prentice2011")
    grid = np.linspace(0.0, 4000.0, 201)
    truth = extended_reference.reference(prentice, grid)
    for tol in (1e-10, 1e-12):
        out, work_arrays = kernel_run(prentice, atol=tol, t_eval=grid, **common)
        label = f"prentice2011 over [0, 4000], auto at {tol:g} (its run in double), 201 times"
        yield line(label, out, work_arrays, truth)


# -- "Double precision's floor" -------------------------------------------------------
@fact('"The promise at tight tolerances" 2.: the harmonic oscillator, 1000 periods, 1e-12')
def landing_time():
    harmonic = hamrkq.load_problem("harmonic")
    span = (0.0, 1000 * 2 * np.pi)
    sol = hamrkq.solve(harmonic, t_span=span, method="rk78q12", atol=1e-12, rtol=0.0,
                       t_eval=np.linspace(*span, 201), gamma_limit=np.inf)  # fmt: skip
    z_error = worst(sol.z - harmonic.exact(sol.t))
    yield f"rk78q12 on 201 output times: the quencher's largest error {g(z_error)}"


# -- "The rounding caveat" -------------------------------------------------------------
@fact('"The rounding caveat": stats["roundoff_steps"] over the steps, rk34q8')
def roundoff_steps():
    def share(sol) -> str:
        steps, roundoff = sol.stats["steps"], sol.stats["roundoff_steps"]
        return f"{roundoff} of {steps} steps ({100 * roundoff / steps:.1f} %)"

    prentice = hamrkq.load_problem("prentice2011")
    sol = hamrkq.solve(prentice, method="rk34q8", atol=1e-6)
    yield f"prentice2011 over [0, 4000] at 1e-6: {share(sol)}"
    harmonic = hamrkq.load_problem("harmonic")
    for tol in (1e-8, 1e-10):
        sol = hamrkq.solve(harmonic, method="rk34q8", atol=tol)
        z_error = worst(sol.z - harmonic.exact(sol.t))
        yield (
            f"harmonic oscillator over [0, {sol.t[-1]:.4g}] at {tol:g}: {share(sol)}; the "
            f"track's true error {g(z_error)}, Gamma at most {g(worst(sol.gamma))}"
        )


# -- "The RKQ family and method='auto'" ------------------------------------------------
@fact('"The quencher in substeps": rk45q12, prentice2011 at 1e-6, 201 times, against heyoka')
def quencher_substeps():
    prentice = hamrkq.load_problem("prentice2011")
    grid = np.linspace(0.0, 4000.0, 201)
    truth = extended_reference.reference(prentice, grid)
    for m in (1, 2):
        # the quencher alone: no Gamma (the shadow needs m >= 2), no stop
        sol = hamrkq.solve(prentice, method="rk45q12", atol=1e-6, z_substeps=m, t_eval=grid,
                           global_error_estimate="off")  # fmt: skip
        error = worst(sol.z - truth)
        yield f"{m} quencher step(s) a step: the quencher's largest true error {g(error)}"


@fact('"Two steps carry a few dozen orbits": prentice2011 over [0, 4000], members named')
def two_steps_stop():
    prentice = hamrkq.load_problem("prentice2011")
    for member, tol in (("rk78q12", 1e-6), ("rk78q12", 1e-8), ("rk67q9", 1e-6)):
        sol = hamrkq.solve(prentice, method=member, atol=tol)
        steps = sol.options["z_substeps"]
        end = f"{sol.status.name} at t = {sol.t[-1]:.0f}"
        yield f"{member} at {tol:g} ({steps} quencher steps): {end}"


@fact('"The projection": prentice2011 over [0, 4000], auto\'s message')
def projection():
    prentice = hamrkq.load_problem("prentice2011")
    sol = hamrkq.solve(prentice, method="auto", atol=1e-6)
    share = sol.stats["discarded_evaluations"] / work(sol)
    yield (
        f"auto at 1e-6 ({sol.method}, then {sol.options['z_substeps']} quencher steps): "
        f"{first_run(sol.message)}; discarded {100 * share:.1f} % of its evaluations"
    )
    sol = as_auto("rk78q12", prentice, atol=1e-6)
    yield f"rk78q12 as auto runs it at 1e-6: {first_run(sol.message)}"
    grid = np.linspace(0.0, 4000.0, 401)
    sol = hamrkq.solve(prentice, method="auto", atol=1e-8, t_eval=grid)
    yield (
        f"auto at 1e-8 on 401 output times ({sol.method}, then {sol.options['z_substeps']} "
        f"quencher steps, {sol.status.name}): {first_run(sol.message)}"
    )
    two = hamrkq.solve(prentice, method="rk78q12", z_substeps=2, atol=1e-8, t_eval=grid)
    yield f"rk78q12 in two, 1e-8, 401 output times: {two.status.name} at t = {two.t[-1]:.0f}"
    sol = hamrkq.solve(prentice, method="auto", atol=1e-9)
    two = hamrkq.solve(prentice, method="rk78q12", z_substeps=2, atol=1e-9)
    ratio = np.abs(two.gamma).max(axis=1) / 1e-9
    yield (
        f"auto at 1e-9 ({sol.method}, then {sol.options['z_substeps']} quencher steps): "
        f"{first_run(sol.message)}"
    )
    yield (
        f"rk78q12 in two at 1e-9: {two.status.name}, |Gamma| / tol at most {ratio.max():.4f} "
        f"(at t = {two.t[ratio.argmax()]:.0f}), {ratio[-1]:.4f} at t_end; auto's evaluations "
        f"{work(sol) / work(two):.2f} times its"
    )
    for tol in (1e-6, 1e-9):
        sol = hamrkq.solve(prentice, method="auto", atol=tol, t_eval=grid)
        yield f"auto at {tol:g} on 401 output times ({sol.method}): {first_run(sol.message)}"
    for m in (2, 3, 4, 6):
        sol = hamrkq.solve(prentice, method="rk78q12", z_substeps=m, atol=1e-12,
                           quencher_precision="double")  # fmt: skip
        floor = "names the floor" if "floor" in sol.message else "does not name the floor"
        yield (
            f"rk78q12 at 1e-12, quencher in double, {m} quencher steps: {sol.status.name} "
            f"at t = {sol.t[-1]:.0f} ({floor})"
        )


@fact('"The stop": runs again after a stop (prentice2011 to 40 000 on 2001 times, heyoka)')
def the_stop():
    arenstorf = hamrkq.load_problem("arenstorf")
    sol = hamrkq.solve(arenstorf, method="rk78q12", atol=1e-6)
    yield (
        f"Arenstorf orbit, rk78q12 at 1e-6 (two quencher steps): {sol.status.name} at "
        f"t = {sol.t[-1]:.3f} of {arenstorf.t_span[1]:.3f}"
    )
    prentice = hamrkq.load_problem("prentice2011")
    span = (0.0, 40_000.0)
    sol = hamrkq.solve(prentice, method="rk78q12", atol=1e-6, t_span=span)
    yield (
        f"prentice2011 to t = 40 000 at 1e-6, rk78q12 in two quencher steps: "
        f"{sol.status.name} at t = {sol.t[-1]:.1f}"
    )
    grid = np.linspace(*span, 2001)
    truth = extended_reference.reference(prentice, grid)
    runs = {
        "rk78q12 as auto runs it": as_auto("rk78q12", prentice, atol=1e-6, t_span=span,
                                           t_eval=grid),
        "auto": hamrkq.solve(prentice, method="auto", atol=1e-6, t_span=span, t_eval=grid),
    }  # fmt: skip
    for label, sol in runs.items():
        evaluations = sol.stats["nfev"] + sol.stats["njev"]
        discarded = sol.stats.get("discarded_evaluations", 0)
        yield (
            f"{label} ({sol.method}): {sol.status.name}, {sol.options['z_substeps']} quencher "
            f"steps, witness ran: {sol.options['rounding_witness']}; {g(evaluations, 3)} "
            f"evaluations plus {g(discarded, 3)} discarded; largest node "
            f"{over_tolerance(sol.y, truth, 1e-6):.4f} delta; {first_run(sol.message)}"
        )


def gamma_over_error(sol, truth, signed: bool = False) -> np.ndarray:
    """Gamma over the quencher's true error, at every node and component where
    that error is above 1e-13 (as ``benchmarks/family.py`` takes its median)."""
    z_error = sol.z - truth
    where = np.abs(z_error) > 1e-13
    ratio = sol.gamma[where] / z_error[where]
    return ratio if signed else np.abs(ratio)


@fact('"Gamma" from the shadow track: prentice2011 over [0, 4000] at 1e-6, every node, heyoka')
def shadow_gamma():
    prentice = hamrkq.load_problem("prentice2011")
    for member in ("rk67q9", "rk78q12"):
        sol = as_auto(member, prentice, atol=1e-6)
        ratio = gamma_over_error(sol, extended_reference.reference(prentice, sol.t))
        p10, p50, p90 = np.percentile(ratio, [10, 50, 90])
        yield (
            f"{member} as auto runs it ({sol.options['z_substeps']} quencher steps): "
            f"|Gamma| over the quencher's true error, median {p50:.2f}, 10 % to 90 % of the "
            f"nodes between {p10:.2f} and {p90:.2f}"
        )


@fact(
    '"The promise at tight tolerances": a Morse oscillator, '
    "H = p^2/2 + 2 (1 - exp(-0.7 (x - 1.5)))^2 from x = 1.2, p = 0.9, atol 1e-6, heyoka"
)
def morse():
    from hamrkq.analysis.extended_reference import extended_reference as reference

    x, p = sp.symbols("x p")
    well = 2 * (1 - sp.exp(-sp.Rational(7, 10) * (x - sp.Rational(3, 2)))) ** 2
    ham = hamrkq.Hamiltonian(p**2 / 2 + well, q=[x], p=[p])
    y0 = np.array([1.2, 0.9])
    energy = 0.9**2 / 2 + 2 * (1 - math.exp(-0.7 * (1.2 - 1.5))) ** 2
    period = 2 * math.pi / (0.7 * math.sqrt(2 * 2) * math.sqrt(1 - energy / 2))
    yield f"period T = {period:.4f}"

    def run(periods, **options):
        span = (0.0, periods * period)
        sol = hamrkq.solve(ham, q0=[1.2], p0=[0.9], t_span=span, atol=1e-6, **options)
        return sol, np.asarray(reference(ham, np.zeros(0), y0, sol.t).y, dtype=float)

    sol, truth = run(200, method="rk67q9")
    median = np.median(gamma_over_error(sol, truth, signed=True))
    yield (
        f"rk67q9, 200 periods: {sol.status.name}, {sol.options['z_substeps']} quencher steps, "
        f"steps up to T/{period / np.diff(sol.t).max():.1f}, Gamma over the quencher's error "
        f"(median, signed) {median:.2f}"
    )
    sol, truth = run(600, method="rk67q9")
    largest = over_tolerance(sol.y, truth, 1e-6)
    yield f"rk67q9, 600 periods: {sol.status.name}, largest node {largest:.3f} delta"
    # the shadow named: a max_step makes the tangent estimate the default
    sol, truth = run(200, method="rk67q9", max_step=period / 20, global_error_estimate="shadow")
    median = np.median(gamma_over_error(sol, truth, signed=True))
    yield f"rk67q9, max_step T/20, 200 periods: Gamma over the quencher's error {median:.2f}"
    sol, truth = run(600, method="auto")
    yield (
        f"auto ({sol.method}, {sol.options['z_substeps']} quencher steps), 600 periods: "
        f"{sol.status.name}, largest node {over_tolerance(sol.y, truth, 1e-6):.3f} delta"
    )


def kepler_polar_exact(mu: float, r0: float, ell: float):
    """Kepler's orbit in polar coordinates from its pericentre ``r0`` at t = 0
    (theta = 0, p_r = 0, p_theta = ``ell``), to 40 digits: (the states at the
    times given, e, the period)."""
    import mpmath

    mp = mpmath.MPContext()
    mp.dps = 40
    mu, r0, ell = mp.mpf(mu), mp.mpf(r0), mp.mpf(ell)
    semi_latus = ell**2 / mu
    e = semi_latus / r0 - 1
    a = semi_latus / (1 - e**2)
    n = mp.sqrt(mu / a**3)
    beta = e / (1 + mp.sqrt(1 - e**2))

    def states(times) -> np.ndarray:
        rows = []
        for t in times:
            mean = n * mp.mpf(float(t))
            big_e = mp.findroot(lambda x: x - e * mp.sin(x) - mean, mean + e * mp.sin(mean))  # noqa: B023
            r = a * (1 - e * mp.cos(big_e))
            theta = big_e + 2 * mp.atan(beta * mp.sin(big_e) / (1 - beta * mp.cos(big_e)))
            p_r = a * e * mp.sin(big_e) * n / (1 - e * mp.cos(big_e))
            rows.append([float(r), float(theta), float(p_r), float(ell)])
        return np.array(rows)

    return states, float(e), float(2 * mp.pi / n)


@fact(
    '"The promise at tight tolerances": Kepler\'s problem in polar coordinates (k = 1.3, '
    "r = 0.4, p_r = 0, theta = 0, p_theta = 0.95), 30 orbits, auto, exact solution (mpmath)"
)
def polar_kepler():
    r, th, pr, pth, k = sp.symbols("r theta p_r p_theta k")
    ham = hamrkq.Hamiltonian(pr**2 / 2 + pth**2 / (2 * r**2) - k / r, q=[r, th], p=[pr, pth],
                             parameters={k: 1.3})  # fmt: skip
    exact, e, period = kepler_polar_exact(1.3, 0.4, 0.95)
    yield f"e = {e:.4f}, period T = {period:.4f}"
    span = (0.0, 30 * period)
    capped = {"max_step": 1e-3, "keep_every": 97}
    # A max_step alone makes auto's estimate the tangent one, whose quencher
    # is in double: the quencher in double-double named keeps the shadow.
    extended = {**capped, "quencher_precision": "double-double"}
    for rtol, extra in ((1e-6, {}), (1e-6, capped), (1e-6, extended), (1e-9, {})):
        sol = hamrkq.solve(ham, q0=[0.4, 0.0], p0=[0.0, 0.95], t_span=span, method="auto",
                           atol=1e-14, rtol=rtol, **extra)  # fmt: skip
        truth = exact(sol.t)
        delta = np.maximum(1e-14, rtol * np.abs(truth))
        at = int(np.argmax((np.abs(sol.y - truth) / delta).max(axis=1)))
        largest_step = 1e-3 if extra else np.diff(sol.t).max()
        label = f"rtol {rtol:g}, atol 1e-14" + (", max_step 1e-3" if extra else "")
        label += ", quencher_precision='double-double'" if "quencher_precision" in extra else ""
        yield (
            f"auto at {label}: {sol.status.name} at t = {sol.t[-1]:.5g} "
            f"({sol.options['quencher_precision']} "
            f"quencher), largest step {largest_step:.2g}, largest node "
            f"{over_tolerance(sol.y, truth, 1e-14, rtol):.3g} delta (at t = {sol.t[at]:.4g}, "
            f"p_r = {truth[at, 2]:.1e} there), the quencher's largest error "
            f"{g(worst(sol.z - truth))}, Gamma at most {g(worst(sol.gamma))}"
        )


# -- "Orbits whose error grows exponentially" -------------------------------------------
@fact('"The rules after a run": the pendulum over the top from q = 0, p = 3, [0, 5000], 501 times')
def pendulum_over_the_top():
    pendulum = hamrkq.load_problem("pendulum")
    times = np.linspace(0.0, 5000.0, 501)
    sol = hamrkq.solve(pendulum, [0.0], [3.0], (0.0, 5000.0), atol=1e-9, t_eval=times,
                       max_steps=10**7, method="rk34q8")  # fmt: skip
    floor = "names DOP853's floor" if "floor" in sol.message else "does not name the floor"
    stop = re.search(r"^At t = ([0-9.]+)", sol.message)
    stopped = float(stop.group(1)) if stop else float(sol.t[-1])
    yield f"rk34q8 at 1e-9: {first_run(sol.message)}"
    yield (
        f"rk34q8 at 1e-9, run again with the witness: {sol.status.name} at t = {stopped:.1f} "
        f"({floor}; the last output time kept {sol.t[-1]:g})"
    )
    sol = hamrkq.solve(pendulum, [0.0], [3.0], (0.0, 5000.0), method="auto", atol=1e-8,
                       t_eval=times)  # fmt: skip
    again = "run again with the witness" in sol.message
    yield (
        f"auto at 1e-8: {sol.status.name}, q = {sol.y[-1, 0]:.0f} at t = 5000, run again with "
        f"the witness: {again}, its quencher in {sol.options['quencher_precision']}"
    )


@fact('"The rules after a run": how far the outer solar system\'s component sizes grow, auto')
def state_growth():
    from hamrkq.rkq.scales import component_scales
    from hamrkq.rkq.witness_rules import STATE_GROWTH

    solar = hamrkq.load_problem("outer_solar_system")
    sol = hamrkq.solve(solar)  # the file's tolerances
    atol = np.broadcast_to(np.asarray(sol.options["atol"], dtype=float), solar.y0.shape)
    start = component_scales(atol, np.abs(solar.y0))
    grown = component_scales(atol, np.maximum(np.abs(solar.y0), np.abs(sol.y).max(axis=0)))
    yield (
        f"the largest growth of a component's size (witness_rules.component_scales) over the "
        f"run, every node: {float(np.max(grown / start)):.2f}-fold "
        f"(STATE_GROWTH = {STATE_GROWTH:g})"
    )


@fact("\"The shadow's linear regime\": the shadow's largest departure, auto on the catalogue")
def catalogue_departure():
    """(m^z - 1) |Gamma_k| / size_k (``auto_rules.shadow_departure``) at
    every node, auto on every catalogue problem over its own interval at
    atol 1e-4, 1e-6, 1e-8 and 1e-10 (rtol 0)."""
    from hamrkq.rkq.scales import component_scales

    largest = []
    for name in hamrkq.list_problems():
        problem = hamrkq.load_problem(name)
        for tol in (1e-4, 1e-6, 1e-8, 1e-10):
            sol = hamrkq.solve(problem, method="auto", atol=tol, rtol=0.0)
            order = int(re.search(r"q(\d+)$", sol.method).group(1))
            amplification = sol.options["z_substeps"] ** order - 1
            scale = component_scales(np.full(problem.y0.shape, tol), np.abs(sol.y).max(axis=0))
            departure = auto_rules.shadow_departure(sol.gamma, scale, amplification)
            largest.append((float(departure.max()), name, tol))
    largest.sort(reverse=True)
    top = ", ".join(f"{d:.2g} ({name} at {tol:g})" for d, name, tol in largest[:3])
    yield f"{len(largest)} runs, atol 1e-4 to 1e-10; the largest: {top}"


# -- "The quencher in double-double" ---------------------------------------------------
@fact(
    '"The quencher in double-double", "Limits": a collision, H = p^2/2 - 1/q from q = 1, '
    "p = -2, auto at atol 1e-6, against the exact solution (mpmath, 40 digits)"
)
def collision():
    import mpmath

    mp = mpmath.MPContext()
    mp.dps = 40
    q, p = sp.symbols("q p")
    ham = hamrkq.Hamiltonian(p**2 / 2 - 1 / q, q=[q], p=[p])

    def since_start(x):  # sqrt(2) (the time from q = 1 to q = x), up to a constant
        return mp.sqrt(x * (x + 1)) - mp.asinh(mp.sqrt(x))

    t_collision = since_start(mp.mpf(1)) / mp.sqrt(2)

    def exact(times) -> np.ndarray:
        rows = []
        for t in times:
            x = mp.mpf(1)
            if t != 0:
                target = since_start(mp.mpf(1)) - mp.sqrt(2) * mp.mpf(float(t))
                x = mp.findroot(lambda x, target=target: since_start(x) - target,
                                (mp.mpf("1e-40"), mp.mpf(1)), solver="anderson")  # fmt: skip
            rows.append([float(x), float(-mp.sqrt(2 + 2 / x))])
        return np.array(rows)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        common = dict(q0=[1.0], p0=[-2.0], t_span=(0.0, 2.0), atol=1e-6)
        sol = hamrkq.solve(ham, method="auto", **common)
        many = hamrkq.solve(ham, method="rk78q12", z_substeps=32,
                            quencher_precision="double-double", **common)  # fmt: skip
    before = float(t_collision - mp.mpf(float(sol.t[-1])))
    yield (
        f"auto: {sol.status.name} {g(before)} before the collision ({sol.options['z_substeps']} "
        f"quencher steps, in {sol.options['quencher_precision']}), largest node "
        f"{over_tolerance(sol.y, exact(sol.t), 1e-6):.3f} delta"
    )
    yield (
        f"rk78q12 with 32 quencher steps in double-double: {many.status.name}, the quencher "
        f"{g(worst(many.z - exact(many.t)))} from the 40-digit solution (rounded to double) "
        f"at its {many.t.size} nodes"
    )


@fact(
    '"The quencher in double-double", "Limits": the substeps\' shortfall, prentice2011 to '
    "t = 1000, rk78q12 in double-double (atol 1e-16, rtol 1e-10), heyoka in 113-bit floats"
)
def dd_shortfall():
    import heyoka as hy

    from hamrkq.analysis.extended_reference import _equations

    prentice = hamrkq.load_problem("prentice2011")
    params = np.asarray(prentice.parameter_array, dtype=float).ravel()
    system = _equations(prentice.hamiltonian, params)

    def states(bits: int) -> np.ndarray:
        real = [hy.real(float(v), bits) for v in prentice.y0]
        tol, start = hy.real(2.0 ** (16 - bits), bits), hy.real(0.0, bits)
        ta = hy.taylor_adaptive(system.equations, np.array(real), fp_type=hy.real, prec=bits,
                                tol=tol, time=start, pars=system.pars(hy.real, bits))  # fmt: skip
        ta.propagate_until(hy.real(1000.0, bits))
        return np.array([float(v) for v in ta.state])

    reference = states(113)
    yield f"the reference against the same at 177 bits: {g(worst(reference - states(177)))}"
    for m in (3, 4, 6, 8):
        sol = hamrkq.solve(prentice, method="rk78q12", z_substeps=m, atol=1e-16, rtol=1e-10,
                           quencher_precision="double-double", t_span=(0.0, 1000.0),
                           gamma_limit=np.inf)  # fmt: skip
        yield f"{m} quencher steps: the quencher {g(worst(sol.z[-1] - reference))} off at t = 1000"


# -- "The promise on the whole catalogue" ------------------------------------------------
@fact("The quenchers' weights: the sum of |b_i| (witness_rules.STAGE_ROUNDING_WEIGHTS)")
def weight_sums():
    from hamrkq.methods.registry import QUENCHERS, get_quencher
    from hamrkq.rkq.witness_rules import STAGE_ROUNDING_WEIGHTS

    for name in QUENCHERS:
        b = np.array([float(x) for x in get_quencher(name).b])
        yield f"{name}: {np.abs(b).sum():.2f}"
    yield f"STAGE_ROUNDING_WEIGHTS = {STAGE_ROUNDING_WEIGHTS:g}"


# -- "## Example" ----------------------------------------------------------------------
def example_block() -> str:
    """The first ``python`` block after the page's "## Example" heading."""
    text = PAGE.read_text()
    section = text[text.index("\n## Example\n") :]
    found = re.search(r"```python\n(.*?)```", section, re.S)
    assert found is not None, "docs/algorithm.md has no python block under ## Example"
    return found.group(1)


@fact('"## Example": the page\'s block, run as it stands; its printed output', raw=True)
def example():
    printed = io.StringIO()
    code = compile(example_block(), "docs/algorithm.md (Example)", "exec")
    with contextlib.redirect_stdout(printed):
        exec(code, {"__name__": "__example__"})
    yield from printed.getvalue().splitlines()


def main() -> None:
    warnings.simplefilter("ignore")
    commit = head_commit()
    lines = [
        "# Facts quoted in docs/algorithm.md (generated by `benchmarks/algorithm_facts.py`)",
        "",
        f"Run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on commit {commit}; "
        "each section's wall time in parentheses.",
    ]
    only = set(sys.argv[1:])
    for title, function, raw in FACTS:
        if only and function.__name__ not in only:
            continue
        start = time.perf_counter()
        lines += ["", f"## {title}", ""] + (["```"] if raw else [])
        for line in function():
            print(line, flush=True)
            lines.append(line if raw else f"- {line}")
        seconds = time.perf_counter() - start
        lines += (["```"] if raw else []) + ["", f"({seconds:.1f} s)"]
        print(f"[{function.__name__}: {seconds:.1f} s]", flush=True)
    if not only:
        OUT.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
