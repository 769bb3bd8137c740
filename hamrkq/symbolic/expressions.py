"""A restricted parser for the expressions in problem files and on the command line.

Problem files are data, never code.  This module turns an expression string
into a SymPy expression *without* ``eval``, ``exec``, ``sympify`` or
``parse_expr``: the text is split into a syntax tree by :func:`ast.parse`
(which only parses, it never runs anything), and the tree is walked node by
node against a whitelist.  The SymPy expression is built directly from the
accepted nodes.

Accepted: numbers, declared names, ``t``, ``+ - * / **``, unary ``+``/``-``,
parentheses, calls of ``sin cos tan asin acos atan atan2 sinh cosh tanh exp
log sqrt Abs``, and the constants ``pi`` and ``E``, all in ASCII characters
(see :func:`_check_ascii`).  Everything else (attribute
access, subscripts, strings, lambdas, comprehensions, keyword arguments,
comparisons, unlisted functions, dunder names, ...) is rejected with an
:class:`~hamrkq.errors.ExpressionError` that names the offending piece.

Two helpers live beside it: :mod:`~hamrkq.symbolic.long_chains` cuts a sum of
thousands of terms (too long for :func:`ast.parse`) into its terms, and
:mod:`~hamrkq.symbolic.float_constants` refuses a constant that is not a
finite real double.
"""

from __future__ import annotations

import ast
import keyword
import math
import unicodedata
from collections.abc import Callable, Mapping
from fractions import Fraction
from pathlib import Path

import sympy as sp

from hamrkq.errors import ExpressionError
from hamrkq.symbolic.float_constants import MAX_MAGNITUDE, check_constants
from hamrkq.symbolic.long_chains import CALL, split_chain, wrapped

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_DEPTH",
    "MAX_LENGTH",
    "MAX_MAGNITUDE",
    "RESERVED_NAMES",
    "check_name",
    "parse_expression",
]

#: Longest expression accepted, in characters.  Far above any catalogue entry
#: (the outer solar system's Hamiltonian is about 3 000), far below what could
#: make parsing itself a denial of service.
MAX_LENGTH = 50_000

#: Deepest nesting accepted.  Python's own parser gives up near 200 nested
#: parentheses; we stop well before any recursion limit.  A chain of the same
#: kind of operation (``a + b - c + ...``, ``a * b / c * ...``) is one level,
#: however many terms it has: nesting is measured as nesting, and a long flat
#: sum (an N-body Hamiltonian) is limited only by :data:`MAX_LENGTH`.
MAX_DEPTH = 60

#: Largest magnitude of a numeric exponent: SymPy evaluates ``2**2**100``
#: eagerly, which would never finish.
MAX_EXPONENT = 1000

#: Longest integer literal, in digits.
MAX_DIGITS = 100

#: Largest exact rational a number in an expression may become, in bits of
#: its numerator or denominator.  ``((2**64)**64)**64`` would otherwise build a
#: 262 144-bit integer (each further level multiplies that by 64), and a
#: product of a few hundred long literals a number that Python refuses to
#: print (more than 4 300 digits), failing far from the file.
MAX_NUMBER_BITS = 4096

#: Values that mean the text is undefined (``1/0``, ``0/0``, ``log(0)``) or
#: not real (``sqrt(-1)``): a problem file has no use for them, and they would
#: only fail later, far from the file and key that caused them.
_UNDEFINED = (sp.zoo, sp.nan, sp.oo, -sp.oo, sp.I)

#: Functions a file may call, with their number of arguments.
FUNCTIONS: Mapping[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1),
    "cos": (sp.cos, 1),
    "tan": (sp.tan, 1),
    "asin": (sp.asin, 1),
    "acos": (sp.acos, 1),
    "atan": (sp.atan, 1),
    "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1),
    "cosh": (sp.cosh, 1),
    "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1),
    "log": (sp.log, 1),
    "sqrt": (sp.sqrt, 1),
    "Abs": (sp.Abs, 1),
}

#: Named constants.
CONSTANTS: Mapping[str, sp.Expr] = {"pi": sp.pi, "E": sp.E}

#: Names a file may not declare as a coordinate, momentum or parameter.
RESERVED_NAMES = frozenset({"t", *FUNCTIONS, *CONSTANTS})

_BINARY = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
}

#: Operators that form one chain (one level of nesting) with their own kind.
_FAMILY = {ast.Add: "sum", ast.Sub: "sum", ast.Mult: "product", ast.Div: "product"}
_SYMBOL = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}


def _combine(first: sp.Expr, rest: list[tuple[str, sp.Expr]]) -> sp.Expr:
    """``first op1 term1 op2 term2 ...`` built at once (``sp.Add(*terms)``):
    adding term by term would cost time quadratic in the number of terms."""
    if not rest:
        return first
    if rest[0][0] in "+-":
        return sp.Add(first, *(term if op == "+" else -term for op, term in rest))
    return sp.Mul(first, *(term if op == "*" else 1 / term for op, term in rest))


