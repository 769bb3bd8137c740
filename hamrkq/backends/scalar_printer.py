"""SymPy expressions printed as the body of a scalar Python function.

:func:`block` prints one function of the generated module (``rhs``, ``jac``,
``jvp``, ``energy``): common subexpressions first (:func:`sympy.cse`), then one
assignment per output.  The printer spells integer powers as products and
every float exactly, and gives each compound base of a power its own
temporary (a half-integer power its square root), so that the interpreted
and the compiled backend compute the same bits.  :func:`rhs_jvp_block` prints
the fused ``rhs_jvp``.  :func:`hamrkq.backends.codegen.generate_source`
assembles the module from these blocks.

A sum of state-dependent terms and two or more constant ones (parameters and
numbers), such as ``q1 + mu - 1``, adds its constant part as a double-double
(:func:`_constant_offsets`): ``(q1 + k) + k_lo`` with ``k + k_lo = mu - 1`` to
about 1e-32.  Rounded to one double, ``mu - 1`` (or ``q1 + mu``, then ``- 1``)
loses the low bits of ``mu`` the same way at every evaluation in a binade of
``q1``: the centre ``1 - mu`` sits displaced by up to half an ulp of 1, a
systematic force error that cancellation near the centre magnifies (on the
Arenstorf orbit the quencher ended about 1e-10 from the exact solution,
whatever the mesh; 2e-12 to 1e-11 with the offsets,
``benchmarks/constant_offsets.txt``) and
that the rounding witness cannot see, since it shares it.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.pycode import PythonCodePrinter

__all__ = ["MAX_FUSED_DIM", "MAX_PRODUCT_POWER", "OffsetSum", "block", "rhs_jvp_block"]


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

    def _print(self, expr, **kwargs) -> str:
        # Every symbol, whatever its class, is printed from the table
        # (check_supported has already proved that it is there): SymPy's own
        # methods print a Dummy as its name and index (``q_8977807``) and a
        # Wild as its name, user-chosen text in the generated source.
        if isinstance(expr, sp.Symbol):
            return self._names[expr]
        return super()._print(expr, **kwargs)

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

    def _print_Integer(self, expr: sp.Integer) -> str:
        # An integer beyond int64 as the double it becomes at run time:
        # numba cannot type such a literal ("Int value is too large"), and a
        # file's 1e20 is read as the integer 10**20, which sent the system
        # to the interpreted loop, about 100 times slower (found by QA).
        # Python converts an int to the nearest double where it meets one,
        # so the interpreter computes the same bits as before.
        if abs(int(expr)) >= INT64_LIMIT:
            return repr(float(expr))
        return super()._print_Integer(expr)

    def _print_Rational(self, expr: sp.Rational) -> str:
        # As above: p/q of integers beyond int64 is Python's correctly
        # rounded true division, which the nearest double to p/q is.
        if max(abs(int(expr.p)), abs(int(expr.q))) >= INT64_LIMIT:
            return repr(float(expr))
        return super()._print_Rational(expr)

    def _print_Float(self, expr: sp.Float) -> str:
        # repr(float) round-trips; SymPy's default prints 15 digits and loses bits.
        return repr(float(expr))

    def _print_OffsetSum(self, expr: sp.Expr) -> str:
        varying, high, low = (self._print(arg) for arg in expr.args)
        return f"(({varying} + {high}) + {low})"


#: Integers from here on do not fit numba's int64 literals.
INT64_LIMIT = 2**63


class OffsetSum(sp.Function):
    """``OffsetSum(x, k, k_lo)``: ``(x + k) + k_lo``, added in this order, where
    ``k + k_lo`` is a constant held as a double-double (see the module
    docstring)."""

    nargs = 3


def _constant_offsets(
    exprs: Sequence[sp.Expr], parameters: frozenset[sp.Symbol], temps
) -> tuple[list[sp.Expr], list[tuple[sp.Symbol, sp.Symbol, tuple[sp.Expr, ...]]]]:
    """``exprs`` with every sum of varying terms and two or more constant
    terms (free of everything but ``parameters``) rewritten as
    ``OffsetSum(varying part, k, k_lo)``, and the offsets ``(k, k_lo,
    constant terms)``, one per distinct constant part."""
    offsets: dict[tuple[sp.Expr, ...], tuple[sp.Symbol, sp.Symbol]] = {}

    def offset(expr: sp.Expr) -> sp.Expr:
        if not expr.is_Add:
            return expr
        constant = tuple(
            sorted((a for a in expr.args if a.free_symbols <= parameters), key=sp.default_sort_key)
        )
        varying = [a for a in expr.args if not a.free_symbols <= parameters]
        if len(constant) < 2 or not varying:
            return expr
        if constant not in offsets:
            offsets[constant] = (next(temps), next(temps))
        high, low = offsets[constant]
        return OffsetSum(sp.Add(*varying, evaluate=False), high, low)

    rewritten = [_bottom_up(_expression(e), offset) for e in exprs]
    return rewritten, [(high, low, terms) for terms, (high, low) in offsets.items()]


def _expression(value) -> sp.Basic:
    """``value`` as a SymPy object: SymPy objects as they are, Python
    numbers as SymPy numbers; never text (nothing here parses a string)."""
    if isinstance(value, sp.Basic):
        return value
    if isinstance(value, int | float) and not isinstance(value, bool):
        return sp.Integer(value) if isinstance(value, int) else sp.Float(value)
    raise TypeError(f"expected a SymPy expression or a number, got {type(value).__name__}")


def _bottom_up(expr: sp.Expr, rule) -> sp.Expr:
    """``expr`` with ``rule`` applied to every node, the arguments first
    (unevaluated, so that nothing the rules built is undone)."""
    if expr.is_Atom:
        return expr
    args = tuple(_bottom_up(arg, rule) for arg in expr.args)
    if args != expr.args:
        expr = expr.func(*args, evaluate=False)
    return rule(expr)


def _offset_lines(offsets, names: dict[sp.Symbol, str], printer) -> list[str]:
    """Each offset's constant terms added by Knuth's TwoSum into ``(k, k_lo)``."""
    lines: list[str] = []
    for high, low, terms in offsets:
        k, k_lo = names[high], names[low]
        lines += [f"    {k} = float({printer.doprint(terms[0])})", f"    {k_lo} = 0.0"]
        for term in terms[1:]:
            lines += [
                f"    _term = float({printer.doprint(term)})",
                f"    _sum = {k} + _term",
                f"    _back = _sum - {k}",
                f"    {k_lo} += ({k} - (_sum - _back)) + (_term - _back)",
                f"    {k} = _sum",
            ]
    return lines


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

    def rule(expr: sp.Expr) -> sp.Expr:
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
        ordered.append((symbol, _bottom_up(value, rule)))
    outputs = [_bottom_up(value, rule) for value in reduced]
    return ordered, outputs


def _body(
    exprs: Sequence[sp.Expr],
    targets: Sequence[str],
    names: dict[sp.Symbol, str],
    parameters: frozenset[sp.Symbol],
    temp_prefix: str = "c",
) -> tuple[list[str], list[str]]:
    """CSE of ``exprs``: the lines assigning the constant offsets (named
    ``<temp_prefix>k0, <temp_prefix>k0_lo, ...``) and the temporaries (named
    ``<temp_prefix>0, 1, ...``), and those assigning each target."""
    # Temporaries equal to no symbol of the table: one that did (a coordinate
    # named _c0) would have its entry overwritten.
    offset_symbols = sp.numbered_symbols("_k", exclude=names)
    exprs, offsets = _constant_offsets(exprs, parameters, offset_symbols)
    temps = sp.numbered_symbols("_c", exclude=names)
    replacements, reduced = sp.cse(list(exprs), symbols=temps, order="none")
    replacements, reduced = _hoist_power_bases(replacements, reduced, temps)
    names = dict(names)
    for k, (high, low, _) in enumerate(offsets):
        names[high], names[low] = f"{temp_prefix}k{k}", f"{temp_prefix}k{k}_lo"
    for k, (symbol, _) in enumerate(replacements):
        names[symbol] = f"{temp_prefix}{k}"
    printer = _ScalarPrinter(names)
    temporaries = _offset_lines(offsets, names, printer) + [
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
    parameters: frozenset[sp.Symbol],
    prologue: Sequence[str] = (),
    returns: bool = False,
) -> list[str]:
    """Lines of one function: CSE temporaries, then one assignment per target.

    The targets (array items) are assigned last, from local values: with no
    store between the loads, the compiler may share the loads of ``y`` and
    the calls on them (a sine and a cosine of the same angle become one
    ``sincos``), which it cannot when a store to ``out`` might change ``y``.
    The ``prologue`` (zeroing the output) runs after the computation too.
    ``parameters`` are the symbols that are constant during a run (printed
    as ``params[j]``): sums of constants are added as double-doubles.
    """
    if returns:
        temporaries, outputs = _body(exprs, ["return"], names, parameters)
        outputs = [line.replace("return = ", "return ", 1) for line in outputs]
        stores: list[str] = []
    else:
        values = [f"r{k}" for k in range(len(targets))]
        temporaries, outputs = _body(exprs, values, names, parameters)
        stores = [*prologue, *(f"    {t} = {v}" for t, v in zip(targets, values, strict=True))]
    return [f"def {name}({signature}):", f'    """{doc}"""', *temporaries, *outputs, *stores]


def rhs_jvp_block(
    rhs, jac, nonzero, dim: int, names: dict[sp.Symbol, str], parameters: frozenset[sp.Symbol]
) -> list[str]:
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
    f_temps, f_out = _body(rhs, [f"r{i}" for i in range(dim)], names, parameters, "f")
    entry = {(i, j): f"j{i}_{j}" for i, j in nonzero}
    j_temps, j_out = _body(
        [jac[i, j] for i, j in nonzero], list(entry.values()), names, parameters, "g"
    )
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
