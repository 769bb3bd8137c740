"""``hamrkq poincare``: the surface of section of a catalogue problem at an energy.

Chooses ``--orbits`` initial conditions on the section at ``--energy``
(:func:`hamrkq.analysis.poincare.energy_orbits`), integrates each with RKQ
and the section as an event, draws the crossings coloured by orbit, or by
its MEGNO with ``--megno`` (``section.png``), and writes them to
``section.npz`` with ``summary.json``.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.analysis.chaos import indicator_of
from hamrkq.analysis.poincare import energy_orbits, poincare
from hamrkq.backends.numeric import numeric_of
from hamrkq.catalogue.problem import Problem
from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import InputError
from hamrkq.io.report import OutputDir, jsonable
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
    p.add_argument("--section", default="q1 = 0", help="the surface, 'q_k = c' (default q1 = 0)")
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
        default=math.inf,
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
    p.add_argument("--dpi", type=int, default=150, help="resolution of the PNG (default 150)")
    p.set_defaults(func=poincare_command)


def initial_energy(problem: Problem) -> float:
    """H at the problem's initial values and parameters (``--energy``'s default)."""
    values = problem.parameter_array
    return float(numeric_of(problem.hamiltonian).energy(problem.t_span[0], problem.y0, values))


def poincare_command(args: argparse.Namespace) -> int:
    """Run the ``poincare`` subcommand; returns the exit status."""
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
    options = dict(atol=args.atol, gamma_limit=args.gamma_limit, backend=args.backend)
    if args.method is not None:
        options["method"] = args.method
    started = time.perf_counter()
    sec = poincare(problem, args.section, q0, p0, (0.0, args.t_end), **options)
    elapsed = time.perf_counter() - started
    indicators = None
    if args.megno:  # along the section's own runs: each orbit integrated once
        indicators = [
            float(indicator_of("megno", orbit, problem).value[-1]) for orbit in sec.solutions
        ]
    lhs = args.section.split("=")[0].strip()
    k = [s.name for s in ham.q].index(lhs)
    x, y = ham.q[1 - k].name, ham.p[1 - k].name
    np.savez_compressed(
        out.file("section.npz"), t=sec.t, y=sec.y, orbit=sec.orbit, q0=q0, p0=p0,
        names=np.array(ham.names),
    )  # fmt: skip
    out.written.append("section.npz")
    if not args.no_plots:
        from hamrkq.plotting.sections import section_figure

        title = f"{problem.name}: {args.section}, E = {energy_text}, {args.orbits} orbits"
        figure = section_figure(sec, x, y, title=title, megno=indicators)
        out.figure("section.png", figure, dpi=args.dpi)
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
                "status": [s.status.name for s in sec.solutions],
                "megno": indicators,
                "wall_time_s": elapsed,
            }
        ),
    )
    print(
        f"{sec.t.size} crossings of {args.section} by {args.orbits} orbits at E = {energy:.6g} "
        f"in {elapsed:.1f} s; wrote {', '.join(out.written)} to {out.path}"
    )
    return 0 if sec.success else 1
