"""Poincare sections: where orbits cross a surface, from the events machinery.

:func:`poincare` integrates each orbit with :func:`hamrkq.solve` and an event
``g = lhs - rhs`` of the section ``"lhs = rhs"`` (every node kept, roots
refined on the dense output, see :mod:`hamrkq.events`), so a crossing's time
and state carry the run's error bound.  :func:`energy_orbits` chooses initial
conditions on a section at a given energy, the classic way of drawing a
section of a two-degree-of-freedom system (Henon & Heiles 1964).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.catalogue.problems import Problem
from hamrkq.errors import InputError
from hamrkq.result import Solution, Status
from hamrkq.solve import solve
from hamrkq.symbolic.expressions import parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["PoincareSection", "poincare", "section_expression", "split_section"]


@dataclass(frozen=True)
class PoincareSection:
    """The crossings of one or many orbits.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Crossing times.
    y : ndarray, shape (m, 2n)
        Full states at the crossings, one row per crossing (the layout of
        :attr:`hamrkq.Solution.y`).
    orbit : ndarray of int, shape (m,)
        The orbit (row of ``q0``/``p0``) each crossing belongs to.
    section : str
        The section's text.
    names : tuple of str
        State component names.
    solutions : list of Solution
        One per orbit (status, counters, error bounds at the crossings).
    """

    t: np.ndarray
    y: np.ndarray
    orbit: np.ndarray
    section: str
    names: tuple[str, ...]
    solutions: list[Solution] = field(repr=False)

    def __repr__(self) -> str:
        # One line, like Solution's (the generated one printed every crossing).
        return (
            f"PoincareSection(section={self.section!r}, crossings={len(self.t)}, "
            f"orbits={len(self.solutions)}, success={self.success})"
        )

    @property
    def success(self) -> bool:
        """True when every orbit's run ended as asked."""
        return all(s.success for s in self.solutions)

    @classmethod
    def of(
        cls, section: str, names: tuple[str, ...], solutions: list[Solution]
    ) -> PoincareSection:
        """The crossings of the runs ``solutions`` (each made with the
        section's event first), orbit ``k`` the ``k``-th run."""
        times = [s.t_events[0] for s in solutions]
        states = [s.y_events[0] for s in solutions]
        return cls(
            t=np.concatenate(times) if times else np.empty(0),
            y=np.concatenate(states) if states else np.empty((0, len(names))),
            orbit=np.concatenate([np.full(t.size, k) for k, t in enumerate(times)]).astype(int)
            if times
            else np.empty(0, dtype=int),
            section=section,
            names=tuple(names),
            solutions=list(solutions),
        )

    def column(self, name: str) -> np.ndarray:
        """One state component at every crossing, by name."""
        return self.y[:, self.names.index(name)]


def split_section(section: str) -> tuple[str, str]:
    if not isinstance(section, str):
        raise InputError(f"section must be a string like 'q1 = 0', got {section!r}")
    parts = re.split(r"(?<![=<>!])=(?!=)", section)
    if len(parts) != 2:
        raise InputError(f"section must have exactly one '=' (like 'q1 = 0'), got {section!r}")
    return parts[0], parts[1]


def section_expression(ham: Hamiltonian, section: str) -> sp.Expr:
    """``lhs - rhs`` of ``"lhs = rhs"``, both sides through the safe parser."""
    lhs, rhs = split_section(section)
    symbols = {s.name: s for s in (*ham.state, *ham.parameters)}
    symbols["t"] = ham.t
    return parse_expression(lhs, symbols, key="section") - parse_expression(
        rhs, symbols, key="section"
    )


def _system(system: Any) -> tuple[Hamiltonian, Problem | None]:
    if isinstance(system, Problem):
        return system.hamiltonian, system
    if isinstance(system, Hamiltonian):
        return system, None
    raise InputError(
        f"system must be a hamrkq.Hamiltonian or a hamrkq.Problem, got {type(system).__name__}"
    )


def poincare(
    system: Any,
    section: str = "q1 = 0",
    q0: Any = None,
    p0: Any = None,
    t_span: Any = None,
    *,
    direction: float = 1.0,
    n_crossings: int | None = None,
    **solve_options: Any,
) -> PoincareSection:
    """Crossings of the surface ``section`` by one orbit, or by many.

    Parameters
    ----------
    system : Hamiltonian or Problem
    section : str
        ``"lhs = rhs"`` in the system's names (``"q1 = 0"``), parsed safely.
    q0, p0 : array of n, or of shape (k, n) for k >= 1 orbits
        Initial values (a Problem's by default; required with a Hamiltonian).
    t_span : (t0, t_end)
    direction : float, default +1
        Count crossings where ``lhs - rhs`` increases (+1), decreases (-1), or
        both (0), along the direction of integration (SciPy's convention): in
        a backward run (``t_span`` decreasing) +1 counts the crossings where
        ``lhs - rhs`` decreases in time, -1 those where it increases.
    n_crossings : int, optional
        Stop each orbit at this many crossings (a terminal event).
    **solve_options
        Passed to :func:`hamrkq.solve` (``atol``, ``method``, ``backend``, ...).

    Returns
    -------
    PoincareSection
        One run per orbit in ``solutions``; after Ctrl-C or SIGTERM, the
        orbits run so far (the last one interrupted, with its crossings so
        far) and no others.

    Raises
    ------
    InputError
        A bad section or ``n_crossings``; ``q0``/``p0`` missing (a
        Hamiltonian has no initial values of its own), of mismatched shapes,
        or with no orbit.
    """
    ham, problem = _system(system)
    expr = section_expression(ham, section)
    if n_crossings is not None and (
        isinstance(n_crossings, bool) or not isinstance(n_crossings, int) or n_crossings < 1
    ):
        raise InputError(f"n_crossings must be a positive integer, got {n_crossings!r}")
    event = {"expression": expr, "direction": direction, "terminal": n_crossings or False}
    if problem is not None:
        q0 = problem.q0 if q0 is None else q0
        p0 = problem.p0 if p0 is None else p0
    elif q0 is None or p0 is None:
        # Else np.asarray(None) reached the shape check: "got shapes () and ()".
        missing = " and ".join(name for name, v in (("q0", q0), ("p0", p0)) if v is None)
        raise InputError(
            f"poincare of a Hamiltonian needs q0 and p0 (one orbit, or one row per orbit); "
            f"{missing} not given (a Problem supplies its own)"
        )
    Q, P = np.asarray(q0, dtype=float), np.asarray(p0, dtype=float)
    if Q.ndim != P.ndim or Q.ndim not in (1, 2) or (Q.ndim == 2 and Q.shape[0] != P.shape[0]):
        raise InputError(
            f"q0 and p0 must both be 1-D (one orbit) or 2-D with one row per orbit, "
            f"got shapes {Q.shape} and {P.shape}"
        )
    Q, P = np.atleast_2d(Q), np.atleast_2d(P)
    if Q.shape[0] == 0:
        # Else np.concatenate of no crossing times: "need at least one array".
        raise InputError(f"q0 and p0 need at least one orbit, got shapes {Q.shape} and {P.shape}")
    solutions: list[Solution] = []
    try:
        for q, p in zip(Q, P, strict=True):
            solutions.append(solve(system, q, p, t_span, events=[event], **solve_options))
            if solutions[-1].status is Status.INTERRUPTED:
                break  # Ctrl-C or SIGTERM: the orbit stands as far as it ran, no other starts
    except KeyboardInterrupt:
        # Between two orbits (or while one was set up): those run so far stand.
        if not solutions:
            raise
    return PoincareSection.of(section, ham.names, solutions)
