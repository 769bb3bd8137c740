"""What a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian` is declared from, checked.

H must be one scalar expression, ``q`` and ``p`` tuples of symbols, ``t`` the
time symbol, and the parameters symbols with optional default values.  Each
check appends what is wrong to a list of problems, so that the Hamiltonian
reports them all at once, with hints for SymPy's pitfalls: a constant bound
by ``from sympy import *`` (``E``, ``I``), symbols that differ only in their
assumptions, ``Abs`` of a symbol not declared real.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import mpmath
import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError
from hamrkq.symbolic.assumptions import assumption_conflict
from hamrkq.symbolic.values import as_number, assumptions_twin

__all__ = [
    "TIME",
    "ParameterSpec",
    "check_scalar",
    "complex_kinks",
    "declared_parameters",
    "degrees_of_freedom",
    "numbers_beyond_double",
    "shadowed_constants",
    "shared_names",
    "symbol_tuple",
    "time_symbol",
    "undeclared_hints",
]

#: The largest double: a number of H beyond it is refused (numbers_beyond_double).
MAX_DOUBLE = float(np.finfo(float).max)

#: The time symbol used when H does not bring its own ``t``.
TIME = sp.Symbol("t", real=True)

ParameterSpec = Mapping[Any, Any] | Sequence[sp.Symbol] | None


def check_scalar(H: Any, problems: list[str]) -> sp.Expr | None:
    if isinstance(H, str):
        problems.append(
            "H is a string; build a SymPy expression (or use hamrkq.parse_expression "
            "or a problem file): hamrkq never evaluates text"
        )
        return None
    if isinstance(H, sp.MatrixBase | list | tuple | np.ndarray):
        shape = getattr(H, "shape", (len(H),))
        problems.append(f"H must be a scalar expression, got an array of shape {shape}")
        return None
    if isinstance(H, numbers.Number) and not isinstance(H, bool | sp.Basic):
        return sp.Float(H) if isinstance(H, float) else sp.Integer(H)
    if not isinstance(H, sp.Expr):
        problems.append(f"H must be a SymPy expression, got {type(H).__name__}")
        return None
    if isinstance(H, sp.Eq | sp.Rel):
        problems.append("H must be an expression, not a relation")
        return None
    return H


def _scalar_array(value: Any) -> bool:
    """A 0-d NumPy array: Iterable by type, but not iterable."""
    return isinstance(value, np.ndarray) and value.ndim == 0


def symbol_tuple(symbols: Any, label: str, problems: list[str]) -> tuple[sp.Symbol, ...]:
    if isinstance(symbols, sp.Symbol):
        symbols = [symbols]
    if isinstance(symbols, str) or not isinstance(symbols, Iterable) or _scalar_array(symbols):
        problems.append(f"{label} must be a sequence of SymPy symbols, got {symbols!r}")
        return ()
    result = []
    for item in symbols:
        if isinstance(item, sp.Symbol):
            result.append(item)
        else:
            problems.append(
                f"{label} contains {item!r}, which is not a SymPy Symbol{_constant_hint(item)}"
            )
    return tuple(result)


def degrees_of_freedom(q: tuple, p: tuple) -> list[str]:
    """What is wrong with the numbers of coordinates and momenta, if anything."""
    if len(q) != len(p):
        return [
            f"q has {len(q)} symbol{'s' if len(q) != 1 else ''} but p has {len(p)}: "
            "every coordinate needs its conjugate momentum, so give q and p the same "
            "number of symbols (q=[q1, q2], p=[p1, p2])"
        ]
    if not q:
        return ["q and p are empty: at least one degree of freedom is needed"]
    return []


def _constant_hint(item: Any) -> str:
    """Why a name like ``E`` is not a symbol: ``from sympy import *`` binds
    ``E`` to Euler's number, ``I`` to the imaginary unit, ``pi``, ``S``, ``N``..."""
    if isinstance(item, sp.NumberSymbol | sp.core.numbers.ImaginaryUnit):
        return (
            f" but the SymPy constant {item} = {sp.N(item, 6)} (`from sympy import *` "
            f"binds the name {item} to it); declare your own symbol, for example "
            f"{item}_ = sympy.Symbol('{item}')"
        )
    if callable(item) and not isinstance(item, sp.Basic):
        name = getattr(item, "__name__", repr(item))
        return f" but the SymPy function or class {name}; declare a symbol with sympy.Symbol"
    if isinstance(item, str):
        return f" but a string: give the symbol itself (sympy.Symbol({item!r}))"
    return ""


