"""What a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian` is declared from, checked.

H must be one scalar expression, ``q`` and ``p`` tuples of symbols, ``t`` the
time symbol, and the parameters symbols with optional default values.  Each
check appends what is wrong to a list of problems, so that the Hamiltonian
reports them all at once, with hints for SymPy's pitfalls: a constant bound
by ``from sympy import *`` (``E``, ``I``), symbols that differ only in their
assumptions, ``Abs`` of a symbol not declared real.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError
from hamrkq.symbolic.assumptions import assumption_conflict
from hamrkq.symbolic.values import as_number

__all__ = [
    "TIME",
    "ParameterSpec",
    "check_scalar",
    "complex_kinks",
    "declared_parameters",
    "shadowed_constants",
    "symbol_tuple",
    "time_symbol",
    "undeclared_hints",
]

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
    return ""


def undeclared_hints(undeclared: set, declared: list) -> list[str]:
    """Explain the undeclared symbols that look like declared ones: SymPy treats
    ``Symbol('q')`` and ``Symbol('q', real=True)`` as different symbols."""
    hints = []
    by_name = {s.name: s for s in declared}
    for symbol in sorted(undeclared, key=str):
        twin = by_name.get(symbol.name)
        if twin is None:
            continue
        mine = {k: v for k, v in symbol.assumptions0.items() if k in ("real", "positive")}
        theirs = {k: v for k, v in twin.assumptions0.items() if k in ("real", "positive")}
        hints.append(
            f"H uses a symbol {symbol.name} ({_assumptions(mine)}) that is not the declared "
            f"{twin.name} ({_assumptions(theirs)}): SymPy treats symbols with other "
            "assumptions as different symbols; create both with the same call, for example "
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
            return sp.Dummy("t", real=True)
    return t


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