_UNARY = {ast.USub: lambda a: -a, ast.UAdd: lambda a: a}

_OPERATOR_TEXT = {
    ast.FloorDiv: "//",
    ast.Mod: "%",
    ast.MatMult: "@",
    ast.BitAnd: "&",
    ast.BitOr: "|",
    ast.BitXor: "^",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.Invert: "~",
    ast.Not: "not",
}


def check_name(name: object) -> str | None:
    """Why ``name`` cannot be declared as a symbol, or ``None`` if it can."""
    if not isinstance(name, str):
        return f"a name must be a string, not {type(name).__name__}"
    if not name.isidentifier() or not name.isascii():
        return f"{name!r} is not a plain identifier"
    if keyword.iskeyword(name):
        return f"{name!r} is a Python keyword"
    if name.startswith("_"):
        return f"{name!r} starts with an underscore"
    if name in RESERVED_NAMES:
        return f"{name!r} is reserved (time, function or constant name)"
    return None


def parse_expression(
    text: object,
    symbols: Mapping[str, sp.Symbol],
    *,
    path: str | Path | None = None,
    key: str | None = None,
    line: int | None = None,
) -> sp.Expr:
    """Parse an expression string into a SymPy expression, safely.

    Parameters
    ----------
    text : str, int or float
        The expression.  Plain numbers are accepted as they are.
    symbols : mapping of str to sympy.Symbol
        The names the expression may use (coordinates, momenta, parameters and,
        where time is allowed, ``t``).  Function and constant names are always
        available.
    path, key, line : optional
        Where the text came from, for error messages.

    Returns
    -------
    sympy.Expr

    Raises
    ------
    ExpressionError
        If the text is not an expression of the accepted form.  Nothing in the
        text is ever executed.

    Examples
    --------
    >>> import sympy as sp
    >>> q, p = sp.symbols("q p")
    >>> parse_expression("p**2/2 - cos(q)", {"q": q, "p": p})
    p**2/2 - cos(q)
    """
    where = {"path": path, "key": key, "line": line}
    if isinstance(text, bool):
        raise ExpressionError("a boolean is not an expression", piece=str(text), **where)
    if isinstance(text, int):
        return sp.Integer(text)
    if isinstance(text, float):
        return _number(text, **where)
    if not isinstance(text, str):
        raise ExpressionError(
            f"expected an expression string or a number, got {type(text).__name__}", **where
        )
    if len(text) > MAX_LENGTH:
        raise ExpressionError(
            f"expression is {len(text)} characters long, the limit is {MAX_LENGTH}",
            piece=text[:40] + "...",
            **where,
        )
    _check_ascii(text, where)
    if not text.strip():
        raise ExpressionError("empty expression", piece=text, **where)
    if "\n" in text.strip() or "\r" in text:
        raise ExpressionError("an expression must be on one line", piece=text[:60], **where)
    builder = _Builder(text.strip(), symbols, where)
    result = builder.parse(text.strip(), depth=0)
    if any(_bits(number) > MAX_NUMBER_BITS for number in result.atoms(sp.Rational)):
        raise ExpressionError(
            f"a number in the expression exceeds {MAX_NUMBER_BITS} bits",
            piece=text.strip()[:60],
            **where,
        )
    if result.has(*_UNDEFINED):
        raise ExpressionError(
            f"expression is undefined, infinite or not real (it evaluates to {result})",
            piece=text.strip()[:60],
            **where,
        )
    check_constants(result, where)
    return result


def _check_ascii(text: str, where: dict) -> None:
    """Refuse an expression with a character outside ASCII.

    :func:`ast.parse` NFKC-normalises identifiers, so a look-alike would be
    read silently as an ASCII name: a fullwidth ``ｑ`` as the coordinate
    ``q``, the script ``ℯ`` as a parameter ``e``.  Declared names are ASCII
    (:func:`check_name`), so no such character can mean anything else.

    Raises
    ------
    ExpressionError
        Naming the first such character, its Unicode name and its position
        (1-based) in ``text``.
    """
    if text.isascii():
        return
    index, char = next((i, c) for i, c in enumerate(text) if not c.isascii())
    name = unicodedata.name(char, "unnamed")
    folded = unicodedata.normalize("NFKC", char)
    # Say what it would have become only where Python folds it (in a name).
    read_as = (
        f"; Python would read it as {folded!r}" if folded.isascii() and folded.isalpha() else ""
    )
    raise ExpressionError(
        f"expressions must be ASCII: character {char!r} ({name}, U+{ord(char):04X}) at "
        f"position {index + 1}{read_as}",
        piece=text.strip()[:60],
        **where,
    )


