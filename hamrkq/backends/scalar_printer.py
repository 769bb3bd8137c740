"""SymPy expressions printed as the body of a scalar Python function.

:func:`block` prints one function of the generated module (``rhs``, ``jac``,
``jvp``, ``energy``): common subexpressions first (:func:`sympy.cse`), then one
assignment per output.  The printer spells integer powers as products and
every float exactly, and gives each compound base of a power its own
temporary (a half-integer power its square root), so that the interpreted
and the compiled backend compute the same bits.  :func:`rhs_jvp_block` prints
the fused ``rhs_jvp``.  :func:`hamrkq.backends.codegen.generate_source`
assembles the module from these blocks.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.pycode import PythonCodePrinter

__all__ = ["MAX_FUSED_DIM", "MAX_PRODUCT_POWER", "block", "rhs_jvp_block"]


#: Integer powers up to this are printed as products (see _ScalarPrinter).
MAX_PRODUCT_POWER = 4
#: Largest dimension for which rhs_jvp repeats the bodies of rhs and jac
#: (fused); above it rhs_jvp calls them (numba's compile time grows with the
#: length of a function: outer_solar_system's fused rhs_jvp took 13 s more).
MAX_FUSED_DIM = 12


class _ScalarPrinter(PythonCodePrinter):
    """PythonCodePrinter with symbols renamed and floats printed exactly."""

    def __init__(self, names: dict[sp.Symbol, str]):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})
        self._names = names

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        # check_supported has already proved every symbol is in the table.
        return self._names[expr]

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        # Integer powers are spelled out so that every backend computes the
        # same bits: Python's float ** int calls the C library's pow(), while
        # numba multiplies (by squaring).  Products for |n| <= 4, otherwise a
        # float exponent, which both send to pow().
        exponent = expr.exp
        if exponent.is_Integer and abs(int(exponent)) >= 2:
            n = int(exponent)
            base = self.parenthesize(expr.base, PRECEDENCE["Mul"], strict=True)
            if abs(n) <= MAX_PRODUCT_POWER:
                # Parenthesised: the product stands where a Pow (which binds
                # tighter than * and /) stood, as in a/b**2 -> a/(b*b).
                product = "*".join([base] * abs(n))
                return f"({product})" if n > 0 else f"(1/({product}))"
            base = self.parenthesize(expr.base, PRECEDENCE["Pow"], strict=True)
            return f"{base}**{float(n)!r}" if n > 0 else f"{base}**({float(n)!r})"
        return super()._print_Pow(expr, rational=rational)

    def _print_Float(self, expr: sp.Float) -> str:
        # repr(float) round-trips; SymPy's default prints 15 digits and loses bits.
        return repr(float(expr))


def _is_half_integer_power(expr: sp.Expr) -> bool:
    return expr.is_Pow and expr.exp.is_Rational and expr.exp.q == 2


def _hoist_power_bases(replacements, reduced, temps):
    """Give every compound base of an integer power its own temporary, and
    every base of a half-integer power its square root.

    The printer spells ``b**3`` as ``b*b*b``; without this, a base such as
    ``cos(q)`` would be computed three times.  A half-integer power
    ``b**(k + 1/2)`` becomes ``b**k * s`` with ``s = sqrt(b)`` a temporary
    shared by every power of ``b`` (``1/(b*s)`` for ``b**(-3/2)``): one
    square root and a few products per particle pair of an N-body force and
    its Jacobian, instead of a ``pow`` call for each of ``r**-3`` and
    ``r**-5``.  ``sqrt``, ``*`` and ``/`` are correctly rounded, so both
    backends compute the same bits.  Bases are hoisted just before the
    temporary (or output) that uses them, so definitions still precede uses.
    """
    known: dict[sp.Expr, sp.Symbol] = {}
    roots: dict[sp.Expr, sp.Symbol] = {}
    ordered: list[tuple[sp.Symbol, sp.Expr]] = []

    def hoist(base: sp.Expr) -> sp.Expr:
        if base.is_Atom:
            return base
        symbol = known.get(base)
        if symbol is None:
            symbol = known[base] = next(temps)
            ordered.append((symbol, base))
        return symbol

    def visit(expr: sp.Expr) -> sp.Expr:
        if expr.is_Atom:
            return expr
        args = tuple(visit(arg) for arg in expr.args)
        if args != expr.args:
            expr = expr.func(*args, evaluate=False)
        if _is_half_integer_power(expr) and expr.exp != sp.S.Half:
            base = hoist(expr.base)
            root = roots.get(base)
            if root is None:
                root = roots[base] = next(temps)
                ordered.append((root, sp.sqrt(base, evaluate=False)))
            k = abs(expr.exp.p) // 2  # |exponent| = k + 1/2
            if k == 0:
                magnitude = root
            elif k == 1:
                magnitude = sp.Mul(base, root, evaluate=False)
            else:
                magnitude = sp.Mul(sp.Pow(base, k, evaluate=False), root, evaluate=False)
            return magnitude if expr.exp > 0 else sp.Pow(magnitude, -1, evaluate=False)
        if expr.is_Pow and expr.exp.is_Integer and abs(int(expr.exp)) >= 2:
            return sp.Pow(hoist(expr.base), expr.exp, evaluate=False)
        return expr

    for symbol, value in replacements:
        ordered.append((symbol, visit(value)))
    outputs = [visit(value) for value in reduced]
    return ordered, outputs


def _body(
    exprs: Sequence[sp.Expr],
    targets: Sequence[str],
    names: dict[sp.Symbol, str],
    temp_prefix: str = "c",
) -> tuple[list[str], list[str]]:
    """CSE of ``exprs``: the lines assigning the temporaries (named
    ``<temp_prefix>0, 1, ...``) and those assigning each target."""
    temps = sp.numbered_symbols("_c")
    replacements, reduced = sp.cse(list(exprs), symbols=temps, order="none")
    replacements, reduced = _hoist_power_bases(replacements, reduced, temps)
    names = dict(names)
    for k, (symbol, _) in enumerate(replacements):
        names[symbol] = f"{temp_prefix}{k}"
    printer = _ScalarPrinter(names)
    temporaries = [
        f"    {names[symbol]} = {printer.doprint(value)}" for symbol, value in replacements
    ]
    outputs = [
        f"    {target} = {printer.doprint(value)}"
        for target, value in zip(targets, reduced, strict=True)
    ]
    return temporaries, outputs


def block(
    name: str,
    signature: str,
    doc: str,
    exprs: Sequence[sp.Expr],
    targets: Sequence[str],
    names: dict[sp.Symbol, str],
    prologue: Sequence[str] = (),
    returns: bool = False,
) -> list[str]:
    """Lines of one function: CSE temporaries, then one assignment per target.

    The targets (array items) are assigned last, from local values: with no
    store between the loads, the compiler may share the loads of ``y`` and
    the calls on them (a sine and a cosine of the same angle become one
    ``sincos``), which it cannot when a store to ``out`` might change ``y``.
    The ``prologue`` (zeroing the output) runs after the computation too.
    """
    if returns:
        temporaries, outputs = _body(exprs, ["return"], names)
        outputs = [line.replace("return = ", "return ", 1) for line in outputs]
        stores: list[str] = []
    else:
        values = [f"r{k}" for k in range(len(targets))]
        temporaries, outputs = _body(exprs, values, names)
        stores = [*prologue, *(f"    {t} = {v}" for t, v in zip(targets, values, strict=True))]
    return [f"def {name}({signature}):", f'    """{doc}"""', *temporaries, *outputs, *stores]


def rhs_jvp_block(rhs, jac, nonzero, dim: int, names: dict[sp.Symbol, str]) -> list[str]:
    """``rhs_jvp(t, y, params, v, out, dout, JM)``: f into ``out`` and J v
    into ``dout`` (``JM`` is a scratch Jacobian).

    Above :data:`MAX_FUSED_DIM` it calls ``rhs``, ``jac`` (into ``JM``) and
    adds the rows of ``JM v`` in order, which is quick to compile.  Up to it:

    The bodies of ``rhs`` and ``jac`` are repeated verbatim (their own CSE, so
    f and every entry of J are the same expressions, evaluated in the same
    order, as in those functions), and each row of J v is added in the order
    k = 0, 1, ..., from 0.0, zero entries included: exactly what ``rhs``, then
    ``jac`` and the loop's matrix-vector product compute, bit for bit.  One
    call instead of two, and the compiler evaluates the sines and cosines
    that f and J share once (they are the same pure expressions).
    """
    if dim > MAX_FUSED_DIM:
        return [
            "def rhs_jvp(t, y, params, v, out, dout, JM):",
            '    """out[:] = dy/dt and dout[:] = Jacobian of rhs at y, times v."""',
            "    rhs(t, y, params, out)",
            "    jac(t, y, params, JM)",
            "    for i in range(JM.shape[0]):",
            "        acc = 0.0",
            "        for k in range(JM.shape[1]):",
            "            acc += JM[i, k] * v[k]",
            "        dout[i] = acc",
        ]
    # Everything is read before anything is written: with no stores in
    # between, the compiler may share the loads and the calls of f and J
    # (it cannot assume that out, dout, y and v do not overlap).
    f_temps, f_out = _body(rhs, [f"r{i}" for i in range(dim)], names, "f")
    entry = {(i, j): f"j{i}_{j}" for i, j in nonzero}
    j_temps, j_out = _body([jac[i, j] for i, j in nonzero], list(entry.values()), names, "g")
    rows = []
    for i in range(dim):
        terms = [f"{entry.get((i, k), '0.0')}*v[{k}]" for k in range(dim)]
        rows.append(f"    d{i} = " + "(" * dim + "0.0 + " + ") + ".join(terms) + ")")
    stores = [f"    out[{i}] = r{i}" for i in range(dim)]
    stores += [f"    dout[{i}] = d{i}" for i in range(dim)]
    return [
        "def rhs_jvp(t, y, params, v, out, dout, JM):",
        '    """out[:] = dy/dt and dout[:] = Jacobian of rhs at y, times v."""',
        *f_temps, *f_out, *j_temps, *j_out, *rows, *stores,
    ]  # fmt: skip
