"""``hamrkq ensemble NAME|FILE --grid NAME=LO:HI:N ...``: a product grid of
initial values and/or parameters, integrated as one ensemble.

Each ``--grid`` names a coordinate, a momentum or a parameter of the problem;
the members are the product grid (the first ``--grid`` varying slowest), and
every other value comes from the problem.  What it writes into ``--out``
(default ``./hamrkq-ensemble/NAME``), every file atomically:

- ``ensemble.npz``: :meth:`hamrkq.EnsembleSolution.save` (read back with
  ``EnsembleSolution.load``);
- ``summary.json``: the settings, the grid, counts of members and failures,
  the largest energy drift and estimated global error, wall time;
- ``ensemble_map.png``: ``--quantity`` over the grid (one or two ``--grid``),
  and ``ensemble_orbits.png``: the orbits in the first ``(q, p)`` plane
  coloured by H (with ``--samples`` of 2 or more), unless ``--no-plots``.

A progress bar over members goes to stderr on a terminal.  Exit status: 0
every member succeeded, 1 some member failed (everything is still written),
2 bad input.  Ctrl-C or SIGTERM ends the ensemble (:func:`hamrkq.ensemble`
keeps the members of every chunk finished and marks the others
``INTERRUPTED``): the files are written with ``"partial": true`` and the exit
status is 1.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from typing import Any

import numpy as np

from hamrkq.catalogue.problems import load_problem
from hamrkq.cli.interrupts import (
    QUICK_REPORT,
    interrupted,
    interrupts_held,
    quick_report,
    signals_received,
)
from hamrkq.cli.run import check_step
from hamrkq.ensemble import EnsembleSolution, ensemble
from hamrkq.errors import InputError
from hamrkq.io.report import OutputDir, check_dpi
from hamrkq.result import Status

__all__ = ["QUANTITIES", "check_kept_states", "ensemble_command", "parse_grid", "register"]

DEFAULT_ROOT = "hamrkq-ensemble"
#: Per-member quantities ``--quantity`` can map, with their labels and scales.
QUANTITIES = {
    "energy_drift": ("max |H - H(0)|", True),
    "max_global_error": ("max estimated |global error|", True),
    "energy0": ("H(0)", False),
    "nfev": ("function evaluations", True),
}
#: Largest grid accepted from the command line (the library takes any size).
MAX_MEMBERS = 100_000_000
#: The share of the machine's memory the states kept (members x samples x 2n
#: doubles) may take: beyond it the run would fail to allocate, or swap.
MEMORY_SHARE = 0.5


def register(subparsers: Any) -> None:
    """Add the ``ensemble`` subcommand."""
    p = subparsers.add_parser(
        "ensemble",
        help="integrate a grid of initial values and/or parameters; write ensemble.npz",
        description=(
            "Integrate the product grid of --grid NAME=LO:HI:N (coordinates, momenta or "
            "parameters of the problem; other values from the problem file) on all "
            "cores. Exit status: 0 every member succeeded, 1 some failed (all results "
            "are written), 2 bad input."
        ),
    )
    p.add_argument("problem", metavar="NAME|FILE", help="catalogue name or .toml file")
    p.add_argument(
        "--grid", action="append", default=[], metavar="NAME=LO:HI:N", required=True,
        help="N values from LO to HI (inclusive) for a coordinate, momentum or parameter; "
        "repeatable, the members are the product grid",
    )  # fmt: skip
    p.add_argument("--t-end", type=float, metavar="T", help="end of the interval")
    p.add_argument("--atol", type=float, metavar="A", help="absolute tolerance")
    p.add_argument("--rtol", type=float, metavar="R", help="relative tolerance")
    p.add_argument("--method", metavar="M", help="integration method (default: the problem's)")
    p.add_argument("--max-steps", type=int, metavar="N", help="limit on step attempts")
    p.add_argument(
        "--samples", type=int, default=1, metavar="K",
        help="keep K equally spaced times per member, t0 to t_end (default 1: the end only)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, metavar="N", help="cores to use (default: all)")
    p.add_argument(
        "--quantity", choices=tuple(QUANTITIES), default="energy_drift",
        help="the per-member quantity mapped over the grid (default energy_drift)",
    )  # fmt: skip
    p.add_argument("--out", metavar="DIR", help="output directory (default hamrkq-ensemble/NAME)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--no-plots", action="store_true", help="do not draw the figures")
    p.add_argument(
        "--dpi", type=int, default=120, help="resolution of the PNGs (10 to 600, default 120)"
    )
    p.set_defaults(func=ensemble_command)


def parse_grid(items: list[str], known: list[str]) -> list[tuple[str, np.ndarray]]:
    """``["q=-1:1:5", ...]`` -> ``[("q", array of 5 values), ...]``; plain numbers
    only (``float``), never expressions, and each name once."""
    parsed: list[tuple[str, float, float, int]] = []
    for item in items:
        name, sep, spec = item.partition("=")
        name = name.strip()
        parts = spec.split(":")
        if not sep or len(parts) != 3:
            raise InputError(f"--grid {item!r}: expected NAME=LO:HI:N")
        lo, hi = (_finite(text) for text in parts[:2])
        if lo is None or hi is None:
            raise InputError(f"--grid {item!r}: LO and HI must be finite numbers")
        try:
            count = int(parts[2])
        except ValueError:
            count = 0
        if count < 1:
            raise InputError(f"--grid {item!r}: N must be a positive integer, got {parts[2]!r}")
        if name not in known:
            raise InputError(
                f"--grid {item!r}: {name!r} is not a coordinate, momentum or parameter "
                f"of the problem ({', '.join(known)})"
            )
        if name in (a for a, *_ in parsed):
            raise InputError(f"--grid {item!r}: {name!r} is given twice")
        parsed.append((name, lo, hi, count))
    # The size before any array: N = 1e11 on one axis once asked NumPy for
    # 745 GiB and ended in a MemoryError traceback.
    size = math.prod(count for *_, count in parsed)
    if size > MAX_MEMBERS:
        raise InputError(f"--grid: {size} members is more than {MAX_MEMBERS}")
    return [(name, np.linspace(lo, hi, count)) for name, lo, hi, count in parsed]


def check_kept_states(members: int, samples: int, dim: int) -> None:
    """Refuse ``--samples`` whose kept states (``members x samples x dim``
    doubles, the ensemble's ``y``) would take more than :data:`MEMORY_SHARE`
    of this machine's memory."""
    if samples < 1:
        raise InputError(f"--samples must be a positive integer, got {samples}")
    needed = members * samples * dim * 8
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # no sysconf: a generous 2**40
        memory = 1 << 40
    if needed > MEMORY_SHARE * memory:
        raise InputError(
            f"--samples {samples}: {members} members x {samples} samples x {dim} numbers "
            f"would take {needed / 2**30:.3g} GiB, more than half this machine's memory "
            f"({memory / 2**30:.3g} GiB); keep fewer samples or members"
        )


def _finite(text: str) -> float | None:
    """``float(text)`` if that is a finite number, else None."""
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def ensemble_command(args: argparse.Namespace) -> int:
    """The ``ensemble`` subcommand; returns the exit status."""
    check_dpi(args.dpi)
    problem = load_problem(args.problem)
    ham = problem.hamiltonian
    q_names = [s.name for s in ham.q]
    p_names = [s.name for s in ham.p]
    par_names = [s.name for s in ham.parameters]
    axes = parse_grid(args.grid, [*q_names, *p_names, *par_names])
    check_step(args.method, None, problem, "hamrkq.ensemble(..., step=h) (this command has none)")
    check_kept_states(math.prod(len(values) for _, values in axes), args.samples, ham.dim)
    mesh = np.meshgrid(*(values for _, values in axes), indexing="ij")
    columns = {name: m.ravel() for (name, _), m in zip(axes, mesh, strict=True)}
    t0 = problem.t_span[0]
    t_end = problem.t_span[1] if args.t_end is None else args.t_end
    options = {
        k: getattr(args, k)
        for k in ("atol", "rtol", "method", "max_steps")
        if getattr(args, k) is not None
    }
    t_eval = np.linspace(t0, t_end, args.samples) if args.samples > 1 else None
    out = OutputDir(args.out or f"{DEFAULT_ROOT}/{problem.name}", force=args.force)

    started = time.perf_counter()
    ens = ensemble(
        problem,
        q0=_pick(columns, q_names),
        p0=_pick(columns, p_names),
        t_span=(t0, t_end),
        parameters=_pick(columns, par_names),
        t_eval=t_eval,
        workers=args.workers,
        **options,
    )
    wall = time.perf_counter() - started
    with interrupts_held() as held:
        out.solution("ensemble.npz", ens)  # any result with .save(path): atomic, recorded
    missing = int(np.count_nonzero(ens.status == Status.INTERRUPTED.code))
    notes = []
    if ens.options.get("events_not_located"):  # the warning's words, kept
        notes.append(str(ens.options["events_not_located"]))
    if missing:
        notes.append(f"interrupted: {missing} of {len(ens)} members not integrated")
    if quick_report():
        notes.append(QUICK_REPORT)
    elif held:  # Ctrl-C while the ensemble was written: as a second Ctrl-C
        notes.append("figures not drawn: interrupted")
    elif not args.no_plots:
        try:
            notes += _figures(out, ens, axes, args)
        except KeyboardInterrupt:  # a second Ctrl-C: the figure being drawn is not written
            notes.append("interrupted while the figures were drawn; figures incomplete")
    with interrupts_held():
        if signals_received():
            notes.append(f"stopped by {', '.join(signals_received())} (handled like Ctrl-C)")
        summary = _summary(args, problem, ens, axes, wall, out, notes)
        out.json("summary.json", summary)
    print(f"{problem.name}: {len(ens)} members, {ens.failed.size} failed, {wall:.2f} s")
    for key in ("max_energy_drift", "max_global_error"):
        print(f"  {key}: {summary[key]}")
    for i, text in zip(ens.failed[:5].tolist(), ens.messages[:5], strict=False):
        print(f"  member {i} ({_where(ens, i)}): {text}")
    for note in notes:
        print(f"note: {note}")
    print(f"wrote {out.path}/: {', '.join(out.written)}")
    return 0 if ens.all_success and not interrupted() else 1


def _pick(columns: dict[str, np.ndarray], names: list[str]) -> dict[str, np.ndarray] | None:
    chosen = {name: columns[name] for name in names if name in columns}
    return chosen or None


def _where(ens: EnsembleSolution, i: int) -> str:
    values = [f"{n}={v:.6g}" for n, v in zip(ens.names, ens.y0[i], strict=True)]
    values += [f"{n}={v[i]:.6g}" for n, v in ens.parameters.items()]
    return ", ".join(values)


def _figures(out: OutputDir, ens: EnsembleSolution, axes, args) -> list[str]:
    from hamrkq.plotting import ensemble as plots

    notes = []
    if len(axes) <= 2:
        label, log = QUANTITIES[args.quantity]
        values = ens.stats["nfev"] if args.quantity == "nfev" else getattr(ens, args.quantity)
        fig = plots.member_map(values, axes, label=label, log=log)
        fig.axes[0].set_title(f"{args.problem}: {args.quantity}, t_end = {ens.t_span[1]:g}")
        out.figure("ensemble_map.png", fig, dpi=args.dpi)
    else:
        notes.append("ensemble_map.png not drawn: more than two --grid axes")
    if ens.t.size >= 2:
        out.figure("ensemble_orbits.png", plots.orbits(ens), dpi=args.dpi)
    return notes


def _summary(args, problem, ens: EnsembleSolution, axes, wall: float, out, notes) -> dict:
    def biggest(values: np.ndarray) -> float | None:
        finite = values[np.isfinite(values)]
        return float(finite.max()) if finite.size else None

    gridded = {name for name, _ in axes}
    return {
        "command": "ensemble",
        "problem": args.problem,
        "grid": [
            {"name": name, "lo": float(v[0]), "hi": float(v[-1]), "n": len(v)} for name, v in axes
        ],
        "members": len(ens),
        # Ctrl-C or SIGTERM: the members not integrated are INTERRUPTED
        "partial": bool(np.any(ens.status == Status.INTERRUPTED.code)),
        "failed": ens.failed.size,
        "failed_members": ens.failed[:100].tolist(),
        "t_span": list(ens.t_span),
        "samples": int(ens.t.size),
        "method": ens.method,  # the file's or the default (auto), which options may not name
        "options": dict(ens.options),
        # the fixed ones: a gridded parameter takes the grid's values (listed
        # under "grid", as gridded initial values are), not the file's default
        "parameters": {k: v for k, v in problem.parameters.items() if k not in gridded},
        "workers": args.workers,
        "max_energy_drift": biggest(ens.energy_drift),
        "max_global_error": biggest(ens.max_global_error),
        "nfev_total": int(ens.stats["nfev"].sum()),
        "wall_time_s": wall,
        "notes": notes,
        "files": [*out.written, "summary.json"],
    }
