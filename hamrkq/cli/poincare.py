"""``hamrkq poincare``: the surface of section of a catalogue problem at an energy.

Chooses ``--orbits`` initial conditions on the section at ``--energy``
(:func:`hamrkq.analysis.energy_surface.energy_orbits`), integrates each with RKQ
and the section as an event, draws the crossings coloured by orbit, or by
its MEGNO with ``--megno`` (``section.png``), and writes them to
``section.npz`` with ``summary.json``.

The orbits run one after the other.  Ctrl-C or SIGTERM stops the orbit
running (its crossings so far are kept, :func:`hamrkq.solve` locating them
for half a second at most) and starts no other; the files are written with
``"partial": true``, every orbit not finished marked ``INTERRUPTED``, and
the exit status is 1.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np
import sympy as sp

from hamrkq._files import atomic_file
from hamrkq.analysis.chaos import indicator_of
from hamrkq.analysis.energy_surface import energy_orbits
from hamrkq.analysis.poincare import PoincareSection, poincare
from hamrkq.backends.numeric import numeric_of
from hamrkq.baselines import PREFIX as SCIPY_PREFIX
from hamrkq.catalogue.problem import Problem
from hamrkq.catalogue.problems import load_problem
from hamrkq.cli.interrupts import (
    QUICK_REPORT,
    interrupted,
    interrupts_held,
    quick_report,
    signals_received,
)
from hamrkq.errors import InputError
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS
from hamrkq.io.report import OutputDir, check_dpi, jsonable
from hamrkq.options import refused_options
from hamrkq.result import Status
from hamrkq.symbolic.expressions import parse_expression

__all__ = ["poincare_command", "register"]


def register(subparsers: Any) -> None:
    """Add the ``poincare`` subcommand."""
    p = subparsers.add_parser(
        "poincare",
        help="Poincare section of a two-degree-of-freedom problem at a given energy",
        description=(
            "Integrate ORBITS orbits started on the section at energy E, record their "
            "crossings of the section (events refined on the dense output) and write "
            "section.npz, section.png and summary.json."
        ),
    )
    p.add_argument("problem", metavar="NAME|FILE", help="catalogue name or .toml file")
    p.add_argument(
        "--section",
        default="q1 = 0",
        help="the surface, 'q_k = c': a coordinate and a constant, such as 'q1 = 1/10' "
        "(default q1 = 0)",
    )
    p.add_argument(
        "--energy",
        help="the energy E (a number or '1/8'; default: H at the problem's initial values)",
    )
    p.add_argument("--orbits", type=int, default=20, help="number of orbits (default 20)")
    p.add_argument("--t-end", type=float, default=1000.0, help="length of each run (1000)")
    p.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance (1e-9)")
    p.add_argument(
        "--gamma-limit",
        type=float,
        default=None,
        help="solve's gamma_limit (default inf: chaotic orbits run to the end; the "
        "pointwise promise is lost after a few Lyapunov times, the section is not)",
    )
    p.add_argument(
        "--method", metavar="M", help="integration method, 'auto' say (default: the problem's)"
    )
    p.add_argument("--backend", default="auto", help="auto, numba or python")
    p.add_argument(
        "--megno",
        action="store_true",
        help="also compute each orbit's MEGNO <Y> at the end (summary.json) and colour the "
        "section by it",
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default hamrkq-poincare/NAME)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--no-plots", action="store_true", help="do not draw the figure")
    p.add_argument(
        "--dpi", type=int, default=150, help="resolution of the PNG (10 to 600, default 150)"
    )
    p.set_defaults(func=poincare_command)


def initial_energy(problem: Problem) -> float:
    """H at the problem's initial values and parameters (``--energy``'s default)."""
    values = problem.parameter_array
    return float(numeric_of(problem.hamiltonian).energy(problem.t_span[0], problem.y0, values))


def poincare_command(args: argparse.Namespace) -> int:
    """Run the ``poincare`` subcommand; returns the exit status."""
    check_dpi(args.dpi)
    problem = load_problem(args.problem)
    ham = problem.hamiltonian
    if ham.n != 2:
        raise InputError(
            f"hamrkq poincare starts its orbits on the energy surface of a system with two "
            f"degrees of freedom (the section is then the plane of the other coordinate "
            f"and momentum); {problem.name} has {ham.n}. For other systems, call "
            "hamrkq.poincare(problem, section, q0, p0, t_span) with initial values of your own"
        )
    if args.energy is None:
        energy = initial_energy(problem)
        energy_text = f"{energy:.6g}"
    else:
        energy = float(sp.N(parse_expression(args.energy, {}, key="--energy")))
        energy_text = args.energy
    if args.orbits < 1:
        raise InputError(f"--orbits must be at least 1, got {args.orbits}")
    out = OutputDir(args.out or f"hamrkq-poincare/{problem.name}", force=args.force)
    q0, p0 = energy_orbits(ham, energy, args.orbits, args.section, problem.parameters)
    options = dict(atol=args.atol, backend=args.backend)
    if args.method is not None:
        options["method"] = args.method
    method = options.get("method") or problem.integration.get("method") or "auto"
    if method in FIXED_STEP_METHODS or method.startswith(SCIPY_PREFIX):
        raise InputError(
            f"poincare finds the crossings on the dense output of the RKQ family: method "
            f"{method!r} has none; use --method auto, rk34q8 or another member"
        )
    if args.gamma_limit is not None:
        options["gamma_limit"] = args.gamma_limit  # solve refuses it where it does not apply
    elif "gamma_limit" not in refused_options(method)[0]:
        options["gamma_limit"] = math.inf  # chaotic orbits run to the end
    started = time.perf_counter()
    sec, indicators = _orbits(
        problem, args.section, q0, p0, (0.0, args.t_end), options, args.megno
    )
    elapsed = time.perf_counter() - started
    done = len(sec.solutions)
    statuses = [s.status.name for s in sec.solutions]
    statuses += [Status.INTERRUPTED.name] * (args.orbits - done)  # never started
    partial = Status.INTERRUPTED.name in statuses
    notes = []
    if done < args.orbits:
        notes.append(f"orbits {done} to {args.orbits - 1} (from 0) were not started")
    notes += sorted({s.options["events_not_located"] for s in sec.solutions if _partial(s)})
    lhs = args.section.split("=")[0].strip()
    k = [s.name for s in ham.q].index(lhs)
    x, y = ham.q[1 - k].name, ham.p[1 - k].name
    with interrupts_held() as held:
        with atomic_file(out.file("section.npz")) as handle:
            np.savez_compressed(
                handle, t=sec.t, y=sec.y, orbit=sec.orbit, q0=q0, p0=p0,
                names=np.array(ham.names),
            )  # fmt: skip
        out.written.append("section.npz")
    if quick_report():
        notes.append(QUICK_REPORT)
    elif held:  # Ctrl-C while the crossings were written: as a second Ctrl-C
        notes.append("section.png not drawn: interrupted")
    elif not args.no_plots:
        title = f"{problem.name}: {args.section}, E = {energy_text}, {args.orbits} orbits"
        notes += _figure(out, sec, x, y, indicators, title, args.dpi)
    with interrupts_held():
        if signals_received():
            notes.append(f"stopped by {', '.join(signals_received())} (handled like Ctrl-C)")
        out.json(
            "summary.json",
            jsonable(
                {
                    "command": "poincare",
                    "problem": problem.name,
                    "section": args.section,
                    "energy": energy,
                    "orbits": args.orbits,
                    "t_end": args.t_end,
                    "options": options,
                    # what ran ("auto" names its member)
                    "method": sorted({s.method for s in sec.solutions}),
                    "crossings": int(sec.t.size),
                    # one per orbit: an orbit not started is INTERRUPTED too
                    "status": statuses,
                    "partial": partial,
                    "megno": indicators,
                    "wall_time_s": elapsed,
                    "notes": notes,
                    "files": [*out.written, "summary.json"],
                }
            ),
        )
    orbits = f"{args.orbits}" if done == args.orbits else f"{done} of {args.orbits}"
    print(
        f"{sec.t.size} crossings of {args.section} by {orbits} orbits at "
        f"E = {energy:.6g} in {elapsed:.1f} s; wrote {', '.join(out.written)} to {out.path}"
    )
    for note in notes:
        print(f"note: {note}")
    return 0 if sec.success and not partial and not interrupted() else 1


def _orbits(
    problem: Problem,
    section: str,
    q0: np.ndarray,
    p0: np.ndarray,
    t_span: tuple[float, float],
    options: dict[str, Any],
    megno: bool,
) -> tuple[PoincareSection, list[float] | None]:
    """The section's crossings by each orbit of ``q0``/``p0`` in turn, and
    each orbit's MEGNO at its end (with ``megno``; NaN for an orbit
    interrupted).  Ctrl-C or SIGTERM ends the orbit running (solve keeps its
    nodes and the crossings among them) and starts no other; the orbits
    run so far are returned.  Before the first orbit has a result, it
    propagates: nothing to keep (the command line says "terminated")."""
    parts: list[PoincareSection] = []
    indicators: list[float] = []
    try:
        for q, p in zip(q0, p0, strict=True):
            part = poincare(problem, section, q, p, t_span, **options)
            parts.append(part)
            (sol,) = part.solutions
            if sol.status is Status.INTERRUPTED:
                break
            if megno:  # along the section's own run: each orbit integrated once
                indicators.append(float(indicator_of("megno", sol, problem).value[-1]))
    except KeyboardInterrupt:
        # Between two orbits, or while one was set up or its MEGNO computed:
        # the orbits run so far stand.
        if not parts:
            raise
    if megno:
        indicators += [math.nan] * (len(parts) - len(indicators))
    combined = PoincareSection.of(
        parts[0].section, parts[0].names, [part.solutions[0] for part in parts]
    )
    return combined, indicators if megno else None


def _partial(sol: Any) -> bool:
    """Whether ``sol``'s crossings were located along part of its run only."""
    return bool(sol.options.get("events_not_located"))


def _figure(
    out: OutputDir,
    sec: PoincareSection,
    x: str,
    y: str,
    indicators: list[float] | None,
    title: str,
    dpi: int,
) -> list[str]:
    """Draw ``section.png``; returns notes (none, or that Ctrl-C or SIGTERM
    stopped the drawing, which leaves no file)."""
    from hamrkq.plotting.sections import section_figure

    try:
        figure = section_figure(sec, x, y, title=title, megno=indicators)
        out.figure("section.png", figure, dpi=dpi)
    except KeyboardInterrupt:
        return ["section.png not drawn: interrupted"]
    return []
