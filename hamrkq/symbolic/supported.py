"""What an expression may contain for hamrkq to turn it into numerical code.

One list, used twice: :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`
refuses at once what no backend can evaluate, and the code generator
(:mod:`hamrkq.backends.codegen`) prints exactly these nodes.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from hamrkq.errors import CodegenError

__all__ = ["CONSTANTS", "FUNCTIONS", "check_supported", "what_is_supported"]

# Functions that may appear in an expression, and what they print to.  The
# problem-file grammar allows sin cos tan asin acos atan atan2 sinh cosh tanh
# exp log sqrt Abs; differentiation adds sign (from Abs) and nothing else that
# the printer cannot handle.
FUNCTIONS = (
    sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2,
    sp.sinh, sp.cosh, sp.tanh, sp.asinh, sp.acosh, sp.atanh,
    sp.exp, sp.log, sp.Abs, sp.sign,
)  # fmt: skip
ATOMS = (sp.Integer, sp.Rational, sp.Float, sp.Symbol)
OPERATIONS = (sp.Add, sp.Mul, sp.Pow)
CONSTANTS = (type(sp.pi), type(sp.E))


def what_is_supported() -> str:
    """One line naming what an expression may contain (for messages)."""
    names = ", ".join(function.__name__ for function in FUNCTIONS)
    return f"numbers, pi, E, the declared symbols, + * ** and {names}"


def check_supported(exprs: Sequence[sp.Expr], allowed: set[sp.Symbol]) -> None:
    """Raise :class:`CodegenError` unless every node of ``exprs`` can be printed.

    Allowed nodes: integers, rationals, finite floats, ``pi`` and ``E``, the
    symbols in ``allowed``, ``+ * **`` and the functions of the problem-file
    grammar (plus ``sign``, the derivative of ``Abs``).  All offending nodes
    are listed in one message.
    """
    bad: set[str] = set()
    for expr in exprs:
        for node in sp.preorder_traversal(expr):
            if isinstance(node, sp.Symbol):
                if node not in allowed:
                    bad.add(f"symbol {node}")
            elif isinstance(node, sp.Float):
                if not node.is_finite:
                    bad.add(f"non-finite number {node}")
            elif isinstance(node, ATOMS + OPERATIONS + CONSTANTS + FUNCTIONS):
                continue
            else:
                bad.add(f"{type(node).__name__} ({node})")
    if bad:
        raise CodegenError("cannot generate scalar code for: " + "; ".join(sorted(bad)))