def undeclared_hints(undeclared: set, declared: list) -> list[str]:
    """Explain the undeclared symbols that look like declared ones: SymPy treats
    ``Symbol('q')`` and ``Symbol('q', real=True)`` as different symbols
    (:func:`hamrkq.symbolic.values.assumptions_twin`, which explains the same
    for a parameter's or an initial value's key)."""
    hints = []
    for symbol in sorted(undeclared, key=str):
        twin = assumptions_twin(symbol, tuple(declared))
        if twin is not None:
            hints.append(
                f"H uses {symbol.name}, {twin}: create both with the same call, for example "
                f"sympy.symbols('{symbol.name} ...', real=True) everywhere"
            )
    return hints


def time_symbol(t: Any, free: set, q: tuple, p: tuple, problems: list[str]) -> sp.Symbol:
    """The time symbol: the given one, else H's symbol named ``t``, else :data:`TIME`."""
    if t is not None:
        if isinstance(t, sp.Symbol):
            return t
        problems.append(f"t must be a sympy Symbol, got {t!r}")
        return TIME
    named_t = [s for s in free if s.name == "t"]
    t = named_t[0] if len(named_t) == 1 else TIME
    for label, symbols in (("coordinate", q), ("momentum", p)):
        if t in symbols:
            # Otherwise reported as "duplicated symbols: t", which does not
            # say that t is the time.
            problems.append(
                f"the {label} is called 't', the name of the time symbol: rename it "
                "(for example 'theta'), or pass the time symbol explicitly "
                "(t=sympy.Symbol('tau'))"
            )
            return _NO_TIME
    return t


#: The time symbol returned with a coordinate or momentum named ``t``: that
#: problem is reported, and the placeholder is no duplicate of the coordinate
#: nor (shared_names) a namesake.
_NO_TIME = sp.Dummy("t", real=True)


def shared_names(
    q: Sequence[sp.Symbol], p: Sequence[sp.Symbol], params: Sequence[sp.Symbol], t: sp.Symbol
) -> list[str]:
    """One problem for each name that different declared symbols share:
    ``Symbol("x")`` and ``Symbol("x", real=True)`` as two coordinates, a
    coordinate and a parameter, or a ``Dummy("q")`` beside a ``Symbol("q")``.
    SymPy tells them apart by their assumptions (a Dummy by its index), but
    values are bound by name (``q0={"x": 1.0}``, ``parameters={"a": 2}``) and
    results are labelled by it.  (The same symbol twice is a duplicate,
    reported as such.)"""
    roles = [("coordinate", q), ("momentum", p), ("parameter", params)]
    if t is not _NO_TIME:
        roles.append(("time", (t,)))
    by_name: dict[str, dict[sp.Symbol, str]] = {}
    for role, symbols in roles:
        for symbol in symbols:
            by_name.setdefault(symbol.name, {}).setdefault(symbol, role)
    return [
        f"{len(symbols)} different symbols are named {name}: "
        + ", ".join(f"the {role} {_described(symbol)}" for symbol, role in symbols.items())
        + "; SymPy tells them apart by their assumptions (a Dummy by its index), but "
        f"hamrkq binds values by name (q0={{'{name}': 1.0}}) and labels results by it: "
        "give each its own name"
        for name, symbols in by_name.items()
        if len(symbols) > 1
    ]


def _described(symbol: sp.Symbol) -> str:
    written = getattr(symbol, "_assumptions_orig", None) or {}
    kind = ", a Dummy" if isinstance(symbol, sp.Dummy) else ""
    return f"{symbol.name} ({_assumptions(written)}{kind})"


def shadowed_constants(H: sp.Expr, params: tuple[sp.Symbol, ...]) -> list[str]:
    """``H = p**2/2 + E*q**2`` after ``from sympy import *``: the E in H is
    Euler's number, and a parameter named E would silently do nothing."""
    constants = {str(c): c for c in H.atoms(sp.NumberSymbol, sp.core.numbers.ImaginaryUnit)}
    return [
        f"parameter {s.name} does not occur in H, but H contains the SymPy constant "
        f"{s.name} = {sp.N(constants[s.name], 6)} (`from sympy import *` binds the name "
        f"{s.name} to it): build H with {s.name} = sympy.Symbol('{s.name}')"
        for s in params
        if s not in H.free_symbols and s.name in constants
    ]