def _bits(number: sp.Rational) -> int:
    """Size of an exact rational: bits of its numerator or denominator."""
    return max(abs(number.p).bit_length(), number.q.bit_length())


def _number(value: float, **where) -> sp.Expr:
    if not math.isfinite(value):
        raise ExpressionError("numbers must be finite", piece=repr(value), **where)
    # The shortest decimal that round-trips, as an exact rational: keeps
    # symbolic checks (first integrals, simplification) exact.
    frac = Fraction(repr(value))
    return sp.Rational(frac.numerator, frac.denominator)


class _Builder:
    """Walks a syntax tree and builds the SymPy expression, or refuses."""

    def __init__(self, text: str, symbols: Mapping[str, sp.Symbol], where: dict):
        self.text = text
        self.path: list[ast.AST] = []  # the nodes being built, outermost first
        self.symbols = symbols
        self.where = where

    def fail(self, message: str, node: ast.AST) -> ExpressionError:
        piece = ast.get_source_segment(self.text, node) or type(node).__name__
        return ExpressionError(message, piece=piece, **self.where)

    def too_deep(self) -> ExpressionError:
        """The error of an expression nested deeper than :data:`MAX_DEPTH`.

        It names the outermost term that holds the nesting (the first node
        of :attr:`path` that is not a sum or a product), not the node that
        reached the limit, which is the innermost one: ``x**2**2**...`` was
        refused naming '2' as the offending piece (found by QA).
        """
        outer = next(
            (n for n in self.path if not (isinstance(n, ast.BinOp) and type(n.op) in _FAMILY)),
            None,
        )
        piece = (ast.get_source_segment(self.text, outer) if outer else None) or self.text
        return ExpressionError(
            f"expression nested deeper than {MAX_DEPTH} levels (operators, function calls "
            "or signs inside one another; a long flat sum or product is one level)",
            piece=_shortened(piece),
            **self.where,
        )

    def parse(self, text: str, depth: int) -> sp.Expr:
        """Parse ``text`` (a whole expression, or one term of a long chain)."""
        try:
            tree = ast.parse(text, mode="eval")
        except SyntaxError as exc:
            raise ExpressionError(
                f"not a valid expression ({exc.msg})", piece=text, **self.where
            ) from None
        except (ValueError, RecursionError, MemoryError):
            # Too long a chain for Python's parser: parse it term by term.
            split = split_chain(text)
            if split is None and wrapped(text):
                return self.parse(text[1:-1].strip(), depth + 1)
            call = CALL.match(text)
            if split is None and call and wrapped(text[call.end() - 1 :]):
                # f(<long chain>): a listed one-argument function of a long sum.
                name = call.group(1)
                if name not in FUNCTIONS:
                    raise ExpressionError(
                        f"function {name!r} is not allowed", piece=name, **self.where
                    ) from None
                if FUNCTIONS[name][1] != 1:
                    raise ExpressionError(
                        f"{name} of a chain this long cannot be parsed (only one-argument "
                        "functions can take one)",
                        piece=name,
                        **self.where,
                    ) from None
                argument = self.parse(text[call.end() : -1].strip(), depth + 1)
                return self.apply(FUNCTIONS[name][0], [argument])
            if split is None:
                raise ExpressionError(
                    "expression cannot be parsed", piece=text[:60], **self.where
                ) from None
            pieces, operators = split
            terms = [self.parse(piece.strip(), depth + 1) for piece in pieces]
            return _combine(terms[0], list(zip(operators, terms[1:], strict=True)))
        saved, self.text, outer, self.path = self.text, text, self.path, []
        try:
            return self.build(tree.body, depth)
        finally:
            self.text, self.path = saved, outer

    def chain(self, node: ast.BinOp, depth: int) -> sp.Expr:
        """A chain ``a + b - c ...`` (or ``a * b / c ...``) as one level: the
        left spine of the tree is walked in a loop, not by recursion."""
        family = _FAMILY[type(node.op)]
        rest: list[tuple[str, ast.AST]] = []
        while isinstance(node, ast.BinOp) and _FAMILY.get(type(node.op)) == family:
            rest.append((_SYMBOL[type(node.op)], node.right))
            node = node.left
        first = self.build(node, depth + 1)
        others = [(op, self.build(right, depth + 1)) for op, right in reversed(rest)]
        return _combine(first, others)

    def build(self, node: ast.AST, depth: int) -> sp.Expr:
        self.path.append(node)
        try:
            return self.build_node(node, depth)
        finally:
            self.path.pop()

    def build_node(self, node: ast.AST, depth: int) -> sp.Expr:
        """The expression of ``node``, ``depth`` levels inside the whole."""
        if depth > MAX_DEPTH:
            raise self.too_deep()
        if isinstance(node, ast.Constant):
            return self.constant(node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.BinOp) and type(node.op) in _FAMILY:
            return self.chain(node, depth)
        if isinstance(node, ast.BinOp):
            op = _BINARY.get(type(node.op))
            if op is None:
                text = _OPERATOR_TEXT.get(type(node.op), type(node.op).__name__)
                raise self.fail(f"operator {text!r} is not allowed", node)
            left = self.build(node.left, depth + 1)
            right = self.build(node.right, depth + 1)
            if isinstance(node.op, ast.Pow):
                self.check_power(left, right, node)
            return op(left, right)
        if isinstance(node, ast.UnaryOp):
            op = _UNARY.get(type(node.op))
            if op is None:
                text = _OPERATOR_TEXT.get(type(node.op), type(node.op).__name__)
                raise self.fail(f"operator {text!r} is not allowed", node)
            return op(self.build(node.operand, depth + 1))
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise self.fail(f"{_describe(node)} is not allowed in an expression", node)

    def constant(self, node: ast.Constant) -> sp.Expr:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, int | float):
            kind = "a string" if isinstance(value, str | bytes) else type(value).__name__
            raise self.fail(f"{kind} is not allowed in an expression", node)
        if isinstance(value, int):
            if len(str(abs(value))) > MAX_DIGITS:
                raise self.fail(f"integer literal longer than {MAX_DIGITS} digits", node)
            return sp.Integer(value)
        return _number(value, **self.where)

    def name(self, node: ast.Name) -> sp.Expr:
        ident = node.id
        if ident.startswith("__"):
            raise self.fail("dunder names are not allowed", node)
        if ident in self.symbols:
            return self.symbols[ident]
        if ident in CONSTANTS:
            return CONSTANTS[ident]
        if ident in FUNCTIONS:
            raise self.fail(f"function {ident!r} used without arguments", node)
        raise self.fail("unknown name (not a declared symbol, t, pi or E)", node)

    def call(self, node: ast.Call, depth: int) -> sp.Expr:
        if not isinstance(node.func, ast.Name):
            raise self.fail("only the listed functions may be called", node)
        ident = node.func.id
        if ident not in FUNCTIONS:
            raise self.fail(f"function {ident!r} is not allowed", node)
        if node.keywords:
            raise self.fail("keyword arguments are not allowed", node)
        if any(isinstance(arg, ast.Starred) for arg in node.args):
            raise self.fail("starred arguments are not allowed", node)
        function, arity = FUNCTIONS[ident]
        if len(node.args) != arity:
            raise self.fail(
                f"{ident} takes {arity} argument{'s' if arity > 1 else ''}, got {len(node.args)}",
                node,
            )
        return self.apply(function, [self.build(arg, depth + 1) for arg in node.args])

    def apply(self, function: Callable[..., sp.Expr], args: list[sp.Expr]) -> sp.Expr:
        """``function(*args)``, once each constant argument is known to be a
        finite real double: SymPy's atan2 of an imaginary number,
        ``atan2(acos(27), acos(27))``, never returned."""
        for arg in args:
            check_constants(arg, self.where)
        return function(*args)

    def check_power(self, base: sp.Expr, exponent: sp.Expr, node: ast.AST) -> None:
        if exponent.is_Number and abs(exponent) > MAX_EXPONENT:
            raise self.fail(f"exponent larger than {MAX_EXPONENT} in magnitude", node)
        if base.is_Number and exponent.is_Number and abs(base) > 1 and abs(exponent) > 64:
            raise self.fail("numeric power too large", node)
        if base.is_Rational and exponent.is_Number and base != 0:
            if _bits(base) * abs(float(exponent)) > MAX_NUMBER_BITS:
                raise self.fail(f"numeric power too large (over {MAX_NUMBER_BITS} bits)", node)


def _shortened(text: str, width: int = 60) -> str:
    """``text``, cut to ``width`` characters with "..." where it is longer."""
    return text if len(text) <= width else text[: width - 3] + "..."


def _describe(node: ast.AST) -> str:
    names = {
        ast.Attribute: "attribute access",
        ast.Subscript: "subscripting",
        ast.Lambda: "lambda",
        ast.ListComp: "a comprehension",
        ast.SetComp: "a comprehension",
        ast.DictComp: "a comprehension",
        ast.GeneratorExp: "a generator expression",
        ast.Compare: "a comparison",
        ast.BoolOp: "a boolean operator",
        ast.IfExp: "a conditional expression",
        ast.List: "a list",
        ast.Tuple: "a tuple",
        ast.Dict: "a dict",
        ast.Set: "a set",
        ast.JoinedStr: "an f-string",
        ast.NamedExpr: "an assignment expression",
        ast.Await: "await",
        ast.Yield: "yield",
        ast.YieldFrom: "yield",
        ast.Starred: "a starred expression",
        ast.Slice: "a slice",
    }
    return names.get(type(node), type(node).__name__)
