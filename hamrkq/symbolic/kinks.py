"""Where Hamilton's equations are not smooth: the kinks of ``Abs`` and
``sign`` and the branch cut of ``atan2`` in H.

A Runge-Kutta step's error expansion, and with it the pair's estimate, the
quencher's order and Gamma, assume a smooth right-hand side.  A step across
``q = 0`` of ``H = p^2/2 + |q|`` (``dp/dt`` jumps from -1 to 1) is off by far
more than any of them says: ``auto`` returned SUCCESS 84 times the tolerance
off at 1e-8 on it, and 796 times at 1e-10 on an ``atan2(y, x)`` term whose
value jumps by 2 pi where the orbit crosses the negative x-axis (measured at
6724968, before :mod:`hamrkq.solve.smoothness`).  :func:`kinks` lists the
switching functions whose sign change marks such a place; the solver ends a
certified run before the first step that crosses one
(:mod:`hamrkq.solve.smoothness`).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import sympy as sp

__all__ = ["Kink", "kinks"]


class Kink(NamedTuple):
    """A place where H is not smooth: where ``argument`` changes sign (while
    ``guard`` is negative, where there is one: the branch cut of
    ``atan2(y, x)`` is ``y = 0`` with ``x < 0``), named by the ``term`` of H
    that makes it."""

    argument: sp.Expr
    guard: sp.Expr | None
    term: str


@functools.lru_cache(maxsize=256)
def kinks(H: sp.Expr) -> tuple[Kink, ...]:
    """The kinks of ``H`` (module docstring), in a fixed order; empty for a
    smooth H."""
    found: dict[tuple, Kink] = {}
    for node in sorted(H.atoms(sp.Abs, sp.sign), key=sp.default_sort_key):
        (argument,) = node.args
        if argument.free_symbols:
            found.setdefault((argument, None), Kink(argument, None, str(node)))
    for node in sorted(H.atoms(sp.atan2), key=sp.default_sort_key):
        y, x = node.args
        if y.free_symbols:
            found.setdefault((y, x), Kink(y, x, str(node)))
    return tuple(found.values())