def complex_kinks(H: sp.Expr) -> list[str]:
    """``Abs(q)`` of a symbol not declared real: SymPy differentiates it as a
    complex function (``re``, ``im``, ``Derivative``), which nothing can evaluate."""
    loose = {
        s.name for node in H.atoms(sp.Abs, sp.sign) for s in node.free_symbols if not s.is_real
    }
    if not loose:
        return []
    names = ", ".join(sorted(loose))
    return [
        f"H takes Abs or sign of {names}, not declared real: SymPy then differentiates "
        "it as a complex function (re, im), which cannot be evaluated; declare the "
        f"symbols real, sympy.symbols('{' '.join(sorted(loose))}', real=True)"
    ]


def numbers_beyond_double(exprs: Iterable[sp.Expr], where: str) -> list[str]:
    """A problem naming the numbers of ``exprs`` (``where`` says what they
    are) that no double holds, or none: ``Integer(10)**400``,
    ``Integer(2)**1024``, ``Float("1e400")`` (SymPy's numbers have no range).
    Printed into the generated code, the first two raised OverflowError (in
    an integer division or conversion), the third printed as ``inf``, an
    undefined name.  Each is named by its value to 17 digits and its class.
    (Non-finite ones, ``oo`` and ``Float("inf")``, are :func:`check_supported`'s;
    a number that underflows to 0 or a subnormal is a double, as in a problem
    file.)"""
    found: dict[sp.Number, None] = {}
    for expr in exprs:
        for number in expr.atoms(sp.Rational, sp.Float):
            if number.is_finite and not _is_double(number):
                found[number] = None
    if not found:
        return []
    named = "; ".join(f"{_value_text(n)} ({type(n).__name__})" for n in sorted(found, key=abs))
    return [
        f"{where} holds a number beyond the range of a double (magnitude above "
        f"{MAX_DOUBLE:.4g}), which no backend can evaluate: {named}; rescale the "
        "variables (q = s Q) or the units"
    ]


def _is_double(number: sp.Number) -> bool:
    try:
        value = number.p / number.q if number.is_Rational else float(number)
    except OverflowError:  # int / int beyond the largest double
        return False
    return math.isfinite(value)


def _value_text(number: sp.Number) -> str:
    """To 17 digits, or a Float's own if fewer (2**1024 is
    1.7976931348623159e+308, the largest double 1.7976931348623157e+308)."""
    if number.is_Float:
        with mpmath.workprec(number._prec):
            digits = min(17, mpmath.libmp.prec_to_dps(number._prec))
            return mpmath.nstr(mpmath.mpf(number), digits)
    with mpmath.workdps(30):
        return mpmath.nstr(mpmath.mpf(int(number.p)) / int(number.q), 17)


def _assumptions(values: Mapping[str, bool]) -> str:
    shown = ", ".join(f"{k}={v}" for k, v in sorted(values.items()))
    return shown or "no assumptions"


def declared_parameters(
    spec: ParameterSpec, free: set, problems: list[str]
) -> tuple[tuple[sp.Symbol, ...], dict[sp.Symbol, float]]:
    if spec is None:
        return (), {}
    items: Iterable[tuple[Any, Any]]
    if isinstance(spec, Mapping):
        items = spec.items()
    elif isinstance(spec, str) or not isinstance(spec, Iterable) or _scalar_array(spec):
        problems.append(f"parameters must be a mapping or a sequence of symbols, got {spec!r}")
        return (), {}
    else:
        items = ((s, None) for s in spec)
    by_name = {s.name: s for s in free}
    symbols: list[sp.Symbol] = []
    defaults: dict[sp.Symbol, float] = {}
    for key, value in items:
        symbol = key
        if isinstance(key, str):
            symbol = by_name.get(key, sp.Symbol(key, real=True))
        if not isinstance(symbol, sp.Symbol):
            problems.append(
                f"parameter {key!r} is not a SymPy Symbol or a name{_constant_hint(key)}"
            )
            continue
        symbols.append(symbol)
        if value is not None:
            try:
                defaults[symbol] = as_number(value, f"parameter {symbol}")
            except (InputError, InputTypeError) as exc:
                problems.append(str(exc))
                continue
            conflict = assumption_conflict(symbol, defaults[symbol])
            if conflict is not None:
                problems.append(f"parameter {conflict}")
    return tuple(sorted(symbols, key=lambda s: s.name)), defaults
